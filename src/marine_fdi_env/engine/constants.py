"""Model constants: every parameter of :class:`EngineParams` plus derived constants, as a flat
named tuple that compiled code can take as one argument.

Derived constants (computed once per parameter set):

r_c, r_eo                    effective compression ratio and exhaust-open ratio (eq. B.1-B.8)
rc_pow_kappa, rc_pow_kappa_m1  r_c^κa, r_c^(κa-1) (the compression exponent: κa, or n_comp of the
                             ``cylinder_heat_loss`` submodel)
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

Submodel constants (:mod:`marine_fdi_env.engine.submodels`; ``*_on`` = 1.0 when the submodel is on, else 0.0 and the
values are inert).  ``sm_on`` is 1.0 when any submodel acting on the gas path (Σ3, Σ4) is on: the
compiled model then runs the extended gas path, else the base code path, bit for bit.  Schedules are
knot arrays (``wg_u``/``wg_a``, ``bp_u``/``bp_b``).

Compiled kernels take :data:`KernelConstants` (:func:`kernel_constants`): the same values without the
knot arrays, so that no call between compiled functions reference-counts them.
"""

from __future__ import annotations

import math
from collections import namedtuple
from dataclasses import fields
from functools import lru_cache

import numpy as np

from .geometry import cylinder_geometry
from .params import EngineParams

__all__ = [
    "ModelConstants",
    "model_constants",
    "constants_at_ambient",
    "AMBIENT_FIELDS",
    "DERIVED_FIELDS",
    "SUBMODEL_FIELDS",
    "KernelConstants",
    "kernel_constants",
]

_PARAM_FIELDS = tuple(f.name for f in fields(EngineParams) if f.name not in ("name", "submodels"))
DERIVED_FIELDS = (
    "r_c",
    "r_eo",
    "rc_pow_kappa",
    "rc_pow_kappa_m1",
    "ln_rc_reo",
    "two_pi_over_c",
    "torque_per_work",
    "r_crit",
    "psi_coeff",
    "psi_exp_a",
    "psi_exp_b",
    "pi_exp",
    "gamma_coeff",
    "slip_coeff",
    "cycles_per_rev",
    "chi_g",
    "comp_exp",
)
SUBMODEL_FIELDS = (
    "sm_on",
    "sl_comb",
    "sl_s0",
    "sl_s1",
    "fr_on",
    "fr_a_Pa",
    "fr_d_Pa",
    "fr_torque_per_Pa",
    "tm_on",
    "tm_eta0",
    "tm_s",
    "tm_w",
    "ic_on",
    "ic_eps",
    "ic_dT",
    "ic_tco_nom",
    "eta_c",
    "wg_on",
    "wg_u",
    "wg_a",
    "bp_on",
    "bp_junction_turbine",
    "bp_u",
    "bp_b",
    "tf_on",
    "tf_s",
    "tf_e",
    "bsr_on",
    "bsr_ropt",
    "bsr_w",
    "bsr_norm",
    "bsr_ref",
    "hl_on",
    "hl_ntu_nom",
    "hl_e",
    "hl_mdot_nom",
)
ModelConstants = namedtuple("ModelConstants", _PARAM_FIELDS + DERIVED_FIELDS + SUBMODEL_FIELDS)


def _knots(schedule) -> tuple[np.ndarray, np.ndarray]:
    if schedule is None:
        return np.array([1.0]), np.array([0.0])
    return np.array(schedule.u, dtype=np.float64), np.array(schedule.value, dtype=np.float64)


def _tco_isentropic(p: EngineParams, eta_c: float, x4: float) -> float:
    """Compressor outlet temperature of isentropic compression at η_c to x4 [K]."""
    pi = max(x4 / p.p_amb_Pa, 1.0)
    return p.T_amb_K * (1.0 + (pi ** ((p.kappa_a - 1.0) / p.kappa_a) - 1.0) / eta_c)


def _submodel_constants(p: EngineParams, g) -> dict:
    """Flat values of the submodels of ``p`` (see the module docstring)."""
    sm = p.submodels
    eta_c = p.c_eta / (p.a_turbo * p.eta_com)  # compressor isentropic efficiency of the calibration
    eta0 = p.a_eta_per_Pa2 * p.p1_nom_Pa**2 + p.b_eta_per_Pa * p.p1_nom_Pa + p.c_eta  # eq. 3.33 at p1_nom
    out = {k: 0.0 for k in SUBMODEL_FIELDS}
    out["eta_c"] = eta_c
    out["tm_eta0"] = eta0
    out["wg_u"], out["wg_a"] = _knots(None)
    out["bp_u"], out["bp_b"] = _knots(None)
    out["tf_s"], out["tf_e"] = 1.0, 2.0
    out["ic_eps"], out["tm_s"], out["bsr_ropt"], out["bsr_norm"] = 1.0, 1.0, 1.0, 1.0
    if sm.speed_law is not None:
        out.update(sl_comb=1.0, sl_s0=sm.speed_law.speed_zero_load_rel, sl_s1=sm.speed_law.speed_full_load_rel)
    if sm.friction is not None:
        out.update(
            fr_on=1.0,
            fr_a_Pa=sm.friction.fmep_offset_Pa,
            fr_d_Pa=sm.friction.fmep_speed2_Pa,
            fr_torque_per_Pa=g.swept_volume_m3 * p.n_cylinders / (2.0 * math.pi * p.revs_per_cycle),
        )
    gas = False
    if sm.turbocharger_map is not None:
        gas = True
        out.update(tm_on=1.0, tm_s=sm.turbocharger_map.eta_scale, tm_w=sm.turbocharger_map.curvature)
    if sm.intercooler is not None:
        out.update(
            ic_on=1.0,
            ic_eps=sm.intercooler.effectiveness,
            ic_dT=sm.intercooler.dT_outlet_K,
            ic_tco_nom=_tco_isentropic(p, eta_c, p.p1_nom_Pa),
        )
    if sm.waste_gate is not None:
        gas = True
        out["wg_on"] = 1.0
        out["wg_u"], out["wg_a"] = _knots(sm.waste_gate.opening)
    if sm.bypass_valve is not None:
        gas = True
        out["bp_on"] = 1.0
        out["bp_junction_turbine"] = 1.0 if sm.bypass_valve.junction == "turbine" else 0.0
        out["bp_u"], out["bp_b"] = _knots(sm.bypass_valve.opening)
    if sm.turbine_flow_law is not None:
        gas = True
        out.update(tf_on=1.0, tf_s=sm.turbine_flow_law.area_scale, tf_e=sm.turbine_flow_law.exponent)
    if sm.turbine_efficiency_bsr is not None:
        gas = True
        b = sm.turbine_efficiency_bsr
        # blade-speed ratio squared relative to the nominal point: (Δh_c,is / Δh_t,is) / (δ_f η_TC)_nom, since the
        # turbocharger power balance gives Δh_c,is = δ_f η_TC Δh_t,is
        d_nom = 1.0 + p.x1_nom_kg / ((1.0 + p.s_sl_nom) * p.m1_nom_kg)
        out.update(
            bsr_on=1.0,
            bsr_ropt=b.bsr_opt_rel,
            bsr_w=b.curvature,
            bsr_norm=1.0 - b.curvature * (1.0 / b.bsr_opt_rel - 1.0) ** 2,
            bsr_ref=d_nom * eta0,
        )
    if sm.exhaust_heat_loss is not None:
        gas = True
        h = sm.exhaust_heat_loss
        mdot_nom = ((1.0 + p.s_sl_nom) * p.m1_nom_kg + p.x1_nom_kg) * p.n_nom_rev_s * p.n_cylinders / p.revs_per_cycle
        out.update(
            hl_on=1.0, hl_ntu_nom=-math.log(1.0 - h.loss_fraction_nom), hl_e=h.flow_exponent, hl_mdot_nom=mdot_nom
        )
    out["sm_on"] = 1.0 if gas else 0.0
    return out


_geometry = lru_cache(maxsize=64)(cylinder_geometry)


@lru_cache(maxsize=256)
def model_constants(p: EngineParams) -> ModelConstants:
    """Flatten a parameter set and add the derived and submodel constants."""
    g = _geometry(p.bore_m, p.stroke_m, p.crank_rod_m, p.eps_c, p.alpha_IC_deg, p.alpha_EO_deg)
    kg = p.kappa_g
    chl = p.submodels.cylinder_heat_loss
    k_comp = p.kappa_a if chl is None else chl.n_comp
    derived = {
        "r_c": g.r_c,
        "r_eo": g.r_eo,
        "rc_pow_kappa": g.r_c**k_comp,
        "rc_pow_kappa_m1": g.r_c ** (k_comp - 1.0),
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
    values = [float(getattr(p, k)) for k in _PARAM_FIELDS]
    if chl is not None:  # the expansion exponent of the cylinder_heat_loss submodel
        values[_PARAM_FIELDS.index("n_exp")] = float(p.n_exp + chl.dn_exp)
    sub = _submodel_constants(p, g)
    values += [float(derived[k]) for k in DERIVED_FIELDS]
    values += [sub[k] if isinstance(sub[k], np.ndarray) else float(sub[k]) for k in SUBMODEL_FIELDS]
    return ModelConstants(*values)


#: the parameters that set an engine's ambient state: a measured row's boundary conditions (validation)
AMBIENT_FIELDS = ("p_amb_Pa", "T_amb_K", "p_ex_Pa")


def constants_at_ambient(c: ModelConstants, p: EngineParams) -> ModelConstants:
    """``model_constants(p)`` from the constants ``c`` of an engine that differs from ``p`` in
    :data:`AMBIENT_FIELDS` only (a validation fit runs each measured row at its own ambient state, thousands of
    times: rebuilding every constant per row cost about a fifth of a protocol fit, ``benchmarks/validation.py``).
    The ambient fields are copied; of the derived constants only the intercooler's nominal compressor outlet
    temperature depends on them, and is recomputed.
    Equal to :func:`model_constants` field for field, bit for bit (tested for every submodel)."""
    ch = {k: float(getattr(p, k)) for k in AMBIENT_FIELDS}
    if c.ic_on != 0.0:
        ch["ic_tco_nom"] = _tco_isentropic(p, c.eta_c, p.p1_nom_Pa)
    return c._replace(**ch)


# The compiled code takes the model constants as a named tuple of floats.  ModelConstants also holds
# the valve schedules of the gas-path submodels as arrays, and a tuple holding arrays is reference
# counted at every compiled call that receives it (an atomic increment and decrement per array and
# call, which the compiler cannot remove): that was about 2/3 of the reference diagnoser's kernel time
# (measured, 5.3 -> 1.6 µs per engine-sample) and half of the simulator's (1.7 -> 0.8 µs, one thread,
# ``benchmarks/simulator_cpu.py``).  Only the gas-path submodels' functions read the schedules; they
# get the full constants as a separate argument ``csm``, None for a model without them, which removes
# that code at compile time.
_KNOT_FIELDS = ("wg_u", "wg_a", "bp_u", "bp_b")
KernelConstants = namedtuple("KernelConstants", [f for f in ModelConstants._fields if f not in _KNOT_FIELDS])
_KERNEL_CONSTANTS: dict = {}


def kernel_constants(c) -> tuple:
    """(kc, csm): the model constants ``c`` as the compiled kernels take them, ``kc`` the
    :data:`KernelConstants` (floats only) and ``csm`` ``c`` itself where a gas-path submodel is on
    (``c.sm_on``), else None; (c, c) for constants of another type.  Kept per object."""
    hit = _KERNEL_CONSTANTS.get(id(c))
    if hit is not None and hit[0] is c:
        return hit[1], hit[2]
    if type(c) is ModelConstants and all(isinstance(getattr(c, f), float) for f in KernelConstants._fields):
        kc = KernelConstants(*(getattr(c, f) for f in KernelConstants._fields))
        csm = c if c.sm_on != 0.0 else None
    else:
        kc, csm = c, c
    if len(_KERNEL_CONSTANTS) > 64:
        _KERNEL_CONSTANTS.clear()
    _KERNEL_CONSTANTS[id(c)] = (c, kc, csm)
    return kc, csm
