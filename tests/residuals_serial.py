"""The reference diagnoser's residual kernel as it was before the two chains were interleaved and
the tabulated inclusion added (commit ecfb703): one sensor chain after the other, exact inclusion.

Kept verbatim (imports made absolute) as the regression anchor of ``inclusion="exact"``: the
restructured kernel must give the same residuals and thresholds bit for bit
(tests/unit/test_residual_inclusion.py).
"""

from __future__ import annotations

import math

import numpy as np

from marine_fdi_env._jit import jit
from marine_fdi_env.diagnosis.modules import MODULE_IDS
from marine_fdi_env.engine.integrators import THREADED_MIN_ENGINES, etd_scalar, thread_pool
from marine_fdi_env.engine.seiliger import seiliger_cycle
from marine_fdi_env.engine.sensors import NOISE_BOUNDS, SENSOR_IDS
from marine_fdi_env.engine.subsystems.air_intake import (
    compressor_outlet_temperature,
    delta_f,
    eta_tc,
    inlet_air_temperature,
)
from marine_fdi_env.engine.subsystems.engine_block import (
    constant_volume_portion,
    engine_block,
    friction_torque,
    speed_sweep,
)
from marine_fdi_env.engine.subsystems.exhaust_receiver import (
    receiver_and_turbine,
    receiver_forcing,
    scavenge_flow_function,
    turbine_expansion,
    turbine_mass_flow,
    turbine_outlet_from_expansion,
    turbine_outlet_temperature,
)

__all__ = [
    "OBSERVER_GAINS",
    "compute_residuals",
    "compute_residuals_batch",
    "ResidualTrace",
    "SAFETY",
    "MODEL_MARGIN",
    "new_state",
    "N_STATE",
    "residuals_for_run",
]

# Observer gains L [1/s] of table 6.1 for M(1,q), M(3,q), M(4,q).
OBSERVER_GAINS = (33.3833, 1.25, 0.3764)
SAFETY = 1.05
MODEL_MARGIN = 1e-6  # η̄ per step, relative to the state, and relative margin of algebraic ARRs
SPEED_SWEEPS = 4
ONE_SIDED = False  # measured and rejected (see the module docstring)
LINEAR_SPEED = True  # perturbed points: one sweep + linearisation in the speed (see cycle_table)
SLOPE_STEP = 1e-5  # relative step of the centre's speed slope

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
def centre_speed(c, x1, x4, T1, n_guess):
    """Σ2's speed loop at the centre from the previous sample's speed: two sweeps and an Aitken
    extrapolation (as ``engine_block``), one sweep and a second extrapolation with the slope of
    the first two sweeps, and the output sweep; returns (n, p6, T6).  Four sweeps where
    ``engine_block(..., SPEED_SWEEPS=4)`` takes five; same result to ~1e-12 (measured)."""
    V1 = c.V1_m3
    m1 = x4 * V1 / (c.R_a_J_per_kgK * T1)
    q = (c.eta_comb * c.h_L_J_per_kg) * x1 / m1
    X_ct = c.X_ct_nom * x1 / c.x1_nom_kg
    n0 = n_guess
    n1, torque, cyc = speed_sweep(n0, x4, T1, q, m1, X_ct, c)
    n2, torque, cyc = speed_sweep(n1, x4, T1, q, m1, X_ct, c)
    den = (n2 - n1) - (n1 - n0)
    k = (n2 - n1) / (n1 - n0) if n1 != n0 else 0.0
    a = n2 - (n2 - n1) ** 2 / den if den != 0.0 else n2
    b, torque, cyc = speed_sweep(a, x4, T1, q, m1, X_ct, c)
    if math.isfinite(k) and abs(k) < 0.5:
        a = a + (b - a) / (1.0 - k)
    else:
        a = b
    n, torque, cyc = speed_sweep(a, x4, T1, q, m1, X_ct, c)
    return n, cyc[5], cyc[3]


@jit
def cycle_table(c, x1, x4, T1, dx1, dx4, dT1, n_guess, tab):
    """Σ2 at the centre and at +d̄ (and -d̄ unless ``ONE_SIDED``) of x1, x4, T1: rows (n, p6, T6) in
    the order centre, x1+, x1-, x4+, x4-, T1+, T1- (fills tab 7x3; skipped rows repeat the centre).

    The centre is solved to ~1e-12 relative by :func:`centre_speed` (from the previous sample's speed).
    A perturbed point is one sweep from the centre's speed n_c, linearised in the speed with the
    centre's slopes (one more sweep at n_c + h)::

        n_p  = n_c + (f_p(n_c) - n_c) / (1 - f_c'(n_c))
        p6_p = p6_p(n_c) + p6_c'(n_c) (n_p - n_c)           (T6 alike)

    exact to first order in the perturbation; the neglected terms are second order (the slope's
    change over the noise box times the speed change, and the curvature in n), the same order as
    the mixed terms the coordinate-wise inclusion neglects (see the module docstring).  Where the
    slope is not a contraction (never seen in the envelope) every point is solved in full.
    """
    V1 = c.V1_m3
    n_c, p6, T6 = centre_speed(c, x1, x4, T1, n_guess)
    tab[0, 0] = n_c
    tab[0, 1] = p6
    tab[0, 2] = T6
    for p in range(1, 7):
        tab[p, 0] = n_c
        tab[p, 1] = p6
        tab[p, 2] = T6
    step = 2 if ONE_SIDED else 1
    h = SLOPE_STEP * n_c
    n_h, tq, p6_h, T6_h, p_max, m1 = engine_block(x1, x4, T1, V1, n_c + h, c, 1)
    k = (n_h - n_c) / h
    linear = LINEAR_SPEED and math.isfinite(k) and abs(k) < 0.5
    s_p6 = (p6_h - p6) / h
    s_T6 = (T6_h - T6) / h
    for p in range(1, 7, step):
        a = dx1 if p == 1 else (-dx1 if p == 2 else 0.0)
        b = dx4 if p == 3 else (-dx4 if p == 4 else 0.0)
        d = dT1 if p == 5 else (-dT1 if p == 6 else 0.0)
        if linear:
            f_p, tq, p6_p, T6_p, p_max, m1 = engine_block(x1 + a, x4 + b, T1 + d, V1, n_c, c, 1)
            dn = (f_p - n_c) / (1.0 - k)
            tab[p, 0] = n_c + dn
            tab[p, 1] = p6_p + s_p6 * dn
            tab[p, 2] = T6_p + s_T6 * dn
        else:
            n, tq, p6_p, T6_p, p_max, m1 = engine_block(x1 + a, x4 + b, T1 + d, V1, n_c, c, SPEED_SWEEPS)
            tab[p, 0] = n
            tab[p, 1] = p6_p
            tab[p, 2] = T6_p


@jit
def _dev(g0, gp, gm):
    """One coordinate's term of the inclusion: max(|g(+)-g0|, |g(-)-g0|), or |g(+)-g0| if ONE_SIDED."""
    if ONE_SIDED:
        return abs(gp - g0)
    return max(abs(gp - g0), abs(gm - g0))


@jit
def _torque_cycle(x1, x4, T1, n, c):
    """The T6-independent part of :func:`torque_given_speed`: (m1, w without the T6 term, T4, Q_loss).

    Same operations in the same order, so ``_torque_from(...)`` equals ``torque_given_speed`` bit
    for bit; the measured-T6 perturbations of M2.5/6 then reuse one Seiliger cycle."""
    m1 = x4 * c.V1_m3 / (c.R_a_J_per_kgK * T1)
    q = (c.eta_comb * c.h_L_J_per_kg) * x1 / m1
    X_ct = c.X_ct_nom * x1 / c.x1_nom_kg
    X_cv = constant_volume_portion(n, X_ct, c)
    T2, T3, T4, _, _, _, _ = seiliger_cycle(x4, T1, q, X_cv, X_ct, c)
    R = c.R_a_J_per_kgK
    w0 = -c.c_v_a_J_per_kgK * (T2 - T1) + R * (T4 - T3) + X_ct * q
    return m1, w0, T4, friction_torque(n, c)


@jit
def _torque_from(parts, T6, c):
    m1, w0, T4, q_loss = parts
    w = w0 + c.R_a_J_per_kgK * (T4 - T6) / (c.n_exp - 1.0)
    return m1 * w * c.torque_per_work - q_loss


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
def _point(c, x1, x3, x4, T1, n, psi, Pi, T_in, T_out, T6, p6, out, j):
    """h3, h4, T_in(model), T_co(model) at one point of the (x1, x3, x4, T1, n) box into out[j],
    sharing m1, s_sl, ṁ_g, δ_f; psi = Ψ_sc(x3/x4) and Pi = Π_turbo(x3) are passed in (they depend
    on x3, x4 only, so most points reuse the centre's).  The same operations as ``slip_ratio``,
    ``receiver_forcing``, ... in the same order, so the numbers equal the direct calls bit for bit."""
    m1 = x4 * c.V1_m3 / (c.R_a_J_per_kgK * T1)
    s_sl = c.slip_coeff * x4 * psi / (n * m1)
    mdot = turbine_mass_flow(x1, m1, s_sl, n, c)
    df = delta_f(x1, m1, s_sl)
    out[j, 0] = receiver_forcing(mdot, T_in, c)
    out[j, 1] = _compressor_forcing(x4, df, T_in, Pi, c)
    out[j, 2] = receiver_and_turbine(x1, x3, x4, m1, s_sl, n, T6, p6, c.T_sl_K, c)[1]
    out[j, 3] = compressor_outlet_temperature(df, T_in, T_out, 0.0, c)
    return m1, s_sl, mdot, df


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


# Observer state of one engine, one row per side (0: odd sensors, 1: even sensors):
# columns of ST: 0 x̂1, 1 ē1, 2 x̂3, 3 ē3, 4 F3(prev), 5 H3(prev), 6 ok3(prev), 7 x̂4, 8 ē4, 9 F4(prev),
# 10 H4(prev), 11 ok4(prev), 12 speed warm start, 13 u(prev), 14 samples seen
N_STATE = 15


def new_state(n_engines: int, n_nom: float) -> np.ndarray:
    """Fresh observer state for ``n_engines`` engines, shape (n_engines, 2, N_STATE)."""
    st = np.zeros((n_engines, 2, N_STATE))
    st[:, :, 12] = n_nom
    return st


@jit
def compute_residuals(c, Y, U, dt, dbar, side_cols, t_out_col, R, THR, ST):
    """Residuals R (T, 19) and thresholds THR (T, 19) of all modules for samples Y (T, 19) of one
    engine, continuing from the observer state ST (2, N_STATE), which is updated in place.

    U : (T,) applied fuel setting (the known control input); dbar : (19,) noise bounds.
    Module columns follow ``MODULE_IDS``.  A module whose inputs are not finite gets R = inf
    (its ARR is violated).
    """
    T = Y.shape[0]
    L1, L3, L4 = OBSERVER_GAINS
    E1, q1, r1 = etd_scalar(-1.0 / c.tau_X_s, dt)
    E3, q3, r3 = etd_scalar(-1.0 / c.tau_pd_s, dt)
    E4, q4, r4 = etd_scalar(-1.0 / c.tau_TC_s, dt)
    Ld1, Ld3, Ld4 = -math.expm1(-L1 * dt), -math.expm1(-L3 * dt), -math.expm1(-L4 * dt)
    fuel_gain = c.x1_nom_kg / c.tau_X_s
    T1_model = inlet_air_temperature(0.0, c)
    tab = np.empty((2, 7, 3))
    # model values at the points of the (x1, x3, x4, T1) box, columns h3, h4, T_in, T_co; rows:
    # 0 centre, 1/2 x1+-, 3/4 x3+-, 5/6 x4+-, 7/8 T1+-, 9/10 T_in+-, 11/12 p6+-, 13/14 T6+-, 15/16 T_out+-
    G = np.empty((17, 4))
    step = 2 if ONE_SIDED else 1
    for kk in range(T):
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
            if base_ok:
                cycle_table(c, x1, x4, T1, d1, d4, dT1, st[12], tab[side])
                if math.isfinite(tab[side, 0, 0]):
                    st[12] = tab[side, 0, 0]
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
            # ---------------------------------------------------------------- M2.(1,2): p6, M2.(3,4): T6
            for j in range(2):
                m = 2 + 2 * j + side
                col = cp6 if j == 0 else cT6
                if base_ok and math.isfinite(y[col]):
                    g0 = t[0, 1 + j]
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
                n_t = math.sqrt(c.two_pi_over_c * tqm)
                dq = dbar[ctq]
                dT6 = dbar[cT6]
                pc = _torque_cycle(x1, x4, T1, n_t, c)
                g0 = _torque_from(pc, T6m, c)
                r0 = tqm - g0
                n_p = math.sqrt(c.two_pi_over_c * (tqm + dq))
                rp = (tqm + dq) - _torque_from(_torque_cycle(x1, x4, T1, n_p, c), T6m, c)
                rm = r0
                if not ONE_SIDED:
                    n_m = math.sqrt(c.two_pi_over_c * max(tqm - dq, 0.0))
                    rm = (tqm - dq) - _torque_from(_torque_cycle(x1, x4, T1, n_m, c), T6m, c)
                b = _dev(r0, rp, rm)
                b += _dev(r0, tqm - _torque_from(pc, T6m + dT6, c), tqm - _torque_from(pc, T6m - dT6, c))
                rp = tqm - _torque_from(_torque_cycle(x1 + d1, x4, T1, n_t, c), T6m, c)
                if not ONE_SIDED:
                    rm = tqm - _torque_from(_torque_cycle(x1 - d1, x4, T1, n_t, c), T6m, c)
                b += _dev(r0, rp, rm)
                rp = tqm - _torque_from(_torque_cycle(x1, x4 + d4, T1, n_t, c), T6m, c)
                if not ONE_SIDED:
                    rm = tqm - _torque_from(_torque_cycle(x1, x4 - d4, T1, n_t, c), T6m, c)
                b += _dev(r0, rp, rm)
                rp = tqm - _torque_from(_torque_cycle(x1, x4, T1 + dT1, n_t, c), T6m, c)
                if not ONE_SIDED:
                    rm = tqm - _torque_from(_torque_cycle(x1, x4, T1 - dT1, n_t, c), T6m, c)
                b += _dev(r0, rp, rm)
                R[kk, m] = r0
                THR[kk, m] = SAFETY * b + MODEL_MARGIN * abs(g0)
            else:
                R[kk, m] = math.inf
                THR[kk, m] = dbar[ctq]
            # ------------------------------------------------- model values of M3.q, M3.(3,4), M4.q, M4.(5,6)
            ok = base_ok and math.isfinite(x3) and math.isfinite(T_in)
            if ok:
                dp6 = dbar[cp6]
                dT6 = dbar[cT6]
                psi = scavenge_flow_function(x3 / x4, c)
                Pi = turbine_expansion(x3, c)
                m1, s_sl, mdot, df = _point(c, x1, x3, x4, T1, n0, psi, Pi, T_in, T_out, T6m, p6m, G, 0)
                for j in range(1, 9, step):
                    a = d1 if j == 1 else (-d1 if j == 2 else 0.0)
                    e = d3 if j == 3 else (-d3 if j == 4 else 0.0)
                    f = d4 if j == 5 else (-d4 if j == 6 else 0.0)
                    g = dT1 if j == 7 else (-dT1 if j == 8 else 0.0)
                    psi_j, Pi_j = psi, Pi
                    if j == 3 or j == 4:
                        psi_j = scavenge_flow_function((x3 + e) / x4, c)
                        Pi_j = turbine_expansion(x3 + e, c)
                    elif j == 5 or j == 6:
                        psi_j = scavenge_flow_function(x3 / (x4 + f), c)
                    n_j = t[j, 0] if j < 3 else (n0 if j < 5 else t[j - 2, 0])
                    _point(c, x1 + a, x3 + e, x4 + f, T1 + g, n_j, psi_j, Pi_j, T_in, T_out, T6m, p6m, G, j)
                for j in range(9, 17, step):
                    sg = 1.0 if j % 2 == 1 else -1.0
                    Ti = T_in + sg * dTin if j < 11 else T_in
                    if j < 11:  # T_in: h3, h4, T_co
                        G[j, 0] = receiver_forcing(mdot, Ti, c)
                        G[j, 1] = _compressor_forcing(x4, df, Ti, Pi, c)
                        G[j, 3] = compressor_outlet_temperature(df, Ti, T_out, 0.0, c)
                    elif j >= 15:  # T_out: T_co only
                        G[j, 3] = compressor_outlet_temperature(df, T_in, T_out + sg * dTo, 0.0, c)
                    else:  # p6 or T6: T_in
                        pp = p6m + sg * dp6 if j < 13 else p6m
                        TT = T6m + sg * dT6 if j >= 13 else T6m
                        G[j, 2] = receiver_and_turbine(x1, x3, x4, m1, s_sl, n0, TT, pp, c.T_sl_K, c)[1]
                if ONE_SIDED:
                    for j in range(2, 17, 2):
                        for q in range(4):
                            G[j, q] = G[0, q]
            # ---------------------------------------------------------------- M3.q (receiver observer)
            m = 8 + side
            F, H = 0.0, 0.0
            if ok:
                F = G[0, 0]
                H = SAFETY * (
                    _dev(F, G[1, 0], G[2, 0])
                    + _dev(F, G[3, 0], G[4, 0])
                    + _dev(F, G[5, 0], G[6, 0])
                    + _dev(F, G[7, 0], G[8, 0])
                    + _dev(F, G[9, 0], G[10, 0])
                )
            R[kk, m], THR[kk, m] = _observer_update(st, 2, first, ok, x3, F, H, E3, q3, r3, Ld3, d3)
            # ---------------------------------------------------------------- M3.(3,4): T_in
            m = 10 + side
            if ok and math.isfinite(p6m) and math.isfinite(T6m):
                g0 = G[0, 2]
                b = _dev(g0, G[1, 2], G[2, 2]) + _dev(g0, G[3, 2], G[4, 2]) + _dev(g0, G[5, 2], G[6, 2])
                b += _dev(g0, G[7, 2], G[8, 2])
                b += _dev(g0, G[11, 2], G[12, 2])
                b += _dev(g0, G[13, 2], G[14, 2])
                R[kk, m] = T_in - g0
                THR[kk, m] = dbar[cTin] + SAFETY * b + MODEL_MARGIN * abs(g0)
            else:
                R[kk, m] = math.inf
                THR[kk, m] = dbar[cTin]
            # ---------------------------------------------------------------- M4.q (charge observer)
            m = 13 + side
            F, H = 0.0, 0.0
            if ok:
                F = G[0, 1]
                H = SAFETY * (
                    _dev(F, G[1, 1], G[2, 1])
                    + _dev(F, G[3, 1], G[4, 1])
                    + _dev(F, G[5, 1], G[6, 1])
                    + _dev(F, G[7, 1], G[8, 1])
                    + _dev(F, G[9, 1], G[10, 1])
                )
            R[kk, m], THR[kk, m] = _observer_update(st, 7, first, ok, x4, F, H, E4, q4, r4, Ld4, d4)
            # ---------------------------------------------------------------- M4.(3,4): T1
            m = 15 + side
            R[kk, m] = T1 - T1_model if math.isfinite(T1) else math.inf
            THR[kk, m] = dT1 + MODEL_MARGIN * T1_model
            # ---------------------------------------------------------------- M4.(5,6): compressor outlet
            m = 17 + side
            if ok and math.isfinite(T_co) and math.isfinite(T_out):
                g0 = G[0, 3]
                b = _dev(g0, G[1, 3], G[2, 3]) + _dev(g0, G[3, 3], G[4, 3]) + _dev(g0, G[5, 3], G[6, 3])
                b += _dev(g0, G[7, 3], G[8, 3])
                b += _dev(g0, G[9, 3], G[10, 3])
                b += _dev(g0, G[15, 3], G[16, 3])
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
    constants, measurements: np.ndarray, u: np.ndarray, dt: float, noise_bounds: np.ndarray | None = None
) -> ResidualTrace:
    """Run all 19 modules over one engine's measurements (T, 19) with the applied fuel setting (T,)."""
    Y = np.ascontiguousarray(measurements, dtype=np.float64)
    U = np.ascontiguousarray(u, dtype=np.float64)
    db = np.array(NOISE_BOUNDS if noise_bounds is None else noise_bounds, dtype=np.float64)
    T = Y.shape[0]
    R = np.zeros((T, len(MODULE_IDS)))
    THR = np.zeros((T, len(MODULE_IDS)))
    st = new_state(1, constants.n_nom_rev_s)[0]
    compute_residuals(constants, Y, U, float(dt), db, SIDE_COLS, T_OUT_COL, R, THR, st)
    return ResidualTrace(R, THR)


@jit
def _batch_range(c, Y, U, dt, dbar, side_cols, t_out_col, R, THR, ST, i0, i1):
    for i in range(i0, i1):
        compute_residuals(c, Y[i], U[i], dt, dbar, side_cols, t_out_col, R[i], THR[i], ST[i])


def compute_residuals_batch(c, Y, U, dt, dbar, side_cols, t_out_col, R, THR, ST):
    """:func:`compute_residuals` for N engines: Y (N, B, 19), U (N, B), R/THR (N, B, 19), ST (N, 2, N_STATE).

    Batches of at least ``THREADED_MIN_ENGINES`` engines run on the simulator's two worker
    threads (the compiled loop releases the GIL) as ``THREAD_CHUNKS`` contiguous chunks, so that a
    thread slowed down by other load does not hold up the other; engines are independent, so the
    results equal the single-thread loop bit for bit.
    """
    n = Y.shape[0]
    args = (c, Y, U, float(dt), dbar, side_cols, t_out_col, R, THR, ST)
    if n < THREADED_MIN_ENGINES:
        _batch_range(*args, 0, n)
        return
    edges = np.linspace(0, n, THREAD_CHUNKS + 1).astype(np.int64)
    list(thread_pool().map(lambda r: _batch_range(*args, r[0], r[1]), list(zip(edges[:-1], edges[1:]))))


THREAD_CHUNKS = 8
