"""The six-point Seiliger cycle, rebuilt stage by stage from table B.1.

The closed forms of eq. 3.8-3.10 are garbled in the PDF extraction; this module evaluates the
cycle one process at a time instead (all quantities per kg of trapped charge):

====  =========================  =============================================================
1-2   isentropic compression     T2 = T1 r_c^(κa-1),  p2 = p1 r_c^κa
2-3   constant-volume heat       q23 = X_cv q = c_v (T3 - T2),  p3 = p2 T3/T2
3-4   constant-pressure heat     q34 = X_cp q = c_p (T4 - T3),  V4/V3 = T4/T3
4-5   constant-temperature heat  q45 = X_ct q = R T4 ln c,  V5/V4 = c,  p5 = p4 / c
5-6   polytropic expansion       V6 = r_eo V1,  T6 = T5 (V5/V6)^(n_exp-1),  p6 = p5 (V5/V6)^n_exp
====  =========================  =============================================================

with q = η h_L m_f / m_1 the heat released per kg of charge and X_cp = 1 - X_cv - X_ct.

Corrections of table B.1 (each follows from the ideal-gas law of the stage):

* 4-5: the table gives ``p5/p4 = c``; an isothermal expansion by the volume ratio c lowers the
  pressure, ``p5/p4 = 1/c``.
* 5-6: the table gives ``p6/p5 = (r_eo r_c / (b c))^n_exp``, i.e. the pressure *rising* in an
  expansion; the volume ratio must be inverted, ``p6/p5 = (V5/V6)^n_exp`` (same for T6/T5).
* Work: the table's w12 and w56 carry the sign of work done *on* the gas.  The net indicated
  work per kg used for the torque (eq. B.9, 3.10) is the work done *by* the gas:
  ``w = -c_v (T2 - T1) + R (T4 - T3) + R T4 ln c + R (T5 - T6) / (n_exp - 1)``.

The maximum cylinder pressure is p3 = p4 (end of the constant-volume stage).
"""

from __future__ import annotations

import math

from .._jit import jit

__all__ = ["seiliger_cycle"]


@jit
def seiliger_cycle(p1: float, T1: float, q: float, X_cv: float, X_ct: float, c) -> tuple:
    """Evaluate the Seiliger cycle point by point (table B.1, corrected; eq. B.9).

    Parameters
    ----------
    p1, T1 : pressure [Pa] and temperature [K] at inlet closure (point 1).
    q : heat released per kg of trapped charge [J/kg].
    X_cv, X_ct : fractions of q released at constant volume and constant temperature.
    c : :class:`~marine_fdi_env.engine.constants.ModelConstants`.

    Returns
    -------
    (T2, T3, T4, T6, p3, p6, w): temperatures [K], p3 = p_max and p6 [Pa], net work w [J/kg].
    """
    R = c.R_a_J_per_kgK
    T2 = T1 * c.rc_pow_kappa_m1
    T3 = T2 + X_cv * q / c.c_v_a_J_per_kgK
    T4 = T3 + (1.0 - X_cv - X_ct) * q / c.c_p_a_J_per_kgK
    ln_c = X_ct * q / (R * T4)
    # ln(V5/V6) = ln(V4/V3) + ln c - ln(r_c r_eo), with V4/V3 = T4/T3 and V3 = V1 / r_c
    ln_v = math.log(T4 / T3) + ln_c - c.ln_rc_reo
    ratio_n1 = math.exp((c.n_exp - 1.0) * ln_v)  # (V5/V6)^(n_exp-1)
    T6 = T4 * ratio_n1
    p3 = p1 * c.rc_pow_kappa * (T3 / T2)
    # p6 = p5 (V5/V6)^n_exp with p5 = p3/c and (V5/V6)/c = T4 / (T3 r_c r_eo): no second exponential
    p6 = p3 * ratio_n1 * T4 / (T3 * c.r_c * c.r_eo)
    w = -c.c_v_a_J_per_kgK * (T2 - T1) + R * (T4 - T3) + X_ct * q + R * (T4 - T6) / (c.n_exp - 1.0)
    return T2, T3, T4, T6, p3, p6, w
