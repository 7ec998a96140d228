"""Σ3 and Σ4 with the gas-path submodels: waste gate, bypass valve, turbine flow law, turbine efficiency
vs blade-speed ratio, turbocharger map and exhaust heat loss (:mod:`marine_fdi_env.engine.submodels`).

The compiled model runs this path only when a gas-path submodel is on (``c.sm_on``); otherwise it
runs the base functions of :mod:`.exhaust_receiver` and :mod:`.air_intake` unchanged.  With every
submodel inert the equations below reduce to the base ones (tested to rounding).

Flows and temperatures (per engine, SI):

* ``ṁ_g = ((1 + s_sl) m1 + x1) n i_e/k_e``: what the cylinders discharge (exhaust and slip air), at
  ``T_cyl = (ψ2 T_sl + ψ̃3 T6)/(ψ2 + ψ3)`` (eq. 3.20-3.23 as corrected in :mod:`.exhaust_receiver`).
* Exhaust heat loss: ``T_hl = T_amb + (T_cyl - T_amb) exp(-NTU)``, ``NTU = NTU_nom (ṁ_g/ṁ_g,nom)^(-e)``.
* Bypass: ``ṁ_bp = α_z A_eff b(u) sqrt(2 x4/(R_a T_c) (x4 - x3))`` for x4 > x3 (charge air at the cooler
  outlet).  The turbine gets ``T_t = (c_p,g ṁ_g T_hl + c_p,a ṁ_bp T_c)/(c_p,g ṁ_g + c_p,a ṁ_bp)``; the
  turbine-inlet thermocouple reads T_t (junction ``receiver``) or T_hl (junction ``turbine``).
* Flow law (eq. 3.16 generalised): the receiver passes ``ṁ_t = ṁ_g + ṁ_bp`` through the turbine and the
  waste gate, area ``α_z A_eff s (1 + a(u))``:  ``ṁ_t² R_g T_t / (α_z A_eff s (1 + a))² = P² (1 - (p_ex/P)^e)``
  with ``P = τ_pd h3``.  As T_cyl (hence T_t) is affine in P through the blowdown term, e = 2 is a quadratic
  in P (the base's closed form); other e take a few Newton steps from it.
* Turbine (eq. 3.24-3.26): ``T_out = T_t (1 - η_turbo f (1 - Π))`` with ``Π = (p_ex/x3)^((κg-1)/κg)`` and
  ``f`` the blade-speed-ratio factor (1 without that submodel); ``η_turbo`` from eq. 3.26 or, with the
  map, ``η_TC,map/(η_c η_com)``.
* Compressor (eq. 3.31, 3.38 rebuilt): the turbine passes ``ṁ_t/(1 + a)``, the compressor delivers
  ``ṁ_c = (1 + s_sl) m1 n i_e/k_e + ṁ_bp``; with ``δ = ṁ_t / ((1 + a) ṁ_c)`` the power balance gives
  ``h4 = (p_amb/τ_TC)(1 + χ_g δ η_TC f (T_t/T_amb)(1 - Π))^(κa/(κa-1))`` and
  ``T_co = T_amb + η_com χ_g δ (T_t - T_out) + f_z,Tc``.
* After the waste-gate junction: ``T_exh = (T_out + a T_t)/(1 + a)`` (equal heat capacities).
"""

from __future__ import annotations

import math

from ..._jit import jit
from .air_intake import compressor_forcing
from .exhaust_receiver import turbine_expansion, turbine_mass_flow, turbine_outlet_from_expansion

__all__ = [
    "valve_opening",
    "valve_flows",
    "flow_law_pressure",
    "extended_gas_path",
    "N_GAS_OUT",
    "extended_gas_path_kernel",
]

N_GAS_OUT = 13


@jit
def valve_opening(u: float, ku, kv) -> float:
    """Piecewise-linear schedule through the knots (ku, kv), constant outside them."""
    k = ku.shape[0]
    if u <= ku[0]:
        return kv[0]
    if u >= ku[k - 1]:
        return kv[k - 1]
    for j in range(1, k):
        if u <= ku[j]:
            t = (u - ku[j - 1]) / (ku[j] - ku[j - 1])
            return kv[j - 1] + t * (kv[j] - kv[j - 1])
    return kv[k - 1]


@jit
def flow_law_pressure(gam: float, A0: float, A1: float, c) -> float:
    """P with ``P² (1 - (p_ex/P)^e) = gam (A0 + A1 P)``: closed form for e = 2, Newton steps otherwise."""
    pe = c.p_ex_Pa
    gb = gam * A1
    P = 0.5 * (gb + math.sqrt(gb * gb + 4.0 * (pe * pe + gam * A0)))
    if c.tf_on == 0.0 or c.tf_e == 2.0:
        return P
    e = c.tf_e
    pee = math.exp(e * math.log(pe))
    for _ in range(30):
        p2e = math.exp((2.0 - e) * math.log(P))
        f = P * P - pee * p2e - gam * (A0 + A1 * P)
        df = 2.0 * P - (2.0 - e) * pee * p2e / P - gam * A1
        step = f / df
        Pn = P - step
        if Pn <= pe:
            Pn = 0.5 * (P + pe)
        if abs(Pn - P) <= 1e-14 * P:
            return Pn
        P = Pn
    return P


@jit
def valve_flows(x1, x3, x4, m1, s_sl, n, T_c, c, ov_wg, ov_bp) -> tuple:
    """(ṁ_g [kg/s], ṁ_bp [kg/s], waste-gate opening a [-], cylinder air ṁ_air [kg/s]): the cylinders'
    discharge, the bypass air and the waste-gate opening at the measured fuel setting u = x1/x1_nom
    (ov_wg, ov_bp: openings overriding the schedules, NaN: the schedules)."""
    return _valve_flows(x1, x3, x4, m1, s_sl, n, T_c, c, c, ov_wg, ov_bp)


@jit
def _valve_flows(x1, x3, x4, m1, s_sl, n, T_c, c, csm, ov_wg, ov_bp) -> tuple:
    """:func:`valve_flows` with the constants split as the compiled kernels take them (``c`` floats
    only, ``csm`` the full constants with the valve schedules; see
    :func:`~marine_fdi_env.engine.constants.kernel_constants`)."""
    u = x1 / c.x1_nom_kg
    mdot_g = turbine_mass_flow(x1, m1, s_sl, n, c)
    m_air = (1.0 + s_sl) * m1 * (n * c.cycles_per_rev)
    a_wg = 0.0
    if c.wg_on != 0.0:
        a_wg = valve_opening(u, csm.wg_u, csm.wg_a) if math.isnan(ov_wg) else ov_wg
    mdot_bp = 0.0
    if c.bp_on != 0.0 and x4 > x3:
        b = valve_opening(u, csm.bp_u, csm.bp_b) if math.isnan(ov_bp) else ov_bp
        rho = x4 / (c.R_a_J_per_kgK * T_c)
        mdot_bp = c.alpha_z * c.A_eff_m2 * b * math.sqrt(2.0 * rho * (x4 - x3))
    return mdot_g, mdot_bp, a_wg, m_air


@jit
def extended_gas_path(x1, x3, x4, m1, s_sl, n, T6, p6, T_sl, T_c, dT_c, c, ov_wg, ov_bp, turbine_share=1.0) -> tuple:
    """Algebraic part of Σ3 and Σ4 with the gas-path submodels (module docstring).

    m1 : trapped mass of the gas exchange [kg]; T_sl : slip-air temperature incl. f_z,Tsl [K];
    T_c : cooler outlet temperature [K]; dT_c : intercooler-blockage fault f_z,Tc [K].
    ov_wg, ov_bp : waste-gate and bypass openings that override the schedules (NaN: use the schedules;
    the steady-state solver sets one opening per measured point while a fit looks for them).
    turbine_share : share of the cylinders' gas flow that reaches the turbine, 1 - φ_rec (receiver leak term).

    Returns
    -------
    (h3 [Pa/s], T_in (turbine-inlet thermocouple) [K], T_out [K], Π_turbo, ṁ_exh (to the exhaust system)
    [kg/s], h4 [Pa/s], T_co [K], T_cyl [K], T_t (turbine gas inlet) [K], ṁ_bp [kg/s], waste-gate flow
    fraction [-], ṁ_c (compressor air) [kg/s], T_exh (after the waste-gate junction) [K])
    """
    return extended_gas_path_kernel(x1, x3, x4, m1, s_sl, n, T6, p6, T_sl, T_c, dT_c, c, c, ov_wg, ov_bp, turbine_share)


@jit
def extended_gas_path_kernel(
    x1, x3, x4, m1, s_sl, n, T6, p6, T_sl, T_c, dT_c, c, csm, ov_wg, ov_bp, turbine_share
) -> tuple:
    """:func:`extended_gas_path` with the constants split as the compiled kernels take them (``c``
    floats only, ``csm`` the full constants with the valve schedules; see
    :func:`~marine_fdi_env.engine.constants.kernel_constants`): the same numbers."""
    mdot_g, mdot_bp, a_wg, m_air = _valve_flows(x1, x3, x4, m1, s_sl, n, T_c, c, csm, ov_wg, ov_bp)
    mdot_gt = mdot_g * turbine_share  # the cylinders' gas that reaches the turbine (receiver leak term)
    # receiver mixing of exhaust and slip air: T_cyl = alpha + beta P (blowdown term, eq. 3.20-3.23)
    psi2 = c.c_p_a_J_per_kgK * s_sl * m1
    psi3 = c.c_p_g_J_per_kgK * (x1 + m1)
    inv = 1.0 / (psi2 + psi3)
    alpha = (psi2 * T_sl + psi3 * T6 / c.n_bld) * inv
    beta = psi3 * T6 * (c.n_bld - 1.0) / (c.n_bld * p6) * inv
    E = 1.0
    if c.hl_on != 0.0:
        E = math.exp(-c.hl_ntu_nom * math.exp(-c.hl_e * math.log(max(mdot_g, 1e-9) / c.hl_mdot_nom)))
    cg = c.c_p_g_J_per_kgK * mdot_gt
    ca = c.c_p_a_J_per_kgK * mdot_bp
    wg = cg / (cg + ca)
    # turbine gas temperature T_t = A0 + A1 P
    A0 = wg * ((1.0 - E) * c.T_amb_K + E * alpha) + (1.0 - wg) * T_c
    A1 = wg * E * beta
    mdot_t = mdot_gt + mdot_bp
    area = c.tf_s * (1.0 + a_wg)
    gam = c.gamma_coeff * mdot_t * mdot_t / (area * area)
    P = flow_law_pressure(gam, A0, A1, c)
    T_cyl = alpha + beta * P
    T_hl = (1.0 - E) * c.T_amb_K + E * T_cyl
    T_t = A0 + A1 * P
    T_in = T_hl if c.bp_junction_turbine != 0.0 else T_t
    Pi = turbine_expansion(x3, c)
    T_out = turbine_outlet_from_expansion(T_t, Pi, x4, c)
    m_c = m_air + mdot_bp
    d_f = mdot_t / ((1.0 + a_wg) * m_c)
    h4 = compressor_forcing(x4, d_f, T_t, Pi, c)
    T_co = c.T_amb_K + c.eta_com * c.chi_g * d_f * (T_t - T_out) + dT_c
    T_exh = (T_out + a_wg * T_t) / (1.0 + a_wg)
    return (P / c.tau_pd_s, T_in, T_out, Pi, mdot_t, h4, T_co, T_cyl, T_t, mdot_bp, a_wg / (1.0 + a_wg), m_c, T_exh)
