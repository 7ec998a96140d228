"""Steady operating points of the engine model (with its submodels) fixed by fuel, power or fuel flow.

:func:`marine_fdi_env.engine.steady_state.steady_state` solves the equilibrium for a fuel setting with the
speed from the load law inside the algebraic loop; the simulator starts from it.  Validation against
measured data needs more ways to fix a point, and a prescribed speed:

* ``MODE_U`` (fuel setting u given): unknowns ``(x3, x4, n)``, third equation the load law;
* ``MODE_P`` (brake power given, with the speed the law gives at that power, or prescribed):
  unknowns ``(x3, x4, x1)``, third equation ``2π n z3 = P``;
* ``MODE_F`` (fuel mass flow given): unknowns ``(x3, x4, n)`` with ``x1 = ṁ_f k_e/(i_e n)``.

In every mode the pressures solve ``(1 + φ_tur) x3 = τ_pd h3`` and ``(1 + φ_int) x4 = τ_TC h4`` (the
equilibrium of eq. 3.15 and 3.30) with the algebraic equations evaluated at the speed by
:func:`marine_fdi_env.engine.model.algebraic_at_speed`: the same compiled functions as the dynamic model,
so a point found here is an equilibrium of the simulator (tested).  Load law ``law``: 0 = the
parameter set's (propeller law, or the combinator of the ``speed_law`` submodel), 2 = prescribed
(the measured speed; steady state only).

A damped Newton method with a finite-difference 3x3 Jacobian runs in compiled code for all points
(tens of µs per point); a point that does not converge is retried from the default guess and then
with :func:`scipy.optimize.root`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from scipy.optimize import root

from .._jit import jit
from .constants import model_constants
from .fault_registry import I_PHI_INT, I_PHI_TUR
from .model import ALG_FIELDS, HEALTHY_PF, N_ALG, algebraic_at_speed
from .params import EngineParams
from .turbocharger_speed import turbocharger_speed_rpm

__all__ = [
    "MODE_U",
    "MODE_P",
    "MODE_F",
    "LAW_PARAMS",
    "LAW_PRESCRIBED",
    "SUMMARY_KEYS",
    "OperatingPoints",
    "solve_points",
    "solve_raw",
    "speed_of_power",
    "power_of_speed",
    "summaries_from_alg",
    "ALG_INDEX",
    "Summary",
]

MODE_U, MODE_P, MODE_F = 0, 1, 2
LAW_PARAMS, LAW_PRESCRIBED = 0, 2
_A = {f: i for i, f in enumerate(ALG_FIELDS)}
ALG_INDEX = _A

SUMMARY_KEYS = (
    "fuel_setting",
    "engine_speed_rev_s",
    "power_W",
    "torque_Nm",
    "fuel_per_cycle_kg",
    "fuel_mass_flow_kg_s",
    "sfc_kg_per_J",
    "charge_air_pressure_Pa",
    "exhaust_receiver_pressure_Pa",
    "p_max_Pa",
    "cylinder_pressure_eo_Pa",
    "cylinder_temperature_eo_K",
    "turbine_inlet_temperature_K",
    "turbine_outlet_temperature_K",
    "compressor_outlet_temperature_K",
    "inlet_air_temperature_K",
    "air_mass_flow_kg_s",
    "exhaust_mass_flow_kg_s",
    "air_excess_ratio",
    "slip_ratio",
    # beyond the base summary of steady_state.SteadyState
    "charge_air_cooler_outlet_temperature_K",
    "cylinder_outlet_temperature_K",
    "turbine_gas_inlet_temperature_K",
    "exhaust_after_waste_gate_temperature_K",
    "bypass_air_flow_kg_s",
    "bypass_fraction",
    "waste_gate_fraction",
    "turbocharger_speed_rpm",
)


class Summary(Mapping):
    """The operating points as arrays of SI quantities (keys :data:`SUMMARY_KEYS`, ending in their unit), each
    computed when first asked for (fits read a few keys many thousand times).

    Built from the algebraic output matrix ``alg`` (rows x ``ALG_FIELDS``), the states and ``conv`` (NaN where a
    point did not converge); ``p_amb_Pa``/``T_amb_K`` (per point) override the parameter set's ambient state for the
    turbocharger speed.  The base keys are computed exactly as
    :meth:`marine_fdi_env.engine.steady_state.SteadyState.summary` computes them.
    """

    def __init__(
        self,
        params: EngineParams,
        x1,
        x3,
        x4,
        alg: np.ndarray,
        conv: np.ndarray | None = None,
        p_amb_Pa=None,
        T_amb_K=None,
    ):
        ok = np.ones(alg.shape[0], bool) if conv is None else np.asarray(conv, bool)
        self._p, self._ok = params, ok
        self._x1 = np.where(ok, x1, np.nan)
        self._x3 = np.where(ok, x3, np.nan)
        self._x4 = np.where(ok, x4, np.nan)
        self._alg = alg
        self._amb = (p_amb_Pa, T_amb_K)
        self._cache: dict[str, np.ndarray] = {}

    def _a(self, f: str) -> np.ndarray:
        return np.where(self._ok, self._alg[:, _A[f]], np.nan)

    def _compute(self, k: str) -> np.ndarray:
        p = self._p
        a = self._a
        if k == "fuel_setting":
            return self._x1 / p.x1_nom_kg
        if k == "engine_speed_rev_s":
            return a("n")
        if k == "power_W":
            return 2.0 * np.pi * a("n") * a("torque")
        if k == "torque_Nm":
            return a("torque")
        if k == "fuel_per_cycle_kg":
            return self._x1
        if k == "fuel_mass_flow_kg_s":
            return self._x1 * a("n") * p.n_cylinders / p.revs_per_cycle
        if k == "sfc_kg_per_J":
            P = self["power_W"]
            with np.errstate(divide="ignore", invalid="ignore"):
                return np.where(P > 0, self["fuel_mass_flow_kg_s"] / P, np.inf)
        if k == "charge_air_pressure_Pa":
            return self._x4
        if k == "exhaust_receiver_pressure_Pa":
            return self._x3
        if k == "bypass_fraction":
            mc = a("mdot_c")
            with np.errstate(divide="ignore", invalid="ignore"):
                return np.where(mc > 0, a("mdot_bp") / mc, 0.0)
        if k == "turbocharger_speed_rpm":
            return turbocharger_speed_rpm(p, self._x4, *self._amb)
        f = _DIRECT.get(k)
        if f is None:
            raise KeyError(k)
        return a(f)

    def __getitem__(self, k: str) -> np.ndarray:
        v = self._cache.get(k)
        if v is None:
            v = self._cache[k] = self._compute(k)
        return v

    def __iter__(self):
        return iter(SUMMARY_KEYS)

    def __len__(self) -> int:
        return len(SUMMARY_KEYS)

    def __contains__(self, k) -> bool:
        return k in SUMMARY_KEYS


_DIRECT = {
    "p_max_Pa": "p_max",
    "cylinder_pressure_eo_Pa": "p6",
    "cylinder_temperature_eo_K": "T6",
    "turbine_inlet_temperature_K": "T_in",
    "turbine_outlet_temperature_K": "T_out",
    "compressor_outlet_temperature_K": "T_co",
    "inlet_air_temperature_K": "T1",
    "air_mass_flow_kg_s": "mdot_c",
    "exhaust_mass_flow_kg_s": "mdot_g",
    "air_excess_ratio": "lam",
    "slip_ratio": "s_sl",
    "charge_air_cooler_outlet_temperature_K": "T_c",
    "cylinder_outlet_temperature_K": "T_cyl",
    "turbine_gas_inlet_temperature_K": "T_t",
    "exhaust_after_waste_gate_temperature_K": "T_exh",
    "bypass_air_flow_kg_s": "mdot_bp",
    "waste_gate_fraction": "wg_frac",
}


def summaries_from_alg(
    params: EngineParams, x1, x3, x4, alg: np.ndarray, conv=None, p_amb_Pa=None, T_amb_K=None
) -> dict[str, np.ndarray]:
    """Every key of :class:`Summary` as a plain dict."""
    return dict(Summary(params, x1, x3, x4, alg, conv, p_amb_Pa, T_amb_K))


# --------------------------------------------------------------------------------------- compiled core
@jit
def _law_residual(n, power, c):
    """Residual of the parameter set's load law at speed n and brake power P (normalised)."""
    if c.sl_comb != 0.0:
        return n / c.n_nom_rev_s - c.sl_s0 - (c.sl_s1 - c.sl_s0) * power / c.P_nom_W
    return (power - c.c_load_W_s3 * n * n * n) / c.P_nom_W


@jit
def _residual(mode, law, y0, y1, y2, a0, a1, c, pf, alg, ov):
    """The three equilibrium residuals at unknowns y (module docstring); fills ``alg``; returns (r, x1, n)."""
    x3 = y0
    x4 = y1
    if mode == 1:  # MODE_P: y2 = x1, a0 = power, a1 = speed
        x1 = y2
        n = a1
    elif mode == 0:  # MODE_U: y2 = n, a0 = u
        n = y2
        x1 = c.x1_nom_kg * a0
    else:  # MODE_F: y2 = n, a0 = fuel mass flow
        n = y2
        x1 = a0 / (max(n, 1e-9) * c.cycles_per_rev)
    algebraic_at_speed(c, x1, x3, x4, n, pf, alg, ov[0], ov[1])
    r3 = 1.0 - c.tau_pd_s * alg[14] / ((1.0 + pf[I_PHI_TUR]) * x3)
    r4 = 1.0 - c.tau_TC_s * alg[15] / ((1.0 + pf[I_PHI_INT]) * x4)
    torque = alg[1]
    if mode == 1:
        r5 = (torque - a0 / (2.0 * math.pi * n)) * (2.0 * math.pi * c.n_nom_rev_s / c.P_nom_W)
    elif law == 2:
        r5 = (n - a1) / c.n_nom_rev_s
    else:
        r5 = _law_residual(n, 2.0 * math.pi * n * torque, c)
    return r3, r4, r5, x1


@jit
def _initial_guess(mode, law, a0, a1, c, y):
    dp = c.p1_nom_Pa - c.p_amb_Pa
    if mode == 1:
        load = max(a0 / c.P_nom_W, 0.02)
        x4 = c.p_amb_Pa + dp * load
        y[2] = c.SFC_nom_kg_per_J * a0 / (a1 * c.cycles_per_rev)
    else:
        if mode == 0:
            u = max(a0, 0.05)
        else:
            u = max(a0 / (c.x1_nom_kg * c.n_nom_rev_s * c.cycles_per_rev), 0.05)
        x4 = c.p_amb_Pa + dp * u**1.5
        if law == 2:
            y[2] = a1
        elif c.sl_comb != 0.0:
            y[2] = c.n_nom_rev_s * (c.sl_s0 + (c.sl_s1 - c.sl_s0) * u**1.5)
        else:
            y[2] = c.n_nom_rev_s * u ** (1.0 / 3.0)
    y[0] = c.p_ex_Pa + 0.7 * (x4 - c.p_amb_Pa) + 1.0
    y[1] = x4


@jit
def _solve3(J, f, s):
    """Solve the 3x3 system J s = f by Cramer's rule; returns False if singular."""
    a, b, cc = J[0, 0], J[0, 1], J[0, 2]
    d, e, ff = J[1, 0], J[1, 1], J[1, 2]
    g, hh, i = J[2, 0], J[2, 1], J[2, 2]
    det = a * (e * i - ff * hh) - b * (d * i - ff * g) + cc * (d * hh - e * g)
    if det == 0.0 or not math.isfinite(det):
        return False
    s[0] = (f[0] * (e * i - ff * hh) - b * (f[1] * i - ff * f[2]) + cc * (f[1] * hh - e * f[2])) / det
    s[1] = (a * (f[1] * i - ff * f[2]) - f[0] * (d * i - ff * g) + cc * (d * f[2] - f[1] * g)) / det
    s[2] = (a * (e * f[2] - f[1] * hh) - b * (d * f[2] - f[1] * g) + f[0] * (d * hh - e * g)) / det
    return True


@jit
def _newton(mode, law, a0, a1, c, pf, y, alg, tol, max_iter, ov):
    """Damped Newton on the three residuals from ``y`` (updated in place); returns converged."""
    f = np.empty(3)
    ft = np.empty(3)
    J = np.empty((3, 3))
    s = np.empty(3)
    yt = np.empty(3)
    r = _residual(mode, law, y[0], y[1], y[2], a0, a1, c, pf, alg, ov)
    f[0], f[1], f[2] = r[0], r[1], r[2]
    norm = abs(f[0]) + abs(f[1]) + abs(f[2])
    for _ in range(max_iter):
        if not math.isfinite(norm):
            return False
        for j in range(3):
            yt[0], yt[1], yt[2] = y[0], y[1], y[2]
            d = 1e-7 * abs(y[j]) + 1e-300
            yt[j] += d
            r = _residual(mode, law, yt[0], yt[1], yt[2], a0, a1, c, pf, alg, ov)
            J[0, j] = (r[0] - f[0]) / d
            J[1, j] = (r[1] - f[1]) / d
            J[2, j] = (r[2] - f[2]) / d
        if not _solve3(J, f, s):
            return False
        # steps that keep the pressures physical and the third unknown positive
        s[0] = min(max(s[0], -0.5 * (y[0] - c.p_ex_Pa)), 0.5 * y[0])
        s[1] = min(max(s[1], -0.5 * (y[1] - 0.2 * c.p_amb_Pa)), 0.5 * y[1])
        s[2] = min(max(s[2], -0.3 * abs(y[2])), 0.3 * abs(y[2]))
        lam = 1.0
        for _ in range(8):
            yt[0], yt[1], yt[2] = y[0] - lam * s[0], y[1] - lam * s[1], y[2] - lam * s[2]
            r = _residual(mode, law, yt[0], yt[1], yt[2], a0, a1, c, pf, alg, ov)
            ft[0], ft[1], ft[2] = r[0], r[1], r[2]
            nt = abs(ft[0]) + abs(ft[1]) + abs(ft[2])
            if math.isfinite(nt) and nt <= norm:
                break
            lam *= 0.5
        y[0], y[1], y[2] = yt[0], yt[1], yt[2]
        f[0], f[1], f[2] = ft[0], ft[1], ft[2]
        norm = abs(f[0]) + abs(f[1]) + abs(f[2])
        small = (
            abs(lam * s[0]) <= tol * abs(y[0])
            and abs(lam * s[1]) <= tol * abs(y[1])
            and abs(lam * s[2]) <= tol * abs(y[2])
        )
        if small or norm == 0.0:
            if norm < 1e-9:
                _residual(mode, law, y[0], y[1], y[2], a0, a1, c, pf, alg, ov)
                return True
    return norm < 1e-11


@jit
def _solve_batch(mode, law, c, pf, a, y, use_guess, alg, x1_out, status, tol, max_iter, ov):
    """Solve every point i with inputs a[i] = (a0, a1) from y[i] (if use_guess[i]) else the default guess."""
    for i in range(a.shape[0]):
        if not (math.isfinite(a[i, 0]) and math.isfinite(a[i, 1])):
            status[i] = -1
            for k in range(alg.shape[1]):
                alg[i, k] = math.nan
            x1_out[i] = math.nan
            continue
        ok = False
        if use_guess[i]:
            ok = _newton(mode, law, a[i, 0], a[i, 1], c, pf, y[i], alg[i], tol, max_iter, ov[i])
        if not ok:
            _initial_guess(mode, law, a[i, 0], a[i, 1], c, y[i])
            ok = _newton(mode, law, a[i, 0], a[i, 1], c, pf, y[i], alg[i], tol, max_iter, ov[i])
        r = _residual(mode, law, y[i, 0], y[i, 1], y[i, 2], a[i, 0], a[i, 1], c, pf, alg[i], ov[i])
        x1_out[i] = r[3]
        status[i] = 1 if ok else 0


@jit
def _residual_vec(mode, law, a0, a1, c, pf, y, alg, ov):
    r = _residual(mode, law, y[0], y[1], y[2], a0, a1, c, pf, alg, ov)
    out = np.empty(3)
    out[0], out[1], out[2] = r[0], r[1], r[2]
    return out


# --------------------------------------------------------------------------------------- results
@dataclass(frozen=True)
class OperatingPoints:
    """Steady operating points: ``values[key]`` arrays in SI (keys :data:`SUMMARY_KEYS`), NaN where a point did
    not converge; ``state`` (n, 3) the final unknowns (a warm start for the next solve)."""

    values: dict[str, np.ndarray]
    converged: np.ndarray
    state: np.ndarray

    def __len__(self) -> int:
        return int(self.converged.size)

    def summary(self, i: int = 0) -> dict[str, float]:
        return {k: float(v[i]) for k, v in self.values.items()}


def speed_of_power(params: EngineParams, power_W) -> np.ndarray:
    """Engine speed [rev/s] of the parameter set's load law at brake power P (propeller law or combinator)."""
    P = np.atleast_1d(np.asarray(power_W, float))
    sl = params.submodels.speed_law
    if sl is not None:
        return params.n_nom_rev_s * (
            sl.speed_zero_load_rel + (sl.speed_full_load_rel - sl.speed_zero_load_rel) * P / params.P_nom_W
        )
    return np.cbrt(P / params.c_load_W_s3)


def power_of_speed(params: EngineParams, speed_rev_s) -> np.ndarray:
    """Brake power [W] of the load law at engine speed n (inverse of :func:`speed_of_power`)."""
    n = np.atleast_1d(np.asarray(speed_rev_s, float))
    sl = params.submodels.speed_law
    if sl is not None:
        ds = sl.speed_full_load_rel - sl.speed_zero_load_rel
        if ds == 0:
            raise ValueError("a constant-speed combinator line cannot give the power from the speed")
        return params.P_nom_W * (n / params.n_nom_rev_s - sl.speed_zero_load_rel) / ds
    return params.c_load_W_s3 * n**3


def solve_raw(
    c,
    mode: int,
    a0: np.ndarray,
    a1: np.ndarray,
    law: int,
    y: np.ndarray,
    pf: np.ndarray,
    ov: np.ndarray,
    tol: float = 1e-12,
    max_iter: int = 60,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The compiled solve of :func:`solve_points` on model constants ``c``, without summaries (a hot path of
    fits): returns (alg (n, N_ALG), x1 (n,), converged (n,)); ``y`` (n, 3) is the warm start, updated in place
    (NaN or non-positive rows start from the default guess)."""
    n = a0.size
    a = np.ascontiguousarray(np.column_stack([a0, a1]), dtype=float)
    use = np.all(np.isfinite(y) & (y > 0), axis=1)
    y[~use] = 0.0
    alg = np.empty((n, N_ALG))
    x1 = np.empty(n)
    status = np.zeros(n, dtype=np.int64)
    _solve_batch(int(mode), law, c, pf, a, y, use, alg, x1, status, tol, max_iter, ov)
    for i in np.flatnonzero(status == 0):  # last resort: scipy's hybrid method
        if _scipy_fallback(int(mode), law, a[i], c, pf, y[i], alg[i], ov[i]):
            x1[i] = _residual(int(mode), law, y[i, 0], y[i, 1], y[i, 2], a[i, 0], a[i, 1], c, pf, alg[i], ov[i])[3]
            status[i] = 1
    return alg, x1, status == 1


def solve_points(
    params: EngineParams,
    mode: int,
    a0,
    a1=None,
    *,
    prescribed_speed: bool = False,
    guess: np.ndarray | None = None,
    pf: np.ndarray | None = None,
    valves: np.ndarray | None = None,
    tol: float = 1e-12,
    max_iter: int = 60,
) -> OperatingPoints:
    """Solve operating points of ``params`` (submodels included).

    mode : ``MODE_U`` (a0 = fuel setting), ``MODE_P`` (a0 = brake power [W], a1 = speed [rev/s]; default: the
    load law's speed at that power) or ``MODE_F`` (a0 = fuel mass flow [kg/s]).  prescribed_speed : in
    MODE_U/MODE_F the speed is a1 instead of the load law's.  pf : process-fault vector (``PF_FIELDS``),
    healthy by default.  guess : (n, 3) warm start (see :attr:`OperatingPoints.state`).  valves : (n, 2)
    waste-gate and bypass openings per point overriding the schedules of the submodels (NaN: schedule).
    """
    c = model_constants(params)
    a0 = np.atleast_1d(np.asarray(a0, float))
    n = a0.size
    if mode == MODE_P and a1 is None:
        a1 = speed_of_power(params, a0)
    if prescribed_speed and a1 is None:
        raise ValueError("a prescribed speed needs the speed of every point (a1)")
    a1 = np.full(n, 0.0) if a1 is None else np.broadcast_to(np.asarray(a1, float), (n,))
    law = LAW_PRESCRIBED if prescribed_speed else LAW_PARAMS
    y = np.full((n, 3), np.nan) if guess is None else np.array(guess, dtype=float, order="C").reshape(n, 3)
    pfv = np.array(HEALTHY_PF if pf is None else pf, dtype=float)
    ov = np.full((n, 2), np.nan) if valves is None else np.ascontiguousarray(np.broadcast_to(valves, (n, 2)), float)
    alg, x1, ok = solve_raw(c, mode, a0, np.asarray(a1, float), law, y, pfv, ov, tol, max_iter)
    vals = summaries_from_alg(params, x1, y[:, 0], y[:, 1], alg, ok)
    return OperatingPoints(values=vals, converged=ok, state=y)


def _scipy_fallback(mode, law, a, c, pf, y, alg, ov) -> bool:
    y0 = np.empty(3)
    _initial_guess(mode, law, a[0], a[1], c, y0)
    scale = y0.copy()
    fun = lambda z: _residual_vec(mode, law, a[0], a[1], c, pf, z * scale, alg, ov)  # noqa: E731
    try:
        sol = root(fun, np.ones(3), method="hybr", tol=1e-13)
    except (ValueError, ZeroDivisionError, FloatingPointError):
        return False
    if sol.success and np.all(np.isfinite(sol.x)) and np.max(np.abs(fun(sol.x))) < 1e-9:
        y[:] = sol.x * scale
        _residual_vec(mode, law, a[0], a[1], c, pf, y, alg, ov)
        return True
    return False
