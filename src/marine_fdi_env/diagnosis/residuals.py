"""Residuals and adaptive thresholds of the 19 monitoring modules (eq. 5.4-5.18), compiled.

State-based modules (M1.q, M3.q, M4.q): a discrete-time form of the Lipschitz observer of eq. 5.4,

    x̂⁻_{k+1} = e^{-h/τ} x̂_k + h φ1 F(y_k) + h φ2 (F(y_{k+1}) - F(y_k))   (model step, as the simulator)
    x̂_{k+1}  = x̂⁻_{k+1} + L_d (y_{k+1} - x̂⁻_{k+1})                       (output injection)

with ``L_d = 1 - exp(-L h)`` the discrete equivalent of the gains L of table 6.1, F the forcing of
the subsystem evaluated on the module's measurements, and the residual ``ε_k = y_k - x̂⁻_k``
(eq. 5.6).  The adaptive threshold is eq. 5.10-5.11 computed recursively per sample.  For these
scalar observers the bounds of eq. 5.13-5.14 hold exactly with ρ = 1 and ξ = 1/τ + L, so the
discrete recursion of the error bound is::

    ē_{k+1} = e^{-h/τ} ((1 - L_d) ē_k + L_d d̄) + h (φ1 - φ2) H̄_k + h φ2 H̄_{k+1} + η̄
    threshold_k = ē_k + d̄                                                   (eq. 5.10)

where d̄ is the checked sensor's noise bound and H̄_k bounds |F(true) - F(measured)| over the
noise boxes of the interconnection sensors.  The thesis bounds that term with a Lipschitz constant
times the interconnection noise bound (λ_h d̄_χ in eq. 5.11); we use the local, state-dependent
version of the same bound (see "inclusion" below), which keeps the threshold valid everywhere in
the operating envelope and tight at each operating point.  Table 6.1's constants ρ = 0.02 for
M(3,q) and ρ = 1.67e-7 for M(4,q) violate eq. 5.13 at t = 0 (|e^{A_L 0}| = 1), so they cannot be
used as stated.  η̄ (``model_margin``) covers the simulator's own integration error (the η_x of
eq. 3.1).

Algebraic modules: ``ε = y_checked - ξ(y_inputs)`` (eq. 5.6-5.7) must lie in ±(d̄_checked + Ξ̄)
(eq. 5.15-5.18) with Ξ̄ the inclusion bound of ξ over the input noise boxes.

Inclusion: for a function g of the sensors y_i with noise bounds d̄_i we use the centred,
coordinate-wise form ``Σ_i max(|g(y + d̄_i e_i) - g(y)|, |g(y - d̄_i e_i) - g(y)|)`` times a safety
factor 1.05.  It is exact for functions that are monotone in each input up to the mixed
second-order terms, which over the small noise boxes are below 1e-3 of the total (measured), and
far tighter than the natural interval extension, which multiplies the overestimation of every
subtraction in the Seiliger cycle.

Cost (see docs/diagnosis.md, "Performance"): the engine speed at the ±d̄ points of x1, x4, T1 is
one sweep of the speed loop from the centre's converged speed, linearised with the centre's slope
(:func:`cycle_table`); this drops only second-order terms and lowers the M2.1-M2.4 inclusion terms
by at most 0.21 % and M3.1-M3.4 by 0.03 % against full solves (measured over 16 runs x 200 s,
constant and manoeuvring), well inside SAFETY.  The model values of M3.q, M3.(3,4), M4.q and
M4.(5,6) share their intermediates (m1, slip, mass flow, Ψ_sc, Π_turbo) per point.  The one-sided
form Σ_i |g(y + d̄_i e_i) - g(y)| is not used: measured, it lowers the T_in inclusion (M3.3/4)
by up to 15 % and T6 (M2.3/4) by 3.4 %, not covered by SAFETY.  ``ONE_SIDED`` and
``LINEAR_SPEED`` switch these choices (compile-time constants, for measurements).

Every module's inputs that are not finite (a sensor that dropped out) violate its ARR; an
observer then holds its last estimate.
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import jit, jit_inline
from ..engine.constants import kernel_constants
from ..engine.integrators import THREADED_MIN_ENGINES, etd_scalar, thread_pool
from ..engine.sensors import NOISE_BOUNDS, SENSOR_IDS
from ..engine.subsystems.air_intake import (
    compressor_forcing,
    compressor_outlet_temperature,
    cooler_outlet_temperature,
    eta_tc,
    inlet_air_temperature,
    inlet_air_temperature_at,
)
from ..engine.subsystems.engine_block import (
    speed_of_torque,
    torque_cycle,
    torque_from_cycle,
)
from ..engine.subsystems.exhaust_receiver import (
    scavenge_flow_function,
    turbine_expansion,
    turbine_outlet_from_expansion,
    turbine_outlet_temperature,
)
from ..engine.subsystems.gas_path import extended_gas_path, flow_law_pressure, valve_flows
from .inclusion_table import interpolate_rows, sigma2_table
from .modules import MODULE_IDS
from .sigma2 import (
    ONE_SIDED,
    SLOPE_STEP,
    centre_speed,
    centre_speed2,
    cycle_table,
    perturbed_rows,
    perturbed_rows2,
)
from .thresholds import DEFAULT_THRESHOLDS, closed_form, threshold_array

__all__ = [
    "OBSERVER_GAINS",
    "compute_residuals",
    "compute_residuals_batch",
    "model_terms",
    "MODEL_TERM_OUTPUTS",
    "MODEL_TERM_INPUTS",
    "observer_steady_gains",
    "ResidualTrace",
    "SAFETY",
    "MODEL_MARGIN",
    "new_state",
    "N_STATE",
    "residuals_for_run",
    "INCLUSIONS",
    "inclusion_arrays",
    "table_arrays",
    "SIDE_COLS",
    "T_OUT_COL",
]

# Observer gains L [1/s] of table 6.1 for M(1,q), M(3,q), M(4,q).
OBSERVER_GAINS = (33.3833, 1.25, 0.3764)
SAFETY = 1.05
CHUNK = 32  # samples per Σ2 pass (see _kernel)
MODEL_MARGIN = 1e-6  # η̄ per step, relative to the state, and relative margin of algebraic ARRs

# sensor columns
S = {sid: i for i, sid in enumerate(SENSOR_IDS)}
# per side (0: odd sensors, 1: even sensors): x1, p6, T6, torque, x3, T_in, x4, T1, T_co
SIDE_COLS = np.array(
    [
        [S["S1.1"], S["S2.1"], S["S2.3"], S["S2.5"], S["S3.1"], S["S3.3"], S["S4.1"], S["S4.3"], S["S4.5"]],
        [S["S1.2"], S["S2.2"], S["S2.4"], S["S2.6"], S["S3.2"], S["S3.4"], S["S4.2"], S["S4.4"], S["S4.6"]],
    ],
    dtype=np.int64,
)
T_OUT_COL = S["S3.5"]
# module column of each module id (for output arrays)
_M = {m: i for i, m in enumerate(MODULE_IDS)}


@jit
def _dev(g0, gp, gm):
    """One coordinate's term of the inclusion: max(|g(+)-g0|, |g(-)-g0|), or |g(+)-g0| if ONE_SIDED."""
    if ONE_SIDED:
        return abs(gp - g0)
    return max(abs(gp - g0), abs(gm - g0))


@jit
def _compressor_forcing(x4, d_f, T_in, Pi_turbo, c):
    """:func:`compressor_forcing` (h4 of eq. 3.31) with the power base^(κa/(κa-1)) taken as
    base³ √base when κa = 1.4 (all shipped parameter sets): the same value to a few ulp (1e-15
    relative, far below the observers' model margin), without a log and an exp."""
    base = max(1.0 + c.chi_g * d_f * eta_tc(x4, c) * (T_in / c.T_amb_K) * (1.0 - Pi_turbo), 1e-12)
    if abs(c.comp_exp - 3.5) < 1e-9:
        pw = base * base * base * math.sqrt(base)
    else:
        pw = math.exp(c.comp_exp * math.log(base))
    return (c.p_amb_Pa / c.tau_TC_s) * pw


@jit
def _h3(mdot, T_in, c):
    """h3 = sqrt(p_ex² + R_g z1 ṁ²/(α_z A_eff)²)/τ_pd (eq. 3.16, ``receiver_forcing``: the same
    operations)."""
    return math.sqrt(c.p_ex_Pa * c.p_ex_Pa + c.gamma_coeff * mdot * mdot * T_in) / c.tau_pd_s


@jit
def _mixing(x1, m1, s_sl, mdot, T6, p6, c):
    """Turbine inlet temperature z1 of eq. 3.20-3.23 with the fault-free slip-air temperature:
    ``receiver_and_turbine(...)[1]``, the same operations, given ṁ_g (computed once per point)."""
    psi2 = c.c_p_a_J_per_kgK * s_sl * m1
    psi3 = c.c_p_g_J_per_kgK * (x1 + m1)
    inv = 1.0 / (psi2 + psi3)
    alpha = (psi2 * c.T_sl_K + psi3 * T6 / c.n_bld) * inv
    beta = psi3 * T6 * (c.n_bld - 1.0) / (c.n_bld * p6) * inv
    gamma = c.gamma_coeff * mdot * mdot
    gb = gamma * beta
    P = 0.5 * (gb + math.sqrt(gb * gb + 4.0 * (c.p_ex_Pa * c.p_ex_Pa + gamma * alpha)))
    return alpha + beta * P


@jit
def _point(c, csm, x1, x3, x4, m1, n, psi, Pi, T_in, T_out, T6, p6, out, j):
    """h3, h4, T_in(model), T_co(model) at one point of the (x1, x3, x4, T1, n) box into out[j],
    sharing s_sl, ṁ_g, δ_f; m1 = x4 V1/(R_a T1), psi = Ψ_sc(x3/x4) and Pi = Π_turbo(x3) are passed
    in (most points reuse the centre's).  The same operations as ``slip_ratio``,
    ``receiver_forcing``, ... in the same order, so the numbers equal the direct calls bit for bit.
    csm: the full constants for the gas-path submodels, or None (see :func:`kernel_constants`)."""
    s_sl = c.slip_coeff * x4 * psi / (n * m1)
    if csm is not None:  # compiled only where a gas-path submodel may be on
        if c.sm_on != 0.0:
            return _point_sm(csm, x1, x3, x4, m1, n, s_sl, Pi, T_in, T_out, T6, p6, out, j)
    opm = (1.0 + s_sl) * m1
    mdot = (opm + x1) * n * c.cycles_per_rev
    df = 1.0 + x1 / opm
    out[j, 0] = _h3(mdot, T_in, c)
    out[j, 1] = _compressor_forcing(x4, df, T_in, Pi, c)
    out[j, 2] = _mixing(x1, m1, s_sl, mdot, T6, p6, c)
    out[j, 3] = compressor_outlet_temperature(df, T_in, T_out, 0.0, c)
    return s_sl, mdot, df


@jit_inline
def _box_points(c, csm, x1, x3, x4, T1, m1, t, psi, Pi, T_in, T_out, T6m, p6m, d1, d3, d4, dT1, G):
    """The model values at the centre and at ±d̄ of x1, x3, x4, T1 into G[0:9] (columns h3, h4,
    T_in, T_co; the rows of the kernel's box) with the Σ2 speeds of ``t`` (the cycle table: centre,
    x1±, x4±, T1±); returns the centre's (s_sl, ṁ_g, δ_f).  Inlined by numba into the kernel (an
    out-of-line call with these arrays costs 3-5 % of the kernel, measured)."""
    n0 = t[0, 0]
    s_sl, mdot, df = _point(c, csm, x1, x3, x4, m1, n0, psi, Pi, T_in, T_out, T6m, p6m, G, 0)
    # the x1, x3, x4, T1 points, unrolled (x + 0.0 and x + (-d) equal x and x - d exactly)
    _point(c, csm, x1 + d1, x3, x4, m1, t[1, 0], psi, Pi, T_in, T_out, T6m, p6m, G, 1)
    _point(c, csm, x1 - d1, x3, x4, m1, t[2, 0], psi, Pi, T_in, T_out, T6m, p6m, G, 2)
    _point(
        c,
        csm,
        x1,
        x3 + d3,
        x4,
        m1,
        n0,
        scavenge_flow_function((x3 + d3) / x4, c),
        turbine_expansion(x3 + d3, c),
        T_in,
        T_out,
        T6m,
        p6m,
        G,
        3,
    )
    _point(
        c,
        csm,
        x1,
        x3 - d3,
        x4,
        m1,
        n0,
        scavenge_flow_function((x3 - d3) / x4, c),
        turbine_expansion(x3 - d3, c),
        T_in,
        T_out,
        T6m,
        p6m,
        G,
        4,
    )
    _point(
        c,
        csm,
        x1,
        x3,
        x4 + d4,
        _charge_mass(x4 + d4, T1, c),
        t[3, 0],
        scavenge_flow_function(x3 / (x4 + d4), c),
        Pi,
        T_in,
        T_out,
        T6m,
        p6m,
        G,
        5,
    )
    _point(
        c,
        csm,
        x1,
        x3,
        x4 - d4,
        _charge_mass(x4 - d4, T1, c),
        t[4, 0],
        scavenge_flow_function(x3 / (x4 - d4), c),
        Pi,
        T_in,
        T_out,
        T6m,
        p6m,
        G,
        6,
    )
    _point(c, csm, x1, x3, x4, _charge_mass(x4, T1 + dT1, c), t[5, 0], psi, Pi, T_in, T_out, T6m, p6m, G, 7)
    _point(c, csm, x1, x3, x4, _charge_mass(x4, T1 - dT1, c), t[6, 0], psi, Pi, T_in, T_out, T6m, p6m, G, 8)
    return s_sl, mdot, df


@jit
def _model_terms_at(c, x1, x3, x4, T1, T_in, T_out, d1, d3, d4, dT1, dTin, dTo, n_guess, tab, G, out):
    """:func:`model_terms` at one point into out (3, 6); returns the engine speed there."""
    cycle_table(c, x1, x4, T1, d1, d4, dT1, n_guess, tab)
    psi = scavenge_flow_function(x3 / x4, c)
    Pi = turbine_expansion(x3, c)
    m1 = _charge_mass(x4, T1, c)
    s_sl, mdot, df = _box_points(
        c, None, x1, x3, x4, T1, m1, tab, psi, Pi, T_in, T_out, tab[0, 2], tab[0, 1], d1, d3, d4, dT1, G
    )
    for q, col in enumerate((0, 1, 3)):
        F = G[0, col]
        for k in range(4):
            out[q, k] = _dev(F, G[1 + 2 * k, col], G[2 + 2 * k, col])
        out[q, 5] = 0.0
    out[0, 4] = _dev(G[0, 0], _h3(mdot, T_in + dTin, c), _h3(mdot, T_in - dTin, c))
    out[1, 4] = _dev(
        G[0, 1], _compressor_forcing(x4, df, T_in + dTin, Pi, c), _compressor_forcing(x4, df, T_in - dTin, Pi, c)
    )
    out[2, 4] = _dev(
        G[0, 3],
        compressor_outlet_temperature(df, T_in + dTin, T_out, 0.0, c),
        compressor_outlet_temperature(df, T_in - dTin, T_out, 0.0, c),
    )
    out[2, 5] = _dev(
        G[0, 3],
        compressor_outlet_temperature(df, T_in, T_out + dTo, 0.0, c),
        compressor_outlet_temperature(df, T_in, T_out - dTo, 0.0, c),
    )
    return tab[0, 0]


MODEL_TERM_OUTPUTS = ("h3", "h4", "T_co")
MODEL_TERM_INPUTS = ("x1", "x3", "x4", "T1", "T_in", "T_out")


def model_terms(c, readings: np.ndarray, dbar=None, side: int = 0) -> np.ndarray:
    """The inclusion terms of the observers' forcing and of the compressor-outlet model (the
    deviation of the output at ±d̄ of one input, without the safety factor) at the readings (K, 19)
    of one sensor chain (``side`` 0: the odd sensors, 1: the even ones; true values give the terms
    at the true state).  Returns (K, 3, 6): rows :data:`MODEL_TERM_OUTPUTS` (h3 of M3.q, h4 of
    M4.q, T_co of M4.5/M4.6), columns :data:`MODEL_TERM_INPUTS`; the Σ2 speeds solved as the exact
    inclusion does.  The base model only (no gas-path submodel)."""
    kc, csm = kernel_constants(c)
    if csm is not None and c.sm_on != 0.0:
        raise ValueError("model_terms covers the base model only (a gas-path submodel is on)")
    db = np.array(NOISE_BOUNDS if dbar is None else dbar, dtype=np.float64)
    cols = SIDE_COLS[side]
    d1, d3, d4, dT1, dTin = (db[cols[0]], db[cols[4]], db[cols[6]], db[cols[7]], db[cols[5]])
    dTo = db[T_OUT_COL]
    Y = np.asarray(readings, dtype=np.float64)
    if Y.ndim != 2 or Y.shape[1] != len(SENSOR_IDS):
        raise ValueError(f"readings must have shape (K, {len(SENSOR_IDS)}), got {Y.shape}")
    X = Y[:, [cols[0], cols[4], cols[6], cols[7], cols[5], T_OUT_COL]]
    out = np.zeros((len(X), 3, 6))
    tab = np.empty((7, 3))
    G = np.empty((22, 4))
    n = c.n_nom_rev_s
    for i, (x1, x3, x4, T1, T_in, T_out) in enumerate(X):
        n = _model_terms_at(kc, x1, x3, x4, T1, T_in, T_out, d1, d3, d4, dT1, dTin, dTo, n, tab, G, out[i])
    return out


def observer_steady_gains(c, dt: float) -> dict[str, tuple[float, float]]:
    """Per observer pair (``M3``, ``M4``) the steady gains (g_d, g_H) of the threshold recursion at a
    constant operating point: ē → g_d d̄ + g_H H̄ with g_d = E L_d / (1 - E (1 - L_d)) and
    g_H = q / (1 - E (1 - L_d)) (E, q of the exact step, L_d = 1 - exp(-L h)); the model margin
    aside."""
    out = {}
    for name, tau, L in (("M3", c.tau_pd_s, OBSERVER_GAINS[1]), ("M4", c.tau_TC_s, OBSERVER_GAINS[2])):
        E, q, _ = etd_scalar(-1.0 / tau, dt)
        Ld = -math.expm1(-L * dt)
        den = 1.0 - E * (1.0 - Ld)
        out[name] = (E * Ld / den, q / den)
    return out


# ------------------------------------------------------------------------------------------------
# The plant with the gas-path submodels (waste gate, bypass valve, turbine flow law, efficiency vs
# blade-speed ratio, exhaust heat loss, intercooler; ``c.sm_on``): the same module structure, with
# the equations of :func:`~marine_fdi_env.engine.subsystems.gas_path.extended_gas_path` given the measured
# turbine-inlet and -outlet temperatures.  Valve openings follow their schedules over the measured
# fuel setting u = x1/x1_nom.  The base model (``sm_on`` 0) never enters these functions, so its
# residuals are unchanged bit for bit.
@jit
def _sm_flows(c, x1, x3, x4, m1, s_sl, n, T_c):
    """(ṁ_g, ṁ_bp, waste-gate opening a, compressor air ṁ_c) of the extended gas path."""
    mdot_g, mdot_bp, a_wg, m_air = valve_flows(x1, x3, x4, m1, s_sl, n, T_c, c, math.nan, math.nan)
    return mdot_g, mdot_bp, a_wg, m_air + mdot_bp


@jit
def _sm_turbine_gas(c, T_in, mdot_g, mdot_bp, T_c):
    """Gas temperature entering the turbine from the turbine-inlet reading: the reading itself, or,
    with a bypass that joins at the turbine (the thermocouple sits before the junction), its mixture
    with the bypass air."""
    if c.bp_on != 0.0 and c.bp_junction_turbine != 0.0 and mdot_bp > 0.0:
        cg = c.c_p_g_J_per_kgK * mdot_g
        ca = c.c_p_a_J_per_kgK * mdot_bp
        return (cg * T_in + ca * T_c) / (cg + ca)
    return T_in


@jit
def _sm_h3(c, mdot_t, a_wg, T_t):
    """h3 = P/τ_pd with P from the generalised flow law through turbine and waste gate."""
    area = c.tf_s * (1.0 + a_wg)
    gam = c.gamma_coeff * mdot_t * mdot_t / (area * area)
    return flow_law_pressure(gam, T_t, 0.0, c) / c.tau_pd_s


@jit
def _sm_tco(c, d_f, T_t, T_out):
    """Compressor outlet temperature T_co = T_amb + η_com χ_g δ (T_t - T_out) (fault-free)."""
    return c.T_amb_K + c.eta_com * c.chi_g * d_f * (T_t - T_out)


@jit
def _point_sm(c, x1, x3, x4, m1, n, s_sl, Pi, T_in, T_out, T6, p6, out, j):
    """:func:`_point` with the gas-path submodels; returns (s_sl, ṁ through the receiver, δ)."""
    T_c = cooler_outlet_temperature(x4, c)
    mdot_g, mdot_bp, a_wg, m_c = _sm_flows(c, x1, x3, x4, m1, s_sl, n, T_c)
    mdot_t = mdot_g + mdot_bp
    d_f = mdot_t / ((1.0 + a_wg) * m_c)
    T_t = _sm_turbine_gas(c, T_in, mdot_g, mdot_bp, T_c)
    out[j, 0] = _sm_h3(c, mdot_t, a_wg, T_t)
    out[j, 1] = compressor_forcing(x4, d_f, T_t, Pi, c)
    out[j, 2] = extended_gas_path(x1, x3, x4, m1, s_sl, n, T6, p6, c.T_sl_K, T_c, 0.0, c, math.nan, math.nan)[1]
    out[j, 3] = _sm_tco(c, d_f, T_t, T_out)
    return s_sl, mdot_t, d_f


@jit
def _sm_perturbed(c, x1, x3, x4, m1, n, s_sl, Pi, T_in, T_out, dTin, dTo, T6m, p6m, dp6, dT6, G, step):
    """Rows 9-16 of the inclusion box (T_in, p6, T6, T_out perturbed) with the gas-path submodels."""
    T_c = cooler_outlet_temperature(x4, c)
    mdot_g, mdot_bp, a_wg, m_c = _sm_flows(c, x1, x3, x4, m1, s_sl, n, T_c)
    mdot_t = mdot_g + mdot_bp
    d_f = mdot_t / ((1.0 + a_wg) * m_c)
    for j in range(9, 17, step):
        sg = 1.0 if j % 2 == 1 else -1.0
        if j < 11:
            T_t = _sm_turbine_gas(c, T_in + sg * dTin, mdot_g, mdot_bp, T_c)
            G[j, 0] = _sm_h3(c, mdot_t, a_wg, T_t)
            G[j, 1] = compressor_forcing(x4, d_f, T_t, Pi, c)
            G[j, 3] = _sm_tco(c, d_f, T_t, T_out)
        elif j >= 15:
            G[j, 3] = _sm_tco(c, d_f, _sm_turbine_gas(c, T_in, mdot_g, mdot_bp, T_c), T_out + sg * dTo)
        else:
            pp = p6m + sg * dp6 if j < 13 else p6m
            TT = T6m + sg * dT6 if j >= 13 else T6m
            G[j, 2] = extended_gas_path(x1, x3, x4, m1, s_sl, n, TT, pp, c.T_sl_K, T_c, 0.0, c, math.nan, math.nan)[1]


@jit
def _speed_of(tq, c):
    """Engine speed at brake torque tq for the torque module: the propeller law (eq. 3.11) as the
    thesis writes it, or the combinator line of the ``speed_law`` submodel."""
    if c.sl_comb != 0.0:
        return speed_of_torque(tq, c)
    return math.sqrt(c.two_pi_over_c * tq)


# Near a kink of Ψ_sc (x3/x4 clipped to [r_crit, 1]; Ψ_sc ∝ sqrt(1 - x3/x4) below 1, so its
# curvature grows without bound towards 1) the coordinate-wise inclusion misses the mixed term of
# x3 and x4 (the corner term of _kink_corners covers it) and the mixed terms of the slip flow with
# the other coordinates (their sensitivities at the centre differ from those at the true point):
# there the whole inclusion of M3.x/M4.x is enlarged by KINK_SAFETY.  "Near": the box's largest
# ratio reaches R_NEAR_KINK (steady state: fuel settings below about 0.5) or its smallest comes
# within 0.05 of r_crit.  Measured: with the corner term only where the box straddles 1, 2 of 2400
# fault-free runs (200 h, all profile families, fuel settings 0.3-1.1) violated M3.4 by up to
# 3.5 % of the threshold on load increases from 0.3 (box ratios 0.90-0.9997); with both, none
# (docs/diagnosis.md, "Where the model has a kink").
R_NEAR_KINK = 0.9
KINK_SAFETY = 1.25


@jit
def _straddles_kink(x3, x4, d3, d4, c):
    """Whether the pressure ratio x3/x4 over the noise box comes near (see R_NEAR_KINK) or across
    r_crit or 1, where Ψ_sc (eq. 3.19, clipped to [r_crit, 1]) has a kink."""
    r_lo = (x3 - d3) / (x4 + d4)
    r_hi = (x3 + d3) / (x4 - d4)
    return r_hi >= R_NEAR_KINK or r_lo <= c.r_crit + 0.05


@jit
def _kink_corners(c, csm, x1, x3, x4, T1, d3, d4, n_x4p, n_x4m, T_in, T_out, T6m, p6m, G, kc):
    """The model values at the 4 corners (x3 ± d3, x4 ± d4) into G[18:22] and, per output q, how
    much their largest deviation from the centre exceeds the sum of the x3 and x4 coordinate terms
    (kc[q] >= 0): the mixed term that the coordinate-wise inclusion neglects, which is not small
    where Ψ_sc has a kink inside the box (Ψ_sc depends on x3/x4 only and is monotone on each side
    of the kink, so its extremes over the box are at the corners).  The speed of a corner is that
    of its x4 point (x3 does not enter Σ2)."""
    row = 18
    for e in (d3, -d3):
        for f in (d4, -d4):
            x3c = x3 + e
            x4c = x4 + f
            _point(
                c,
                csm,
                x1,
                x3c,
                x4c,
                _charge_mass(x4c, T1, c),
                n_x4p if f > 0.0 else n_x4m,
                scavenge_flow_function(x3c / x4c, c),
                turbine_expansion(x3c, c),
                T_in,
                T_out,
                T6m,
                p6m,
                G,
                row,
            )
            row += 1
    for q in range(4):
        g0 = G[0, q]
        corner = 0.0
        for r in range(18, 22):
            corner = max(corner, abs(G[r, q] - g0))
        kc[q] = max(0.0, corner - (_dev(g0, G[3, q], G[4, q]) + _dev(g0, G[5, q], G[6, q])))


@jit
def _charge_mass(x4, T1, c):
    """m1 = x4 V1 / (R_a T1), the trapped charge mass [kg] (as ``engine_block``)."""
    return x4 * c.V1_m3 / (c.R_a_J_per_kgK * T1)


@jit
def _observer_update(st, b, first, ok, y, F, H, E, q, r, Ld, dbar):
    """One sample of a receiver/charge observer whose state sits at st[b:b+5] =
    (x̂, ē, F(prev), H̄(prev), ok(prev)); returns (residual, threshold).  See the module docstring."""
    if first or st[b + 4] == 0.0:
        if ok:  # (re)start from the measurement
            st[b] = y
            st[b + 1] = dbar
        res = 0.0 if ok else math.inf
    elif ok:
        prior = E * st[b] + q * st[b + 2] + r * (F - st[b + 2])
        st[b + 1] = E * ((1.0 - Ld) * st[b + 1] + Ld * dbar) + (q - r) * st[b + 3] + r * H + MODEL_MARGIN * abs(prior)
        res = y - prior
        st[b] = prior + Ld * (y - prior)
    else:
        res = math.inf
    st[b + 4] = 1.0 if ok else 0.0
    st[b + 2] = F
    st[b + 3] = H
    return res, st[b + 1] + dbar


@jit
def _all_finite(y, idx):
    for i in idx:
        if not math.isfinite(y[i]):
            return False
    return True


SPEED_MARGIN_FACTOR = 2.0  # the speed sensitivity may change over the noise box (a few %): generous
# ... except where a perturbed point crosses a kink of the model (Ψ_sc clipped at x3/x4 = 1: no slip,
# δ_f then independent of n) while the centre does not: there |∂g/∂n| at the perturbed point is
# bounded by the model's speed elasticity |n ∂g/∂n| / |g| (below 4 for h3, h4, T_in, T_co by their
# forms: ṁ_g ∝ n at most, h4 ∝ base^3.5 with base - 1 ∝ δ_f; measured below 1.2 in the envelope)
SPEED_ELASTICITY = 4.0


@jit_inline
def _tabulate(table, ti, x1, x4, T1, t, dl, mg):
    """Rows 1-6 of a chain's cycle table t (7, 3) from table ``ti`` of the tabulated differences
    (t[0] holds the exactly solved centre): t[p] = t[0] + Δ_p; dl (6, 3) gets the interpolated
    differences and mg (6, 3) their certified margins.  False (t, dl, mg untouched) outside the
    table or in an invalid cell, where the rows are computed exactly."""
    delta, margin, valid, grid, dims, tside = table
    cell = interpolate_rows(delta, dims, grid, valid, ti, x1, x4, T1, dl)
    if cell < 0:
        return False
    base = np.uint64((ti * ((dims[0] - 1) * (dims[1] - 1) * (dims[2] - 1)) + cell) * 18)
    for p in range(6):
        for q in range(3):
            mg[p, q] = margin[base + np.uint64(3 * p + q)]
            t[p + 1, q] = t[0, q] + dl[p, q]
    return True


@jit
def _dev_margin(dl, mg, q):
    """Tabulated-mode inclusion term of M2.1-M2.4 for column q (1: p6, 2: T6): Σ over x1, x4, T1 of
    max(|Δ+| + e+, |Δ-| + e-),
    never below the exact Σ max(|Δ+|, |Δ-|) (each interpolated Δ is within its margin e)."""
    b = 0.0
    for i in range(3):
        b += max(abs(dl[2 * i, q]) + mg[2 * i, q], abs(dl[2 * i + 1, q]) + mg[2 * i + 1, q])
    return b


@jit
def _speed_margins(c, csm, x1, x3, x4, m1, n0, psi, Pi, T_in, T_out, T6m, p6m, G, mg, spm):
    """Margins spm (4,) of the M3/M4 model values h3, h4, T_in, T_co for the tabulated speeds of
    the x1, x4, T1 points: each is off by at most its certified margin e_n, which moves a model
    value by at most |∂g/∂n| e_n (mean value theorem); ∂g/∂n by a forward difference at the centre
    (row 17 of G), times SPEED_MARGIN_FACTOR for its change over the noise box, and at least the
    elasticity bound SPEED_ELASTICITY |g| / n (a perturbed point across a kink)."""
    hn = SLOPE_STEP * n0
    _point(c, csm, x1, x3, x4, m1, n0 + hn, psi, Pi, T_in, T_out, T6m, p6m, G, 17)
    en = 0.0
    for i in range(3):
        en += max(mg[2 * i, 0], mg[2 * i + 1, 0])
    for q in range(4):
        spm[q] = max(SPEED_MARGIN_FACTOR * abs(G[17, q] - G[0, q]) / hn, SPEED_ELASTICITY * abs(G[0, q]) / n0) * en


_NO_TABLE = (
    np.zeros(18),
    np.zeros(18),
    np.zeros(1, dtype=np.bool_),
    np.zeros((1, 2, 3)),
    np.full(3, 2, dtype=np.int64),
    np.zeros(2, dtype=np.int64),
)

# the kernel's threshold array of the ``local`` reading (every H̄ term weighed 1, nothing added)
_LOCAL_THRESHOLDS = threshold_array(DEFAULT_THRESHOLDS)

INCLUSIONS = ("tabulated", "exact")


def inclusion_arrays(c, dbar, inclusion: str):
    """The kernel's ``table`` argument for an inclusion mode: None for ``"exact"``, the tables for
    ``"tabulated"``."""
    if inclusion == "exact":
        return None
    if inclusion == "tabulated":
        return table_arrays(c, dbar)
    raise ValueError(f"inclusion must be one of {', '.join(INCLUSIONS)}, got {inclusion!r}")


def table_arrays(c, dbar, side_cols=None) -> tuple:
    """The tabulated Σ2 inclusion terms for both sensor chains in the kernel's layout: (delta,
    margin, valid (flat), grid (ntab, 2, 3): first node and 1/step, dims (3,): nodes per axis,
    chain -> table index (2,)), one table per distinct noise-bound triple (x1, x4, T1) of the
    chains (one for table 6.3's bounds)."""
    cols = SIDE_COLS if side_cols is None else side_cols
    keys, tables, index = [], [], []
    for side in range(2):
        key = (float(dbar[cols[side, 0]]), float(dbar[cols[side, 6]]), float(dbar[cols[side, 7]]))
        if key not in keys:
            keys.append(key)
            tables.append(sigma2_table(c, *key))
        index.append(keys.index(key))

    def flat(name):
        arrs = [getattr(t, name).reshape(-1) for t in tables]
        return arrs[0] if len(arrs) == 1 else np.concatenate(arrs)

    return (
        flat("delta"),
        flat("margin"),
        flat("valid"),
        np.stack([np.stack([t.lo, 1.0 / t.step]) for t in tables]),
        np.array(tables[0].shape, dtype=np.int64),
        np.array(index, dtype=np.int64),
    )


# Observer state of one engine, one row per side (0: odd sensors, 1: even sensors):
# columns of ST: 0 x̂1, 1 ē1, 2 x̂3, 3 ē3, 4 F3(prev), 5 H3(prev), 6 ok3(prev), 7 x̂4, 8 ē4, 9 F4(prev),
# 10 H4(prev), 11 ok4(prev), 12 speed warm start, 13 u(prev), 14 samples seen, 15/16 time since the
# M3/M4 observer (re)started [s] (kept for the closed-form thresholds of ``thesis-table-6.1`` only)
N_STATE = 17


def new_state(n_engines: int, n_nom: float) -> np.ndarray:
    """Fresh observer state for ``n_engines`` engines, shape (n_engines, 2, N_STATE)."""
    st = np.zeros((n_engines, 2, N_STATE))
    st[:, :, 12] = n_nom
    return st


def compute_residuals(c, Y, U, dt, dbar, side_cols, t_out_col, R, THR, ST, table=None, thr=None) -> None:
    """Residuals R (T, 19) and thresholds THR (T, 19) of all modules for samples Y (T, 19) of one
    engine, continuing from the observer state ST (2, N_STATE), which is updated in place.

    U : (T,) applied fuel setting (the known control input); dbar : (19,) noise bounds.
    Module columns follow ``MODULE_IDS``.  A module whose inputs are not finite gets R = inf
    (its ARR is violated).
    table : None (exact inclusion) or :func:`table_arrays` (the tabulated Σ2 inclusion terms with
    their certified margins, :mod:`marine_fdi_env.diagnosis.inclusion_table`).
    thr : None (the ``local`` thresholds) or :func:`~marine_fdi_env.diagnosis.thresholds.threshold_array`
    of a reading of the observers' thresholds.
    """
    kc, csm = kernel_constants(c)
    tw = _LOCAL_THRESHOLDS if thr is None else thr
    if table is None:
        _kernel(kc, csm, Y, U, float(dt), dbar, side_cols, t_out_col, R, THR, ST, _NO_TABLE, False, tw)
    else:
        _kernel(kc, csm, Y, U, float(dt), dbar, side_cols, t_out_col, R, THR, ST, table, True, tw)


@jit
def _kernel(c, csm, Y, U, dt, dbar, side_cols, t_out_col, R, THR, ST, table, use_table, tw):
    """:func:`compute_residuals` (``use_table`` False: exact inclusion, ``table`` unused) with the
    constants of :func:`kernel_constants` and the observers' threshold reading ``tw``
    (:func:`~marine_fdi_env.diagnosis.thresholds.threshold_array`: rows M1, M3, M4)."""
    T = Y.shape[0]
    L1, L3, L4 = OBSERVER_GAINS
    E1, q1, r1 = etd_scalar(-1.0 / c.tau_X_s, dt)
    E3, q3, r3 = etd_scalar(-1.0 / c.tau_pd_s, dt)
    E4, q4, r4 = etd_scalar(-1.0 / c.tau_TC_s, dt)
    Ld1, Ld3, Ld4 = -math.expm1(-L1 * dt), -math.expm1(-L3 * dt), -math.expm1(-L4 * dt)
    fuel_gain = c.x1_nom_kg / c.tau_X_s
    T1_model = inlet_air_temperature(0.0, c)
    # per sample of a chunk and chain: Σ2's cycle table (centre and perturbed rows); tabulated
    # mode: interpolated differences row - centre (6 rows x n/p6/T6), their certified margins, and
    # whether the chain's sample was tabulated (else computed exactly)
    tabs = np.empty((CHUNK, 2, 7, 3))
    dls = np.zeros((CHUNK, 2, 6, 3))
    mgs = np.zeros((CHUNK, 2, 6, 3))
    tabulated = np.zeros((CHUNK, 2), dtype=np.bool_)
    spm = np.zeros(4)  # margins of h3, h4, T_in, T_co for the tabulated perturbed speeds
    kc = np.zeros(4)  # kink corrections of h3, h4, T_in, T_co (see _kink_corners)
    kinked = False
    # model values at the points of the (x1, x3, x4, T1) box, columns h3, h4, T_in, T_co; rows:
    # 0 centre, 1/2 x1+-, 3/4 x3+-, 5/6 x4+-, 7/8 T1+-, 9/10 T_in+-, 11/12 p6+-, 13/14 T6+-, 15/16 T_out+-,
    # 17 centre at speed n0 + h (tabulated mode: the speed sensitivity for the margin of the perturbed speeds),
    # 18-21 the (x3, x4) corners where the box straddles a kink of Ψ_sc
    G = np.empty((22, 4))
    step = 2 if ONE_SIDED else 1
    for k0 in range(0, T, CHUNK):
        k1 = min(T, k0 + CHUNK)
        # Σ2 of both chains for the chunk first (a small loop, separate from the modules' code:
        # the whole per-sample body does not fit the instruction cache), the same numbers
        _sigma2_chunk(c, Y, dbar, side_cols, ST, table, use_table, k0, k1, tabs, dls, mgs, tabulated)
        for kk in range(k0, k1):
            tab = tabs[kk - k0]
            dl = dls[kk - k0]
            mg = mgs[kk - k0]
            tabd = tabulated[kk - k0]
            y = Y[kk]
            T_out = y[t_out_col]
            dTo = dbar[t_out_col]
            for side in range(2):
                st = ST[side]
                first = st[14] == 0.0
                cols = side_cols[side]
                cx1, cp6, cT6, ctq, cx3, cTin, cx4, cT1, cTco = (
                    cols[0],
                    cols[1],
                    cols[2],
                    cols[3],
                    cols[4],
                    cols[5],
                    cols[6],
                    cols[7],
                    cols[8],
                )
                x1, p6m, T6m, tqm, x3, T_in, x4, T1, T_co = (
                    y[cx1],
                    y[cp6],
                    y[cT6],
                    y[ctq],
                    y[cx3],
                    y[cTin],
                    y[cx4],
                    y[cT1],
                    y[cTco],
                )
                d1, d3, d4, dT1, dTin = dbar[cx1], dbar[cx3], dbar[cx4], dbar[cT1], dbar[cTin]
                base_ok = math.isfinite(x1) and math.isfinite(x4) and math.isfinite(T1)
                t = tab[side]
                n0 = t[0, 0]
                # ---------------------------------------------------------------- M1.q (fuel observer)
                m = 0 + side
                if first:
                    st[0] = x1
                    st[1] = d1
                    R[kk, m] = 0.0 if math.isfinite(x1) else math.inf
                else:
                    # prior from the exact model step with the known input (u linear within the step)
                    F0 = fuel_gain * st[13]
                    F1 = fuel_gain * U[kk]
                    prior = E1 * st[0] + q1 * F0 + r1 * (F1 - F0)
                    eta = r1 * abs(F1 - F0) + MODEL_MARGIN * abs(prior)
                    st[1] = E1 * ((1.0 - Ld1) * st[1] + Ld1 * d1) + eta
                    if math.isfinite(x1):
                        R[kk, m] = x1 - prior
                        st[0] = prior + Ld1 * (x1 - prior)
                    else:
                        R[kk, m] = math.inf
                        st[0] = prior
                THR[kk, m] = st[1] + d1
                if tw[0, 8] != 0.0:
                    THR[kk, m] = closed_form(st[14] * dt, d1, tw[0])
                # ---------------------------------------------------------------- M2.(1,2): p6, M2.(3,4): T6
                for j in range(2):
                    m = 2 + 2 * j + side
                    col = cp6 if j == 0 else cT6
                    if base_ok and math.isfinite(y[col]):
                        g0 = t[0, 1 + j]
                        if tabd[side]:
                            b = _dev_margin(dl[side], mg[side], 1 + j)
                        else:
                            b = (
                                _dev(g0, t[1, 1 + j], t[2, 1 + j])
                                + _dev(g0, t[3, 1 + j], t[4, 1 + j])
                                + _dev(g0, t[5, 1 + j], t[6, 1 + j])
                            )
                        R[kk, m] = y[col] - g0
                        THR[kk, m] = dbar[col] + SAFETY * b + MODEL_MARGIN * abs(g0)
                    else:
                        R[kk, m] = math.inf
                        THR[kk, m] = dbar[col]
                # ---------------------------------------------------------------- M2.(5,6): torque
                m = 6 + side
                if base_ok and math.isfinite(tqm) and math.isfinite(T6m) and tqm > 0.0:
                    n_t = _speed_of(tqm, c)
                    dq = dbar[ctq]
                    dT6 = dbar[cT6]
                    pc = torque_cycle(x1, x4, T1, n_t, c)
                    g0 = torque_from_cycle(pc, T6m, c)
                    r0 = tqm - g0
                    n_p = _speed_of(tqm + dq, c)
                    rp = (tqm + dq) - torque_from_cycle(torque_cycle(x1, x4, T1, n_p, c), T6m, c)
                    rm = r0
                    if not ONE_SIDED:
                        n_m = _speed_of(max(tqm - dq, 0.0), c)
                        rm = (tqm - dq) - torque_from_cycle(torque_cycle(x1, x4, T1, n_m, c), T6m, c)
                    b = _dev(r0, rp, rm)
                    b += _dev(r0, tqm - torque_from_cycle(pc, T6m + dT6, c), tqm - torque_from_cycle(pc, T6m - dT6, c))
                    rp = tqm - torque_from_cycle(torque_cycle(x1 + d1, x4, T1, n_t, c), T6m, c)
                    if not ONE_SIDED:
                        rm = tqm - torque_from_cycle(torque_cycle(x1 - d1, x4, T1, n_t, c), T6m, c)
                    b += _dev(r0, rp, rm)
                    rp = tqm - torque_from_cycle(torque_cycle(x1, x4 + d4, T1, n_t, c), T6m, c)
                    if not ONE_SIDED:
                        rm = tqm - torque_from_cycle(torque_cycle(x1, x4 - d4, T1, n_t, c), T6m, c)
                    b += _dev(r0, rp, rm)
                    rp = tqm - torque_from_cycle(torque_cycle(x1, x4, T1 + dT1, n_t, c), T6m, c)
                    if not ONE_SIDED:
                        rm = tqm - torque_from_cycle(torque_cycle(x1, x4, T1 - dT1, n_t, c), T6m, c)
                    b += _dev(r0, rp, rm)
                    R[kk, m] = r0
                    THR[kk, m] = SAFETY * b + MODEL_MARGIN * abs(g0)
                else:
                    R[kk, m] = math.inf
                    THR[kk, m] = dbar[ctq]
                # ------------------------------------------------- model values of M3.q, M3.(3,4), M4.q, M4.(5,6)
                ok = base_ok and math.isfinite(x3) and math.isfinite(T_in)
                kinked = False
                if ok:
                    dp6 = dbar[cp6]
                    dT6 = dbar[cT6]
                    psi = scavenge_flow_function(x3 / x4, c)
                    Pi = turbine_expansion(x3, c)
                    m1 = _charge_mass(x4, T1, c)
                    s_sl, mdot, df = _box_points(
                        c, csm, x1, x3, x4, T1, m1, t, psi, Pi, T_in, T_out, T6m, p6m, d1, d3, d4, dT1, G
                    )
                    # near a kink of Ψ_sc (x3/x4 clipped to [r_crit, 1]) the coordinate-wise terms miss
                    # the range of the slip flow (e.g. measured x3/x4 > 1, no slip at any coordinate-wise
                    # point, but slip at the corner x3 - d, x4 + d): take the larger of the two
                    # coordinate terms' sum and the corners' deviation, and enlarge (KINK_SAFETY)
                    kinked = _straddles_kink(x3, x4, d3, d4, c)
                    if kinked:
                        _kink_corners(c, csm, x1, x3, x4, T1, d3, d4, t[3, 0], t[4, 0], T_in, T_out, T6m, p6m, G, kc)
                    for j in range(9, 17, step):
                        if csm is not None:  # compiled only where a gas-path submodel may be on
                            if c.sm_on != 0.0:
                                _sm_perturbed(
                                    csm,
                                    x1,
                                    x3,
                                    x4,
                                    m1,
                                    n0,
                                    s_sl,
                                    Pi,
                                    T_in,
                                    T_out,
                                    dTin,
                                    dTo,
                                    T6m,
                                    p6m,
                                    dp6,
                                    dT6,
                                    G,
                                    step,
                                )
                                break
                        sg = 1.0 if j % 2 == 1 else -1.0
                        Ti = T_in + sg * dTin if j < 11 else T_in
                        if j < 11:  # T_in: h3, h4, T_co
                            G[j, 0] = _h3(mdot, Ti, c)
                            G[j, 1] = _compressor_forcing(x4, df, Ti, Pi, c)
                            G[j, 3] = compressor_outlet_temperature(df, Ti, T_out, 0.0, c)
                        elif j >= 15:  # T_out: T_co only
                            G[j, 3] = compressor_outlet_temperature(df, T_in, T_out + sg * dTo, 0.0, c)
                        else:  # p6 or T6: T_in
                            pp = p6m + sg * dp6 if j < 13 else p6m
                            TT = T6m + sg * dT6 if j >= 13 else T6m
                            G[j, 2] = _mixing(x1, m1, s_sl, mdot, TT, pp, c)
                    if ONE_SIDED:
                        for j in range(2, 17, 2):
                            for q in range(4):
                                G[j, q] = G[0, q]
                    if tabd[side]:
                        _speed_margins(c, csm, x1, x3, x4, m1, n0, psi, Pi, T_in, T_out, T6m, p6m, G, mg[side], spm)
                # ---------------------------------------------------------------- M3.q (receiver observer)
                m = 8 + side
                F, H = 0.0, 0.0
                w = tw[1]
                if ok:
                    F = G[0, 0]
                    H = SAFETY * (
                        w[0] * _dev(F, G[1, 0], G[2, 0])
                        + w[1] * _dev(F, G[3, 0], G[4, 0])
                        + w[2] * _dev(F, G[5, 0], G[6, 0])
                        + w[3] * _dev(F, G[7, 0], G[8, 0])
                        + w[4] * _dev(F, G[9, 0], G[10, 0])
                        + w[7]
                    )
                    if tabd[side]:
                        H += SAFETY * (w[5] * spm[0])
                    if kinked:
                        H = (H + SAFETY * (w[6] * kc[0])) * KINK_SAFETY
                restart = first or st[6] == 0.0
                R[kk, m], THR[kk, m] = _observer_update(st, 2, first, ok, x3, F, H, E3, q3, r3, Ld3, d3)
                if w[8] != 0.0:
                    st[15] = 0.0 if restart else st[15] + dt
                    THR[kk, m] = closed_form(st[15], d3, w)
                # ---------------------------------------------------------------- M3.(3,4): T_in
                m = 10 + side
                if ok and math.isfinite(p6m) and math.isfinite(T6m):
                    g0 = G[0, 2]
                    b = _dev(g0, G[1, 2], G[2, 2]) + _dev(g0, G[3, 2], G[4, 2]) + _dev(g0, G[5, 2], G[6, 2])
                    b += _dev(g0, G[7, 2], G[8, 2])
                    b += _dev(g0, G[11, 2], G[12, 2])
                    b += _dev(g0, G[13, 2], G[14, 2])
                    if tabd[side]:
                        b += spm[2]
                    if kinked:
                        b = (b + kc[2]) * KINK_SAFETY
                    R[kk, m] = T_in - g0
                    THR[kk, m] = dbar[cTin] + SAFETY * b + MODEL_MARGIN * abs(g0)
                else:
                    R[kk, m] = math.inf
                    THR[kk, m] = dbar[cTin]
                # ---------------------------------------------------------------- M4.q (charge observer)
                m = 13 + side
                F, H = 0.0, 0.0
                w = tw[2]
                if ok:
                    F = G[0, 1]
                    H = SAFETY * (
                        w[0] * _dev(F, G[1, 1], G[2, 1])
                        + w[1] * _dev(F, G[3, 1], G[4, 1])
                        + w[2] * _dev(F, G[5, 1], G[6, 1])
                        + w[3] * _dev(F, G[7, 1], G[8, 1])
                        + w[4] * _dev(F, G[9, 1], G[10, 1])
                        + w[7]
                    )
                    if tabd[side]:
                        H += SAFETY * (w[5] * spm[1])
                    if kinked:
                        H = (H + SAFETY * (w[6] * kc[1])) * KINK_SAFETY
                restart = first or st[11] == 0.0
                R[kk, m], THR[kk, m] = _observer_update(st, 7, first, ok, x4, F, H, E4, q4, r4, Ld4, d4)
                if w[8] != 0.0:
                    st[16] = 0.0 if restart else st[16] + dt
                    THR[kk, m] = closed_form(st[16], d4, w)
                # ---------------------------------------------------------------- M4.(3,4): T1
                m = 15 + side
                T1m = T1_model
                if c.ic_on != 0.0:  # intercooler submodel: the cooler outlet follows the charge pressure
                    T1m = inlet_air_temperature_at(0.0, x4 if math.isfinite(x4) else c.p_amb_Pa, c)
                R[kk, m] = T1 - T1m if math.isfinite(T1) else math.inf
                THR[kk, m] = dT1 + MODEL_MARGIN * T1m
                # ---------------------------------------------------------------- M4.(5,6): compressor outlet
                m = 17 + side
                if ok and math.isfinite(T_co) and math.isfinite(T_out):
                    g0 = G[0, 3]
                    b = _dev(g0, G[1, 3], G[2, 3]) + _dev(g0, G[3, 3], G[4, 3]) + _dev(g0, G[5, 3], G[6, 3])
                    b += _dev(g0, G[7, 3], G[8, 3])
                    b += _dev(g0, G[9, 3], G[10, 3])
                    b += _dev(g0, G[15, 3], G[16, 3])
                    if tabd[side]:
                        b += spm[3]
                    if kinked:
                        b = (b + kc[3]) * KINK_SAFETY
                    R[kk, m] = T_co - g0
                    THR[kk, m] = dbar[cTco] + SAFETY * b + MODEL_MARGIN * abs(g0)
                else:
                    R[kk, m] = math.inf
                    THR[kk, m] = dbar[cTco]
                st[13] = U[kk]
                st[14] += 1.0
            # ---------------------------------------------------------------- M3.5: turbine outlet
            m = 12
            x3e, Tine, x4e = y[side_cols[1, 4]], y[side_cols[1, 5]], y[side_cols[1, 6]]
            if math.isfinite(x3e) and math.isfinite(Tine) and math.isfinite(x4e) and math.isfinite(T_out):
                dTi, dx3, dx4 = dbar[side_cols[1, 5]], dbar[side_cols[1, 4]], dbar[side_cols[1, 6]]
                Pi = turbine_expansion(x3e, c)
                g0 = turbine_outlet_from_expansion(Tine, Pi, x4e, c)
                gp = turbine_outlet_from_expansion(Tine + dTi, Pi, x4e, c)
                gm = g0 if ONE_SIDED else turbine_outlet_from_expansion(Tine - dTi, Pi, x4e, c)
                b = _dev(g0, gp, gm)
                gp = turbine_outlet_temperature(Tine, x3e + dx3, x4e, c)
                gm = g0 if ONE_SIDED else turbine_outlet_temperature(Tine, x3e - dx3, x4e, c)
                b += _dev(g0, gp, gm)
                gp = turbine_outlet_from_expansion(Tine, Pi, x4e + dx4, c)
                gm = g0 if ONE_SIDED else turbine_outlet_from_expansion(Tine, Pi, x4e - dx4, c)
                b += _dev(g0, gp, gm)
                R[kk, m] = T_out - g0
                THR[kk, m] = dTo + SAFETY * b + MODEL_MARGIN * abs(g0)
            else:
                R[kk, m] = math.inf
                THR[kk, m] = dTo


@jit
def _sigma2_chunk(c, Y, dbar, side_cols, ST, table, use_table, k0, k1, tabs, dls, mgs, tabulated):
    """Σ2 of both chains for samples k0..k1-1 into tabs[k - k0] (rows as :func:`cycle_table`):
    the centre speeds in sample order (each from the previous sample's speed, ST[:, 12]), then the
    perturbed rows, from the table or exactly.  A chain whose x1, x4 or T1 is not finite gets no
    rows (its modules do not use them then) and keeps its warm start."""
    tside = table[5]
    ca = side_cols[0]
    cb = side_cols[1]
    for kk in range(k0, k1):
        y = Y[kk]
        x1a, x4a, T1a = y[ca[0]], y[ca[6]], y[ca[7]]
        x1b, x4b, T1b = y[cb[0]], y[cb[6]], y[cb[7]]
        oka = math.isfinite(x1a) and math.isfinite(x4a) and math.isfinite(T1a)
        okb = math.isfinite(x1b) and math.isfinite(x4b) and math.isfinite(T1b)
        ta = tabs[kk - k0, 0]
        tb = tabs[kk - k0, 1]
        if oka and okb:
            ta[0, 0], ta[0, 1], ta[0, 2], tb[0, 0], tb[0, 1], tb[0, 2] = centre_speed2(
                c, x1a, x4a, T1a, ST[0, 12], x1b, x4b, T1b, ST[1, 12]
            )
        elif oka:
            ta[0, 0], ta[0, 1], ta[0, 2] = centre_speed(c, x1a, x4a, T1a, ST[0, 12])
        elif okb:
            tb[0, 0], tb[0, 1], tb[0, 2] = centre_speed(c, x1b, x4b, T1b, ST[1, 12])
        if oka and math.isfinite(ta[0, 0]):
            ST[0, 12] = ta[0, 0]
        if okb and math.isfinite(tb[0, 0]):
            ST[1, 12] = tb[0, 0]
        exa = oka
        exb = okb
        tabulated[kk - k0, 0] = False
        tabulated[kk - k0, 1] = False
        if use_table:
            tabulated[kk - k0, 0] = oka and _tabulate(
                table, tside[0], x1a, x4a, T1a, ta, dls[kk - k0, 0], mgs[kk - k0, 0]
            )
            tabulated[kk - k0, 1] = okb and _tabulate(
                table, tside[1], x1b, x4b, T1b, tb, dls[kk - k0, 1], mgs[kk - k0, 1]
            )
            exa = oka and not tabulated[kk - k0, 0]
            exb = okb and not tabulated[kk - k0, 1]
        if exa and exb:
            perturbed_rows2(
                c,
                x1a,
                x4a,
                T1a,
                dbar[ca[0]],
                dbar[ca[6]],
                dbar[ca[7]],
                ta,
                x1b,
                x4b,
                T1b,
                dbar[cb[0]],
                dbar[cb[6]],
                dbar[cb[7]],
                tb,
            )
        elif exa:
            perturbed_rows(c, x1a, x4a, T1a, dbar[ca[0]], dbar[ca[6]], dbar[ca[7]], ta)
        elif exb:
            perturbed_rows(c, x1b, x4b, T1b, dbar[cb[0]], dbar[cb[6]], dbar[cb[7]], tb)


class ResidualTrace:
    """Residuals, thresholds and violations of the 19 modules over a run (arrays (T, 19))."""

    def __init__(self, residuals: np.ndarray, thresholds: np.ndarray) -> None:
        self.residuals = residuals
        self.thresholds = thresholds
        with np.errstate(invalid="ignore"):
            self.violations = ~(np.abs(residuals) <= thresholds)

    @property
    def ratio(self) -> np.ndarray:
        """|residual| / threshold (> 1 means the ARR is violated)."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.abs(self.residuals) / self.thresholds


def residuals_for_run(
    constants,
    measurements: np.ndarray,
    u: np.ndarray,
    dt: float,
    noise_bounds: np.ndarray | None = None,
    inclusion: str = "tabulated",
    thresholds: str = DEFAULT_THRESHOLDS,
    params_name: str = "thesis-12v28",
) -> ResidualTrace:
    """Run all 19 modules over one engine's measurements (T, 19) with the applied fuel setting (T,);
    ``inclusion`` and ``thresholds`` as :class:`~marine_fdi_env.diagnosis.agent.ReferenceDiagnoser`'s
    (``params_name``: the parameter set whose global bounds a ``thesis-...`` reading takes)."""
    Y = np.ascontiguousarray(measurements, dtype=np.float64)
    U = np.ascontiguousarray(u, dtype=np.float64)
    db = np.array(NOISE_BOUNDS if noise_bounds is None else noise_bounds, dtype=np.float64)
    T = Y.shape[0]
    R = np.zeros((T, len(MODULE_IDS)))
    THR = np.zeros((T, len(MODULE_IDS)))
    st = new_state(1, constants.n_nom_rev_s)[0]
    table = inclusion_arrays(constants, db, inclusion)
    thr = threshold_array(thresholds, params_name)
    compute_residuals(constants, Y, U, float(dt), db, SIDE_COLS, T_OUT_COL, R, THR, st, table, thr)
    return ResidualTrace(R, THR)


@jit
def _batch_loop(c, csm, Y, U, dt, dbar, side_cols, t_out_col, R, THR, ST, table, use_table, tw, i0, i1):
    for i in range(i0, i1):
        _kernel(c, csm, Y[i], U[i], dt, dbar, side_cols, t_out_col, R[i], THR[i], ST[i], table, use_table, tw)


def _batch_range(c, Y, U, dt, dbar, side_cols, t_out_col, R, THR, ST, table, use_table, i0, i1, thr=None) -> None:
    """Engines i0..i1-1 of :func:`compute_residuals_batch` on this thread (``table`` the kernel's:
    ``_NO_TABLE`` with ``use_table`` False for the exact inclusion; ``thr`` as
    :func:`compute_residuals`'s)."""
    kc, csm = kernel_constants(c)
    tw = _LOCAL_THRESHOLDS if thr is None else thr
    _batch_loop(kc, csm, Y, U, float(dt), dbar, side_cols, t_out_col, R, THR, ST, table, use_table, tw, i0, i1)


def compute_residuals_batch(c, Y, U, dt, dbar, side_cols, t_out_col, R, THR, ST, table=None, thr=None):
    """:func:`compute_residuals` for N engines: Y (N, B, 19), U (N, B), R/THR (N, B, 19), ST (N, 2, N_STATE).

    Batches of at least ``THREADED_MIN_ENGINES`` engines run on the simulator's two worker
    threads (the compiled loop releases the GIL) as ``THREAD_CHUNKS`` contiguous chunks, so that a
    thread slowed down by other load does not hold up the other; engines are independent, so the
    results equal the single-thread loop bit for bit.  ``thr`` as :func:`compute_residuals`'s.
    """
    n = Y.shape[0]
    kc, csm = kernel_constants(c)
    args = (
        kc,
        csm,
        Y,
        U,
        float(dt),
        dbar,
        side_cols,
        t_out_col,
        R,
        THR,
        ST,
        _NO_TABLE if table is None else table,
        table is not None,
        _LOCAL_THRESHOLDS if thr is None else thr,
    )
    if n < THREADED_MIN_ENGINES:
        _batch_loop(*args, 0, n)
        return
    edges = np.linspace(0, n, THREAD_CHUNKS + 1).astype(np.int64)
    list(thread_pool().map(lambda r: _batch_loop(*args, r[0], r[1]), list(zip(edges[:-1], edges[1:]))))


THREAD_CHUNKS = 8
