"""Σ2, the engine block: cylinder pressure, cylinder temperature and shaft torque (eq. 3.7-3.13).

The algebraic variables are z1 = p6 (cylinder pressure at exhaust opening, Seiliger point 6),
z2 = T6 (cylinder temperature at exhaust opening) and z3 = shaft torque.  They follow from the
Seiliger cycle (:mod:`marine_fdi_env.engine.seiliger`) fed with the trapped charge (p1 = x4, T1 = z1^(4),
V1 + f_V1) and the fuel x1.

Engine speed closes an algebraic loop: the fixed-pitch propeller law ``P = c n^3`` gives
``n = sqrt(2π z3 / c)`` (eq. 3.11) while z3 depends on n through X_cv(n) (eq. 3.12) and the
friction torque ``Q_loss(n)`` (eq. 3.10).  The fixed-point map ``n <- sqrt(2π z3(n)/c)`` is a
contraction with factor 0.06-0.12 over the operating range (the propeller torque grows with n²
while the engine torque depends on n only through X_cv and the friction).  Two sweeps from the
warm start (the previous sample's speed), one Aitken Δ² extrapolation (which makes the
convergence quadratic) and a last sweep give the speed to about machine precision.

Decisions where the thesis is silent or garbled:

* The torque is the net indicated work of the cycle times cylinders per revolution,
  ``z3 = m1 w i_e / (2π k_e) - Q_loss`` (eq. 3.10 rebuilt; the closed form is garbled).
* ``X_cv`` is clipped to [0, 1 - X_ct] so that no heat fraction turns negative at extreme speeds.

Submodels (:mod:`marine_fdi_env.engine.submodels`): ``friction`` adds ``Δfmep = a + d (n/n_nom)^2`` to the
friction torque; ``speed_law`` (combinator) replaces the propeller law in the speed loop by
``n = n_nom (s0 + (s1 - s0) P/P_nom)`` with ``P = 2π n z3``, i.e. the fixed point
``n <- n_nom s0 / (1 - 2π n_nom (s1 - s0) z3 / P_nom)``.  With both off the code is the base model's.
"""

from __future__ import annotations

import math

from ..._jit import jit
from ..seiliger import seiliger_cycle

__all__ = [
    "constant_volume_portion",
    "friction_torque",
    "engine_block",
    "torque_given_speed",
    "torque_cycle",
    "torque_from_cycle",
    "speed_of_torque",
    "engine_block_at_speed",
    "speed_sweep",
]


@jit
def constant_volume_portion(n: float, X_ct: float, c) -> float:
    """X_cv = X_cv_nom + X_cv_grad (n - n_nom)/n_nom (eq. 3.12), clipped to [0, 1 - X_ct]."""
    X_cv = c.X_cv_nom + (c.X_cv_grad / c.n_nom_rev_s) * (n - c.n_nom_rev_s)
    return min(max(X_cv, 0.0), 1.0 - X_ct)


@jit
def friction_torque(n: float, c) -> float:
    """Q_loss = Q_loss_nom (1 + Q_loss_grad (n_nom - n)/n_nom) [N m] (eq. 3.10), plus the ``friction``
    submodel's ``V_d i_e/(2π k_e) (a + d (n/n_nom)^2)`` when it is on."""
    q = c.Q_loss_nom_Nm * (1.0 + c.Q_loss_grad * (c.n_nom_rev_s - n) / c.n_nom_rev_s)
    if c.fr_on != 0.0:
        nr = n / c.n_nom_rev_s
        q = q + c.fr_torque_per_Pa * (c.fr_a_Pa + c.fr_d_Pa * nr * nr)
    return q


@jit
def speed_of_torque(torque: float, c) -> float:
    """Engine speed of the load law at brake torque z3 [rev/s]: the propeller law n = sqrt(2π z3/c)
    (eq. 3.11), or the combinator line of the ``speed_law`` submodel."""
    if c.sl_comb != 0.0:
        den = 1.0 - 2.0 * math.pi * c.n_nom_rev_s * (c.sl_s1 - c.sl_s0) * max(torque, 0.0) / c.P_nom_W
        return c.n_nom_rev_s * c.sl_s0 / max(den, 1e-3)
    return math.sqrt(c.two_pi_over_c * max(torque, 0.0))


@jit
def speed_sweep(n, x4, T1, q, m1, X_ct, c):
    """One fixed-point sweep n <- sqrt(2π z3(n)/c) of the speed loop; returns (n_new, torque, cycle)."""
    X_cv = constant_volume_portion(n, X_ct, c)
    cyc = seiliger_cycle(x4, T1, q, X_cv, X_ct, c)
    torque = m1 * cyc[6] * c.torque_per_work - friction_torque(n, c)
    return speed_of_torque(torque, c), torque, cyc


@jit
def engine_block_at_speed(x1: float, x4: float, T1: float, V1: float, n: float, c) -> tuple:
    """Σ2 at a given engine speed n [rev/s] (no load law): (torque [N m], p6, T6, p_max [Pa], m1 [kg]).

    The same cycle and friction as one sweep of :func:`engine_block`; the steady-state solver of
    :mod:`marine_fdi_env.engine.operating_point` uses it with the speed as an unknown or prescribed.
    """
    m1 = x4 * V1 / (c.R_a_J_per_kgK * T1)
    q = (c.eta_comb * c.h_L_J_per_kg) * x1 / m1
    X_ct = c.X_ct_nom * x1 / c.x1_nom_kg
    X_cv = constant_volume_portion(n, X_ct, c)
    cyc = seiliger_cycle(x4, T1, q, X_cv, X_ct, c)
    torque = m1 * cyc[6] * c.torque_per_work - friction_torque(n, c)
    return torque, cyc[5], cyc[3], cyc[4], m1


@jit
def engine_block(x1: float, x4: float, T1: float, V1: float, n_guess: float, c, sweeps: int) -> tuple:
    """Solve Σ2 with the propeller law for the speed (eq. 3.7-3.13).

    Parameters
    ----------
    x1 : fuel per cylinder and cycle [kg].  x4 : charge-air pressure p1 [Pa].
    T1 : inlet air temperature z1^(4) [K].  V1 : cylinder volume at point 1 incl. bore damage [m³].
    n_guess : warm start for the speed [rev/s].
    sweeps : 1 or 2 = that many plain sweeps; 3 = two sweeps, Aitken extrapolation, one sweep;
        each further unit repeats the sweep-sweep-extrapolate block (the steady-state solver
        uses more).

    Returns
    -------
    (n [rev/s], torque z3 [N m], p6 = z1 [Pa], T6 = z2 [K], p_max [Pa], m1 [kg])
    """
    m1 = x4 * V1 / (c.R_a_J_per_kgK * T1)
    q = (c.eta_comb * c.h_L_J_per_kg) * x1 / m1
    X_ct = c.X_ct_nom * x1 / c.x1_nom_kg  # eq. 3.13
    n0 = n_guess
    if sweeps < 3:  # plain sweeps only (predictor stages, where the warm start is close)
        n, torque, cyc = speed_sweep(n0, x4, T1, q, m1, X_ct, c)
        for _ in range(sweeps - 1):
            n, torque, cyc = speed_sweep(n, x4, T1, q, m1, X_ct, c)
        return n, torque, cyc[5], cyc[3], cyc[4], m1
    for _ in range(sweeps - 2):
        n1, torque, cyc = speed_sweep(n0, x4, T1, q, m1, X_ct, c)
        n2, torque, cyc = speed_sweep(n1, x4, T1, q, m1, X_ct, c)
        den = (n2 - n1) - (n1 - n0)
        # Aitken Δ² extrapolation; where the sweeps have already converged keep n2
        n0 = n2 - (n2 - n1) ** 2 / den if den != 0.0 else n2
    n, torque, cyc = speed_sweep(n0, x4, T1, q, m1, X_ct, c)
    return n, torque, cyc[5], cyc[3], cyc[4], m1


@jit
def torque_given_speed(x1: float, x4: float, T1: float, T6: float, n: float, c) -> float:
    """Shaft torque z3 [N m] at a known speed n and exhaust-opening temperature T6 (eq. 3.10).

    Eq. 3.10 writes the expansion work with ξ_z2 = T6, so a monitoring module can use the
    measured cylinder temperature there; with the cycle's own T6 this equals the torque of
    :func:`engine_block` at speed n.
    """
    return torque_from_cycle(torque_cycle(x1, x4, T1, n, c), T6, c)


@jit
def torque_cycle(x1, x4, T1, n, c):
    """The T6-independent part of :func:`torque_given_speed`: (m1, w without the T6 term, T4, Q_loss), so that
    torques at several T6 (a monitoring module's perturbations of the measured T6) reuse one Seiliger cycle."""
    m1 = x4 * c.V1_m3 / (c.R_a_J_per_kgK * T1)
    q = (c.eta_comb * c.h_L_J_per_kg) * x1 / m1
    X_ct = c.X_ct_nom * x1 / c.x1_nom_kg
    X_cv = constant_volume_portion(n, X_ct, c)
    T2, T3, T4, _, _, _, _ = seiliger_cycle(x4, T1, q, X_cv, X_ct, c)
    R = c.R_a_J_per_kgK
    w0 = -c.c_v_a_J_per_kgK * (T2 - T1) + R * (T4 - T3) + X_ct * q
    return m1, w0, T4, friction_torque(n, c)


@jit
def torque_from_cycle(parts, T6, c):
    """The shaft torque [N m] of :func:`torque_cycle`'s parts at the exhaust-opening temperature T6 (eq. 3.10)."""
    m1, w0, T4, q_loss = parts
    w = w0 + c.R_a_J_per_kgK * (T4 - T6) / (c.n_exp - 1.0)
    return m1 * w * c.torque_per_work - q_loss
