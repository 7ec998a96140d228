"""The measurement that would decide between explanations: where, in the engine's envelope and the data's ambient
range, their predictions differ most in tolerances.

Each explanation's fitted engine (valves on their schedules over the fuel setting, sensor calibrations applied, as
the fitted engine file runs) is solved on a grid: loads :data:`LOADS` of the rated power (the engine's range, the
propeller law's speed) at the data's ambient conditions, the mean and the four corners of the recorded range of
ambient pressure and intake temperature (the parameter set's where the data recorded none), the back pressure over
load as the data recorded it; loads within :data:`NEAR` of a measured load are left out (the data already hold a
reading there, and both explanations were fitted to it). For two explanations A and B every channel's difference
``|a - b|`` is taken over the grid against the scale a new reading would scatter by about either prediction: the
channel's tolerance, or the explanations' own misfit on that channel where it is larger (``sqrt((rmse_A² +
rmse_B²)/2)`` of their in-sample residuals; a channel both miss by 30 K decides nothing at 10 K). The largest is the
measurement that decides: "measure X at load Y: A predicts a, B predicts b (n tolerances apart)", with its ratio to
that scale. A difference below about three of them would not decide on one reading.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from ...engine.operating_point import MODE_P, solve_points, speed_of_power
from ..fit.fitting import FitResult, channel_rmse, predict_setting
from ..fit.problem import FitProblem, quantity_values

__all__ = ["LOADS", "NEAR", "Decider", "ambient_cases", "deciding_measurements", "readings_over_load"]

#: load fractions of the rated power the explanations are compared at (the engine's range, 25-110 %)
LOADS = np.round(np.arange(0.25, 1.1001, 0.025), 4)
#: a grid load this close to a measured load (in load fraction) is not proposed
NEAR = 0.03


@dataclass(frozen=True)
class Decider:
    """Where two explanations' predictions differ most on one channel."""

    channel: str
    unit: str
    load: float
    p_amb_Pa: float
    T_amb_K: float
    a: str
    b: str
    a_value: float
    b_value: float
    tolerance: float
    scale: float  #: the tolerance or the explanations' misfit on the channel, the larger (module docstring)

    @property
    def n_tolerances(self) -> float:
        return abs(self.a_value - self.b_value) / self.tolerance

    @property
    def n_scales(self) -> float:
        return abs(self.a_value - self.b_value) / self.scale

    def text(self) -> str:
        misfit = (
            ""
            if self.scale <= self.tolerance
            else (
                f"; {self.n_scales:.1f} times the explanations' misfit of {self.scale:.3g} {self.unit} on this channel"
            )
        )
        return (
            f"measure {self.channel} at {100 * self.load:.0f} % load (intake {self.T_amb_K - 273.15:.0f} °C, "
            f"ambient {self.p_amb_Pa / 100:.0f} hPa): {self.a} predicts {self.a_value:.4g}, {self.b} predicts "
            f"{self.b_value:.4g} {self.unit} ({self.n_tolerances:.1f} tolerances apart{misfit})"
        )

    def as_dict(self) -> dict[str, Any]:
        return {
            "channel": self.channel,
            "unit": self.unit,
            "load": self.load,
            "p_amb_Pa": self.p_amb_Pa,
            "T_amb_K": self.T_amb_K,
            "a": self.a,
            "b": self.b,
            "a_value": self.a_value,
            "b_value": self.b_value,
            "tolerance": self.tolerance,
            "scale": self.scale,
            "n_tolerances": self.n_tolerances,
            "n_scales": self.n_scales,
            "text": self.text(),
        }


def ambient_cases(problem: FitProblem) -> list[tuple[float, float]]:
    """(ambient pressure [Pa], intake temperature [K]): the data's mean and the corners of its recorded range (the
    parameter set's value for a quantity the data did not record)."""
    b = problem.boundary

    def span(key: str, default: float) -> tuple[float, float, float]:
        v = b[key][np.isfinite(b[key])]
        return (float(v.mean()), float(v.min()), float(v.max())) if v.size else (default, default, default)

    pm, plo, phi = span("p_amb_Pa", problem.params.p_amb_Pa)
    tm, tlo, thi = span("T_amb_K", problem.params.T_amb_K)
    out = [(pm, tm)] + [(p, t) for p in (plo, phi) for t in (tlo, thi)]
    return list(dict.fromkeys(out))


def readings_over_load(
    problem: FitProblem, fit: FitResult, loads: Sequence[float], p_amb_Pa: float, T_amb_K: float
) -> np.ndarray:
    """Readings (loads x channels, the channels' units; NaN where the model has no steady state) of ``fit``'s
    fitted engine at ``loads`` of the rated power, at the given ambient conditions and the data's back pressure."""
    setting = fit.schedule_setting(problem)
    eng = problem.engine(setting)
    loads = np.asarray(loads, dtype=float)
    tb = problem.test_bed_conditions() or {}
    bp = tb.get("back_pressure")
    dp = (
        np.interp(loads, bp["load_fraction"], bp["dp_Pa"])
        if bp
        else np.full(loads.size, problem.params.p_ex_Pa - problem.params.p_amb_Pa)
    )
    pa = p_amb_Pa + setting.dp_amb_Pa
    out = np.full((loads.size, len(problem.channels)), np.nan)
    P = loads * problem.ds.rated_power_W
    for k in np.unique(np.round(dp, 3)):
        idx = np.flatnonzero(np.round(dp, 3) == k)
        p = eng.replace(validate=False, p_amb_Pa=pa, T_amb_K=T_amb_K + setting.dT_amb_K, p_ex_Pa=pa + float(k))
        op = solve_points(p, MODE_P, P[idx], speed_of_power(p, P[idx]))
        for j, c in enumerate(problem.channels):
            v = problem.ds.spec(c).from_si(quantity_values(problem.ds.column_quantity[c], op.values, problem.ctx), pa)
            if c in setting.sensors:
                g, o = setting.sensors[c]
                v = g * v + o
            out[idx, j] = np.where(op.converged, v, np.nan)
    return out


def deciding_measurements(
    problem: FitProblem, explanations: Sequence[tuple[str, FitResult]], *, per_pair: int = 3
) -> list[dict[str, Any]]:
    """For each pair of ``explanations`` (name, fit), best first: the ``per_pair`` channels whose predictions differ
    most in tolerances anywhere on the grid of the module docstring, each at its most telling point."""
    cases = ambient_cases(problem)
    pred = {name: [readings_over_load(problem, f, LOADS, pa, ta) for pa, ta in cases] for name, f in explanations}
    rows = np.arange(problem.n_points)
    rmse = {name: channel_rmse(problem, predict_setting(problem, f, rows)) for name, f in explanations}
    measured = problem.load_axis()[problem.rows_with_data()]
    new_load = np.array([np.all(np.abs(x - measured) >= NEAR) for x in LOADS])
    tol = problem.tolerance
    out = []
    names = [n for n, _ in explanations]
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            best: list[Decider] = []
            for j, c in enumerate(problem.channels):
                top = None
                scale = max(float(tol[j]), math.sqrt(0.5 * (rmse[a][c] ** 2 + rmse[b][c] ** 2)))
                for k, (pa, ta) in enumerate(cases):
                    d = np.where(new_load, np.abs(pred[a][k][:, j] - pred[b][k][:, j]) / scale, np.nan)
                    if not np.isfinite(d).any():
                        continue
                    n = int(np.nanargmax(d))
                    if top is None or d[n] > top[0]:
                        top = (float(d[n]), n, pa, ta, k)
                if top is not None:
                    _, n, pa, ta, k = top
                    best.append(
                        Decider(
                            c,
                            problem.ds.spec(c).unit,
                            float(LOADS[n]),
                            pa,
                            ta,
                            a,
                            b,
                            float(pred[a][k][n, j]),
                            float(pred[b][k][n, j]),
                            float(tol[j]),
                            scale,
                        )
                    )
            best.sort(key=lambda d: -d.n_scales)
            out.append(
                {
                    "a": a,
                    "b": b,
                    "measurements": [d.as_dict() for d in best[:per_pair]],
                    "at_measured_loads": _at_measured(problem, explanations, a, b),
                }
            )
    return out


def _at_measured(problem: FitProblem, explanations: Sequence[tuple[str, FitResult]], a: str, b: str) -> float:
    """The largest difference in tolerances between ``a`` and ``b`` at the measured points (both fit there)."""
    fits = dict(explanations)
    rows = np.arange(problem.n_points)
    pa, pb = predict_setting(problem, fits[a], rows), predict_setting(problem, fits[b], rows)
    d = np.abs(pa - pb) / problem.tolerance
    return float(np.nanmax(d)) if np.isfinite(d).any() else math.nan
