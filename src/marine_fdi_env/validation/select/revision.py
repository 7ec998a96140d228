"""The selection's revision after its forward steps (:mod:`.selection`, step 5): every named cause must still earn
its place among the others (:func:`removal_step`), and a named physical cause may be exchanged for a sensor
calibration (:func:`exchange_step`)."""

from __future__ import annotations

import math
from typing import Any, Mapping, Sequence

import numpy as np

from ..fit.fitting import Combination, FitResult, cross_validate, fit_combination, loco_predictions, predict_setting
from ..fit.mechanisms import Mechanism, SensorCalibration
from ..fit.problem import FitProblem
from .calibration_candidates import CALIBRATION_REFITS, sensor_fit
from .candidates import CandidateScore
from .eligibility import structure_left, why_pinned
from .evidence import BESIDE_VALVE_DEFAULT, EXCHANGE_IN_SAMPLE, IN_SAMPLE_ALONE, earns, judged_in_sample

__all__ = ["exchange_step", "removal_step"]


def removal_step(
    problem: FitProblem,
    current: Combination,
    current_fit: FitResult,
    current_S: float,
    M: int,
    penalty: float,
    min_gain: float,
    thresholds: Mapping[str, float],
    max_folds: int | None,
    step_no: int,
    say,
    beside_valve: str = BESIDE_VALVE_DEFAULT,
) -> tuple[dict[str, Any], CandidateScore] | None:
    """The weakest named cause that no longer earns its place among the others, as a removal step (and the model
    without it), or None when each does.

    A forward step judges a mechanism against the causes named *before* it; one named later may take over what an
    earlier one explained (a turbine flow law named at the first step, as one of a pair, made redundant by the bypass
    valve and the pressure-gauge calibration named next; docs/validation.md, step 4).  So at the end every named cause
    is put to the test its own step put it to, against the model of all the others refitted and cross-validated:
    it must lower the cross-validated score by ``min_gain`` with the F-test's p below the threshold of the step
    that named it (:func:`~.evidence.earns`: in sample for a physical mechanism beside a valve when ``beside_valve``
    says so).  The weakest failing cause is removed and the test repeated."""
    if len(current.mechanisms) < 2:
        return None
    tried: list[CandidateScore] = []
    for m in current.mechanisms:
        comb = Combination(tuple(x for x in current.mechanisms if x is not m))
        support = {k: v for k, v in current_fit.support.items() if k in {x.id for x in comb.valves}}
        fit = fit_combination(problem, comb, start=current_fit, known=current_fit.values(), support=support)
        c = CandidateScore(comb, m.label, fit, 2.0 * fit.data_cost / M)
        c.score(problem, *cross_validate(problem, comb, fit, max_folds=max_folds), M, penalty, current_S, current_fit.k)
        tried.append(c)
        say(f"step {step_no}: without {m.label:42s} CV {c.cv_score:9.4g}")
    worst = None
    s_in = 2.0 * current_fit.data_cost / M
    for c, m in zip(tried, current.mechanisms):
        thr = thresholds.get(c.added, 1.0)
        in_sample = judged_in_sample(c.combination, [m], beside_valve)
        gain, p, why = earns(
            (c.cv_score, c.in_sample_score, c.fit.k),
            (current_S, s_in, current_fit.k),
            M,
            min_gain,
            thr,
            in_sample,
            cv_guard=beside_valve not in IN_SAMPLE_ALONE,
        )
        if why and (worst is None or gain < worst[1]):
            worst = (c, gain, p, thr, why)
    if worst is None:
        return None
    c, gain, p, thr, why = worst
    step = {
        "step": step_no,
        "best": c.added,
        "accepted": True,
        "removed": c.added,
        "decision": f"removed: {c.added} adds only {gain:.1%} to the other named causes ({why})",
        "threshold_p": thr,
        "current_score": current_S,
        "candidates": tried,
    }
    say(f"step {step_no}: {step['decision']}")
    return step, c


def exchange_step(
    problem: FitProblem,
    current: Combination,
    current_fit: FitResult,
    current_S: float,
    current_pen: float,
    M: int,
    penalty: float,
    min_gain: float,
    alpha: float,
    mechanisms: Sequence[Mechanism],
    max_folds: int | None,
    step_no: int,
    say,
    beside_valve: str = BESIDE_VALVE_DEFAULT,
) -> tuple[dict[str, Any], CandidateScore, Mechanism] | None:
    """The exchange step: a named physical cause that a sensor calibration, named in its place, explains better
    (the step, the model after the exchange, the cause taken out), or None.

    Forward selection never takes a cause back, and a calibration is only eligible when its gain and offset leave no
    local departure on its channel (:func:`~.eligibility.structure_left`). When a physical mechanism has absorbed
    part of a miscalibrated sensor, what the calibration would leave on top of it is bent, so the true calibration
    stays ineligible, and further mechanisms are named to mop up (friction + a p_max gauge reading 5 % high named as
    cylinder heat loss + friction, then ambient + turbine flow law; the p_max calibration scored best at step 2 but
    left structure on top of the heat loss; docs/validation.md, step 4). So at the end each named physical
    cause is taken out in turn (the others refitted, as :func:`removal_step` does), every sensor calibration not yet
    named is fitted on that model's readings, and the best is refitted as a whole model and cross-validated. The
    exchange is made when it lowers the cross-validated score by ``min_gain`` and its penalised score, the
    calibration leaves no local departure against the model without the cause, and no parameter is pinned; the best
    such exchange is made, and the caller runs the removal step again. Beside a valve (the model after the exchange
    keeps one) and with ``beside_valve`` in :data:`~.evidence.EXCHANGE_IN_SAMPLE` the gain is the in-sample one (as
    :func:`~.evidence.earns`: the valve's held-out openings dilute the cross-validated gain; a swap back to the true
    calibration gained 7.0 % cross-validated, docs/validation.md); the penalised cross-validated
    score must still be lower."""
    phys = [m for m in current.mechanisms if not isinstance(m, SensorCalibration)]
    named = {m.channel for m in current.mechanisms if isinstance(m, SensorCalibration)}
    cals = [m for m in mechanisms if isinstance(m, SensorCalibration) and m.channel not in named]
    if not phys or not cals:
        return None
    rows_all = np.arange(problem.n_points)
    s_in_cur = 2.0 * current_fit.data_cost / M
    tried: list[CandidateScore] = []
    best: tuple[CandidateScore, Mechanism, float | None] | None = None
    for m in phys:
        comb0 = Combination(tuple(x for x in current.mechanisms if x is not m))
        support = {k: v for k, v in current_fit.support.items() if k in {x.id for x in comb0.valves}}
        fit0 = fit_combination(problem, comb0, start=current_fit, known=current_fit.values(), support=support)
        in_pred = predict_setting(problem, fit0, rows_all)
        loco0 = None  # the model without m, judged channel by channel: computed once, when a candidate needs it
        in_sample = beside_valve in EXCHANGE_IN_SAMPLE and bool(comb0.valves)
        # the channel whose calibration gains most on these readings is the candidate (as at a forward step,
        # calibrations_to_refit); it is then refitted as a whole model, nuisance included
        for cheap in sorted((sensor_fit(problem, fit0, in_pred, cal) for cal in cals), key=lambda f: f.data_cost)[
            :CALIBRATION_REFITS
        ]:
            cal = cheap.combination.mechanisms[-1]
            fit = fit_combination(problem, cheap.combination, start=cheap, known=cheap.values(), support=support)
            c = CandidateScore(cheap.combination, f"{m.label} -> {cal.label}", fit, 2.0 * fit.data_cost / M)
            if c.in_sample_score >= s_in_cur:
                say(f"step {step_no}: exchange {c.added:40s} in-sample {c.in_sample_score:9.4g}: no better")
                continue
            c.score(
                problem,
                *cross_validate(problem, c.combination, fit, max_folds=max_folds),
                M,
                penalty,
                current_S,
                current_fit.k,
            )
            tried.append(c)
            gain = (s_in_cur - c.in_sample_score) / s_in_cur if in_sample else c.gain
            if gain < min_gain or c.penalised >= current_pen:
                c.screened = (
                    f"{'in-sample ' if in_sample else ''}gain {gain:.1%}, penalised {c.penalised:.4g} "
                    f"against {current_pen:.4g}"
                )
            else:
                pins = why_pinned(problem, c, fit.values(), support)
                if not pins and loco0 is None:
                    loco0 = loco_predictions(problem, fit0)
                left = "" if pins else structure_left(problem, loco0, cal, alpha)
                if pins or left:
                    c.screened = "not eligible: " + ("; ".join(pins) if pins else left)
            say(
                f"step {step_no}: exchange {c.added:40s} CV {c.cv_score:9.4g}  gain {c.gain:+.1%}  "
                + (c.screened or "eligible")
            )
            if not c.screened and (best is None or c.penalised < best[0].penalised):
                best = (c, m, gain if in_sample else None)
    if best is None:
        return None
    c, m, in_gain = best
    step = {
        "step": step_no,
        "best": c.combination.mechanisms[-1].label,
        "accepted": True,
        "exchanged": m.label,
        "decision": f"exchanged: {m.label} replaced by {c.combination.mechanisms[-1].label} (cross-validated "
        f"score {current_S:.4g} -> {c.cv_score:.4g}, gain {c.gain:.1%}"
        + (f"; beside a valve, in-sample gain {in_gain:.1%})" if in_gain is not None else ")"),
        "threshold_p": math.nan,
        "current_score": current_S,
        "candidates": tried,
    }
    say(f"step {step_no}: {step['decision']}")
    return step, c, m
