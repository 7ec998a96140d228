"""Pairs of physical mechanisms added together at a selection step (:mod:`.selection`, step 5), and the test each
member of an accepted pair must pass against the other alone."""

from __future__ import annotations

import math
from typing import Mapping, Sequence

from ..fit.fitting import Combination, FitResult, cross_validate, fit_combination
from ..fit.mechanisms import SensorCalibration
from ..fit.problem import FitProblem
from .candidates import CandidateScore
from .evidence import BESIDE_VALVE_DEFAULT, IN_SAMPLE_ALONE, earns, judged_in_sample

__all__ = ["PAIR_CV", "members_earn_their_place", "pair_candidates"]

#: per greedy step, at most this many pairs (the best by in-sample penalised score) are cross-validated
PAIR_CV = 3


def pair_candidates(
    problem: FitProblem,
    current: Combination,
    current_fit: FitResult,
    scored: Sequence[CandidateScore],
    known: Mapping[str, float],
    M: int,
    penalty: float,
    current_S: float,
    bar_pen: float,
    min_gain: float,
    max_folds: int | None,
    say,
) -> list[CandidateScore]:
    """Every pair of physical mechanisms added together to ``current`` (fitted jointly), the promising ones
    cross-validated.

    Greedy forward selection is myopic: two mechanisms whose effects only fit the data together (more friction
    needs more fuel and heats the exhaust; a manifold heat loss cools it again) can each explain little alone,
    while a sensor calibration absorbs the one channel the pair disagrees on and blocks the way to both.  Pairs
    are formed with at least one member that improves the current model's in-sample score by ``min_gain`` alone
    (fitted from the better member's fit, without standard errors; the accepted pair is refitted with them).  A
    pair is cross-validated only when its in-sample penalised score is below ``bar_pen`` (the best the step's single
    candidates reached, cross-validated) and its in-sample fit improves on the current model and on each member
    alone by ``min_gain``; at most :data:`PAIR_CV` of them, best first.  Sensor calibrations are not paired (they
    are fitted on a model's readings and can join at the next step)."""
    singles = [c for c in scored if not isinstance(c.combination.mechanisms[-1], SensorCalibration)]
    s_in = 2.0 * current_fit.data_cost / M  # the current model's in-sample score: what a lead member must improve
    lead = {id(c) for c in singles if s_in > 0 and (s_in - c.in_sample_score) / s_in >= min_gain}
    pairs: list[CandidateScore] = []
    for i, a in enumerate(singles):
        for b in singles[i + 1 :]:
            if id(a) not in lead and id(b) not in lead:
                continue
            comb = current.plus(a.combination.mechanisms[-1]).plus(b.combination.mechanisms[-1])
            first = min((a, b), key=lambda c: c.in_sample_score)  # its fit as the start, the other's starts tried
            fit = fit_combination(
                problem,
                comb,
                start=first.fit,
                known={**known, **first.fit.values()},
                support=current_fit.support,
                uncertainty=False,
            )
            c = CandidateScore(comb, f"{a.added} + {b.added}", fit, 2.0 * fit.data_cost / M)
            say(f"pair: fitted {c.added:48s} in-sample {c.in_sample_score:9.4g} (k = {fit.k}, nfev {fit.nfev})")
            c.members = (a, b)
            pairs.append(c)
    pairs.sort(key=lambda c: c.in_sample_score * math.exp(penalty * c.fit.k / M))
    n_cv = 0
    for c in pairs:
        in_pen = c.in_sample_score * math.exp(penalty * c.fit.k / M)
        gains = [(current_S - c.in_sample_score) / current_S if current_S > 0 else 0.0] + [
            (m.in_sample_score - c.in_sample_score) / m.in_sample_score if m.in_sample_score > 0 else 0.0
            for m in c.members
        ]
        if min(gains) < min_gain:
            c.screened = (
                f"not cross-validated: in-sample gain {min(gains):.1%} over the current model or a member "
                f"alone below {min_gain:.0%}"
            )
            continue
        if in_pen >= bar_pen or n_cv >= PAIR_CV:
            c.screened = (
                f"not cross-validated: in-sample penalised score {in_pen:.4g} not among the best pairs "
                f"below {bar_pen:.4g}"
            )
            continue
        n_cv += 1
        c.score(
            problem,
            *cross_validate(problem, c.combination, c.fit, max_folds=max_folds),
            M,
            penalty,
            current_S,
            current_fit.k,
        )
        say(f"pair: {c.added:48s} CV {c.cv_score:9.4g}  gain {c.gain:+.1%}  p = {c.p_value:.2g}")
    return pairs


def members_earn_their_place(
    problem: FitProblem,
    pair: CandidateScore,
    M: int,
    min_gain: float,
    threshold: float,
    max_folds: int | None,
    penalty: float,
    current_S: float,
    current_k: int,
    beside_valve: str = BESIDE_VALVE_DEFAULT,
) -> str:
    """ "" when the pair beats each of its members alone (cross-validated, cross-validating a member that was
    screened) by ``min_gain`` with the F-test's ``p < threshold`` (:func:`~.evidence.earns`; in sample for a physical
    mechanism beside a valve when ``beside_valve`` says so): the second mechanism of a pair must pass the test a
    forward step would have put it to; else why not."""
    for m in pair.members:
        if not m.cross_validated:  # scored against the pair's step like any single candidate
            m.score(
                problem,
                *cross_validate(problem, m.combination, m.fit, max_folds=max_folds),
                M,
                penalty,
                current_S,
                current_k,
            )
            m.screened = (
                "cross-validated only as a member of a pair (" + m.screened.removeprefix("not cross-validated: ") + ")"
            )
        o = next(x for x in pair.members if x is not m)
        in_sample = judged_in_sample(m.combination, o.combination.mechanisms[-1:], beside_valve)
        gain, _, why = earns(
            (m.cv_score, m.in_sample_score, m.fit.k),
            (pair.cv_score, pair.in_sample_score, pair.fit.k),
            M,
            min_gain,
            threshold,
            in_sample,
            cv_guard=beside_valve not in IN_SAMPLE_ALONE,
        )
        if why:
            return f"{o.added} adds {gain:.1%} to {m.added} alone ({why})"
    return ""
