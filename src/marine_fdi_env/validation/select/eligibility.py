"""Whether a scored candidate may be named (:mod:`.selection`, end of its docstring): a sensor calibration only
when its gain and offset leave no local departure on its channel (:func:`structure_left`); no candidate whose valve
opens nowhere or whose fit sits at a bound of its plausible range that the data want beyond (:func:`why_pinned`)."""

from __future__ import annotations

import dataclasses
import math
from typing import Any, Mapping

import numpy as np

from ..fit.fitting import Combination, FitResult, fit_combination, fit_sensor
from ..fit.mechanisms import Mechanism, SensorCalibration
from ..fit.problem import FitProblem
from .candidates import CandidateScore, f_test_p
from .window_scan import noise_ratio, window_excess

__all__ = [
    "BINDING_ALPHA",
    "CALIBRATION_EXPLAINS",
    "RELAX_SPAN",
    "binding_bounds",
    "params_at_bound",
    "relaxed_mechanism",
    "shut_valves",
    "structure_left",
    "undetermined_params",
    "why_pinned",
]

#: share of a channel's RMS discrepancy a calibration must remove to explain it although structure is left
CALIBRATION_EXPLAINS = 0.75


def structure_left(problem: FitProblem, loco: np.ndarray, mech: SensorCalibration, alpha: float) -> str:
    """A description of what a gain and an offset leave unexplained on the sensor's channel, judged against the model
    fitted without that channel (``loco``, :func:`~.fit.fitting.loco_predictions`); "" when the calibration is an
    explanation.

    A sensor's gain and offset explain its channel when what they leave looks like noise (no significant local
    departure), or when they remove at least ``CALIBRATION_EXPLAINS`` (75 %) of the channel's RMS discrepancy (a
    large calibration error with a smaller structure left, which is then reported as unexplained).  A local effect
    that a gain and offset only bend towards (a bump, a step) passes neither."""
    j = problem.channels.index(mech.channel)
    tol = float(problem.tolerance[j])
    rows = np.flatnonzero(np.isfinite(loco[:, j]) & problem.measured_mask[:, j])
    g, o = fit_sensor(problem, j, loco[rows], rows, [p.bounds for p in mech.params])
    before = loco[rows, j] - problem.Y[rows, j]
    after = g * loco[rows, j] + o - problem.Y[rows, j]
    load = problem.load_axis()
    noise = noise_ratio((loco - problem.Y) / problem.tolerance_cells, load)
    best = window_excess(g * loco[:, j] + o - problem.Y[:, j], load, tol, noise=noise)
    if best is not None and best["p"] < alpha and abs(best["d"]) >= tol:
        rms_b, rms_a = float(np.sqrt(np.mean(before**2))), float(np.sqrt(np.mean(after**2)))
        if rms_a <= (1.0 - CALIBRATION_EXPLAINS) * rms_b:
            return ""
        lo, hi = best["load_range"]
        return (
            f"load {lo:.3g}-{hi:.3g}, {best['d']:+.3g}, p {'<' if best['p_at_floor'] else '='} {best['p']:.2g}; "
            f"the calibration removes only {1 - rms_a / rms_b:.0%} of the channel's error"
        )
    return ""


def shut_valves(fit: FitResult) -> list[str]:
    """Valves of the fit that act at no measured point (then they are not valves, and the candidate is not
    eligible); bounds are judged by :func:`binding_bounds`."""
    return [
        f"{m.label} opens at no measured point"
        for m in fit.combination.mechanisms
        if m.pointwise and not fit.support.get(m.id)
    ]


def params_at_bound(fit: FitResult) -> list[tuple[Mechanism, Any, str]]:
    """(mechanism, parameter, side) of the parameters sitting at a bound that is not a natural limit."""
    vals = fit.values()
    return [
        (m, p, side)
        for m in fit.combination.mechanisms
        for p in m.params
        if (side := p.pinned(vals[f"{m.label}.{p.name}"]))
    ]


def undetermined_params(fit: FitResult) -> list[str]:
    """Parameters the data do not determine (standard error above half the plausible range): reported, not a
    reason to reject a mechanism whose effect as a whole passed the cross-validated tests (two parameters of one
    curve, such as the optimum and the curvature of an efficiency parabola seen over a part of it, trade off)."""
    vals = fit.values()
    se = dict(zip(fit.combination.names, fit.stderr))
    out = []
    for m in fit.combination.mechanisms:
        for p in m.params:
            key = f"{m.label}.{p.name}"
            if (
                not p.pinned(vals[key])
                and math.isfinite(se.get(key, math.nan))
                and se[key] > 0.5 * (p.bounds[1] - p.bounds[0])
            ):
                out.append(f"{key} not determined by the data (standard error {se[key]:.3g})")
    return out


#: share of a parameter's plausible span by which :func:`relaxed_mechanism` widens a bound (kept inside the submodel's
#: own validity range by halving)
RELAX_SPAN = 0.25
#: a bound is binding when widening it lowers the in-sample loss with p below this (F-test, one parameter)
BINDING_ALPHA = 0.05


def relaxed_mechanism(m: Mechanism, name: str, side: str, problem: FitProblem) -> Mechanism | None:
    """``m`` with parameter ``name``'s plausible range widened on ``side`` by :data:`RELAX_SPAN` of its span,
    halved until the submodel accepts the value (None when it accepts no wider value)."""
    import copy

    params = m.params
    p = next(q for q in params if q.name == name)
    lo, hi = p.bounds
    span = hi - lo
    for f in (RELAX_SPAN, RELAX_SPAN / 2, RELAX_SPAN / 4, RELAX_SPAN / 8):
        b = (lo - f * span, hi) if side == "lower" else (lo, hi + f * span)
        x = b[0] if side == "lower" else b[1]
        try:
            m.apply(
                problem.base_setting, {q.name: (x if q.name == name else q.default) for q in params}, problem.params
            )
        except ValueError:
            continue
        wide = tuple(dataclasses.replace(q, bounds=b) if q.name == name else q for q in params)
        sub = type(type(m).__name__ + "Relaxed", (type(m),), {"params": property(lambda self, w=wide: w)})
        r = copy.copy(m)
        object.__setattr__(r, "__class__", sub)
        return r
    return None


def binding_bounds(problem: FitProblem, c: "CandidateScore", known: Mapping[str, float], support) -> list[str]:
    """The bounds of ``c``'s fit that the data want to go beyond: widening the bound (:func:`relaxed_mechanism`) and
    refitting lowers the in-sample loss significantly (one-parameter F-test, p < :data:`BINDING_ALPHA`).  A
    bound the fit merely touches because two parameters trade off costs nothing to keep."""
    out = []
    M = c.fit.n_cells
    for m, p, side in params_at_bound(c.fit):
        bound = p.bounds[0 if side == "lower" else 1]
        r = None if isinstance(m, SensorCalibration) else relaxed_mechanism(m, p.name, side, problem)
        if r is None:
            out.append(f"{m.label}.{p.name} at its {side} bound {bound:g}")
            continue
        comb = Combination(tuple(r if x is m else x for x in c.combination.mechanisms))
        try:
            wide = fit_combination(problem, comb, start=c.fit, known=known, support=support, uncertainty=False)
        except (ValueError, FloatingPointError):
            out.append(f"{m.label}.{p.name} at its {side} bound {bound:g}")
            continue
        pv = f_test_p(c.fit.data_cost, wide.data_cost, c.fit.k - 1, c.fit.k, M)
        if pv < BINDING_ALPHA:
            out.append(f"{m.label}.{p.name} at its {side} bound {bound:g} (widening it gains p = {pv:.2g})")
        else:
            c.notes.append(
                f"{m.label}.{p.name} touches its {side} bound {bound:g} but the data do not want more "
                f"(widening it gains p = {pv:.2g})"
            )
    return out


def why_pinned(problem: FitProblem, c: "CandidateScore", known: Mapping[str, float], support) -> list[str]:
    """Why a cross-validated candidate is pinned (a valve shut everywhere, a bound the data want beyond), empty if
    it is not; notes the parameters its fit leaves undetermined."""
    c.notes += undetermined_params(c.fit)
    pins = shut_valves(c.fit)
    if not pins and params_at_bound(c.fit):
        pins = binding_bounds(problem, c, known, support)
    return pins
