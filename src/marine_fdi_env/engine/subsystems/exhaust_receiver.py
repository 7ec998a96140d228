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

import math

from ..._jit import jit
from .air_intake import bsr_factor

__all__ = [
    "scavenge_flow_function",
    "slip_ratio",
    "turbine_mass_flow",
    "receiver_forcing",
    "turbine_expansion",
    "turbine_outlet_temperature",
    "receiver_and_turbine",
    "turbine_efficiency",
    "turbine_outlet_from_expansion",
]


@jit
def scavenge_flow_function(ratio: float, c) -> float:
    """Ψ_sc of the pressure ratio x3/x4 (eq. 3.19), clipped to [critical ratio, 1]."""
    r = min(max(ratio, c.r_crit), 1.0)
    r_1k = math.exp(math.log(r) / c.kappa_g)  # r^(1/κ): r^(2/κ) - r^((κ+1)/κ) = r^(1/κ) (r^(1/κ) - r)
    return c.psi_coeff * math.sqrt(max(r_1k * (r_1k - r), 0.0))


@jit
def slip_ratio(x3: float, x4: float, m1: float, n: float, c) -> float:
    """s_sl = s_nom (n_nom/n)(m1_nom/m1)(x4/p1_nom)(Ψ/Ψ_nom) (eq. 3.18)."""
    return c.slip_coeff * x4 * scavenge_flow_function(x3 / x4, c) / (n * m1)


@jit
def turbine_mass_flow(x1: float, m1: float, s_sl: float, n: float, c) -> float:
    """ṁ_g = ((1 + s_sl) m1 + x1) n i_e/k_e [kg/s]: scavenge air plus fuel (eq. 3.16 corrected)."""
    return ((1.0 + s_sl) * m1 + x1) * n * c.cycles_per_rev


@jit
def receiver_forcing(mdot: float, T_in: float, c) -> float:
    """h3 = sqrt(p_ex² + R_g z1 ṁ² / (α_z A_eff)²) / τ_pd [Pa/s] (eq. 3.16)."""
    return math.sqrt(c.p_ex_Pa * c.p_ex_Pa + c.gamma_coeff * mdot * mdot * T_in) / c.tau_pd_s


@jit
def turbine_expansion(x3: float, c) -> float:
    """Π_turbo = (p_ex / x3)^((κg-1)/κg) (eq. 3.25)."""
    return math.exp(c.pi_exp * math.log(c.p_ex_Pa / x3)) if x3 > 0.0 else math.inf


@jit
def turbine_efficiency(T_in: float, Pi: float, x4: float, c) -> float:
    """η_turbo(x4) = a + b x4 + c x4² (eq. 3.26), or with the ``turbocharger_map`` submodel the map's η_TC / (η_c
    η_com); times the ``turbine_efficiency_bsr`` factor when that submodel is on."""
    if c.tm_on != 0.0:
        dx = x4 / c.p1_nom_Pa - 1.0
        eta_t = c.tm_s * c.tm_eta0 * (1.0 - c.tm_w * dx * dx) * (c.a_turbo / c.c_eta)
    else:
        eta_t = c.a_turbo + c.b_turbo_per_Pa * x4 + c.c_turbo_per_Pa2 * x4 * x4
    if c.bsr_on != 0.0:
        eta_t = eta_t * bsr_factor(x4, T_in, Pi, c)
    return eta_t


@jit
def turbine_outlet_from_expansion(T_in: float, Pi: float, x4: float, c) -> float:
    """z2 = ψ4 z1 = z1 (1 - η_turbo(x4) (1 - Π_turbo)) [K] (eq. 3.24, 3.26)."""
    return T_in * (1.0 - turbine_efficiency(T_in, Pi, x4, c) * (1.0 - Pi))


@jit
def turbine_outlet_temperature(T_in: float, x3: float, x4: float, c) -> float:
    """z2 = ψ4 z1 = z1 (1 - η_turbo(x4) (1 - Π_turbo(x3))) [K] (eq. 3.24-3.26)."""
    return turbine_outlet_from_expansion(T_in, turbine_expansion(x3, c), x4, c)


@jit
def receiver_and_turbine(x1, x3, x4, m1, s_sl, n, T6, p6, T_sl, c, turbine_share=1.0) -> tuple:
    """Algebraic part of Σ3 and the forcing h3 (eq. 3.16, 3.20-3.26, corrected as documented above).

    T_sl is the slip-air temperature including the lubrication-loss fault f_z,Tsl [K]; turbine_share the
    share of the cylinders' gas flow that passes the turbine, 1 - φ_rec (the receiver leak term of
    :mod:`marine_fdi_env.engine.fault_registry`; 1 when healthy).

    Returns
    -------
    (h3 [Pa/s], T_in = z1 [K], T_out = z2 [K], Π_turbo, ṁ_g [kg/s])
    """
    mdot = turbine_mass_flow(x1, m1, s_sl, n, c) * turbine_share
    psi2 = c.c_p_a_J_per_kgK * s_sl * m1
    psi3 = c.c_p_g_J_per_kgK * (x1 + m1)
    inv = 1.0 / (psi2 + psi3)
    # z1 = alpha + beta P with P = τ_pd h3 = sqrt(p_ex² + gamma z1): a quadratic in P
    alpha = (psi2 * T_sl + psi3 * T6 / c.n_bld) * inv
    beta = psi3 * T6 * (c.n_bld - 1.0) / (c.n_bld * p6) * inv
    gamma = c.gamma_coeff * mdot * mdot
    gb = gamma * beta
    P = 0.5 * (gb + math.sqrt(gb * gb + 4.0 * (c.p_ex_Pa * c.p_ex_Pa + gamma * alpha)))
    T_in = alpha + beta * P
    Pi = turbine_expansion(x3, c)
    return P / c.tau_pd_s, T_in, turbine_outlet_from_expansion(T_in, Pi, x4, c), Pi, mdot
