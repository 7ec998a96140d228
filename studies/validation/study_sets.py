"""The open-world study's view of the explanation set (:mod:`.explanations`): what a trial records of it and how a
condition's trials are summarised.

A trial's set is the list of its members' causes (sorted labels; the valve points in ``set_supports``).  Set
coverage is the share of trials whose true causes are the causes of a member (for (e), whose truth is no library
mechanism, a member with no cause); first-ranked identification the share whose best-ranked member's causes are
the truth's, beside the selection's own (``exact``).  A control's set names a cause when any member has one.
"""

from __future__ import annotations

import statistics
from typing import Any, Mapping, Sequence

from marine_fdi_env.validation.explain.explanations import explanation_set_of
from marine_fdi_env.validation.select.binomial import proportion_ci95

__all__ = ["set_outcome", "set_summary"]


def set_outcome(sel, truth_labels: Sequence[str], alternative: Sequence[str] | None = None) -> dict[str, Any]:
    """What a trial records of its explanation set (no profiles, no deciding measurement: the study scores the set
    only); ``alternative``: the structure a condition-(f) trial was constructed to be confused with."""
    es = explanation_set_of(sel, profiles=False)
    members = [sorted(e.labels) for e in es.members]
    truth = sorted(truth_labels)
    out = {
        "set": members,
        "set_size": len(members),
        "truth_in_set": truth in members,
        "first_ranked": members[0],
        "first_ranked_exact": members[0] == truth,
        "set_names_a_cause": any(members),
        "set_supports": [{k: [int(i) + 1 for i in v] for k, v in e.fit.support.items()} for e in es.members],
        "set_delta_aic": [e.delta_aic for e in es.members],
        "set_structures_tried": len(es.tried),
        "set_seconds": es.seconds,
    }
    if alternative is not None:
        out["alternative_in_set"] = sorted(alternative) in members
    return out


def _rate(k: int, n: int) -> dict[str, Any]:
    return {"k": k, "n": n, "rate": k / n if n else None, "ci95": proportion_ci95(k, n)}


def set_summary(results: Sequence[Mapping[str, Any]], condition: str) -> dict[str, Any]:
    """Set coverage, first-ranked identification (with exact 95 % intervals) and the median set size of a
    condition's trials, and how often its controls' sets name a cause; {} when the trials recorded no set."""
    tr = [r for r in results if r["condition"] == condition and not r["control"] and "set" in r]
    ct = [r for r in results if r["condition"] == condition and r["control"] and "set" in r]
    if not tr and not ct:
        return {}
    out: dict[str, Any] = {}
    if tr:
        out["set_coverage"] = _rate(sum(r["truth_in_set"] for r in tr), len(tr))
        out["first_ranked_identification"] = _rate(sum(r["first_ranked_exact"] for r in tr), len(tr))
        out["named_identification"] = _rate(sum(bool(r.get("exact")) for r in tr), len(tr))
        out["median_set_size"] = statistics.median(r["set_size"] for r in tr)
        out["set_sizes"] = {str(k): sum(r["set_size"] == k for r in tr) for k in sorted({r["set_size"] for r in tr})}
        alt = [r for r in tr if "alternative_in_set" in r]
        if alt:
            out["alternative_in_set"] = _rate(sum(r["alternative_in_set"] for r in alt), len(alt))
    if ct:
        out["control_set_names_a_cause"] = _rate(sum(r["set_names_a_cause"] for r in ct), len(ct))
        out["control_median_set_size"] = statistics.median(r["set_size"] for r in ct)
    return out
