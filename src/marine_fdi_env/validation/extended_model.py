"""The steady state of the engine model with extension hooks, for validation against measured data.

This is the *steady-state* counterpart of :mod:`marine_fdi_env.model` for validation only (the
dynamic simulator is untouched).  It composes the same scalar subsystem functions (Seiliger cycle,
constant-volume portion, friction, slip ratio, scavenge flow, turbine expansion) and adds hooks that
the named mechanisms of :mod:`.mechanisms` switch on:

=====================  ============================================================================
hook                   what it changes
=====================  ============================================================================
speed law              ``propeller`` (eq. 3.11, ``P = c n^3``), ``combinator`` (controllable pitch:
                       ``n/n_nom = s0 + (s1 - s0) P/P_nom``) or ``prescribed`` (the measured speed)
extra friction         ``ΔQ = V_d i_e/(2π k_e) (a + b p_max + c n/n_nom + d (n/n_nom)^2)``, a
                       Chen-Flynn-like friction mean effective pressure (c_m ∝ n) added to eq. 3.10
ambient                ambient temperature and pressure (``T_amb``, ``p_amb`` and the turbine back
                       pressure ``p_ex``) via ``params.replace`` and ``model_constants``
turbocharger map       ``η_TC = s η_TC,3.33(p1_nom) (1 - w (x4/p1_nom - 1)^2)`` instead of eq. 3.33,
                       with the turbine efficiency kept at ``η_turbo = η_TC/(η_c η_com)``
bypass                 a fraction ``β`` of the compressor air flows from the charge-air receiver
                       (at the cooler outlet temperature) straight to the exhaust receiver: it mixes
                       with the exhaust before the turbine and bypasses the cylinders;
                       ``β = β_max ramp((x4/p1_nom - threshold)/width)`` (0 below the threshold)
intercooler            cooler outlet ``T_c = T_c,nom + (1 - ε)(T_co,is(x4) - T_co,is(p1_nom))``:
                       the outlet follows the cooler inlet (isentropic compressor outlet at
                       ``η_c``) with the effectiveness ε (ε = 1: the constant ``T_c`` of eq. 3.37)
cylinder heat loss     polytropic exponents: expansion ``n_exp`` (a parameter) and compression
                       ``n_comp`` (eq. B.1-B.9 use κa; the derived ``r_c^n``, ``r_c^(n-1)`` change)
sensor gain/offset     per measured column: ``reading = gain * model + offset`` (column units)
=====================  ============================================================================

With no hook active the result equals :func:`marine_fdi_env.steady_state.steady_state` (tested to
1e-9 relative).

Solving.  At equilibrium ``x1 = x1_nom u`` and the pressures solve ``x3 = τ_pd h3``, ``x4 = τ_TC h4``.
The third unknown depends on what fixes the operating point:

* ``MODE_U`` (fuel setting given): unknowns ``(x3, x4, n)``, third equation the speed law;
* ``MODE_P`` (power given): the speed follows from the law (explicitly: ``n = (P/c)^(1/3)``, the
  combinator line, or the prescribed speed), unknowns ``(x3, x4, x1)``, third equation
  ``2π n z3 = P``;
* ``MODE_F`` (fuel mass flow given): unknowns ``(x3, x4, n)`` with ``x1 = ṁ_f k_e/(i_e n)``.

A damped Newton method with a finite-difference 3x3 Jacobian runs in compiled code for all points of
a dataset at once (about 10-40 µs per point; fits call it many thousand times); a point that does not
converge is retried from the default guess and then with :func:`scipy.optimize.root`.
"""

from __future__ import annotations

import dataclasses
import math
from functools import lru_cache
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np
from scipy.optimize import root

from .._jit import jit
from ..constants import ModelConstants, model_constants
from ..geometry import cylinder_geometry
from ..params import EngineParams
from ..seiliger import seiliger_cycle
from ..subsystems.engine_block import constant_volume_portion, friction_torque
from ..subsystems.exhaust_receiver import slip_ratio, turbine_expansion

__all__ = [
    "Hooks", "ExtendedModel", "SteadyPoints", "SUMMARY_KEYS", "MODE_U", "MODE_P", "MODE_F", "SPEED_LAWS",
    "NO_HOOKS",
]

MODE_U, MODE_P, MODE_F = 0, 1, 2
SPEED_LAWS = {"propeller": 0, "combinator": 1, "prescribed": 2}

# ---- hook vector layout (compiled code takes the hooks as one float array)
H_LAW, H_S0, H_S1 = 0, 1, 2
H_FA, H_FB, H_FC, H_FD = 3, 4, 5, 6
H_TCMAP, H_TCS, H_TCW = 7, 8, 9
H_BPF, H_BPT, H_BPW = 10, 11, 12
H_ICE = 13
H_VSWEPT = 14
N_HOOKS = 15

# ---- output layout of one point
SUMMARY_KEYS = (
    "fuel_setting", "engine_speed_rev_s", "power_W", "torque_Nm", "fuel_per_cycle_kg", "fuel_mass_flow_kg_s",
    "sfc_kg_per_J", "charge_air_pressure_Pa", "exhaust_receiver_pressure_Pa", "p_max_Pa", "cylinder_pressure_eo_Pa",
    "cylinder_temperature_eo_K", "turbine_inlet_temperature_K", "turbine_outlet_temperature_K",
    "compressor_outlet_temperature_K", "inlet_air_temperature_K", "air_mass_flow_kg_s", "exhaust_mass_flow_kg_s",
    "air_excess_ratio", "slip_ratio", "charge_air_cooler_outlet_temperature_K", "bypass_fraction",
    "turbocharger_efficiency",
)
(O_U, O_N, O_P, O_Q, O_X1, O_MF, O_SFC, O_X4, O_X3, O_PMAX, O_P6, O_T6, O_TIN, O_TOUT, O_TCO, O_T1, O_AIR, O_EXH,
 O_LAM, O_SLIP, O_TC, O_BP, O_ETA) = range(len(SUMMARY_KEYS))
N_OUT = len(SUMMARY_KEYS)
_BASE_KEYS = SUMMARY_KEYS[:20]  # the keys of SteadyState.summary


# --------------------------------------------------------------------------------------- compiled core
@jit
def _eta_c(c) -> float:
    """Compressor isentropic efficiency of the calibration, η_c = η_TC/(η_turbo η_com) (constant)."""
    return c.c_eta / (c.a_turbo * c.eta_com)


@jit
def _tco_isentropic(x4, c) -> float:
    """Compressor outlet temperature of isentropic compression at η_c to x4 [K] (cooler inlet estimate)."""
    pi = max(x4 / c.p_amb_Pa, 1.0)
    return c.T_amb_K * (1.0 + (math.exp(math.log(pi) / c.comp_exp) - 1.0) / _eta_c(c))


@jit
def _bypass_fraction(x4, c, h) -> float:
    frac = h[H_BPF]
    if frac <= 0.0:
        return 0.0
    z = (x4 / c.p1_nom_Pa - h[H_BPT]) / max(h[H_BPW], 1e-6)
    if z <= 0.0:
        return 0.0
    if z >= 1.0:
        return frac
    return frac * z * z * (3.0 - 2.0 * z)  # smooth ramp (C1) from closed to fully open


@jit
def _evaluate(c, h, x1, x3, x4, n, o):
    """All algebraic quantities of one point at (x1, x3, x4, n); fills ``o`` (SUMMARY_KEYS order except u)
    and returns the relative pressure residuals and the brake torque."""
    # Σ4 inlet: cooler outlet (intercooler hook) and inlet duct (eq. 3.37)
    T_c = c.T_c_K
    eps = h[H_ICE]
    if eps < 1.0:
        T_c = T_c + (1.0 - eps) * (_tco_isentropic(x4, c) - _tco_isentropic(c.p1_nom_Pa, c))
    T1 = T_c + c.eps_inl * (c.T_inl_K - T_c)
    # Σ2 at the given speed
    m1 = x4 * c.V1_m3 / (c.R_a_J_per_kgK * T1)
    q = (c.eta_comb * c.h_L_J_per_kg) * x1 / m1
    X_ct = c.X_ct_nom * x1 / c.x1_nom_kg
    X_cv = constant_volume_portion(n, X_ct, c)
    cyc = seiliger_cycle(x4, T1, q, X_cv, X_ct, c)
    T6 = cyc[3]
    p_max = cyc[4]
    p6 = cyc[5]
    nr = n / c.n_nom_rev_s
    dfmep = h[H_FA] + h[H_FB] * p_max + h[H_FC] * nr + h[H_FD] * nr * nr
    torque = m1 * cyc[6] * c.torque_per_work - friction_torque(n, c) - h[H_VSWEPT] * c.torque_per_work * dfmep
    # Σ3: slip, bypass, receiver mixing and turbine (eq. 3.16-3.26 with a bypass stream)
    s_sl = slip_ratio(x3, x4, m1, max(n, 1e-9), c)
    beta = _bypass_fraction(x4, c, h)
    m_air = (1.0 + s_sl) * m1
    m_bp = beta / (1.0 - beta) * m_air
    mdot = (m_air + x1 + m_bp) * n * c.cycles_per_rev
    psi2 = c.c_p_a_J_per_kgK * s_sl * m1
    psi3 = c.c_p_g_J_per_kgK * (x1 + m1)
    psi_bp = c.c_p_a_J_per_kgK * m_bp
    inv = 1.0 / (psi2 + psi3 + psi_bp)
    alpha = (psi2 * c.T_sl_K + psi3 * T6 / c.n_bld + psi_bp * T_c) * inv
    beta_t = psi3 * T6 * (c.n_bld - 1.0) / (c.n_bld * p6) * inv
    gamma = c.gamma_coeff * mdot * mdot
    gb = gamma * beta_t
    P = 0.5 * (gb + math.sqrt(gb * gb + 4.0 * (c.p_ex_Pa * c.p_ex_Pa + gamma * alpha)))
    T_in = alpha + beta_t * P
    Pi = turbine_expansion(x3, c)
    if h[H_TCMAP] > 0.0:
        eta0 = c.a_eta_per_Pa2 * c.p1_nom_Pa * c.p1_nom_Pa + c.b_eta_per_Pa * c.p1_nom_Pa + c.c_eta
        dx = x4 / c.p1_nom_Pa - 1.0
        eta = h[H_TCS] * eta0 * (1.0 - h[H_TCW] * dx * dx)
        eta_t = eta * (c.a_turbo / c.c_eta)
    else:
        eta = c.a_eta_per_Pa2 * x4 * x4 + c.b_eta_per_Pa * x4 + c.c_eta
        eta_t = c.a_turbo + c.b_turbo_per_Pa * x4 + c.c_turbo_per_Pa2 * x4 * x4
    T_out = T_in * (1.0 - eta_t * (1.0 - Pi))
    # Σ4: compressor (eq. 3.31 corrected, 3.32 with the bypass air in the compressor flow, 3.38 rebuilt)
    d_f = 1.0 + x1 / (m_air + m_bp)
    base = 1.0 + c.chi_g * d_f * eta * (T_in / c.T_amb_K) * (1.0 - Pi)
    x4_bal = c.p_amb_Pa * math.exp(c.comp_exp * math.log(max(base, 1e-12)))
    T_co = c.T_amb_K + c.eta_com * c.chi_g * d_f * (T_in - T_out)
    power = 2.0 * math.pi * n * torque
    mf = x1 * n * c.cycles_per_rev
    o[O_N] = n
    o[O_P] = power
    o[O_Q] = torque
    o[O_X1] = x1
    o[O_MF] = mf
    o[O_SFC] = mf / power if power > 0.0 else math.inf
    o[O_X4] = x4
    o[O_X3] = x3
    o[O_PMAX] = p_max
    o[O_P6] = p6
    o[O_T6] = T6
    o[O_TIN] = T_in
    o[O_TOUT] = T_out
    o[O_TCO] = T_co
    o[O_T1] = T1
    o[O_AIR] = (m_air + m_bp) * n * c.cycles_per_rev
    o[O_EXH] = mdot
    o[O_LAM] = m1 / (x1 * c.sigma_f)
    o[O_SLIP] = s_sl
    o[O_TC] = T_c
    o[O_BP] = beta
    o[O_ETA] = eta
    return 1.0 - P / x3, 1.0 - x4_bal / x4, torque


@jit
def _speed_of_power(P, n_given, c, h) -> float:
    """Engine speed of the speed law at brake power P [rev/s]."""
    law = h[H_LAW]
    if law == 0.0:
        return math.exp(math.log(max(P, 1e-300) / c.c_load_W_s3) / 3.0)
    if law == 1.0:
        return c.n_nom_rev_s * (h[H_S0] + (h[H_S1] - h[H_S0]) * P / c.P_nom_W)
    return n_given


@jit
def _residual(mode, y0, y1, y2, a0, a1, c, h, o):
    """The three equilibrium residuals at unknowns y (see module docstring); fills ``o``."""
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
    r3, r4, torque = _evaluate(c, h, x1, x3, x4, n, o)
    o[O_U] = x1 / c.x1_nom_kg
    if mode == 1:
        r5 = (torque - a0 / (2.0 * math.pi * n)) * (2.0 * math.pi * c.n_nom_rev_s / c.P_nom_W)
    else:
        power = 2.0 * math.pi * n * torque
        law = h[H_LAW]
        if law == 0.0:
            r5 = (power - c.c_load_W_s3 * n * n * n) / c.P_nom_W
        elif law == 1.0:
            r5 = n / c.n_nom_rev_s - h[H_S0] - (h[H_S1] - h[H_S0]) * power / c.P_nom_W
        else:
            r5 = (n - a1) / c.n_nom_rev_s
    return r3, r4, r5


@jit
def _initial_guess(mode, a0, a1, c, h, y):
    dp = c.p1_nom_Pa - c.p_amb_Pa
    if mode == 1:
        load = max(a0 / c.P_nom_W, 0.02)
        n = a1
        x4 = c.p_amb_Pa + dp * load
        y[2] = c.SFC_nom_kg_per_J * a0 / (n * c.cycles_per_rev)
    else:
        if mode == 0:
            u = max(a0, 0.05)
        else:
            u = max(a0 / (c.x1_nom_kg * c.n_nom_rev_s * c.cycles_per_rev), 0.05)
        x4 = c.p_amb_Pa + dp * u ** 1.5
        law = h[H_LAW]
        if law == 0.0:
            y[2] = c.n_nom_rev_s * u ** (1.0 / 3.0)
        elif law == 1.0:
            y[2] = c.n_nom_rev_s * (h[H_S0] + (h[H_S1] - h[H_S0]) * u ** 1.5)
        else:
            y[2] = a1
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
def _newton(mode, a0, a1, c, h, y, o, tol, max_iter):
    """Damped Newton on the three residuals from ``y`` (updated in place); returns (converged, iterations)."""
    f = np.empty(3)
    ft = np.empty(3)
    J = np.empty((3, 3))
    s = np.empty(3)
    yt = np.empty(3)
    r = _residual(mode, y[0], y[1], y[2], a0, a1, c, h, o)
    f[0], f[1], f[2] = r[0], r[1], r[2]
    norm = abs(f[0]) + abs(f[1]) + abs(f[2])
    for it in range(max_iter):
        if not math.isfinite(norm):
            return False, it
        for j in range(3):
            yt[0], yt[1], yt[2] = y[0], y[1], y[2]
            d = 1e-7 * abs(y[j]) + 1e-300
            yt[j] += d
            r = _residual(mode, yt[0], yt[1], yt[2], a0, a1, c, h, o)
            J[0, j] = (r[0] - f[0]) / d
            J[1, j] = (r[1] - f[1]) / d
            J[2, j] = (r[2] - f[2]) / d
        if not _solve3(J, f, s):
            return False, it
        # steps that keep the pressures physical (as steady_state) and the third unknown positive
        s[0] = min(max(s[0], -0.5 * (y[0] - c.p_ex_Pa)), 0.5 * y[0])
        s[1] = min(max(s[1], -0.5 * (y[1] - 0.2 * c.p_amb_Pa)), 0.5 * y[1])
        s[2] = min(max(s[2], -0.3 * abs(y[2])), 0.3 * abs(y[2]))
        lam = 1.0
        for _ in range(8):
            yt[0], yt[1], yt[2] = y[0] - lam * s[0], y[1] - lam * s[1], y[2] - lam * s[2]
            r = _residual(mode, yt[0], yt[1], yt[2], a0, a1, c, h, o)
            ft[0], ft[1], ft[2] = r[0], r[1], r[2]
            nt = abs(ft[0]) + abs(ft[1]) + abs(ft[2])
            if math.isfinite(nt) and nt <= norm:
                break
            lam *= 0.5
        y[0], y[1], y[2] = yt[0], yt[1], yt[2]
        f[0], f[1], f[2] = ft[0], ft[1], ft[2]
        norm = abs(f[0]) + abs(f[1]) + abs(f[2])
        small = (abs(lam * s[0]) <= tol * abs(y[0]) and abs(lam * s[1]) <= tol * abs(y[1])
                 and abs(lam * s[2]) <= tol * abs(y[2]))
        if small or norm == 0.0:
            if norm < 1e-9:
                _residual(mode, y[0], y[1], y[2], a0, a1, c, h, o)
                return True, it + 1
    return norm < 1e-11, max_iter


@jit
def _solve_batch(mode, c, h, a, y, use_guess, out, status, tol, max_iter):
    """Solve every point i with inputs a[i] = (a0, a1) from y[i] (if use_guess[i]) else the default guess."""
    for i in range(a.shape[0]):
        if not (math.isfinite(a[i, 0]) and math.isfinite(a[i, 1])):
            status[i] = -1
            for k in range(out.shape[1]):
                out[i, k] = math.nan
            continue
        ok = False
        if use_guess[i]:
            ok, it = _newton(mode, a[i, 0], a[i, 1], c, h, y[i], out[i], tol, max_iter)
        if not ok:
            _initial_guess(mode, a[i, 0], a[i, 1], c, h, y[i])
            ok, it = _newton(mode, a[i, 0], a[i, 1], c, h, y[i], out[i], tol, max_iter)
        status[i] = 1 if ok else 0


@jit
def _residual_vec(mode, a0, a1, c, h, y, o):
    r = _residual(mode, y[0], y[1], y[2], a0, a1, c, h, o)
    out = np.empty(3)
    out[0], out[1], out[2] = r[0], r[1], r[2]
    return out


# --------------------------------------------------------------------------------------- hooks
@dataclass(frozen=True)
class Hooks:
    """The extension hooks of :class:`ExtendedModel` (defaults: the base model).

    speed_law : ``propeller`` | ``combinator`` | ``prescribed``.
    speed_zero_load_rel, speed_full_load_rel : combinator line ``n/n_nom = s0 + (s1 - s0) P/P_nom``.
    fmep_a_Pa, fmep_b, fmep_c_Pa, fmep_d_Pa : extra friction mean effective pressure
        ``a + b p_max + c n/n_nom + d (n/n_nom)^2`` [Pa] (b dimensionless).
    dT_amb_K, dp_amb_Pa : ambient temperature and pressure minus the parameter set's (the pressure
        change applies to the turbine back pressure p_ex too).
    tc_map : use the turbocharger efficiency map; tc_eta_scale (s), tc_curvature (w).
    bypass_max_fraction (β_max), bypass_threshold_rel (x4/p1_nom where it starts to open),
        bypass_width_rel (opening range in x4/p1_nom).
    intercooler_effectiveness : ε (1 = constant cooler outlet T_c).
    n_exp : expansion polytropic exponent (``None``: the parameter set's); n_comp : compression
        polytropic exponent (``None``: κa).
    sensors : ``{column: (gain, offset)}`` (offset in the column's units).
    """

    speed_law: str = "propeller"
    speed_zero_load_rel: float = 1.0
    speed_full_load_rel: float = 1.0
    fmep_a_Pa: float = 0.0
    fmep_b: float = 0.0
    fmep_c_Pa: float = 0.0
    fmep_d_Pa: float = 0.0
    dT_amb_K: float = 0.0
    dp_amb_Pa: float = 0.0
    tc_map: bool = False
    tc_eta_scale: float = 1.0
    tc_curvature: float = 0.0
    bypass_max_fraction: float = 0.0
    bypass_threshold_rel: float = 0.9
    bypass_width_rel: float = 0.1
    intercooler_effectiveness: float = 1.0
    n_exp: float | None = None
    n_comp: float | None = None
    sensors: tuple[tuple[str, float, float], ...] = ()

    def replace(self, **changes: Any) -> "Hooks":
        return dataclasses.replace(self, **changes)

    def with_sensor(self, column: str, gain: float, offset: float) -> "Hooks":
        rest = tuple(s for s in self.sensors if s[0] != column)
        return self.replace(sensors=rest + ((column, float(gain), float(offset)),))

    def active(self) -> list[str]:
        """Names of the hooks that differ from the base model."""
        base = NO_HOOKS
        return [f.name for f in dataclasses.fields(self) if getattr(self, f.name) != getattr(base, f.name)]


NO_HOOKS = Hooks()


def _vector(h: Hooks, swept_volume_m3: float) -> np.ndarray:
    if h.speed_law not in SPEED_LAWS:
        raise ValueError(f"unknown speed law {h.speed_law!r}; allowed: {', '.join(SPEED_LAWS)}")
    v = np.zeros(N_HOOKS)
    v[H_LAW] = SPEED_LAWS[h.speed_law]
    v[H_S0], v[H_S1] = h.speed_zero_load_rel, h.speed_full_load_rel
    v[H_FA], v[H_FB], v[H_FC], v[H_FD] = h.fmep_a_Pa, h.fmep_b, h.fmep_c_Pa, h.fmep_d_Pa
    v[H_TCMAP] = 1.0 if h.tc_map else 0.0
    v[H_TCS], v[H_TCW] = h.tc_eta_scale, h.tc_curvature
    v[H_BPF], v[H_BPT], v[H_BPW] = h.bypass_max_fraction, h.bypass_threshold_rel, h.bypass_width_rel
    v[H_ICE] = h.intercooler_effectiveness
    v[H_VSWEPT] = swept_volume_m3
    return v


_constants_raw = getattr(model_constants, "__wrapped__", model_constants)


# --------------------------------------------------------------------------------------- results
@dataclass(frozen=True)
class SteadyPoints:
    """Steady states of several points: ``values[key]`` arrays in SI (keys: :data:`SUMMARY_KEYS`)."""

    values: dict[str, np.ndarray]
    converged: np.ndarray
    state: np.ndarray  # (n, 3) final Newton unknowns (warm start of a next solve)

    def __len__(self) -> int:
        return int(self.converged.size)

    def summary(self, i: int = 0, all_keys: bool = False) -> dict[str, float]:
        """Point ``i`` as a flat dict like :meth:`SteadyState.summary` (``all_keys``: also the extra keys)."""
        keys = SUMMARY_KEYS if all_keys else _BASE_KEYS
        return {k: float(self.values[k][i]) for k in keys}

    def summaries(self, all_keys: bool = True) -> list[dict[str, float] | None]:
        return [self.summary(i, all_keys) if self.converged[i] else None for i in range(len(self))]


# --------------------------------------------------------------------------------------- the model
@dataclass
class ExtendedModel:
    """Steady state of the engine model of ``params`` with the extension ``hooks``.

    >>> from marine_fdi_env import load_params
    >>> m = ExtendedModel(load_params("man-12v32-40"), Hooks(tc_map=True, tc_curvature=0.2))
    >>> pts = m.at_power([2.7e6, 5.4e6])            # speed from the propeller law
    >>> pts.values["charge_air_pressure_Pa"]         # doctest: +SKIP
    """

    params: EngineParams
    hooks: Hooks = field(default_factory=Hooks)
    tol: float = 1e-12
    max_iter: int = 60
    constants: ModelConstants = field(init=False, repr=False)
    params_effective: EngineParams = field(init=False, repr=False)
    hook_vector: np.ndarray = field(init=False, repr=False)

    def __post_init__(self) -> None:
        p, h = self.params, self.hooks
        changes: dict[str, float] = {}
        if h.dT_amb_K != 0.0:
            changes["T_amb_K"] = p.T_amb_K + h.dT_amb_K
        if h.dp_amb_Pa != 0.0:
            changes["p_amb_Pa"] = p.p_amb_Pa + h.dp_amb_Pa
            changes["p_ex_Pa"] = p.p_ex_Pa + h.dp_amb_Pa
        if h.n_exp is not None:
            changes["n_exp"] = float(h.n_exp)
        pe = p.replace(**changes) if changes else p
        c = _constants_raw(pe) if changes else model_constants(pe)
        if h.n_comp is not None:
            if not 1.0 < h.n_comp < 2.0:
                raise ValueError(f"compression polytropic exponent must lie in (1, 2), got {h.n_comp!r}")
            c = c._replace(rc_pow_kappa=c.r_c ** h.n_comp, rc_pow_kappa_m1=c.r_c ** (h.n_comp - 1.0))
        self.params_effective = pe
        self.constants = c
        self.swept_volume_m3 = _swept_volume(p)
        self.hook_vector = _vector(h, self.swept_volume_m3)

    def with_hooks(self, hooks: Hooks) -> "ExtendedModel":
        return ExtendedModel(self.params, hooks, self.tol, self.max_iter)

    # ---- solving
    def speed_of_power(self, power_W, speed_rev_s=None) -> np.ndarray:
        """Engine speed [rev/s] the speed law gives at brake power P (prescribed: ``speed_rev_s``)."""
        P = np.atleast_1d(np.asarray(power_W, float))
        ng = np.broadcast_to(np.nan if speed_rev_s is None else np.asarray(speed_rev_s, float), P.shape)
        law = self.hooks.speed_law
        p = self.params
        if law == "propeller":
            return np.cbrt(P / p.c_load_W_s3)
        if law == "combinator":
            h = self.hooks
            return p.n_nom_rev_s * (h.speed_zero_load_rel + (h.speed_full_load_rel - h.speed_zero_load_rel)
                                    * P / p.P_nom_W)
        if speed_rev_s is None:
            raise ValueError("speed law 'prescribed' needs the measured speed of every point")
        return np.array(ng, dtype=float)

    def power_of_speed(self, speed_rev_s) -> np.ndarray:
        """Brake power [W] the speed law gives at engine speed n (inverse of :meth:`speed_of_power`)."""
        n = np.atleast_1d(np.asarray(speed_rev_s, float))
        p, h = self.params, self.hooks
        if h.speed_law == "propeller":
            return p.c_load_W_s3 * n**3
        if h.speed_law == "combinator":
            ds = h.speed_full_load_rel - h.speed_zero_load_rel
            if ds == 0:
                raise ValueError("a constant-speed combinator law cannot give the power from the speed")
            return p.P_nom_W * (n / p.n_nom_rev_s - h.speed_zero_load_rel) / ds
        raise ValueError("speed law 'prescribed': the speed does not fix the power")

    def solve(self, mode: int, a0, a1=None, guess: np.ndarray | None = None) -> SteadyPoints:
        """Solve points with inputs ``a0`` (u, power [W] or fuel mass flow [kg/s] by ``mode``) and ``a1``
        (the speed [rev/s]: required in MODE_P, the prescribed speed otherwise)."""
        a0 = np.atleast_1d(np.asarray(a0, float))
        n = a0.size
        a1 = np.full(n, 0.0) if a1 is None else np.broadcast_to(np.asarray(a1, float), (n,))
        a = np.ascontiguousarray(np.column_stack([a0, a1]), dtype=float)
        y = np.zeros((n, 3)) if guess is None else np.array(guess, dtype=float, order="C").reshape(n, 3)
        use = np.zeros(n, dtype=np.bool_) if guess is None else np.all(np.isfinite(y) & (y > 0), axis=1)
        out = np.empty((n, N_OUT))
        status = np.zeros(n, dtype=np.int64)
        _solve_batch(int(mode), self.constants, self.hook_vector, a, y, use, out, status, self.tol, self.max_iter)
        for i in np.flatnonzero(status == 0):  # last resort: scipy's hybrid method
            self._scipy_fallback(int(mode), a[i], y[i], out[i], status, i)
        return SteadyPoints(values={k: out[:, j].copy() for j, k in enumerate(SUMMARY_KEYS)},
                            converged=status == 1, state=y)

    def _scipy_fallback(self, mode, a, y, o, status, i) -> None:
        c, h = self.constants, self.hook_vector
        y0 = np.empty(3)
        _initial_guess(mode, a[0], a[1], c, h, y0)
        scale = y0.copy()
        fun = lambda z: _residual_vec(mode, a[0], a[1], c, h, z * scale, o)  # noqa: E731
        try:
            sol = root(fun, np.ones(3), method="hybr", tol=1e-13)
        except (ValueError, ZeroDivisionError, FloatingPointError):
            return
        if sol.success and np.all(np.isfinite(sol.x)) and np.max(np.abs(fun(sol.x))) < 1e-9:
            y[:] = sol.x * scale
            _residual_vec(mode, a[0], a[1], c, h, y, o)
            status[i] = 1

    def at_fuel_setting(self, u, speed_rev_s=None, guess=None) -> SteadyPoints:
        """Steady states at fuel setting(s) u (speed from the speed law, or prescribed)."""
        return self.solve(MODE_U, u, speed_rev_s, guess)

    def at_power(self, power_W, speed_rev_s=None, guess=None) -> SteadyPoints:
        """Steady states at brake power(s) P [W]; speed from the law (prescribed: ``speed_rev_s``)."""
        P = np.atleast_1d(np.asarray(power_W, float))
        return self.solve(MODE_P, P, self.speed_of_power(P, speed_rev_s), guess)

    def at_fuel_flow(self, fuel_kg_s, speed_rev_s=None, guess=None) -> SteadyPoints:
        """Steady states at fuel mass flow(s) [kg/s]."""
        return self.solve(MODE_F, fuel_kg_s, speed_rev_s, guess)

    def steady_function(self):
        """The ``steady(u, point) -> summary`` hook of :func:`~.matching.match_operating_points`
        (prescribed speed: the point's ``engine_speed_rev_s``)."""

        def steady(u: float, point: Mapping[str, float]) -> dict[str, float]:
            ng = point.get("engine_speed_rev_s") if self.hooks.speed_law == "prescribed" else None
            pts = self.at_fuel_setting(float(u), ng)
            if not pts.converged[0]:
                raise RuntimeError(f"extended model: no steady state at fuel setting {u}")
            return pts.summary(0, all_keys=True)

        return steady

    def sensor_reading(self, column: str, model_values: np.ndarray) -> np.ndarray:
        """Apply the sensor hooks of ``column`` to model values in the column's units."""
        for col, g, o in self.hooks.sensors:
            if col == column:
                return g * np.asarray(model_values, float) + o
        return np.asarray(model_values, float)


@lru_cache(maxsize=16)
def _swept_volume(p: EngineParams) -> float:
    return cylinder_geometry(p.bore_m, p.stroke_m, p.crank_rod_m, p.eps_c, p.alpha_IC_deg,
                             p.alpha_EO_deg).swept_volume_m3


def base_reproduction_error(params: EngineParams, u: Sequence[float]) -> float:
    """Largest relative difference between the hook-free extended model and ``steady_state`` over ``u``
    (a self-check; the tests require < 1e-9)."""
    from ..model import EngineModel
    from ..steady_state import steady_state

    u = np.asarray(u, float)
    ss = steady_state(EngineModel(params), u)
    ext = ExtendedModel(params).at_fuel_setting(u)
    worst = 0.0
    for i in range(u.size):
        ref = ss.summary(params, i)
        got = ext.summary(i)
        for k, v in ref.items():
            if k not in got:
                continue
            worst = max(worst, abs(got[k] - v) / max(abs(v), 1e-300))
    return worst
