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

Every module's inputs that are not finite (a sensor that dropped out) violate its ARR; an
observer then holds its last estimate.
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import jit
from ..integrators import _etd_scalar
from ..sensors import NOISE_BOUNDS, SENSOR_IDS
from ..subsystems.air_intake import compressor_forcing, compressor_outlet_temperature, delta_f, inlet_air_temperature
from ..subsystems.engine_block import engine_block, torque_given_speed
from ..subsystems.exhaust_receiver import (
    receiver_and_turbine,
    receiver_forcing,
    slip_ratio,
    turbine_expansion,
    turbine_mass_flow,
    turbine_outlet_temperature,
)
from .modules import MODULE_IDS

__all__ = ["OBSERVER_GAINS", "compute_residuals", "compute_residuals_batch", "ResidualTrace", "SAFETY",
           "MODEL_MARGIN", "new_state", "N_STATE", "residuals_for_run"]

# Observer gains L [1/s] of table 6.1 for M(1,q), M(3,q), M(4,q).
OBSERVER_GAINS = (33.3833, 1.25, 0.3764)
SAFETY = 1.05
MODEL_MARGIN = 1e-6  # η̄ per step, relative to the state, and relative margin of algebraic ARRs
SPEED_SWEEPS = 4

# sensor columns
S = {sid: i for i, sid in enumerate(SENSOR_IDS)}
# per side (0: odd sensors, 1: even sensors): x1, p6, T6, torque, x3, T_in, x4, T1, T_co
_SIDE_COLS = np.array([
    [S["S1.1"], S["S2.1"], S["S2.3"], S["S2.5"], S["S3.1"], S["S3.3"], S["S4.1"], S["S4.3"], S["S4.5"]],
    [S["S1.2"], S["S2.2"], S["S2.4"], S["S2.6"], S["S3.2"], S["S3.4"], S["S4.2"], S["S4.4"], S["S4.6"]],
], dtype=np.int64)
_T_OUT_COL = S["S3.5"]
# module column of each module id (for output arrays)
_M = {m: i for i, m in enumerate(MODULE_IDS)}


@jit
def _cycle_table(c, x1, x4, T1, dx1, dx4, dT1, n_guess, tab):
    """Σ2 at the centre and at ±d̄ of x1, x4, T1: rows (n, p6, T6); returns nothing (fills tab 7x3)."""
    pts = ((0.0, 0.0, 0.0), (dx1, 0.0, 0.0), (-dx1, 0.0, 0.0), (0.0, dx4, 0.0), (0.0, -dx4, 0.0),
           (0.0, 0.0, dT1), (0.0, 0.0, -dT1))
    for p in range(7):
        a, b, d = pts[p]
        n, torque, p6, T6, p_max, m1 = engine_block(x1 + a, x4 + b, T1 + d, c.V1_m3, n_guess, c, SPEED_SWEEPS)
        tab[p, 0] = n
        tab[p, 1] = p6
        tab[p, 2] = T6


@jit
def _h3(c, x1, x3, x4, T1, T_in, n):
    m1 = x4 * c.V1_m3 / (c.R_a_J_per_kgK * T1)
    s_sl = slip_ratio(x3, x4, m1, n, c)
    return receiver_forcing(turbine_mass_flow(x1, m1, s_sl, n, c), T_in, c)


@jit
def _h4(c, x1, x3, x4, T1, T_in, n):
    m1 = x4 * c.V1_m3 / (c.R_a_J_per_kgK * T1)
    s_sl = slip_ratio(x3, x4, m1, n, c)
    return compressor_forcing(x4, delta_f(x1, m1, s_sl), T_in, turbine_expansion(x3, c), c)


@jit
def _t_in(c, x1, x3, x4, T1, p6, T6, n):
    m1 = x4 * c.V1_m3 / (c.R_a_J_per_kgK * T1)
    s_sl = slip_ratio(x3, x4, m1, n, c)
    return receiver_and_turbine(x1, x3, x4, m1, s_sl, n, T6, p6, c.T_sl_K, c)[1]


@jit
def _t_co(c, x1, x3, x4, T1, T_in, T_out, n):
    m1 = x4 * c.V1_m3 / (c.R_a_J_per_kgK * T1)
    s_sl = slip_ratio(x3, x4, m1, n, c)
    return compressor_outlet_temperature(delta_f(x1, m1, s_sl), T_in, T_out, 0.0, c)


@jit
def _dev(g0, gp, gm):
    return max(abs(gp - g0), abs(gm - g0))


@jit
def _forcing_and_bound(c, which, y, tab, db):
    """F (h3 or h4) on the measurements and its inclusion bound; y = (x1, x3, x4, T1, T_in)."""
    x1, x3, x4, T1, T_in = y[0], y[1], y[2], y[3], y[4]
    n0 = tab[0, 0]
    if which == 3:
        f0 = _h3(c, x1, x3, x4, T1, T_in, n0)
        b = _dev(f0, _h3(c, x1 + db[0], x3, x4, T1, T_in, tab[1, 0]), _h3(c, x1 - db[0], x3, x4, T1, T_in, tab[2, 0]))
        b += _dev(f0, _h3(c, x1, x3 + db[1], x4, T1, T_in, n0), _h3(c, x1, x3 - db[1], x4, T1, T_in, n0))
        b += _dev(f0, _h3(c, x1, x3, x4 + db[2], T1, T_in, tab[3, 0]), _h3(c, x1, x3, x4 - db[2], T1, T_in, tab[4, 0]))
        b += _dev(f0, _h3(c, x1, x3, x4, T1 + db[3], T_in, tab[5, 0]), _h3(c, x1, x3, x4, T1 - db[3], T_in, tab[6, 0]))
        b += _dev(f0, _h3(c, x1, x3, x4, T1, T_in + db[4], n0), _h3(c, x1, x3, x4, T1, T_in - db[4], n0))
    else:
        f0 = _h4(c, x1, x3, x4, T1, T_in, n0)
        b = _dev(f0, _h4(c, x1 + db[0], x3, x4, T1, T_in, tab[1, 0]), _h4(c, x1 - db[0], x3, x4, T1, T_in, tab[2, 0]))
        b += _dev(f0, _h4(c, x1, x3 + db[1], x4, T1, T_in, n0), _h4(c, x1, x3 - db[1], x4, T1, T_in, n0))
        b += _dev(f0, _h4(c, x1, x3, x4 + db[2], T1, T_in, tab[3, 0]), _h4(c, x1, x3, x4 - db[2], T1, T_in, tab[4, 0]))
        b += _dev(f0, _h4(c, x1, x3, x4, T1 + db[3], T_in, tab[5, 0]), _h4(c, x1, x3, x4, T1 - db[3], T_in, tab[6, 0]))
        b += _dev(f0, _h4(c, x1, x3, x4, T1, T_in + db[4], n0), _h4(c, x1, x3, x4, T1, T_in - db[4], n0))
    return f0, SAFETY * b


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
    E1, q1, r1 = _etd_scalar(-1.0 / c.tau_X_s, dt)
    E3, q3, r3 = _etd_scalar(-1.0 / c.tau_pd_s, dt)
    E4, q4, r4 = _etd_scalar(-1.0 / c.tau_TC_s, dt)
    Ld1, Ld3, Ld4 = -math.expm1(-L1 * dt), -math.expm1(-L3 * dt), -math.expm1(-L4 * dt)
    fuel_gain = c.x1_nom_kg / c.tau_X_s
    T1_model = inlet_air_temperature(0.0, c)
    tab = np.empty((2, 7, 3))
    yv = np.empty(5)
    db = np.empty(5)
    for kk in range(T):
        y = Y[kk]
        for side in range(2):
            st = ST[side]
            first = st[14] == 0.0
            cols = side_cols[side]
            cx1, cp6, cT6, ctq, cx3, cTin, cx4, cT1, cTco = (cols[0], cols[1], cols[2], cols[3], cols[4], cols[5],
                                                               cols[6], cols[7], cols[8])
            x1, p6m, T6m, tqm, x3, T_in, x4, T1, T_co = (y[cx1], y[cp6], y[cT6], y[ctq], y[cx3], y[cTin], y[cx4],
                                                         y[cT1], y[cTco])
            base_ok = math.isfinite(x1) and math.isfinite(x4) and math.isfinite(T1)
            if base_ok:
                _cycle_table(c, x1, x4, T1, dbar[cx1], dbar[cx4], dbar[cT1], st[12], tab[side])
                if math.isfinite(tab[side, 0, 0]):
                    st[12] = tab[side, 0, 0]
            t = tab[side]
            n0 = t[0, 0]
            # ---------------------------------------------------------------- M1.q (fuel observer)
            m = 0 + side
            if first:
                st[0] = x1
                st[1] = dbar[cx1]
                R[kk, m] = 0.0 if math.isfinite(x1) else math.inf
            else:
                # prior from the exact model step with the known input (u linear within the step)
                F0 = fuel_gain * st[13]
                F1 = fuel_gain * U[kk]
                prior = E1 * st[0] + q1 * F0 + r1 * (F1 - F0)
                eta = r1 * abs(F1 - F0) + MODEL_MARGIN * abs(prior)
                st[1] = E1 * ((1.0 - Ld1) * st[1] + Ld1 * dbar[cx1]) + eta
                if math.isfinite(x1):
                    R[kk, m] = x1 - prior
                    st[0] = prior + Ld1 * (x1 - prior)
                else:
                    R[kk, m] = math.inf
                    st[0] = prior
            THR[kk, m] = st[1] + dbar[cx1]
            # ---------------------------------------------------------------- M2.(1,2): p6, M2.(3,4): T6
            for j in range(2):
                m = 2 + 2 * j + side
                col = cp6 if j == 0 else cT6
                if base_ok and math.isfinite(y[col]):
                    g0 = t[0, 1 + j]
                    b = _dev(g0, t[1, 1 + j], t[2, 1 + j]) + _dev(g0, t[3, 1 + j], t[4, 1 + j]) + \
                        _dev(g0, t[5, 1 + j], t[6, 1 + j])
                    R[kk, m] = y[col] - g0
                    THR[kk, m] = dbar[col] + SAFETY * b + MODEL_MARGIN * abs(g0)
                else:
                    R[kk, m] = math.inf
                    THR[kk, m] = dbar[col]
            # ---------------------------------------------------------------- M2.(5,6): torque
            m = 6 + side
            if base_ok and math.isfinite(tqm) and math.isfinite(T6m) and tqm > 0.0:
                n_t = math.sqrt(c.two_pi_over_c * tqm)
                g0 = torque_given_speed(x1, x4, T1, T6m, n_t, c)
                r0 = tqm - g0
                b = 0.0
                dq = dbar[ctq]
                n_p = math.sqrt(c.two_pi_over_c * (tqm + dq))
                n_m = math.sqrt(c.two_pi_over_c * max(tqm - dq, 0.0))
                b += _dev(r0, (tqm + dq) - torque_given_speed(x1, x4, T1, T6m, n_p, c),
                          (tqm - dq) - torque_given_speed(x1, x4, T1, T6m, n_m, c))
                b += _dev(r0, tqm - torque_given_speed(x1, x4, T1, T6m + dbar[cT6], n_t, c),
                          tqm - torque_given_speed(x1, x4, T1, T6m - dbar[cT6], n_t, c))
                b += _dev(r0, tqm - torque_given_speed(x1 + dbar[cx1], x4, T1, T6m, n_t, c),
                          tqm - torque_given_speed(x1 - dbar[cx1], x4, T1, T6m, n_t, c))
                b += _dev(r0, tqm - torque_given_speed(x1, x4 + dbar[cx4], T1, T6m, n_t, c),
                          tqm - torque_given_speed(x1, x4 - dbar[cx4], T1, T6m, n_t, c))
                b += _dev(r0, tqm - torque_given_speed(x1, x4, T1 + dbar[cT1], T6m, n_t, c),
                          tqm - torque_given_speed(x1, x4, T1 - dbar[cT1], T6m, n_t, c))
                R[kk, m] = r0
                THR[kk, m] = SAFETY * b + MODEL_MARGIN * abs(g0)
            else:
                R[kk, m] = math.inf
                THR[kk, m] = dbar[ctq]
            # ---------------------------------------------------------------- M3.q (receiver observer)
            yv[0], yv[1], yv[2], yv[3], yv[4] = x1, x3, x4, T1, T_in
            db[0], db[1], db[2], db[3], db[4] = dbar[cx1], dbar[cx3], dbar[cx4], dbar[cT1], dbar[cTin]
            m = 8 + side
            ok = base_ok and math.isfinite(x3) and math.isfinite(T_in)
            F, H = _forcing_and_bound(c, 3, yv, t, db) if ok else (0.0, 0.0)
            R[kk, m], THR[kk, m] = _observer_update(st, 2, first, ok, x3, F, H, E3, q3, r3, Ld3, dbar[cx3])
            # ---------------------------------------------------------------- M3.(3,4): T_in
            m = 10 + side
            if base_ok and math.isfinite(x3) and math.isfinite(p6m) and math.isfinite(T6m) and math.isfinite(T_in):
                g0 = _t_in(c, x1, x3, x4, T1, p6m, T6m, n0)
                b = _dev(g0, _t_in(c, x1 + db[0], x3, x4, T1, p6m, T6m, t[1, 0]),
                         _t_in(c, x1 - db[0], x3, x4, T1, p6m, T6m, t[2, 0]))
                b += _dev(g0, _t_in(c, x1, x3 + db[1], x4, T1, p6m, T6m, n0), _t_in(c, x1, x3 - db[1], x4, T1, p6m, T6m, n0))
                b += _dev(g0, _t_in(c, x1, x3, x4 + db[2], T1, p6m, T6m, t[3, 0]),
                          _t_in(c, x1, x3, x4 - db[2], T1, p6m, T6m, t[4, 0]))
                b += _dev(g0, _t_in(c, x1, x3, x4, T1 + db[3], p6m, T6m, t[5, 0]),
                          _t_in(c, x1, x3, x4, T1 - db[3], p6m, T6m, t[6, 0]))
                b += _dev(g0, _t_in(c, x1, x3, x4, T1, p6m + dbar[cp6], T6m, n0),
                          _t_in(c, x1, x3, x4, T1, p6m - dbar[cp6], T6m, n0))
                b += _dev(g0, _t_in(c, x1, x3, x4, T1, p6m, T6m + dbar[cT6], n0),
                          _t_in(c, x1, x3, x4, T1, p6m, T6m - dbar[cT6], n0))
                R[kk, m] = T_in - g0
                THR[kk, m] = dbar[cTin] + SAFETY * b + MODEL_MARGIN * abs(g0)
            else:
                R[kk, m] = math.inf
                THR[kk, m] = dbar[cTin]
            # ---------------------------------------------------------------- M4.q (charge observer)
            m = 13 + side
            ok = base_ok and math.isfinite(x3) and math.isfinite(T_in)
            F, H = _forcing_and_bound(c, 4, yv, t, db) if ok else (0.0, 0.0)
            R[kk, m], THR[kk, m] = _observer_update(st, 7, first, ok, x4, F, H, E4, q4, r4, Ld4, dbar[cx4])
            # ---------------------------------------------------------------- M4.(3,4): T1
            m = 15 + side
            R[kk, m] = T1 - T1_model if math.isfinite(T1) else math.inf
            THR[kk, m] = dbar[cT1] + MODEL_MARGIN * T1_model
            # ---------------------------------------------------------------- M4.(5,6): compressor outlet
            m = 17 + side
            T_out = y[t_out_col]
            if ok and math.isfinite(T_co) and math.isfinite(T_out):
                g0 = _t_co(c, x1, x3, x4, T1, T_in, T_out, n0)
                b = _dev(g0, _t_co(c, x1 + db[0], x3, x4, T1, T_in, T_out, t[1, 0]),
                         _t_co(c, x1 - db[0], x3, x4, T1, T_in, T_out, t[2, 0]))
                b += _dev(g0, _t_co(c, x1, x3 + db[1], x4, T1, T_in, T_out, n0),
                          _t_co(c, x1, x3 - db[1], x4, T1, T_in, T_out, n0))
                b += _dev(g0, _t_co(c, x1, x3, x4 + db[2], T1, T_in, T_out, t[3, 0]),
                          _t_co(c, x1, x3, x4 - db[2], T1, T_in, T_out, t[4, 0]))
                b += _dev(g0, _t_co(c, x1, x3, x4, T1 + db[3], T_in, T_out, t[5, 0]),
                          _t_co(c, x1, x3, x4, T1 - db[3], T_in, T_out, t[6, 0]))
                b += _dev(g0, _t_co(c, x1, x3, x4, T1, T_in + db[4], T_out, n0),
                          _t_co(c, x1, x3, x4, T1, T_in - db[4], T_out, n0))
                b += _dev(g0, _t_co(c, x1, x3, x4, T1, T_in, T_out + dbar[t_out_col], n0),
                          _t_co(c, x1, x3, x4, T1, T_in, T_out - dbar[t_out_col], n0))
                R[kk, m] = T_co - g0
                THR[kk, m] = dbar[cTco] + SAFETY * b + MODEL_MARGIN * abs(g0)
            else:
                R[kk, m] = math.inf
                THR[kk, m] = dbar[cTco]
            st[13] = U[kk]
            st[14] += 1.0
        # ---------------------------------------------------------------- M3.5: turbine outlet
        m = 12
        x3e, Tine, x4e, T_out = y[side_cols[1, 4]], y[side_cols[1, 5]], y[side_cols[1, 6]], y[t_out_col]
        if math.isfinite(x3e) and math.isfinite(Tine) and math.isfinite(x4e) and math.isfinite(T_out):
            g0 = turbine_outlet_temperature(Tine, x3e, x4e, c)
            b = _dev(g0, turbine_outlet_temperature(Tine + dbar[side_cols[1, 5]], x3e, x4e, c),
                     turbine_outlet_temperature(Tine - dbar[side_cols[1, 5]], x3e, x4e, c))
            b += _dev(g0, turbine_outlet_temperature(Tine, x3e + dbar[side_cols[1, 4]], x4e, c),
                      turbine_outlet_temperature(Tine, x3e - dbar[side_cols[1, 4]], x4e, c))
            b += _dev(g0, turbine_outlet_temperature(Tine, x3e, x4e + dbar[side_cols[1, 6]], c),
                      turbine_outlet_temperature(Tine, x3e, x4e - dbar[side_cols[1, 6]], c))
            R[kk, m] = T_out - g0
            THR[kk, m] = dbar[t_out_col] + SAFETY * b + MODEL_MARGIN * abs(g0)
        else:
            R[kk, m] = math.inf
            THR[kk, m] = dbar[t_out_col]


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


def residuals_for_run(constants, measurements: np.ndarray, u: np.ndarray, dt: float,
                      noise_bounds: np.ndarray | None = None) -> ResidualTrace:
    """Run all 19 modules over one engine's measurements (T, 19) with the applied fuel setting (T,)."""
    Y = np.ascontiguousarray(measurements, dtype=np.float64)
    U = np.ascontiguousarray(u, dtype=np.float64)
    db = np.array(NOISE_BOUNDS if noise_bounds is None else noise_bounds, dtype=np.float64)
    T = Y.shape[0]
    R = np.zeros((T, len(MODULE_IDS)))
    THR = np.zeros((T, len(MODULE_IDS)))
    st = new_state(1, constants.n_nom_rev_s)[0]
    compute_residuals(constants, Y, U, float(dt), db, _SIDE_COLS, _T_OUT_COL, R, THR, st)
    return ResidualTrace(R, THR)


@jit
def compute_residuals_batch(c, Y, U, dt, dbar, side_cols, t_out_col, R, THR, ST):
    """:func:`compute_residuals` for N engines: Y (N, B, 19), U (N, B), R/THR (N, B, 19), ST (N, 2, N_STATE)."""
    for i in range(Y.shape[0]):
        compute_residuals(c, Y[i], U[i], dt, dbar, side_cols, t_out_col, R[i], THR[i], ST[i])
