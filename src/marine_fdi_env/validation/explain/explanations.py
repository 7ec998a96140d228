"""Every explanation the data allow, ranked by evidence: the set the data do not decide between.

The selection (:mod:`.select.selection`) names one model.  Other model structures (mechanisms + each valve's per-point
support, found by :mod:`.search`) may fit the data as well.  Each is refitted with its valve points held
and cross-validated with them held (a left-out point's opening from the schedule through the others', as the
selection predicts it), and ranked by the selection's own criterion, the penalised cross-validated score
``S exp(2k/M)``: ``M ln`` of it is an AIC on the cross-validated robust cost with the residual scale estimated, so
the evidence of a structure relative to the best is

    ``ΔAIC = M ln(S̃ / S̃_best)``  (``exp(-ΔAIC/2)`` its likelihood ratio on the estimated scale).

**The set** holds every admissible structure that the data do not exclude. A structure is excluded only when the
evidence is against it on every count: outside the band on the cross-validated criterion (``ΔAIC >`` :data:`BAND`,
2: a likelihood ratio below e^-1, "barely worth mentioning" on Jeffreys' scale), consistently worse point by point
(one-sided paired t-test of the per-point cross-validated losses against the best, ``p <`` :data:`EXCLUDE_ALPHA`: a
cross-validated difference that one or two held-out points carry is not evidence between structures), and outside
the band in sample too (AICc on the in-sample robust cost with the scale estimated, ``M ln(S) + 2K +
2K(K+1)/(M-K-1)`` with ``K = k + 1``, against the best's). Cross-validation alone is biased between structures of
equal fit: a mechanism whose fit sits at the bounds of its range refits less from fold to fold and predicts the
left-out point better than the true one (in the open-world study: a blade-speed-ratio loss at both its bounds ahead
of the true map change, cross-validated 3 AIC units and p = 0.009-0.03 better, within 1 AIC
unit of it in sample). A structure that is the best one without some of its causes (each remaining valve at the same
points) is excluded by the best's admissibility: each of its causes earned its place against the structure without
it (:func:`nested_in`).

**Admissible** (:func:`admissibility`): every valve opens somewhere, no parameter sits at a bound of its plausible
range that the data want beyond (as the selection's eligibility), and every cause earns its place against the
structure without it by the selection's own test (:func:`~.select.evidence.earns`: gain ≥ ``min_gain`` and the F-test at
``alpha`` over the first step's candidates, in sample for a physical mechanism beside a valve), so that "the named
causes plus a mechanism the data do not ask for" is not an explanation of its own. The first of the set is the named
model unless the search found a better admissible one.

Profile-likelihood intervals (:mod:`.profiles`) are computed for the set's members.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

import numpy as np

from ..fit.fitting import (
    Combination,
    FitResult,
    cell_losses,
    channel_rmse,
    fit_combination,
    predict_setting,
    refit_fold,
    training_folds,
)
from ..fit.problem import FitProblem
from ..select.candidates import CandidateScore, paired_p
from ..select.eligibility import why_pinned
from ..select.evidence import BESIDE_VALVE_DEFAULT, IN_SAMPLE_ALONE, earns, judged_in_sample
from .profiles import ProfileInterval, fit_profiles
from .search import Structure, candidate_structures, support_key

__all__ = [
    "BAND",
    "explanation_set_of",
    "EXCLUDE_ALPHA",
    "Explanation",
    "ExplanationSet",
    "admissibility",
    "aicc_in_sample",
    "cross_validate_held",
    "explanation_set",
    "nested_in",
]

#: ΔAIC on the cross-validated robust cost within which a structure is in the set whatever the paired test says
BAND = 2.0
#: level of the one-sided paired test over points that excludes a structure outside the band
EXCLUDE_ALPHA = 0.05


def cross_validate_held(problem: FitProblem, fit: FitResult, max_folds: int | None = None) -> np.ndarray:
    """Cross-validated predictions (points x channels) of ``fit``'s structure: each fold refitted with the valve
    supports held (the left-out point's opening from the schedule through the training points')."""
    pred = np.full((problem.n_points, len(problem.channels)), np.nan)
    comb = fit.combination
    for _, train, test in training_folds(problem, max_folds):
        f = refit_fold(problem, comb, train, fit, known=fit.values(), support=fit.support)
        pred[test] = predict_setting(problem, f, test)
    return pred


@dataclass
class Explanation:
    """A structure scored as an explanation (module docstring)."""

    structure: Structure
    cv_pred: np.ndarray
    point_losses: np.ndarray
    cv_score: float
    penalised: float
    in_sample_score: float
    delta_aic: float = math.nan
    p_worse: float = math.nan
    delta_aicc_in: float = math.nan
    in_set: bool = False
    why_not: str | None = None  # None: admissibility not checked; "": admissible
    named: bool = False
    profiles: dict[str, ProfileInterval] = field(default_factory=dict)

    @property
    def fit(self) -> FitResult:
        return self.structure.fit

    @property
    def labels(self) -> tuple[str, ...]:
        return self.fit.combination.labels

    @property
    def key(self):
        return self.structure.key

    def valve_states(self, problem: FitProblem) -> dict[str, list[dict[str, Any]]]:
        """Per valve, per measured point (file row order): open or shut, the opening and the diverted flow fraction."""
        out: dict[str, list[dict[str, Any]]] = {}
        if not self.fit.combination.valves:
            return out
        vals, conv = problem.solve(self.fit.setting(problem))
        load = problem.load_axis()
        for m in self.fit.combination.valves:
            sup = set(self.fit.support.get(m.id, ()))
            frac = vals[m.activity_key()]
            out[m.id] = [
                {
                    "point": i + 1,
                    "load": float(load[i]),
                    "open": i in sup,
                    "opening": float(self.fit.openings[m.id][i]) if i in sup else 0.0,
                    "fraction": float(frac[i]) if i in sup and conv[i] else 0.0,
                }
                for i in range(problem.n_points)
            ]
        return out

    def as_dict(self, problem: FitProblem, rank: int | None = None) -> dict[str, Any]:
        fit = self.fit
        rin = channel_rmse(problem, predict_setting(problem, fit, np.arange(problem.n_points)))
        rcv = channel_rmse(problem, self.cv_pred)
        d: dict[str, Any] = {
            "rank": rank,
            "labels": list(self.labels),
            "named": self.named,
            "origin": self.structure.origin,
            "support": {k: [i + 1 for i in v] for k, v in support_key(fit)},
            "k": fit.k,
            "in_sample_score": self.in_sample_score,
            "robust_cost": fit.data_cost,
            "cv_score": self.cv_score,
            "penalised_score": self.penalised,
            "delta_aic": self.delta_aic,
            "p_worse": self.p_worse,
            "delta_aicc_in_sample": self.delta_aicc_in,
            "in_set": self.in_set,
            "admissible": None if self.why_not is None else not self.why_not,
            "parameters": fit.values(),
            "nuisance": fit.nuisance_values(),
            "channels": {c: {"rmse_in_sample": rin[c], "cv_rmse": rcv[c]} for c in problem.channels},
            "valve_states": self.valve_states(problem),
        }
        if self.why_not:
            d["why_not"] = self.why_not
        if self.profiles:
            d["profiles"] = {k: v.as_dict() for k, v in self.profiles.items()}
        if self.structure.notes:
            d["notes"] = list(self.structure.notes)
        return d


@dataclass
class ExplanationSet:
    """The ranked set (:attr:`members`, best first) and every structure tried (:attr:`tried`, by penalised score)."""

    members: list[Explanation]
    tried: list[Explanation]
    n_cells: int
    seconds: float
    rule: str

    def outside(self) -> list[Explanation]:
        return [e for e in self.tried if not e.in_set]

    def runner_up(self) -> Explanation | None:
        """The best-ranked admissible structure outside the set (what the data did decide against)."""
        return next((e for e in self.tried if not e.in_set and e.why_not == ""), None)

    def as_dict(self, problem: FitProblem) -> dict[str, Any]:
        return {
            "rule": self.rule,
            "band_delta_aic": BAND,
            "exclude_alpha": EXCLUDE_ALPHA,
            "n_cells": self.n_cells,
            "seconds": self.seconds,
            "members": [e.as_dict(problem, i + 1) for i, e in enumerate(self.members)],
            "outside": [e.as_dict(problem) for e in self.outside()],
        }


RULE = (
    f"structures ranked by the penalised cross-validated score (ΔAIC = M ln of its ratio to the best); excluded "
    f"when ΔAIC > {BAND:g}, a one-sided paired t-test of the per-point cross-validated losses gives "
    f"p < {EXCLUDE_ALPHA:g} and the in-sample AICc is more than {BAND:g} above the best's, or when it is the best "
    "without some of its causes; every member admissible (each valve opens, no parameter pinned at a bound the "
    "data want beyond, each cause earns its place by the selection's test)"
)


def aicc_in_sample(e: "Explanation", M: int) -> float:
    """AICc of ``e``'s in-sample robust cost with the residual scale estimated (``K = k + 1``)."""
    K = e.fit.k + 1
    return M * math.log(max(e.in_sample_score, 1e-300)) + 2 * K + 2 * K * (K + 1) / max(M - K - 1, 1)


def _score(
    problem: FitProblem, s: Structure, M: int, penalty: float, max_folds: int | None, cv: np.ndarray | None = None
) -> Explanation:
    pred = cross_validate_held(problem, s.fit, max_folds) if cv is None else cv
    L, _ = cell_losses(problem, pred)
    S = float(L.sum() / M)
    return Explanation(s, pred, L, S, S * math.exp(penalty * s.fit.k / M), 2.0 * s.fit.data_cost / M)


def admissibility(
    problem: FitProblem,
    e: Explanation,
    scored: Callable[[FitResult, str], Explanation],
    *,
    M: int,
    min_gain: float,
    threshold: float,
    beside_valve: str,
) -> tuple[str, list[Explanation]]:
    """Why ``e`` is not an explanation ("" when it is; module docstring) and the reduced structures it was tested
    against (each without one cause, valve supports held)."""
    fit = e.fit
    shut = [m.label for m in fit.combination.valves if not fit.support.get(m.id)]
    if shut:
        return f"{', '.join(shut)} opens at no point", []
    c = CandidateScore(fit.combination, " + ".join(fit.combination.labels), fit, e.in_sample_score)
    pins = why_pinned(problem, c, fit.values(), dict(fit.support))
    e.structure.notes.extend(n for n in c.notes if n not in e.structure.notes)
    if pins:
        return "; ".join(pins), []
    reduced = []
    for m in fit.combination.mechanisms:
        comb = Combination(tuple(x for x in fit.combination.mechanisms if x is not m))
        support = {k: v for k, v in fit.support.items() if k in {x.id for x in comb.valves}}
        f = fit_combination(problem, comb, start=fit, known=fit.values(), support=support, uncertainty=False)
        r = scored(f, f"{' + '.join(fit.combination.labels)} without {m.label}")
        reduced.append(r)
        in_sample = judged_in_sample(comb, [m], beside_valve)
        gain, p, why = earns(
            (r.cv_score, r.in_sample_score, f.k),
            (e.cv_score, e.in_sample_score, fit.k),
            M,
            min_gain,
            threshold,
            in_sample,
            cv_guard=beside_valve not in IN_SAMPLE_ALONE,
        )
        if why:
            return f"{m.label} does not earn its place ({why})", reduced
    return "", reduced


def nested_in(e: Explanation, other: Explanation) -> bool:
    """Whether ``e`` is ``other`` without some of its causes, each remaining valve at the same points."""
    return set(e.labels) < set(other.labels) and all(
        sorted(e.fit.support.get(m.id, ())) == sorted(other.fit.support.get(m.id, ())) for m in e.fit.combination.valves
    )


def explanation_set(
    problem: FitProblem,
    named: FitResult,
    steps: Sequence[dict[str, Any]],
    *,
    alpha: float = 0.01,
    min_gain: float = 0.10,
    penalty: float = 2.0,
    max_folds: int | None = None,
    beside_valve: str = BESIDE_VALVE_DEFAULT,
    base_cv: np.ndarray | None = None,
    profiles: bool = True,
    extra: Sequence[FitResult] = (),
    say: Callable[[str], None] | None = None,
) -> ExplanationSet:
    """The explanations of ``problem`` around the selection's named model ``named`` (its fit) and steps (module
    docstring).  ``base_cv``: the calibrated base model's cross-validated predictions (the structure without any
    cause).  ``extra``: fits of further structures to weigh (a hypothesis of one's own; each valve's support as
    fitted).  Nothing named and nothing extra: the set is the base model alone (no search)."""
    t0 = time.perf_counter()
    say = say or (lambda s: None)
    M = named.n_cells
    n1 = sum(1 for c in steps[0]["candidates"] if c.members is None) if steps else 1
    threshold = alpha / max(n1, 1)
    cache: dict[Any, Explanation] = {}

    def scored(fit: FitResult, origin: str) -> Explanation:
        s = Structure(fit, origin)
        if s.key not in cache:
            cv = base_cv if not fit.combination.mechanisms and base_cv is not None else None
            cache[s.key] = _score(problem, s, M, penalty, max_folds, cv)
        return cache[s.key]

    structures = candidate_structures(problem, named, steps, penalty, say)
    structures += [Structure(f, "given") for f in extra]
    for s in structures:
        e = scored(s.fit, s.origin)
        e.structure.notes.extend(n for n in s.notes if n not in e.structure.notes)
    named_key = structures[0].key
    cache[named_key].named = True
    rows = problem.rows_with_data()
    checked: set = set()

    def check(e: Explanation) -> None:
        if e.key in checked:
            return
        checked.add(e.key)
        e.why_not = (
            admissibility(problem, e, scored, M=M, min_gain=min_gain, threshold=threshold, beside_valve=beside_valve)[0]
            if e.fit.combination.mechanisms
            else ""
        )

    def excluded(e: Explanation) -> bool:
        return e is not best and (
            nested_in(e, best) or (e.delta_aic > BAND and e.p_worse < EXCLUDE_ALPHA and e.delta_aicc_in > BAND)
        )

    best: Explanation | None = None
    while True:
        for e in sorted(cache.values(), key=lambda e: e.penalised):  # the best admissible structure is the reference
            if best is not None and e.penalised >= best.penalised:
                break
            check(e)
            if not e.why_not:
                best = e
                break
        if best is None:  # nothing admissible: the named model stands alone
            best = cache[named_key]
            best.why_not = best.why_not or ""
        for e in cache.values():
            e.delta_aic = M * math.log(e.penalised / best.penalised)
            e.delta_aicc_in = aicc_in_sample(e, M) - aicc_in_sample(best, M)
            e.p_worse = 1.0 if e is best else paired_p(e.point_losses, best.point_losses, rows)
        pending = [e for e in cache.values() if e.key not in checked and not excluded(e)]
        if not pending and not any(
            not e.why_not and e.why_not is not None and e.penalised < best.penalised for e in cache.values()
        ):
            break
        for e in pending:
            check(e)
    for e in cache.values():
        e.in_set = e is best or (e.why_not == "" and not excluded(e))
    tried = sorted(cache.values(), key=lambda e: e.penalised)
    members = [e for e in tried if e.in_set]
    if profiles:
        for e in members:
            if e.fit.combination.mechanisms:
                e.profiles = fit_profiles(problem, e.fit)
    say(f"explanations: {len(members)} in the set of {len(tried)} structures tried ({time.perf_counter() - t0:.1f} s)")
    return ExplanationSet(members, tried, M, time.perf_counter() - t0, RULE)


def explanation_set_of(sel: Any, *, profiles: bool = True, say: Callable[[str], None] | None = None) -> ExplanationSet:
    """:func:`explanation_set` of a :class:`~.select.selection.Selection`, under the rules it was selected with (its
    ``settings``)."""
    st = sel.settings
    return explanation_set(
        sel.problem,
        sel.fit,
        sel.steps,
        alpha=st["alpha"],
        min_gain=st["min_gain"],
        penalty=st["penalty"],
        max_folds=st.get("max_folds"),
        beside_valve=st["beside_valve"],
        base_cv=sel.base_pred,
        profiles=profiles,
        say=say,
    )
