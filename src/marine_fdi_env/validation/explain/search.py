"""Where the evidence set (:mod:`.explanations`) looks: model structures near the selection's answer.

A *structure* is a set of mechanisms and, for each valve among them, the points where it acts (its support).  The
greedy selection (:mod:`.select.selection`) follows one path: the best candidate of each step, the valve supports
fixed by the step that added the valve.  The search keeps more than that path, without enumerating the 2^n supports:

1. **The named causes with the valves' points chosen again** with every cause in place (the relaxation of
   :mod:`.fit.fitting` over all supports at once): a later step cannot otherwise revisit the support step 1 chose.
2. **The k best partial models of every step.**  Each step of the path fitted every candidate in sample, singles and
   pairs; a pair of a valve and a base-structure mechanism (map shape, turbine flow law, heat loss) relaxed the
   valve's support jointly with it.  Up to :data:`MAX_STARTS` candidates per step are kept (:func:`_starts`): first
   those the step cross-validated and found eligible within :data:`START_BAND` (AIC units, ``M ln(S exp(2k/M))``)
   of the accepted one's penalised score, then those that hold its valve at other points (another picture of the
   same valve) and then any other within the band in sample; never one that merely adds a mechanism to the accepted
   one with the same valve points (the next step tries those).  Each is completed with the causes the path named
   after that step, fitted with its own valve points held, and again with every support relaxed.
3. **A valve added** to the named structure and to the first step's best alternative, its points relaxed with the
   structure's held: whether a valve can enter at all depends on the structure it joins.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Sequence

from ..fit.fitting import Combination, FitResult, fit_combination
from ..fit.mechanisms import VALVE_MECHANISMS, Mechanism
from ..fit.problem import FitProblem
from ..select.candidates import CandidateScore

__all__ = ["MAX_STARTS", "START_BAND", "Structure", "accepted_steps", "candidate_structures", "support_key"]

#: in-sample AIC units within which a step's candidate is kept as a start (item 2 of the module docstring)
START_BAND = 6.0
#: at most this many starts per step, best in-sample first
MAX_STARTS = 3


def support_key(fit: FitResult) -> tuple[tuple[str, tuple[int, ...]], ...]:
    """The valve supports of a fit, sorted (rows, 0-based)."""
    return tuple(sorted((k, tuple(sorted(int(i) for i in v))) for k, v in fit.support.items()))


@dataclass
class Structure:
    """A candidate explanation: mechanisms, the fit that fixes each valve's support, and how the search found it."""

    fit: FitResult
    origin: str
    notes: list[str] = field(default_factory=list)

    @property
    def combination(self) -> Combination:
        return self.fit.combination

    @property
    def key(self) -> tuple[tuple[str, ...], tuple[tuple[str, tuple[int, ...]], ...]]:
        return tuple(sorted(self.combination.labels)), support_key(self.fit)


def accepted_steps(steps: Sequence[Mapping[str, Any]]) -> list[tuple[Mapping[str, Any], CandidateScore]]:
    """The selection's accepted forward steps with their accepted candidate (not the removal and exchange steps)."""
    out = []
    for s in steps:
        if not s.get("accepted") or "removed" in s or "exchanged" in s:
            continue
        acc = next((c for c in s["candidates"] if c.added == s["best"]), None)
        if acc is not None:
            out.append((s, acc))
    return out


def _penalised_in(c: CandidateScore, M: int, penalty: float) -> float:
    return c.in_sample_score * math.exp(penalty * c.fit.k / M)


def _is_addon(c: CandidateScore, acc: CandidateScore, n_before: int) -> bool:
    """Whether ``c`` is the accepted candidate plus more mechanisms with the accepted candidate's valve points."""
    added = acc.combination.mechanisms[n_before:]
    if not all(m in c.combination.mechanisms for m in added) or len(c.combination.mechanisms) <= len(
        acc.combination.mechanisms
    ):
        return False
    return all(
        sorted(c.fit.support.get(m.id, ())) == sorted(acc.fit.support.get(m.id, ())) for m in added if m.pointwise
    )


def _starts(step: Mapping[str, Any], acc: CandidateScore, M: int, penalty: float) -> list[CandidateScore]:
    """Up to :data:`MAX_STARTS` alternatives to the accepted candidate of a step, in this order: the eligible
    cross-validated candidates within :data:`START_BAND` of its penalised cross-validated score (the selection's own
    ranking), the candidates that hold its valve at other points (another picture of the same valve), then any
    other candidate within the band in sample; never one that merely adds to it with the same valve points."""
    n_before = len(acc.combination.mechanisms) - len(acc.members or (acc,))
    ref_in = _penalised_in(acc, M, penalty)
    ref_cv = acc.penalised if math.isfinite(acc.penalised) else ref_in
    valves = {m.id: sorted(acc.fit.support.get(m.id, ())) for m in acc.combination.mechanisms[n_before:] if m.pointwise}
    groups: list[list[tuple[float, CandidateScore]]] = [[], [], []]
    for c in step["candidates"]:
        if c is acc or c.fit is None or c.screened.startswith("not eligible") or not c.in_sample_score > 0:
            continue
        if _is_addon(c, acc, n_before):
            continue
        if c.cross_validated and math.isfinite(c.penalised):
            d = M * math.log(c.penalised / ref_cv)
            if d <= START_BAND:
                groups[0].append((d, c))
                continue
        d = M * math.log(_penalised_in(c, M, penalty) / ref_in)
        if d > START_BAND:
            continue
        other_points = any(
            v in {m.id for m in c.combination.valves} and sorted(c.fit.support.get(v, ())) != pts
            for v, pts in valves.items()
        )
        groups[1 if other_points else 2].append((d, c))
    out = [c for g in groups for _, c in sorted(g, key=lambda t: t[0])]
    return out[:MAX_STARTS]


def candidate_structures(
    problem: FitProblem,
    named: FitResult,
    steps: Sequence[Mapping[str, Any]],
    penalty: float,
    say: Callable[[str], None] | None = None,
) -> list[Structure]:
    """The structures of the module docstring, the named one first (duplicates by mechanisms and supports
    removed; a valve that opens nowhere is dropped from the structure it was added to)."""
    say = say or (lambda s: None)
    M = named.n_cells
    out: dict[Any, Structure] = {}

    def add(fit: FitResult, origin: str) -> Structure | None:
        if any(not fit.support.get(m.id) for m in fit.combination.valves):
            return None
        s = Structure(fit, origin)
        if s.key not in out:
            out[s.key] = s
            say(
                f"explanations: {' + '.join(fit.combination.labels) or 'nothing'} "
                f"{dict(support_key(fit)) or ''} in-sample {2 * fit.data_cost / M:.4g} ({origin})"
            )
            return s
        return None

    add(named, "named by the selection")
    comb = named.combination
    if not comb.mechanisms:
        return list(out.values())
    known = named.values()
    if comb.valves:
        add(
            fit_combination(problem, comb, start=named, known=known, uncertainty=False),
            "the named causes, every valve's points chosen again with all of them in place",
        )
    first_alt: Structure | None = None
    for i, (step, acc) in enumerate(accepted_steps(steps)):
        n_acc = len(acc.members or (acc,))
        added_at = acc.combination.mechanisms[len(acc.combination.mechanisms) - n_acc :]
        for c in _starts(step, acc, M, penalty):
            later = [
                m
                for m in comb.mechanisms
                if m not in c.combination.mechanisms and m not in added_at and m not in acc.combination.mechanisms
            ]
            full = Combination(c.combination.mechanisms + tuple(later))
            origin = f"step {step['step']}: {c.added} in place of {acc.added}" + (
                ", then " + " + ".join(m.label for m in later) if later else ""
            )
            held = {k: v for k, v in c.fit.support.items() if k in {m.id for m in full.valves}}
            f1 = fit_combination(
                problem, full, start=c.fit, known={**known, **c.fit.values()}, support=held, uncertainty=False
            )
            s1 = add(f1, origin + " (its valve points held)")
            if i == 0 and first_alt is None and s1 is not None:
                first_alt = s1
            if full.valves:
                add(
                    fit_combination(problem, full, start=f1, known=f1.values(), uncertainty=False),
                    origin + " (every valve's points chosen again)",
                )
    for base in [s for s in (out.get(Structure(named, "").key), first_alt) if s is not None]:
        for v in _valves_missing(base.combination):
            f = fit_combination(
                problem,
                base.combination.plus(v),
                start=base.fit,
                known=base.fit.values(),
                support=dict(base.fit.support),
                uncertainty=False,
            )
            add(f, f"{base.origin}, with {v.label} added")
    return list(out.values())


def _valves_missing(comb: Combination) -> list[Mechanism]:
    have = {m.id for m in comb.valves}
    return [v for v in VALVE_MECHANISMS if v.id not in have]
