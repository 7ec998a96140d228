"""Σ1, the fuel pump: first-order lag from fuel setting to fuel injected per cylinder and cycle.

``x1' = -x1 / τ_X + x1_nom f_u u / τ_X`` (eq. 3.4), with ``x1_nom`` from eq. 3.5 and the
valve-seizing fault ``f_u`` multiplying the setting ``u`` (table 3.2).
"""

from __future__ import annotations

from ..._jit import jit

__all__ = ["nominal_fuel_per_cycle", "fuel_pump_linear", "fuel_pump_forcing"]


def nominal_fuel_per_cycle(p) -> float:
    """x1_nom = SFC P k_e / (i_e n) [kg per cylinder and cycle] (eq. 3.5)."""
    return p.SFC_nom_kg_per_J * p.P_nom_W * p.revs_per_cycle / (p.n_cylinders * p.n_nom_rev_s)


@jit
def fuel_pump_linear(c) -> float:
    """Linear coefficient a1 = -1/τ_X [1/s] of eq. 3.4."""
    return -1.0 / c.tau_X_s


@jit
def fuel_pump_forcing(u: float, f_u: float, c) -> float:
    """Forcing x1_nom f_u u / τ_X [kg/s] of eq. 3.4 (u is the fuel setting, 1.0 = nominal)."""
    return (c.x1_nom_kg / c.tau_X_s) * f_u * u
