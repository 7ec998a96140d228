"""Sensor calibrations as candidates of a selection step (:mod:`.selection`, step 5): fitted cheaply on the current
model's readings, the most promising refitted as whole models, and an accepted one followed by a refit of the whole
model."""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from ..fit.fitting import FitResult, FoldData, cross_validate, fit_combination, fit_sensor, fold_data, robust_loss
from ..fit.mechanisms import SensorCalibration
from ..fit.problem import FitProblem
from .candidates import CandidateScore

__all__ = ["CALIBRATION_REFITS", "calibrations_to_refit", "refit_with_calibration", "sensor_candidate", "sensor_fit"]


def sensor_fit(problem: FitProblem, current: FitResult, in_pred: np.ndarray, mech: SensorCalibration) -> FitResult:
    """``current`` plus a sensor calibration whose gain and offset are fitted on ``current``'s readings ``in_pred``
    (nothing else refitted)."""
    j = problem.channels.index(mech.channel)
    rows = current.rows
    g, o = fit_sensor(problem, j, in_pred[rows], rows, [p.bounds for p in mech.params])
    comb = current.combination.plus(mech)
    pred = in_pred.copy()
    pred[:, j] = g * in_pred[:, j] + o
    r = problem.normalised_residuals(pred)[rows][problem.measured_mask[rows]]
    return FitResult(
        comb,
        current.nuisance.copy(),
        np.concatenate([current.x, [g, o]]),
        np.concatenate([current.stderr, [np.nan, np.nan]]),
        dict(current.openings),
        dict(current.support),
        current.cost,
        0.5 * float(np.sum(robust_loss(r))),
        current.n_cells,
        current.k + 2,
        rows,
        current.u,
        at_bound=np.concatenate([current.at_bound, [False, False]]),
    )


def sensor_candidate(
    problem: FitProblem, current: FitResult, in_pred: np.ndarray, folds: FoldData, mech: SensorCalibration
) -> tuple[FitResult, np.ndarray]:
    """``current`` plus a sensor calibration, fitted on ``current``'s readings (in-sample and per fold):
    (the fit, its cross-validated predictions)."""
    j = problem.channels.index(mech.channel)
    bounds = [p.bounds for p in mech.params]
    fit = sensor_fit(problem, current, in_pred, mech)
    cvp = np.full_like(in_pred, np.nan)
    for _, train, test, p_train, p_test in folds.folds:
        gf, of = fit_sensor(problem, j, p_train, train, bounds)
        cvp[test] = p_test
        cvp[test, j] = gf * p_test[:, j] + of
    return fit, cvp


#: per step, the sensor calibrations (best first by their fit on the current readings) refitted as whole models
CALIBRATION_REFITS = 2


def calibrations_to_refit(scored: Sequence[CandidateScore], current_S: float, min_gain: float) -> list[CandidateScore]:
    """The :data:`CALIBRATION_REFITS` most promising sensor calibrations of a step, to be fitted and cross-validated
    with every parameter free, as the physical candidates are.

    A calibration fitted on the current model's readings (:func:`sensor_candidate`) keeps the nuisance that the
    uncorrected channel pulled, while a physical candidate refits it: compared so, the physical mechanisms are
    favoured, and a turbine flow law or a friction + heat-loss pair is named where one sensor reads wrong
    (docs/validation.md, step 4).  Refitting every calibration would cost as much as the physical candidates again;
    the miscalibrated channel is the one whose calibration on the current readings gains most, so the best two
    (those that improve the current score by ``min_gain`` already on the current readings) are refitted."""
    cal = [
        c
        for c in scored
        if isinstance(c.combination.mechanisms[-1], SensorCalibration)
        and current_S > 0
        and (current_S - c.in_sample_score) / current_S >= min_gain
    ]
    return sorted(cal, key=lambda c: c.in_sample_score)[:CALIBRATION_REFITS]


def refit_with_calibration(
    problem: FitProblem,
    best: CandidateScore,
    previous: FitResult,
    M: int,
    penalty: float,
    max_folds: int | None,
    step: dict[str, Any],
    say,
):
    """The model with an accepted sensor calibration, refitted as a whole and cross-validated: (fit, cross-validated
    predictions, point losses, score, penalised score, folds).

    A calibration is chosen on the current model's readings (:func:`sensor_candidate`: cheap, and fair between
    channels), but that model's nuisance and mechanisms were fitted to the channel *before* its correction: a
    miscalibrated sensor pulls them.  Left so, the next step compares every physical candidate (each fitted with all
    parameters free) against a model that is still bent, and whichever is tried first takes the gain of merely
    refitting: in trials with a calibration and model error, every physical candidate of the next step gained about a
    third and one of them was named on top of the true calibration (docs/validation.md, step 4).  So the whole
    model is refitted with the calibration before the next step."""
    comb = best.combination
    fit = fit_combination(problem, comb, start=best.fit, known=best.fit.values(), support=previous.support)
    c = CandidateScore(comb, best.added, fit, 2.0 * fit.data_cost / M)
    c.score(problem, *cross_validate(problem, comb, fit, max_folds=max_folds), M, penalty, best.cv_score, best.fit.k)
    step["refit"] = {
        "cv_score_on_previous_readings": best.cv_score,
        "cv_score_refitted": c.cv_score,
        "fit": fit.values(),
    }
    say(f"refitted with {best.added}: CV {best.cv_score:.4g} -> {c.cv_score:.4g}")
    return fit, c.cv_pred, c.point_losses, c.cv_score, c.penalised, fold_data(problem, c.folds, max_folds)
