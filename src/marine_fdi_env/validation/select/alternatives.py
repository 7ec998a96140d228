"""What the data hardly tell from an accepted cause (:mod:`.selection`): the other candidates of its step
cross-validated within :data:`ALTERNATIVE_MARGIN`, and its structural equivalents (:mod:`.fit.mechanisms`)."""

from __future__ import annotations

from typing import Any, Sequence

from ..fit.mechanisms import equivalents
from .candidates import CandidateScore

__all__ = ["ALTERNATIVE_MARGIN", "pair_alternatives", "step_alternatives"]

#: relative margin of the cross-validated score within which another candidate is reported as an alternative
ALTERNATIVE_MARGIN = 0.05


def step_alternatives(best: CandidateScore, cv: Sequence[CandidateScore], margin: float) -> list[dict[str, Any]]:
    """Other candidates of the step the data hardly tell from the accepted one: cross-validated within ``margin``
    (relative) of its score, and the members of its structural-equivalence class (:mod:`.fit.mechanisms`)."""
    out = []
    eq = equivalents(best.combination.mechanisms[-1].id)
    for c in cv:
        if c is best:
            continue
        close = c.cv_score <= best.cv_score * (1.0 + margin)
        struct = c.combination.mechanisms[-1].id in eq
        if close or struct:
            out.append(
                {
                    "mechanism": c.added,
                    "cv_score": c.cv_score,
                    "relative": c.cv_score / best.cv_score - 1.0,
                    "why": "structurally equivalent on steady-state data"
                    if struct
                    else f"cross-validated score within {margin:.0%}",
                }
            )
    for m in sorted(eq - {c.combination.mechanisms[-1].id for c in cv}):
        out.append(
            {"mechanism": m, "cv_score": None, "relative": None, "why": "structurally equivalent on steady-state data"}
        )
    return out


def pair_alternatives(
    best: CandidateScore, pairs: Sequence[CandidateScore], margin: float
) -> dict[str, list[dict[str, Any]]]:
    """Per member of an accepted pair: the mechanisms that replace it in another cross-validated pair with the
    other member within ``margin`` of the pair's score, and its structural equivalents."""
    out = {}
    a, b = best.members
    for m, other in ((a, b), (b, a)):
        mid = m.combination.mechanisms[-1].id
        alts = []
        for c in pairs:
            if c is best or not c.cross_validated or other not in c.members:
                continue
            z = next(x for x in c.members if x is not other)
            if c.cv_score <= best.cv_score * (1.0 + margin):
                alts.append(
                    {
                        "mechanism": z.added,
                        "cv_score": c.cv_score,
                        "relative": c.cv_score / best.cv_score - 1,
                        "why": f"with {other.added}: cross-validated score within {margin:.0%}",
                    }
                )
        for e in sorted(equivalents(mid)):
            alts.append(
                {
                    "mechanism": e,
                    "cv_score": None,
                    "relative": None,
                    "why": "structurally equivalent on steady-state data",
                }
            )
        out[m.added] = alts
    return out
