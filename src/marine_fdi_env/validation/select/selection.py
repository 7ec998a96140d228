"""Model selection: which named mechanisms explain the discrepancies, where and by how much.

Pipeline (:func:`select_causes`), on a :class:`~.fit.problem.FitProblem`:

1. **Base model.**  The parameter set as it is (its errors are reported per channel), and the base
   model calibrated within its uncertainty: every fit adjusts the model-error nuisance of
   :mod:`.fit.nuisance` (prior σ = 3 % on the turbine area, turbocharger and compressor efficiencies,
   combustion efficiency and heat-release shape).  The calibrated base is what a cause must beat:
   a named mechanism has to explain more than model error of a few per cent can.
2. **Fit** (:mod:`.fit.fitting`).  Each candidate combination is fitted with the robust soft-L1 loss;
   valve-type mechanisms select the points where they act by relaxation with a sparsity penalty, then
   confirmation.
3. **Cross-validation.**  Leave-one-engine-out with several engines, else leave-one-point-out (interleaved
   k-fold when ``max_folds`` is smaller than the number of points): every fold refits everything,
   nuisance and valve supports included, on the other engines/points and predicts the left-out ones.
4. **Score.**  ``S`` = mean robust loss per measured cell of the cross-validated residuals (1 = errors at
   the tolerance); penalised ``S exp(2 k / M)`` with k free parameters (valve openings count one each)
   and M measured cells.
5. **Greedy forward selection.**  Starting from the calibrated base, every remaining mechanism is added in
   turn (refitting all parameters); the best penalised score is accepted when it is (a) better than the
   current model's, (b) at least ``min_gain`` (10 %) lower in S and (c) significant: the one-sided F-test
   of the drop of the cross-validated loss per added parameter against the candidate's loss per
   residual degree of freedom gives ``p < alpha / (number of candidates tried in the step)``
   (Bonferroni, alpha = 0.01).  A physical mechanism joining a model that has a valve is judged on the same
   gain and F-test of its *in-sample* scores (:func:`~.evidence.earns`, without a
   cross-validated guard): the valve's held-out openings add an error to both models that
   dilutes and scatters the cross-validated gain.  Each step also tries pairs of physical mechanisms added
   together (:func:`~.pairs.pair_candidates`); a pair replaces the best single candidate when its penalised
   score is lower, it passes the same tests (Bonferroni over singles and pairs) and each member earns its place
   against the other alone (:func:`~.pairs.members_earn_their_place`); a pair holding the best single
   candidate, a valve, replaces it on the members test alone (:data:`~.evidence.BESIDE_VALVE`).  Sensor
   calibrations are fitted on the current model's readings, the two most promising of them then as whole models
   with every parameter free, as the physical candidates are
   (:func:`~.calibration_candidates.calibrations_to_refit`); an accepted calibration is followed by a refit of
   the whole model (:func:`~.calibration_candidates.refit_with_calibration`), so that the next step's candidates
   are not credited with the gain of merely refitting.  Selection stops at the first step where nothing
   qualifies; then every named cause must still earn its place against all the others
   (:func:`~.revision.removal_step`: the weakest that does not is removed, and the test repeated).  Then each
   named physical cause is tried replaced by a sensor calibration (:func:`~.revision.exchange_step`;
   beside a valve judged by its in-sample gain), and the removal step runs
   again after an exchange.
6. **Unexplained.**  Each channel is judged against the final model refitted *without that channel*
   (:func:`~.fit.fitting.loco_predictions`): an anomaly of one sensor bends a fit that includes it and would
   hide.  The discrepancy analysis of :mod:`.measured.discrepancy` (bias, trend, change point) and a scan for local
   excess (:func:`~.window_scan.window_excess`: contiguous windows of points in load order whose mean residual
   departs from the rest, its p-value simulated at the data's noise level) run on these residuals; what is
   significant at the family-wise level :data:`~.unexplained.ALPHA_UNEXPLAINED` (5 %, Bonferroni over the
   channels) is reported as ``unexplained: channel, kind, region``; single readings as ``outliers``
   (:mod:`.unexplained`).  On a channel with a named sensor calibration, what its gain and offset leave is also
   scanned for steps, kinks and windows (:func:`~.unexplained.calibration_left`, :mod:`.calibration_scan`): the
   bias, trend and change-point tests cannot see it.
   That scan tests the named calibrations only, at ``ALPHA_UNEXPLAINED`` over their number.
   A sensor calibration is only eligible when the gain and offset it fits on the model without its channel
   leave no such local departure: a gain and an offset are a complete explanation of a sensor or none.
   A candidate whose fit sits at a bound of its plausible range that is not a natural limit is not eligible
   either when the data want more than the bound (:func:`~.eligibility.binding_bounds`: widening the bound and
   refitting lowers the in-sample loss significantly); a bound merely touched because two parameters trade off is
   kept, with a note.  Parameters the data do not determine are noted, not a reason to reject.

The parts, one module each: one forward step (:mod:`.forward_step`), a
scored candidate (:mod:`.candidates`), the evidence a cause must give (:mod:`.evidence`), eligibility
(:mod:`.eligibility`), sensor calibrations as candidates (:mod:`.calibration_candidates`), pairs (:mod:`.pairs`),
the removal and exchange steps (:mod:`.revision`), what the data hardly tell from a named cause
(:mod:`.alternatives`) and what the final model leaves (:mod:`.unexplained`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from ..fit.fitting import (
    ROBUST_SCALE,
    Combination,
    FitResult,
    cell_losses,
    channel_rmse,
    cross_validate,
    fit_combination,
    fold_data,
    loco_predictions,
)
from ..fit.mechanisms import Mechanism, SensorCalibration, library, sensor_reference
from ..fit.problem import FitProblem, Setting
from ..measured.columns import QUANTITIES
from ..measured.discrepancy import DiscrepancyReport, analyse_discrepancies
from ..measured.matching import MatchResult
from .candidates import CandidateScore
from .forward_step import CurrentModel, StepRules, forward_step
from .revision import exchange_step, removal_step
from .rules import SelectionRules
from .unexplained import point_outliers, unexplained_findings

__all__ = ["CandidateScore", "Selection", "select_causes", "match_result", "ROBUST_SCALE"]


def match_result(problem: FitProblem, setting: Setting | None = None, pred_fn=None) -> MatchResult:
    """A :class:`~.measured.matching.MatchResult` of a model setting (default the problem's base) at every point (for
    the discrepancy analysis)."""
    setting = problem.base_setting if setting is None else setting
    ds = problem.ds
    rows = np.arange(problem.n_points)
    vals, conv = problem.solve(setting, rows)
    pred = problem.readings(setting, vals, conv, rows, problem.predicted_columns)
    if pred_fn is not None:  # e.g. a fit's own openings at its rows
        ch = pred_fn()
        for j, c in enumerate(problem.channels):
            pred[:, problem.predicted_columns.index(c)] = ch[:, j]
    status = tuple(
        "ok"
        if ok
        else ("missing target" if not math.isfinite(problem.target_si[i]) else "no steady state of the model")
        for i, ok in enumerate(conv)
    )
    return MatchResult(
        dataset=ds,
        params=problem.params,
        law=problem.law,
        target=problem.target,
        target_columns=problem.target_columns,
        u=np.where(conv, vals["fuel_setting"], np.nan),
        status=status,
        predicted={c: pred[:, j] for j, c in enumerate(problem.predicted_columns)},
        measured={c: ds.raw[c].copy() for c in ds.columns},
        model_si={k: np.where(conv, v, np.nan) for k, v in vals.items()},
        channels=problem.channels,
        notes=tuple(ds.notes),
    )


@dataclass
class Selection:
    """Outcome of :func:`select_causes`.

    raw_pred : the parameter set as it is (no nuisance).  base_* : the calibrated base (nuisance only,
    cross-validated).  fit / cv_pred / cv_score : the selected combination.
    """

    problem: FitProblem
    cv_scheme: str
    raw_pred: np.ndarray
    base_fit: FitResult
    base_pred: np.ndarray
    base_score: float
    base_report: DiscrepancyReport
    steps: list[dict[str, Any]]
    selected: Combination
    fit: FitResult
    cv_pred: np.ndarray
    cv_score: float
    final_report: DiscrepancyReport
    unexplained: list[dict[str, Any]]
    outliers: list[dict[str, Any]]
    base_outliers: list[dict[str, Any]]
    seconds: float
    settings: dict[str, Any] = field(default_factory=dict)
    alternatives: dict[str, list[dict[str, Any]]] = field(default_factory=dict)
    #: per accepted cause, what its fit's parameters leave open (a bound touched but not wanted beyond, a
    #: parameter the data do not determine)
    cause_notes: dict[str, list[str]] = field(default_factory=dict)
    #: per channel with a named sensor calibration, what :func:`~.calibration_scan.structure_scan` found on what
    #: its gain and offset leave, reported or not (``p``, ``p_at_floor``, ``z``, ``kind``, ``load_range``, ``d`` and
    #: ``tolerance`` in column units, ``unit``, ``level``: the level it was judged at): readable at any level
    calibration_scans: dict[str, dict[str, Any]] = field(default_factory=dict)
    #: every structure the data do not decide against (:func:`~.explain.explanations.explanation_set`), when asked for
    explanations: Any = None
    #: the rules it was selected under (a replica reuses them)
    rules: SelectionRules = field(default_factory=SelectionRules)

    @property
    def selected_causes(self) -> list[str]:
        return list(self.selected.ids)

    @property
    def selected_labels(self) -> list[str]:
        return list(self.selected.labels)

    def setting(self) -> Setting:
        return self.fit.setting(self.problem)

    def candidates(self) -> list[dict[str, Any]]:
        """Every candidate of every step with its CV score (first step: each mechanism alone)."""
        out = []
        for s in self.steps:
            for c in s["candidates"]:
                d = c.as_dict()
                d["step"] = s["step"]
                out.append(d)
        return out

    def cv_rmse(self) -> dict[str, dict[str, float]]:
        r = channel_rmse(self.problem, self.raw_pred)
        b = channel_rmse(self.problem, self.base_pred)
        e = channel_rmse(self.problem, self.cv_pred)
        return {c: {"rmse_raw": r[c], "cv_rmse_base": b[c], "cv_rmse_extended": e[c]} for c in self.problem.channels}

    def activity(self) -> dict[str, list[float]]:
        """Per selected valve: the diverted flow fraction at every measured point (file row order, 0 where shut)."""
        out = {}
        if not self.selected.valves:
            return out
        vals, conv = self.problem.solve(self.setting())
        for m in self.selected.valves:
            frac = np.where(conv, vals[m.activity_key()], np.nan)
            o = self.fit.openings[m.id]
            out[m.id] = [0.0 if (math.isfinite(oi) and oi == 0.0) else float(f) for f, oi in zip(frac, o)]
        return out

    def openings(self) -> dict[str, list[float]]:
        return {m.id: [float(x) for x in self.fit.openings[m.id]] for m in self.selected.valves}


def select_causes(
    problem: FitProblem,
    mechanisms: Sequence[Mechanism] | None = None,
    *,
    rules: SelectionRules | None = None,
    progress=None,
    **changes: Any,
) -> Selection:
    """Greedy forward selection of named mechanisms (see the module docstring).

    mechanisms : candidates (default: :func:`~.fit.mechanisms.library` with one sensor calibration per channel).
    rules : the selection's rules (:class:`~.rules.SelectionRules`; default: its defaults with the problem's
        ``held_out_valves``); ``changes`` replace single rules (``select_causes(pr, pairs=False)``).  With
        ``cv_all`` off a candidate is cross-validated only if it can still win: its in-sample penalised score (a
        lower bound of its cross-validated one: a fit predicts the data it saw better than data it did not) is
        below the best cross-validated penalised score of an *eligible* candidate of the step so far (one pinned at
        a bound or a calibration that leaves structure cannot win, so it screens nothing out; found with
        :mod:`.replicas`) and improves the current model by ``min_gain`` in-sample.  ``pairs``:
        :func:`~.pairs.pair_candidates`; ``prune``: :func:`~.revision.removal_step`; ``exchange``:
        :func:`~.revision.exchange_step` (off: an ablation); ``beside_valve``: :func:`~.evidence.earns`.
    progress : optional callable receiving one-line status messages.
    """
    given = rules is not None
    rules = (rules or SelectionRules()).replace(**changes)
    if not given and "held_out_valves" not in changes:
        rules = rules.replace(held_out_valves=problem.held_out_valves)
    if rules.held_out_valves != problem.held_out_valves:
        raise ValueError(
            f"the rules' held_out_valves ({rules.held_out_valves!r}) differ from the problem's "
            f"({problem.held_out_valves!r}): build the FitProblem with the rules' held_out_valves"
        )
    max_causes, alpha, alpha_unexplained = rules.max_causes, rules.alpha, rules.alpha_unexplained
    min_gain, penalty = rules.min_gain, rules.penalty
    cv_all, max_folds, pairs = rules.cv_all, rules.max_folds, rules.pairs
    prune, exchange, beside_valve = rules.prune, rules.exchange, rules.beside_valve
    t0 = time.perf_counter()
    say = progress or (lambda s: None)
    if mechanisms is None:
        refs = {
            c: sensor_reference(c, problem.Y[:, j], QUANTITIES[problem.ds.column_quantity[c]].kind)
            for j, c in enumerate(problem.channels)
        }
        mechanisms = library(problem.channels, refs)
    scheme, folds = problem.folds(max_folds)
    tol = dict(zip(problem.channels, problem.tolerance))
    raw_pred, _, _ = problem.predict()
    base_match = match_result(problem)
    base_report = analyse_discrepancies(base_match, alpha=alpha, tolerances=tol)
    base_outliers = point_outliers(base_match, tol, alpha)
    base_fit = fit_combination(problem, Combination())
    base_pred, base_folds = cross_validate(problem, Combination(), base_fit, max_folds=max_folds)
    current_folds = fold_data(problem, base_folds, max_folds)
    L_base, M = cell_losses(problem, base_pred)
    S_base = float(L_base.sum() / M)
    cur = CurrentModel(Combination(), base_fit, base_pred, L_base, S_base, S_base, current_folds)
    step_rules = StepRules(
        n_cells=M,
        rows=problem.rows_with_data(),
        alpha=alpha,
        min_gain=min_gain,
        penalty=penalty,
        cv_all=cv_all,
        max_folds=max_folds,
        max_causes=max_causes,
        pairs=pairs,
        beside_valve=beside_valve,
    )
    steps: list[dict[str, Any]] = []
    alternatives: dict[str, list[dict[str, Any]]] = {}
    cause_notes: dict[str, list[str]] = {}
    say(f"calibrated base model: S = {S_base:.4g} over {M} cells ({scheme}, {len(folds)} folds)")
    for step in range(1, max_causes + 1):
        outcome = forward_step(problem, cur, mechanisms, step_rules, step, say)
        if outcome is None:
            break
        steps.append(outcome.record)
        if outcome.model is None:
            break
        alternatives.update(outcome.alternatives)
        cause_notes.update(outcome.cause_notes)
        cur = outcome.model
    cur = _revise(problem, cur, steps, alternatives, cause_notes, mechanisms, step_rules, prune, exchange, say)
    current, current_fit = cur.combination, cur.fit
    final_setting = current_fit.setting(problem)
    # what is left is judged channel by channel against the model fitted without that channel: an anomaly of one
    # sensor would otherwise bend the fit towards it and hide
    final_loco = loco_predictions(problem, current_fit)
    final_match = match_result(problem, final_setting, pred_fn=lambda: final_loco)
    final_report = analyse_discrepancies(final_match, alpha=alpha, tolerances=tol)
    cal_scans: dict[str, dict[str, Any]] = {}
    unexplained = unexplained_findings(
        final_match,
        final_report,
        tol,
        alpha_unexplained,
        [m.channel for m in current.mechanisms if isinstance(m, SensorCalibration)],
        scans=cal_scans,
    )
    return Selection(
        problem=problem,
        cv_scheme=scheme,
        raw_pred=raw_pred,
        base_fit=base_fit,
        base_pred=base_pred,
        base_score=S_base,
        base_report=base_report,
        steps=steps,
        selected=current,
        fit=current_fit,
        cv_pred=cur.pred,
        cv_score=cur.score,
        final_report=final_report,
        unexplained=unexplained,
        outliers=point_outliers(final_match, tol, alpha),
        base_outliers=base_outliers,
        seconds=time.perf_counter() - t0,
        alternatives=alternatives,
        cause_notes=cause_notes,
        calibration_scans=cal_scans,
        rules=rules,
        settings={
            "held_out_valves": problem.held_out_valves,
            "beside_valve": beside_valve,
            "max_causes": max_causes,
            "alpha": alpha,
            "alpha_unexplained": alpha_unexplained,
            "min_gain": min_gain,
            "penalty": penalty,
            "robust_scale": ROBUST_SCALE,
            "cv": scheme,
            "n_folds": len(folds),
            "n_cells": M,
            "cv_all": cv_all,
            "nuisance_sigma": 0.03,
            "pairs": pairs,
            "prune": prune,
            "exchange": exchange,
            "max_folds": max_folds,
        },
    )


def _revise(
    problem: FitProblem,
    cur: CurrentModel,
    steps: list[dict[str, Any]],
    alternatives: dict[str, list[dict[str, Any]]],
    cause_notes: dict[str, list[str]],
    mechanisms: Sequence[Mechanism],
    rules: StepRules,
    prune: bool,
    exchange: bool,
    say,
) -> CurrentModel:
    """After the forward steps: remove the named causes that no longer earn their place among the others
    (:func:`~.revision.removal_step`), then try each named physical cause replaced by a sensor calibration
    (:func:`~.revision.exchange_step`), and remove again after an exchange.  ``steps``, ``alternatives`` and
    ``cause_notes`` are updated in place; returns the final model."""
    M, penalty, min_gain, max_folds = rules.n_cells, rules.penalty, rules.min_gain, rules.max_folds
    thresholds = {}
    for st in steps:
        if st["accepted"]:
            for lab in st["best"].split(" + "):
                thresholds[lab] = st["threshold_p"]
    for _ in range(rules.max_causes + 1):  # each exchange lowers the score by min_gain: no cycle
        while (
            prune
            and (
                pruned := removal_step(
                    problem,
                    cur.combination,
                    cur.fit,
                    cur.score,
                    M,
                    penalty,
                    min_gain,
                    thresholds,
                    max_folds,
                    len(steps) + 1,
                    say,
                    rules.beside_valve,
                )
            )
            is not None
        ):
            st, c = pruned
            steps.append(st)
            alternatives.pop(c.added, None)
            cause_notes.pop(c.added, None)
            cur = CurrentModel.of(c, None)
        if (
            not exchange
            or (
                ex := exchange_step(
                    problem,
                    cur.combination,
                    cur.fit,
                    cur.score,
                    cur.penalised,
                    M,
                    penalty,
                    min_gain,
                    rules.alpha,
                    mechanisms,
                    max_folds,
                    len(steps) + 1,
                    say,
                    rules.beside_valve,
                )
            )
            is None
        ):
            break
        st, c, gone = ex
        steps.append(st)
        alternatives.pop(gone.label, None)
        cause_notes.pop(gone.label, None)
        thresholds[st["best"]] = thresholds.pop(gone.label, 1.0)
        cur = CurrentModel.of(c, None)
    return cur
