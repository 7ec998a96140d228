"""Σ3, exhaust receiver and turbocharger turbine (eq. 3.15-3.26).

State x3: exhaust receiver pressure p_d [Pa],
``x3' = -(1 + φ_tur) x3 / τ_pd + h3`` with the turbine flow law (eq. 3.16)
``τ_pd h3 = sqrt(p_ex² + R_g z1 ṁ_g² / (α_z A_eff)²)``.
Algebraic variables: z1 = turbine inlet temperature, z2 = turbine outlet temperature.

Corrections and decisions (see also docs/model.md):

* **Turbine mass flow (eq. 3.16).**  The thesis writes the flow as ``ψ1 x4 n / z1^(4) + x1 n i_e/k_e``
  with ``ψ1 = i_e V1 s_sl / (R_a k_e)``, i.e. slip air plus fuel only.  All the scavenge air
  passes the turbine, so the flow is ``ṁ_g = ((1 + s_sl) m1 + x1) n i_e / k_e``, the same
  ``(1 + s_sl) m1`` that eq. 3.32 uses for the air mass per cycle.
* **Mixing temperature (eq. 3.20-3.23).**  The extracted eq. 3.20 fuses two rows; the paper
  version (its eq. 22) shows the energy balance of slip air at T_sl and exhaust gas after
  Zinner blowdown: ``z1 = (ψ2 T_sl + ψ̃3 T6) / (ψ2 + ψ3)`` with ``ψ2 = c_p,a s_sl m1``,
  ``ψ3 = c_p,g (x1 + m1)`` and ``ψ̃3 = (1/n_bld + (n_bld - 1) τ_pd h3 / (n_bld p6)) ψ3``.  Since
  h3 depends on z1 and z1 on h3, the pair is solved in closed form (a quadratic in τ_pd h3).
* **Turbine outlet (eq. 3.24).**  ``z2 = ψ4 z1`` (second row of the paper's eq. 22).
* **Turbine seal leak f_x,tur.**  Table 2.2 calls it a pressure *drop*; eq. 3.15 adds it with a
  plus sign while table 6.4 gives a positive rate.  We subtract it:
  ``x3' = -x3/τ_pd - f_x,tur/τ_pd + h3`` with ``f_x,tur = φ_tur x3`` (table 3.2).
* **Scavenge flow function (eq. 3.19).**  Evaluated at the pressure ratio x3/x4 clipped to
  [critical ratio, 1]: choked flow above the critical ratio, no slip when the receiver pressure
  exceeds the charge pressure (no back-flow through the cylinder).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..params import EngineParams

__all__ = [
    "ExhaustConstants",
    "exhaust_constants",
    "scavenge_flow_function",
    "slip_ratio",
    "receiver_and_turbine",
    "ReceiverResult",
]


@dataclass(frozen=True)
class ExhaustConstants:
    r_crit: float  # critical pressure ratio of the flow function
    psi_coeff: float  # sqrt(2κ/(κ-1))
    exp_a: float  # 2/κ
    exp_b: float  # (κ+1)/κ
    pi_exp: float  # (κg-1)/κg
    gamma_coeff: float  # R_g / (α_z A_eff)²
    slip_coeff: float  # s_nom n_nom m1_nom / (p1_nom Ψ_nom)
    cycles_per_rev: float  # i_e / k_e


def exhaust_constants(p: EngineParams) -> ExhaustConstants:
    kg = p.kappa_g
    return ExhaustConstants(
        r_crit=(2.0 / (kg + 1.0)) ** (kg / (kg - 1.0)),
        psi_coeff=float(np.sqrt(2.0 * kg / (kg - 1.0))),
        exp_a=2.0 / kg,
        exp_b=(kg + 1.0) / kg,
        pi_exp=(kg - 1.0) / kg,
        gamma_coeff=p.R_g_J_per_kgK / (p.alpha_z * p.A_eff_m2) ** 2,
        slip_coeff=p.s_sl_nom * p.n_nom_rev_s * p.m1_nom_kg / (p.p1_nom_Pa * p.Psi_sc_nom),
        cycles_per_rev=p.n_cylinders / p.revs_per_cycle,
    )


def scavenge_flow_function(ratio: np.ndarray, k: ExhaustConstants) -> np.ndarray:
    """Ψ_sc of the pressure ratio x3/x4 (eq. 3.19), clipped to [critical ratio, 1]."""
    r = np.clip(ratio, k.r_crit, 1.0)
    lr = np.log(r)
    return k.psi_coeff * np.sqrt(np.maximum(np.exp(k.exp_a * lr) - np.exp(k.exp_b * lr), 0.0))


def slip_ratio(x3, x4, m1, n, k: ExhaustConstants):
    """s_sl = s_nom (n_nom/n)(m1_nom/m1)(x4/p1_nom)(Ψ/Ψ_nom) (eq. 3.18)."""
    return k.slip_coeff * x4 * scavenge_flow_function(x3 / x4, k) / (n * m1)


@dataclass
class ReceiverResult:
    h3: np.ndarray  # forcing of eq. 3.15 [Pa/s]
    T_in: np.ndarray  # z1^(3) [K]
    T_out: np.ndarray  # z2^(3) [K]
    Pi_turbo: np.ndarray  # (p_ex/x3)^((κg-1)/κg) (eq. 3.25)
    eta_turbo: np.ndarray  # turbine isentropic efficiency (eq. 3.26)
    mdot_g: np.ndarray  # turbine mass flow [kg/s]


def receiver_and_turbine(
    x1, x3, x4, m1, s_sl, n, T6, p6, T_sl, p: EngineParams, k: ExhaustConstants
) -> ReceiverResult:
    """Algebraic part of Σ3 and the forcing h3 (eq. 3.16, 3.20-3.26, corrected as documented above).

    T_sl is the slip-air temperature including the lubrication-loss fault f_z,Tsl [K].
    """
    mdot = ((1.0 + s_sl) * m1 + x1) * n * k.cycles_per_rev
    psi2 = p.c_p_a_J_per_kgK * s_sl * m1
    psi3 = p.c_p_g_J_per_kgK * (x1 + m1)
    inv = 1.0 / (psi2 + psi3)
    # z1 = alpha + beta P with P = τ_pd h3 = sqrt(p_ex² + gamma z1)
    alpha = (psi2 * T_sl + psi3 * T6 / p.n_bld) * inv
    beta = psi3 * T6 * (p.n_bld - 1.0) / (p.n_bld * p6) * inv
    gamma = k.gamma_coeff * mdot * mdot
    gb = gamma * beta
    P = 0.5 * (gb + np.sqrt(gb * gb + 4.0 * (p.p_ex_Pa**2 + gamma * alpha)))
    T_in = alpha + beta * P
    Pi = np.exp(k.pi_exp * np.log(p.p_ex_Pa / x3))
    eta_t = p.a_turbo + p.b_turbo_per_Pa * x4 + p.c_turbo_per_Pa2 * x4 * x4
    T_out = T_in * (1.0 - eta_t * (1.0 - Pi))
    return ReceiverResult(h3=P / p.tau_pd_s, T_in=T_in, T_out=T_out, Pi_turbo=Pi, eta_turbo=eta_t, mdot_g=mdot)
