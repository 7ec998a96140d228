"""The coupled MVFP engine DAE: ``x' = a(t) x + F(x, z, u, t)``, ``0 = g(x, z, u, t)``.

States ``x = (x1, x3, x4)``: fuel per cylinder and cycle [kg] (Σ1), exhaust receiver pressure
[Pa] (Σ3), charge-air pressure [Pa] (Σ4).  Every state has a diagonal linear part
``a = -(1 + φ)/τ`` (φ: the seal-leak process faults of Σ3/Σ4, zero when healthy) and a forcing F
that collects the interconnection terms h of eq. 3.4, 3.15 and 3.30.

The algebraic part is solved in causal order, which the structure allows:
Σ4 inlet temperature -> Σ2 cycle and speed (a contraction, :func:`engine_block`) -> Σ3 slip,
receiver/turbine (closed form) -> Σ4 compressor.  Arrays have shape ``(n_engines,)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields

import numpy as np

from .params import EngineParams
from .subsystems import air_intake as s4
from .subsystems import engine_block as s2
from .subsystems import exhaust_receiver as s3
from .subsystems import fuel_pump as s1

__all__ = ["ProcessFaultValues", "Algebraic", "EngineModel"]


@dataclass
class ProcessFaultValues:
    """Values of the seven process faults at one instant (tables 3.1, 3.2); healthy defaults.

    f_u : valve seizing, multiplier of the fuel setting [-] (1 = healthy).
    dV1_m3 : bore damage f_z,V1, added to V1.
    phi_tur : turbine seal leak, f_x,tur = phi_tur x3 (dimensionless).
    dT_sl_K : turbine lubrication loss f_z,Tsl, added to T_sl.
    phi_int : compressor seal leak, f_x,int = phi_int x4 (dimensionless).
    dT_inl_K : compressor lubrication loss f_z,Tinl, added to T_inl.
    dT_c_K : intercooler blockage f_z,Tc, added to the compressor outlet temperature.
    """

    f_u: np.ndarray | float = 1.0
    dV1_m3: np.ndarray | float = 0.0
    phi_tur: np.ndarray | float = 0.0
    dT_sl_K: np.ndarray | float = 0.0
    phi_int: np.ndarray | float = 0.0
    dT_inl_K: np.ndarray | float = 0.0
    dT_c_K: np.ndarray | float = 0.0


HEALTHY = ProcessFaultValues()


@dataclass
class Algebraic:
    """All algebraic and output variables at one instant (SI units)."""

    n: np.ndarray  # engine speed [rev/s]
    torque: np.ndarray  # z3^(2) [N m]
    p6: np.ndarray  # z1^(2), cylinder pressure at exhaust opening [Pa]
    T6: np.ndarray  # z2^(2), cylinder temperature at exhaust opening [K]
    p_max: np.ndarray  # maximum cylinder pressure p3 [Pa]
    m1: np.ndarray  # trapped mass per cylinder and cycle [kg]
    s_sl: np.ndarray  # slip ratio [-]
    T_in: np.ndarray  # z1^(3), turbine inlet temperature [K]
    T_out: np.ndarray  # z2^(3), turbine outlet temperature [K]
    T1: np.ndarray  # z1^(4), inlet air temperature [K]
    T_co: np.ndarray  # z2^(4), compressor outlet temperature [K]
    lam: np.ndarray  # air excess ratio [-]
    mdot_g: np.ndarray  # turbine mass flow [kg/s]
    Pi_turbo: np.ndarray  # turbine expansion term (p_ex/x3)^((κg-1)/κg)
    h3: np.ndarray  # receiver forcing [Pa/s]
    h4: np.ndarray  # compressor forcing [Pa/s]

    def power(self) -> np.ndarray:
        """Brake power 2π n z3 [W]."""
        return 2.0 * np.pi * self.n * self.torque


@dataclass
class EngineModel:
    """The coupled model of one parameter set; all methods are vectorised over engines."""

    params: EngineParams
    speed_sweeps: int = 3
    _k2: s2.EngineBlockConstants = field(init=False, repr=False)
    _k3: s3.ExhaustConstants = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self._k2 = s2.engine_block_constants(self.params)
        self._k3 = s3.exhaust_constants(self.params)

    @property
    def seiliger_constants(self):
        return self._k2.seiliger

    # ------------------------------------------------------------------ algebraic part
    def algebraic(self, x1, x3, x4, pf: ProcessFaultValues = HEALTHY, n_guess=None, sweeps: int | None = None) -> Algebraic:
        """Solve the algebraic equations of Σ2-Σ4 for given states (eq. 3.7-3.38).

        ``sweeps`` overrides ``speed_sweeps`` of the speed loop (see :func:`engine_block`).
        """
        p = self.params
        if n_guess is None:
            n_guess = np.full(np.shape(x1), p.n_nom_rev_s)
        T1 = s4.inlet_air_temperature(pf.dT_inl_K, p)
        blk = s2.engine_block(x1, x4, T1, p.V1_m3 + pf.dV1_m3, n_guess, p, self._k2,
                              self.speed_sweeps if sweeps is None else sweeps)
        n = blk.n
        n_safe = np.maximum(n, 1e-9)
        s_sl = s3.slip_ratio(x3, x4, blk.m1, n_safe, self._k3)
        rec = s3.receiver_and_turbine(
            x1, x3, x4, blk.m1, s_sl, n, blk.cycle.T6, blk.cycle.p6, p.T_sl_K + pf.dT_sl_K, p, self._k3
        )
        h4 = s4.compressor_forcing(x4, x1, blk.m1, s_sl, rec.T_in, rec.Pi_turbo, p)
        T_co = s4.compressor_outlet_temperature(x1, blk.m1, s_sl, rec.T_in, rec.T_out, pf.dT_c_K, p)
        return Algebraic(
            n=n,
            torque=blk.torque,
            p6=blk.cycle.p6,
            T6=blk.cycle.T6,
            p_max=blk.cycle.p3,
            m1=blk.m1,
            s_sl=s_sl,
            T_in=rec.T_in,
            T_out=rec.T_out,
            T1=T1 if np.ndim(T1) == np.ndim(x1) else np.full(np.shape(x1), T1),
            T_co=T_co,
            lam=s4.air_excess_ratio(blk.m1, x1, p),
            mdot_g=rec.mdot_g,
            Pi_turbo=rec.Pi_turbo,
            h3=rec.h3,
            h4=h4,
        )

    # ---------------------------------------------------------------- differential part
    def linear_coefficients(self, pf: ProcessFaultValues = HEALTHY):
        """Diagonal linear parts a1, a3, a4 [1/s] (eq. 3.4, 3.15, 3.30 with the seal-leak faults)."""
        p = self.params
        return (s1.fuel_pump_linear(p), -(1.0 + pf.phi_tur) / p.tau_pd_s, -(1.0 + pf.phi_int) / p.tau_TC_s)

    def forcing(self, u, alg: Algebraic, pf: ProcessFaultValues = HEALTHY):
        """Forcings F1 [kg/s], F3 = h3 [Pa/s], F4 = h4 [Pa/s]."""
        return s1.fuel_pump_forcing(u, pf.f_u, self.params), alg.h3, alg.h4

    def derivatives(self, x1, x3, x4, u, pf: ProcessFaultValues = HEALTHY, n_guess=None):
        """Time derivatives of the three states and the algebraic solution (for reference solvers)."""
        alg = self.algebraic(x1, x3, x4, pf, n_guess)
        a1, a3, a4 = self.linear_coefficients(pf)
        F1, F3, F4 = self.forcing(u, alg, pf)
        return (a1 * x1 + F1, a3 * x3 + F3, a4 * x4 + F4), alg


def algebraic_field_names() -> list[str]:
    return [f.name for f in fields(Algebraic)]
