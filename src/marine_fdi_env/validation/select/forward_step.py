"""One step of the greedy forward selection (:mod:`.selection`, step 5 of its docstring).

Every remaining mechanism is added to the current model and fitted (:func:`score_singles`), the promising ones are
cross-validated (:func:`cross_validate_promising`), the best single candidate is judged (:func:`judge_best_single`)
and pairs of physical mechanisms are tried beside it (:func:`best_pair`).  :func:`forward_step` runs the four and
says what the step decided.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from ..fit.fitting import (
    Combination,
    FitResult,
    FoldData,
    cross_validate,
    fit_combination,
    fold_data,
    loco_predictions,
    predict_setting,
)
from ..fit.mechanisms import Mechanism, SensorCalibration
from ..fit.problem import FitProblem
from .alternatives import ALTERNATIVE_MARGIN, pair_alternatives, step_alternatives
from .calibration_candidates import calibrations_to_refit, refit_with_calibration, sensor_candidate
from .candidates import CandidateScore
from .eligibility import structure_left, why_pinned
from .evidence import IN_SAMPLE_ALONE, earns, judged_in_sample
from .pairs import members_earn_their_place, pair_candidates

__all__ = [
    "CurrentModel",
    "StepOutcome",
    "StepRules",
    "best_pair",
    "cross_validate_promising",
    "forward_step",
    "judge_best_single",
    "score_singles",
]

Say = Callable[[str], None]


@dataclass(frozen=True)
class StepRules:
    """The settings of :func:`~.selection.select_causes` that a step reads.

    n_cells : measured cells M of the scores.  rows : the rows with data.  alpha : significance level of a named
    cause (Bonferroni over the step's candidates).  min_gain : least relative drop of the score.  penalty : the score
    is penalised by ``exp(penalty k / M)`` for k free parameters.
    """

    n_cells: int
    rows: np.ndarray
    alpha: float
    min_gain: float
    penalty: float
    cv_all: bool
    max_folds: int | None
    max_causes: int
    pairs: bool
    beside_valve: str

    @property
    def cv_guard(self) -> bool:
        """Whether a cause judged in sample beside a valve must still lower the cross-validated score."""
        return self.beside_valve not in IN_SAMPLE_ALONE

    def in_sample_penalised(self, c: CandidateScore) -> float:
        return c.in_sample_score * math.exp(self.penalty * c.fit.k / self.n_cells)


@dataclass(frozen=True)
class CurrentModel:
    """The model a candidate must beat: combination, fit, cross-validated predictions (points x channels), point
    losses, score S, penalised score, and its fold fits' predictions (what a sensor candidate is cross-validated
    on; ``None`` after the final revision, which does not use them)."""

    combination: Combination
    fit: FitResult
    pred: np.ndarray
    losses: np.ndarray
    score: float
    penalised: float
    folds: FoldData | None

    @classmethod
    def of(cls, c: CandidateScore, folds: FoldData | None) -> CurrentModel:
        """The model a scored candidate becomes when it is accepted."""
        return cls(c.combination, c.fit, c.cv_pred, c.point_losses, c.cv_score, c.penalised, folds)

    def in_sample_score(self, n_cells: int) -> float:
        return 2.0 * self.fit.data_cost / n_cells


@dataclass
class StepOutcome:
    """What a step decided: its entry of :attr:`~.selection.Selection.steps`, the model it leaves (``None`` when
    nothing was accepted), and the accepted causes' alternatives and notes."""

    record: dict[str, Any]
    model: CurrentModel | None
    alternatives: dict[str, list[dict[str, Any]]]
    cause_notes: dict[str, list[str]]


def score_singles(
    problem: FitProblem,
    cur: CurrentModel,
    pool: Sequence[Mechanism],
    known: Mapping[str, float],
    in_pred: np.ndarray,
    rules: StepRules,
    step: int,
    say: Say,
) -> tuple[list[CandidateScore], dict[str, np.ndarray]]:
    """Every mechanism of ``pool`` added to the current model and fitted; sensor calibrations on the current
    model's readings ``in_pred``, the most promising of them then refitted as whole models
    (:func:`~.calibration_candidates.calibrations_to_refit`).  Returns the candidates and the cross-validated
    predictions of the calibrations that were not refitted."""
    M = rules.n_cells
    scored: list[CandidateScore] = []
    sensor_cv: dict[str, np.ndarray] = {}
    for mech in pool:
        comb = cur.combination.plus(mech)
        if isinstance(mech, SensorCalibration):
            full, sensor_cv[mech.label] = sensor_candidate(problem, cur.fit, in_pred, cur.folds, mech)
        else:
            full = fit_combination(problem, comb, start=cur.fit, known=known, support=cur.fit.support)
        scored.append(CandidateScore(comb, mech.label, full, 2.0 * full.data_cost / M))
        say(f"step {step}: fitted {mech.label:48s} in-sample {scored[-1].in_sample_score:9.4g} (k = {full.k})")
    for c in calibrations_to_refit(scored, cur.score, rules.min_gain):
        c.fit = fit_combination(problem, c.combination, start=c.fit, known=c.fit.values(), support=cur.fit.support)
        c.in_sample_score = 2.0 * c.fit.data_cost / M
        del sensor_cv[c.added]  # cross-validated as the whole model it would become
        say(f"step {step}: refitted {c.added:46s} in-sample {c.in_sample_score:9.4g} (k = {c.fit.k})")
    scored.sort(key=rules.in_sample_penalised)
    return scored, sensor_cv


def cross_validate_promising(
    problem: FitProblem,
    cur: CurrentModel,
    scored: Sequence[CandidateScore],
    sensor_cv: Mapping[str, np.ndarray],
    known: Mapping[str, float],
    loco_cur: np.ndarray,
    rules: StepRules,
    step: int,
    say: Say,
) -> None:
    """Cross-validate, best in-sample first, the candidates that can still win (all with ``rules.cv_all``), and
    mark the ones that are not eligible (pinned at a bound, or a calibration that leaves structure on its channel:
    :mod:`.eligibility`).  A candidate's in-sample penalised score is a lower bound of its cross-validated one, so
    it is screened out once an *eligible* candidate's cross-validated score is lower."""
    best_pen = math.inf
    for c in scored:
        in_pen = rules.in_sample_penalised(c)
        in_gain = (cur.score - c.in_sample_score) / cur.score if cur.score > 0 else 0.0
        if not rules.cv_all:
            if in_gain < rules.min_gain:
                c.screened = f"not cross-validated: in-sample gain {in_gain:.1%} below {rules.min_gain:.0%}"
                continue
            if in_pen >= best_pen:
                c.screened = (
                    f"not cross-validated: in-sample penalised score {in_pen:.4g} already above the best "
                    f"cross-validated one {best_pen:.4g}"
                )
                continue
        if c.added in sensor_cv:
            pred, c_folds = sensor_cv[c.added], None
        else:
            pred, c_folds = cross_validate(problem, c.combination, c.fit, max_folds=rules.max_folds)
        c.score(problem, pred, c_folds, rules.n_cells, rules.penalty, cur.score, cur.fit.k, cur.losses, rules.rows)
        say(f"step {step}: {c.added:48s} CV {c.cv_score:9.4g}  gain {c.gain:+.1%}  p = {c.p_value:.2g}")
        # eligibility at once: only an eligible candidate's score can screen the others out (one pinned at a
        # bound, or a calibration that leaves structure, cannot win, so it must not stop those that can)
        pins = why_pinned(problem, c, known, cur.fit.support)
        if pins:
            c.screened = "not eligible: " + "; ".join(pins)
        elif isinstance(c.combination.mechanisms[-1], SensorCalibration):
            left = structure_left(problem, loco_cur, c.combination.mechanisms[-1], rules.alpha)
            if left:
                c.screened = (
                    "not eligible: the calibrated channel keeps a local departure ("
                    + left
                    + "): a gain and an offset do not explain it"
                )
        if not c.screened:
            best_pen = min(best_pen, c.penalised)


def judge_best_single(
    cur: CurrentModel, scored: Sequence[CandidateScore], rules: StepRules
) -> tuple[CandidateScore | None, bool, str, list[CandidateScore]]:
    """The best eligible cross-validated candidate, whether it is accepted and why: a lower penalised score than
    the current model's and the evidence of :func:`~.evidence.earns` at ``alpha / len(scored)``.  Returns (best,
    accepted, decision, the eligible cross-validated candidates best first)."""
    M = rules.n_cells
    cv = sorted((c for c in scored if c.cross_validated and not c.screened), key=lambda c: c.penalised)
    threshold = rules.alpha / len(scored)
    best, accept, why = (
        None,
        False,
        (
            f"rejected: no candidate improves the in-sample score by {rules.min_gain:.0%} "
            "without being pinned at the limit of its plausible range"
        ),
    )
    if cv:
        best = cv[0]
        in_sample = judged_in_sample(cur.combination, best.combination.mechanisms[-1:], rules.beside_valve)
        _, _, short = earns(
            (cur.score, cur.in_sample_score(M), cur.fit.k),
            (best.cv_score, best.in_sample_score, best.fit.k),
            M,
            rules.min_gain,
            threshold,
            in_sample,
            cv_guard=rules.cv_guard,
        )
        accept = best.penalised < cur.penalised and not short
        why = (
            "accepted" + (" (beside a valve: judged in sample)" if in_sample else "")
            if accept
            else "rejected: "
            + "; ".join(
                s
                for s, bad in (
                    (
                        f"penalised score {best.penalised:.4g} not below the current {cur.penalised:.4g}",
                        best.penalised >= cur.penalised,
                    ),
                    (short + f" (threshold alpha/{len(scored)})", bool(short)),
                )
                if bad
            )
        )
    return best, accept, why, cv


def best_pair(
    problem: FitProblem,
    cur: CurrentModel,
    scored: Sequence[CandidateScore],
    best: CandidateScore | None,
    accept: bool,
    known: Mapping[str, float],
    rules: StepRules,
    say: Say,
) -> tuple[CandidateScore | None, list[CandidateScore]]:
    """The pair of physical mechanisms that replaces the step's best single candidate, if any, and every pair
    tried (:func:`~.pairs.pair_candidates`).

    A pair must have a lower penalised score than the current model and than an accepted single, pass the
    evidence of :func:`~.evidence.earns` (Bonferroni over singles and pairs), not be pinned at a bound, and each
    member must earn its place against the other alone (:func:`~.pairs.members_earn_their_place`).  Under the rule
    ``in_sample_pairs`` a pair holding the accepted best single, a valve, need only beat the current model's
    penalised score: its second member's place beside the valve is judged in sample by the members test."""
    M = rules.n_cells
    if not rules.pairs or len(cur.combination.mechanisms) + 2 > rules.max_causes:
        return None, []
    bar = min(cur.penalised, best.penalised if accept else math.inf)
    pairs = pair_candidates(
        problem,
        cur.combination,
        cur.fit,
        scored,
        known,
        M,
        rules.penalty,
        cur.score,
        bar,
        rules.min_gain,
        rules.max_folds,
        say,
    )
    p_threshold = rules.alpha / (len(scored) + len(pairs))
    lead_valve = (
        best.combination.mechanisms[-1]
        if accept and rules.beside_valve in IN_SAMPLE_ALONE and best.combination.mechanisms[-1].pointwise
        else None
    )
    s_in_cur = cur.in_sample_score(M)
    for c in sorted((c for c in pairs if c.cross_validated), key=lambda c: c.penalised):
        in_sample = judged_in_sample(cur.combination, c.combination.mechanisms[-2:], rules.beside_valve)
        c_bar = cur.penalised if lead_valve in c.combination.mechanisms[-2:] else bar
        if (
            not c.penalised < c_bar
            or earns(
                (cur.score, s_in_cur, cur.fit.k),
                (c.cv_score, c.in_sample_score, c.fit.k),
                M,
                rules.min_gain,
                p_threshold,
                in_sample,
                rules.cv_guard,
            )[2]
        ):
            continue
        c.fit = fit_combination(problem, c.combination, start=c.fit, known=known, support=cur.fit.support)
        pins = why_pinned(problem, c, known, cur.fit.support)
        if pins:
            c.screened = "not eligible: " + "; ".join(pins)
            continue
        left = members_earn_their_place(
            problem,
            c,
            M,
            rules.min_gain,
            p_threshold,
            rules.max_folds,
            rules.penalty,
            cur.score,
            cur.fit.k,
            rules.beside_valve,
        )
        if left:
            c.screened = "not eligible: " + left
            continue
        return c, pairs
    return None, pairs


def _pair_decision(
    cur: CurrentModel, pair: CandidateScore, best: CandidateScore | None, accept: bool, n_tried: int, rules: StepRules
) -> str:
    """Why an accepted pair replaced the step's best single candidate."""
    evidence = (
        "beside a valve, judged in sample; "
        if judged_in_sample(cur.combination, pair.combination.mechanisms[-2:], rules.beside_valve)
        else f"p = {pair.p_value:.2g} below alpha/{n_tried}; "
    )
    if accept and pair.penalised < best.penalised:
        why = f"penalised score {pair.penalised:.4g} below the best single candidate's {best.penalised:.4g})"
    elif accept:
        why = (
            f"it holds the best single candidate, the valve {best.added}, and its second member earns its place "
            f"beside it in sample)"
        )
    else:
        why = (
            f"penalised score {pair.penalised:.4g} below the current {cur.penalised:.4g}; no single candidate "
            "qualified)"
        )
    return "accepted the pair (" + evidence + why


def forward_step(
    problem: FitProblem, cur: CurrentModel, mechanisms: Sequence[Mechanism], rules: StepRules, step: int, say: Say
) -> StepOutcome | None:
    """One greedy step from ``cur``: ``None`` when there is nothing left to try (every mechanism in the model, or
    ``max_causes`` reached), else what the step decided (its model ``None`` when it accepted nothing)."""
    pool = [m for m in mechanisms if m.label not in cur.combination.labels]
    if not pool or len(cur.combination.mechanisms) >= rules.max_causes:
        return None
    known = cur.fit.values()
    in_pred = predict_setting(problem, cur.fit, np.arange(problem.n_points))
    loco_cur = loco_predictions(problem, cur.fit)
    scored, sensor_cv = score_singles(problem, cur, pool, known, in_pred, rules, step, say)
    cross_validate_promising(problem, cur, scored, sensor_cv, known, loco_cur, rules, step, say)
    best, accept, why, cv = judge_best_single(cur, scored, rules)
    pair, pairs = best_pair(problem, cur, scored, best, accept, known, rules, say)
    if pair is not None:
        n_tried = len(scored) + len(pairs)
        record = {
            "step": step,
            "best": pair.added,
            "accepted": True,
            "pair": True,
            "decision": _pair_decision(cur, pair, best, accept, n_tried, rules),
            "threshold_p": rules.alpha / n_tried,
            "current_score": cur.score,
            "candidates": scored + pairs,
        }
        say(f"step {step}: best pair {pair.added}: accepted")
        alternatives = pair_alternatives(pair, pairs, ALTERNATIVE_MARGIN)
        notes = {m.added: [n for n in pair.notes if m.added in n] for m in pair.members}
        return StepOutcome(
            record, CurrentModel.of(pair, fold_data(problem, pair.folds, rules.max_folds)), alternatives, notes
        )
    record = {
        "step": step,
        "best": best.added if best else None,
        "accepted": accept,
        "decision": why,
        "threshold_p": rules.alpha / len(scored),
        "current_score": cur.score,
        "candidates": scored + pairs,
    }
    say(f"step {step}: " + (f"best {best.added}: " if best else "") + why)
    if not accept:
        return StepOutcome(record, None, {}, {})
    alternatives = {best.added: step_alternatives(best, cv, ALTERNATIVE_MARGIN)}
    notes = {best.added: [n for n in best.notes if best.added in n]}
    if best.folds is not None:
        model = CurrentModel.of(best, fold_data(problem, best.folds, rules.max_folds))
    else:
        fit, pred, losses, score, pen, folds = refit_with_calibration(
            problem, best, cur.fit, rules.n_cells, rules.penalty, rules.max_folds, record, say
        )
        model = CurrentModel(best.combination, fit, pred, losses, score, pen, folds)
    return StepOutcome(record, model, alternatives, notes)
