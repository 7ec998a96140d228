"""Σ4, air intake, compressor and intercooler (eq. 3.28-3.38).

State x4: charge-air pressure p1 [Pa],
``x4' = -(1 + φ_int) x4 / τ_TC + h4`` with the turbocharger power balance (eq. 3.31).
Algebraic variables: z1 = inlet air temperature T1 at the cylinders, z2 = compressor outlet
temperature.

Corrections and decisions (see also docs/model.md):

* **Exponent of eq. 3.31.**  The compressor pressure ratio from the turbocharger power balance
  ``ṁ_a c_p,a T_amb (π^((κa-1)/κa) - 1) = η_TC ṁ_g c_p,g z1^(3) (1 - Π_turbo)`` is
  ``π = (1 + χ_g δ_f η_TC r_TC (1 - Π_turbo))^(κa/(κa-1))``; the extracted text has the inverse
  exponent (κa-1)/κa, which would make the charge pressure almost independent of load.
* **Eq. 3.33.**  With table 4.1's coefficients the polynomial only gives a plausible overall
  turbocharger efficiency (0.69 at 4.1 bar, maximum 0.70 at 3.8 bar) when read as
  ``η_TC = a x4² + b x4 + c`` with ``b = +2.52e-6`` (the table's sign of b is lost in the PDF).
* **Eq. 3.37.**  The inlet duct *heats* the charge air: ``z1 = T_c + ε_inl (T_inl + f - T_c)``.
* **Eq. 3.38** (garbled) is rebuilt from the same power balance: the compressor temperature rise
  equals the turbine temperature drop scaled by the mass-flow and heat-capacity ratios and the
  mechanical efficiency, ``z2 = T_amb + η_com χ_g δ_f (z1^(3) - z2^(3)) + f_z,Tc``.  With the
  turbine efficiency η_turbo = η_TC / (η_c η_com) (see calibration) this is exactly isentropic
  compression with a constant compressor efficiency η_c.
* **Compressor seal leak f_x,int** is a pressure drop (table 2.2); like f_x,tur it is subtracted.
* **Intercooler blockage f_z,Tc** enters z2 (compressor outlet temperature) as in eq. 3.38 and
  table 3.1, so that the thesis's fault signatures stay comparable.
"""

from __future__ import annotations

import math

from ..._jit import jit

__all__ = [
    "inlet_air_temperature",
    "delta_f",
    "eta_tc",
    "compressor_forcing",
    "compressor_outlet_temperature",
    "air_excess_ratio",
    "cooler_outlet_temperature",
    "inlet_air_temperature_at",
    "bsr_factor",
]


@jit
def inlet_air_temperature(dT_inl: float, c) -> float:
    """z1^(4) = T_c + ε_inl (T_inl + f_z,Tinl - T_c) [K] (eq. 3.37, sign corrected)."""
    return c.T_c_K + c.eps_inl * (c.T_inl_K + dT_inl - c.T_c_K)


@jit
def cooler_outlet_temperature(x4: float, c) -> float:
    """Charge-air cooler outlet T_c [K]: the constant of eq. 3.37, or with the ``intercooler`` submodel
    ``T_c,nom + dT_outlet + (1 - ε)(T_co,is(x4) - T_co,is(p1_nom))`` (isentropic compressor outlet at η_c)."""
    if c.ic_on == 0.0:
        return c.T_c_K
    pi = max(x4 / c.p_amb_Pa, 1.0)
    tco = c.T_amb_K * (1.0 + (math.exp(math.log(pi) / c.comp_exp) - 1.0) / c.eta_c)
    return c.T_c_K + c.ic_dT + (1.0 - c.ic_eps) * (tco - c.ic_tco_nom)


@jit
def inlet_air_temperature_at(dT_inl: float, x4: float, c) -> float:
    """z1^(4) of eq. 3.37 with the cooler outlet of :func:`cooler_outlet_temperature` (equal to
    :func:`inlet_air_temperature` when the ``intercooler`` submodel is off)."""
    if c.ic_on == 0.0:
        return inlet_air_temperature(dT_inl, c)
    T_c = cooler_outlet_temperature(x4, c)
    return T_c + c.eps_inl * (c.T_inl_K + dT_inl - T_c)


@jit
def delta_f(x1: float, m1: float, s_sl: float) -> float:
    """Exhaust-to-air mass ratio δ_f = 1 + x1 / ((1 + s_sl) m1) (eq. 3.32)."""
    return 1.0 + x1 / ((1.0 + s_sl) * m1)


@jit
def eta_tc(x4: float, c) -> float:
    """Overall turbocharger efficiency η_TC = a x4² + b x4 + c (eq. 3.33 as corrected), or the
    ``turbocharger_map`` submodel's ``s η_TC(p1_nom) (1 - w (x4/p1_nom - 1)²)``."""
    if c.tm_on != 0.0:
        dx = x4 / c.p1_nom_Pa - 1.0
        return c.tm_s * c.tm_eta0 * (1.0 - c.tm_w * dx * dx)
    return c.a_eta_per_Pa2 * x4 * x4 + c.b_eta_per_Pa * x4 + c.c_eta


@jit
def compressor_forcing(x4: float, d_f: float, T_in: float, Pi_turbo: float, c) -> float:
    """Forcing h4 of eq. 3.31 [Pa/s] (exponent κa/(κa-1), see module docstring); d_f = δ_f, T_in the gas
    entering the turbine.  With the ``turbine_efficiency_bsr`` submodel η_TC carries its factor."""
    eta = eta_tc(x4, c)
    if c.bsr_on != 0.0:
        eta = eta * bsr_factor(x4, T_in, Pi_turbo, c)
    base = 1.0 + c.chi_g * d_f * eta * (T_in / c.T_amb_K) * (1.0 - Pi_turbo)
    return (c.p_amb_Pa / c.tau_TC_s) * math.exp(c.comp_exp * math.log(max(base, 1e-12)))


@jit
def bsr_factor(x4: float, T_t: float, Pi: float, c) -> float:
    """Efficiency factor of the ``turbine_efficiency_bsr`` submodel (1 when off).

    ``r² = (Δh_c,is(x4) / Δh_t,is) / (δ η_TC)_nom`` is the squared blade-speed ratio relative to the
    nominal point (tip speed from a constant isentropic head coefficient, spouting velocity from the
    turbine's isentropic enthalpy drop); the factor is ``(1 - w (r/r_opt - 1)²) / (1 - w (1/r_opt - 1)²)``.
    """
    if c.bsr_on == 0.0:
        return 1.0
    pi_c = max(x4 / c.p_amb_Pa, 1.0)
    dh_c = c.c_p_a_J_per_kgK * c.T_amb_K * (math.exp(math.log(pi_c) / c.comp_exp) - 1.0)
    dh_t = c.c_p_g_J_per_kgK * T_t * max(1.0 - Pi, 1e-9)
    r = math.sqrt(max(dh_c / dh_t, 0.0) / c.bsr_ref)
    d = r / c.bsr_ropt - 1.0
    return max(1.0 - c.bsr_w * d * d, 0.05) / c.bsr_norm


@jit
def compressor_outlet_temperature(d_f: float, T_in: float, T_out: float, dT_c: float, c) -> float:
    """z2^(4) = T_amb + η_com χ_g δ_f (z1^(3) - z2^(3)) + f_z,Tc [K] (eq. 3.38 rebuilt)."""
    return c.T_amb_K + c.eta_com * c.chi_g * d_f * (T_in - T_out) + dT_c


@jit
def air_excess_ratio(m1: float, x1: float, c) -> float:
    """λ = m1 / (x1 σ_f) (eq. 3.28-3.29)."""
    return m1 / (x1 * c.sigma_f)
