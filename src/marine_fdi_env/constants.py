"""Model constants: every parameter of :class:`EngineParams` plus derived constants, as a flat
named tuple of floats that compiled code can take as one argument.

Derived constants (computed once per parameter set):

r_c, r_eo                    effective compression ratio and exhaust-open ratio (eq. B.1-B.8)
rc_pow_kappa, rc_pow_kappa_m1  r_c^κa, r_c^(κa-1)
ln_rc_reo                    ln(r_c r_eo)
two_pi_over_c                2π / c_load (eq. 3.11)
torque_per_work              i_e / (2π k_e) (eq. 3.10)
r_crit                       critical pressure ratio of the scavenge flow function (eq. 3.19)
psi_coeff, psi_exp_a, psi_exp_b  sqrt(2κg/(κg-1)), 2/κg, (κg+1)/κg (eq. 3.19)
pi_exp                       (κg-1)/κg (eq. 3.25)
gamma_coeff                  R_g / (α_z A_eff)² (eq. 3.16)
slip_coeff                   s_nom n_nom m1_nom / (p1_nom Ψ_nom) (eq. 3.18)
cycles_per_rev               i_e / k_e
chi_g                        c_p,g / c_p,a (eq. 3.35)
comp_exp                     κa / (κa - 1) (eq. 3.31 as corrected)
"""

from __future__ import annotations

import math
from collections import namedtuple
from dataclasses import fields
from functools import lru_cache

from .geometry import cylinder_geometry
from .params import EngineParams

__all__ = ["ModelConstants", "model_constants", "DERIVED_FIELDS"]

_PARAM_FIELDS = tuple(f.name for f in fields(EngineParams) if f.name != "name")
DERIVED_FIELDS = (
    "r_c", "r_eo", "rc_pow_kappa", "rc_pow_kappa_m1", "ln_rc_reo", "two_pi_over_c", "torque_per_work",
    "r_crit", "psi_coeff", "psi_exp_a", "psi_exp_b", "pi_exp", "gamma_coeff", "slip_coeff", "cycles_per_rev",
    "chi_g", "comp_exp",
)
ModelConstants = namedtuple("ModelConstants", _PARAM_FIELDS + DERIVED_FIELDS)


@lru_cache(maxsize=64)
def model_constants(p: EngineParams) -> ModelConstants:
    """Flatten a parameter set and add the derived constants (all as floats)."""
    g = cylinder_geometry(p.bore_m, p.stroke_m, p.crank_rod_m, p.eps_c, p.alpha_IC_deg, p.alpha_EO_deg)
    kg = p.kappa_g
    derived = {
        "r_c": g.r_c,
        "r_eo": g.r_eo,
        "rc_pow_kappa": g.r_c**p.kappa_a,
        "rc_pow_kappa_m1": g.r_c ** (p.kappa_a - 1.0),
        "ln_rc_reo": math.log(g.r_c * g.r_eo),
        "two_pi_over_c": 2.0 * math.pi / p.c_load_W_s3,
        "torque_per_work": p.n_cylinders / (2.0 * math.pi * p.revs_per_cycle),
        "r_crit": (2.0 / (kg + 1.0)) ** (kg / (kg - 1.0)),
        "psi_coeff": math.sqrt(2.0 * kg / (kg - 1.0)),
        "psi_exp_a": 2.0 / kg,
        "psi_exp_b": (kg + 1.0) / kg,
        "pi_exp": (kg - 1.0) / kg,
        "gamma_coeff": p.R_g_J_per_kgK / (p.alpha_z * p.A_eff_m2) ** 2,
        "slip_coeff": p.s_sl_nom * p.n_nom_rev_s * p.m1_nom_kg / (p.p1_nom_Pa * p.Psi_sc_nom),
        "cycles_per_rev": p.n_cylinders / p.revs_per_cycle,
        "chi_g": p.c_p_g_J_per_kgK / p.c_p_a_J_per_kgK,
        "comp_exp": p.kappa_a / (p.kappa_a - 1.0),
    }
    values = [float(getattr(p, k)) for k in _PARAM_FIELDS] + [float(derived[k]) for k in DERIVED_FIELDS]
    return ModelConstants(*values)
