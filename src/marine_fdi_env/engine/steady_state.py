"""Steady-state solver: the equilibrium of the DAE for a given fuel setting, found directly.

At equilibrium ``x1 = x1_nom f_u u`` (eq. 3.4) and the pressures solve
``(1 + φ_tur) x3 = τ_pd h3(x)`` and ``(1 + φ_int) x4 = τ_TC h4(x)``; a vectorised Newton method
with a finite-difference 2x2 Jacobian per engine solves the pair to machine precision.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .model import HEALTHY, Algebraic, EngineModel, ProcessFaultValues
from .params import EngineParams
from .turbocharger_speed import turbocharger_speed_rpm

__all__ = ["SteadyState", "steady_state", "FUEL_SETTING_RANGE", "check_fuel_setting"]

FUEL_SETTING_RANGE = (0.0, 1.2)


def check_fuel_setting(u, field_name: str = "fuel_setting") -> np.ndarray:
    """Validate fuel settings: finite and within [0, 1.2]; raise ``ValueError`` naming the field."""
    lo, hi = FUEL_SETTING_RANGE
    try:
        arr = np.asarray(u, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{field_name} must be a number in [{lo}, {hi}], got {u!r}") from None
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{field_name} must be finite and lie in [{lo}, {hi}] (1.0 = nominal), got {u!r}")
    if np.any(arr < lo) or np.any(arr > hi):
        raise ValueError(f"{field_name} must lie in [{lo}, {hi}] (1.0 = nominal), got {u!r}")
    return arr


@dataclass
class SteadyState:
    """Equilibrium states and algebraic variables (arrays over engines)."""

    u: np.ndarray
    x1: np.ndarray
    x3: np.ndarray
    x4: np.ndarray
    alg: Algebraic
    converged: np.ndarray

    def summary(self, params: EngineParams, index: int = 0) -> dict[str, float]:
        """The operating point as a flat dict of SI quantities (keys end in their unit)."""
        a = self.alg
        i = index
        n = float(a.n[i])
        power = float(a.power()[i])
        fuel_flow = float(self.x1[i]) * n * params.n_cylinders / params.revs_per_cycle
        air_flow = float((1.0 + a.s_sl[i]) * a.m1[i]) * n * params.n_cylinders / params.revs_per_cycle
        air_flow += float(a.mdot_bp[i])  # the compressor's air: the cylinders' and the bypass (0 in the base model)
        return {
            "fuel_setting": float(self.u[i]),
            "engine_speed_rev_s": n,
            "power_W": power,
            "torque_Nm": float(a.torque[i]),
            "fuel_per_cycle_kg": float(self.x1[i]),
            "fuel_mass_flow_kg_s": fuel_flow,
            "sfc_kg_per_J": fuel_flow / power if power > 0 else float("inf"),
            "charge_air_pressure_Pa": float(self.x4[i]),
            "exhaust_receiver_pressure_Pa": float(self.x3[i]),
            "p_max_Pa": float(a.p_max[i]),
            "cylinder_pressure_eo_Pa": float(a.p6[i]),
            "cylinder_temperature_eo_K": float(a.T6[i]),
            "turbine_inlet_temperature_K": float(a.T_in[i]),
            "turbine_outlet_temperature_K": float(a.T_out[i]),
            "compressor_outlet_temperature_K": float(a.T_co[i]),
            "inlet_air_temperature_K": float(a.T1[i]),
            "air_mass_flow_kg_s": air_flow,
            "exhaust_mass_flow_kg_s": float(a.mdot_g[i]),
            "air_excess_ratio": float(a.lam[i]),
            "slip_ratio": float(a.s_sl[i]),
            "charge_air_cooler_outlet_temperature_K": float(a.T_c[i]),
            "cylinder_outlet_temperature_K": float(a.T_cyl[i]),
            "turbine_gas_inlet_temperature_K": float(a.T_t[i]),
            "exhaust_after_waste_gate_temperature_K": float(a.T_exh[i]),
            "bypass_air_flow_kg_s": float(a.mdot_bp[i]),
            "bypass_fraction": float(a.mdot_bp[i] / a.mdot_c[i]) if a.mdot_c[i] > 0 else 0.0,
            "waste_gate_fraction": float(a.wg_frac[i]),
            "turbocharger_speed_rpm": float(turbocharger_speed_rpm(params, float(self.x4[i]))),
        }


def steady_state(
    model: EngineModel,
    u,
    pf: ProcessFaultValues = HEALTHY,
    tol: float = 1e-13,
    max_iter: int = 60,
) -> SteadyState:
    """Equilibrium of the engine at fuel setting(s) ``u`` (scalar or array over engines)."""
    p = model.params
    u = np.atleast_1d(check_fuel_setting(u)).astype(float)
    x1 = p.x1_nom_kg * np.asarray(pf.f_u, dtype=float) * u
    x1 = np.broadcast_to(x1, u.shape).copy()
    phi_t = np.asarray(pf.phi_tur, dtype=float)
    phi_i = np.asarray(pf.phi_int, dtype=float)
    # initial guess from the nominal ratios, scaled with load
    load = np.clip(u, 0.05, None)
    x4 = p.p_amb_Pa + (p.p1_nom_Pa - p.p_amb_Pa) * load**1.5
    x3 = p.p_ex_Pa + 0.7 * (x4 - p.p_amb_Pa)
    n = p.n_nom_rev_s * np.cbrt(load)
    sweeps_save = model.speed_sweeps
    model.speed_sweeps = 5
    try:

        def residual(x3_, x4_, n_):
            alg = model.algebraic(x1, x3_, x4_, pf, n_)
            r3 = (1.0 + phi_t) * x3_ - p.tau_pd_s * alg.h3
            r4 = (1.0 + phi_i) * x4_ - p.tau_TC_s * alg.h4
            return r3, r4, alg

        converged = np.zeros(u.shape, dtype=bool)
        for _ in range(max_iter):
            r3, r4, alg = residual(x3, x4, n)
            n = np.where(converged, n, alg.n)
            d3 = 1e-7 * x3
            d4 = 1e-7 * x4
            r3a, r4a, _ = residual(x3 + d3, x4, n)
            r3b, r4b, _ = residual(x3, x4 + d4, n)
            j11, j21 = (r3a - r3) / d3, (r4a - r4) / d3
            j12, j22 = (r3b - r3) / d4, (r4b - r4) / d4
            det = j11 * j22 - j12 * j21
            s3 = (r3 * j22 - r4 * j12) / det
            s4 = (j11 * r4 - j21 * r3) / det
            # damped step that keeps pressures physical
            s3 = np.clip(s3, -0.5 * (x3 - p.p_ex_Pa), 0.5 * x3)
            s4 = np.clip(s4, -0.5 * (x4 - 0.2 * p.p_amb_Pa), 0.5 * x4)
            # an engine stops iterating once converged, so its result does not depend on the
            # other engines of the batch (batched runs equal single runs bit for bit)
            s3 = np.where(converged, 0.0, s3)
            s4 = np.where(converged, 0.0, s4)
            x3 = x3 - s3
            x4 = x4 - s4
            converged = converged | ((np.abs(s3) <= tol * x3) & (np.abs(s4) <= tol * x4))
            if np.all(converged | ~np.isfinite(x3)):
                break
        alg = model.algebraic(x1, x3, x4, pf, n)
    finally:
        model.speed_sweeps = sweeps_save
    return SteadyState(u=u, x1=x1, x3=x3, x4=x4, alg=alg, converged=converged)
