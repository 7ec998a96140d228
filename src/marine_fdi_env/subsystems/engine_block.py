"""Σ2, the engine block: cylinder pressure, cylinder temperature and shaft torque (eq. 3.7-3.13).

The algebraic variables are z1 = p6 (cylinder pressure at exhaust opening, Seiliger point 6),
z2 = T6 (cylinder temperature at exhaust opening) and z3 = shaft torque.  They follow from the
Seiliger cycle (:mod:`marine_fdi_env.seiliger`) fed with the trapped charge (p1 = x4, T1 = z1^(4),
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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry import cylinder_geometry
from ..params import EngineParams
from ..seiliger import SeiligerConstants, SeiligerState, seiliger_cycle

__all__ = ["EngineBlockConstants", "engine_block_constants", "EngineBlockResult", "engine_block"]


@dataclass(frozen=True)
class EngineBlockConstants:
    seiliger: SeiligerConstants
    two_pi_over_c: float  # 2π / c [1/(N m s^2)]
    torque_per_work: float  # i_e / (2π k_e) [1/rad]


def engine_block_constants(p: EngineParams) -> EngineBlockConstants:
    g = cylinder_geometry(p.bore_m, p.stroke_m, p.crank_rod_m, p.eps_c, p.alpha_IC_deg, p.alpha_EO_deg)
    k = SeiligerConstants(
        r_c=g.r_c,
        r_eo=g.r_eo,
        rc_pow_kappa=g.r_c**p.kappa_a,
        rc_pow_kappa_m1=g.r_c ** (p.kappa_a - 1.0),
        ln_rc_reo=float(np.log(g.r_c * g.r_eo)),
        c_v=p.c_v_a_J_per_kgK,
        c_p=p.c_p_a_J_per_kgK,
        R=p.R_a_J_per_kgK,
        n_exp=p.n_exp,
    )
    return EngineBlockConstants(
        seiliger=k,
        two_pi_over_c=2.0 * np.pi / p.c_load_W_s3,
        torque_per_work=p.n_cylinders / (2.0 * np.pi * p.revs_per_cycle),
    )


@dataclass
class EngineBlockResult:
    n: np.ndarray  # engine speed [rev/s]
    torque: np.ndarray  # z3 [N m]
    cycle: SeiligerState  # p6 = z1, T6 = z2, p3 = p_max
    m1: np.ndarray  # trapped air mass per cylinder and cycle [kg]
    X_cv: np.ndarray


def constant_volume_portion(n: np.ndarray, X_ct: np.ndarray, p: EngineParams) -> np.ndarray:
    """X_cv = X_cv_nom + X_cv_grad (n - n_nom)/n_nom (eq. 3.12), clipped to [0, 1 - X_ct]."""
    X_cv = p.X_cv_nom + (p.X_cv_grad / p.n_nom_rev_s) * (n - p.n_nom_rev_s)
    return np.minimum(np.maximum(X_cv, 0.0), 1.0 - X_ct)


def friction_torque(n: np.ndarray, p: EngineParams) -> np.ndarray:
    """Q_loss = Q_loss_nom (1 + Q_loss_grad (n_nom - n)/n_nom) [N m] (eq. 3.10)."""
    return p.Q_loss_nom_Nm * (1.0 + p.Q_loss_grad * (p.n_nom_rev_s - n) / p.n_nom_rev_s)


def engine_block(
    x1: np.ndarray,
    x4: np.ndarray,
    T1: np.ndarray,
    V1: np.ndarray,
    n_guess: np.ndarray,
    p: EngineParams,
    k: EngineBlockConstants,
    sweeps: int = 3,
) -> EngineBlockResult:
    """Solve Σ2 with the propeller law for the speed (eq. 3.7-3.13).

    Parameters
    ----------
    x1 : fuel per cylinder and cycle [kg].  x4 : charge-air pressure p1 [Pa].
    T1 : inlet air temperature z1^(4) [K].  V1 : cylinder volume at point 1 incl. bore damage [m³].
    n_guess : warm start for the speed [rev/s].
    sweeps : 1 or 2 = that many plain sweeps; 3 = two sweeps, Aitken extrapolation, one sweep;
        each further unit repeats the sweep-sweep-extrapolate block (the steady-state solver
        uses more).
    """
    m1 = x4 * V1 / (p.R_a_J_per_kgK * T1)
    q = (p.eta_comb * p.h_L_J_per_kg) * x1 / m1
    X_ct = p.X_ct_nom * x1 / p.x1_nom_kg  # eq. 3.13

    def sweep(n):
        X_cv = constant_volume_portion(n, X_ct, p)
        cyc = seiliger_cycle(x4, T1, q, X_cv, X_ct, k.seiliger)
        torque = m1 * cyc.w * k.torque_per_work - friction_torque(n, p)
        return np.sqrt(k.two_pi_over_c * np.maximum(torque, 0.0)), torque, cyc, X_cv

    n0 = n_guess
    if sweeps < 3:  # plain sweeps only (used for predictor stages, where the warm start is close)
        for _ in range(sweeps):
            n0, torque, cyc, X_cv = sweep(n0)
        return EngineBlockResult(n=n0, torque=torque, cycle=cyc, m1=m1, X_cv=X_cv)
    for _ in range(sweeps - 2):
        n1, torque, cyc, X_cv = sweep(n0)
        n2, torque, cyc, X_cv = sweep(n1)
        d1, d2 = n1 - n0, n2 - n1
        den = d2 - d1
        ok = np.abs(den) > 1e-300
        # Aitken Δ² extrapolation; where the sweeps have already converged keep n2
        n0 = np.where(ok, n2 - d2 * d2 / np.where(ok, den, 1.0), n2)
    n, torque, cyc, X_cv = sweep(n0)
    return EngineBlockResult(n=n, torque=torque, cycle=cyc, m1=m1, X_cv=X_cv)
