"""The coupled MVFP engine DAE: ``x' = a(t) x + F(x, z, u, t)``, ``0 = g(x, z, u, t)``.

States ``x = (x1, x3, x4)``: fuel per cylinder and cycle [kg] (Σ1), exhaust receiver pressure
[Pa] (Σ3), charge-air pressure [Pa] (Σ4).  Every state has a diagonal linear part
``a = -(1 + φ)/τ`` (φ: the seal-leak process faults of Σ3/Σ4, zero when healthy) and a forcing F
that collects the interconnection terms h of eq. 3.4, 3.15 and 3.30.

The algebraic part is solved in causal order, which the structure allows:
Σ4 inlet temperature -> Σ2 cycle and speed (a contraction, :func:`engine_block`) -> Σ3 slip,
receiver/turbine (closed form) -> Σ4 compressor.

Submodels (:mod:`marine_fdi_env.engine.submodels`) are part of the parameters: the speed law and friction act
in Σ2, the intercooler on the inlet temperature, the gas-path submodels replace Σ3/Σ4 by
:func:`~marine_fdi_env.engine.subsystems.gas_path.extended_gas_path`.  With none on, the code is the base
model's, bit for bit.  The output fields after ``h4`` (``T_cyl`` ... ``T_exh``) exist for every engine;
for the base model they repeat base quantities (T_cyl = T_t = T_in, T_exh = T_out, no bypass flow).

:func:`solve_algebraic` works on one engine (compiled); :class:`EngineModel` evaluates arrays of
engines with compiled loops and returns named arrays (:class:`Algebraic`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, make_dataclass

import numpy as np

from .._jit import jit, jit_inline
from .constants import ModelConstants, kernel_constants, model_constants
from .fault_registry import I_DT_C, I_DT_INL, I_DT_SL, I_DV1, I_F_U, I_PHI_INT, I_PHI_REC, I_PHI_TUR, TERMS
from .params import EngineParams
from .subsystems.air_intake import (
    air_excess_ratio,
    compressor_forcing,
    compressor_outlet_temperature,
    cooler_outlet_temperature,
    delta_f,
    inlet_air_temperature_at,
)
from .subsystems.engine_block import engine_block, engine_block_at_speed
from .subsystems.exhaust_receiver import receiver_and_turbine, slip_ratio
from .subsystems.fuel_pump import fuel_pump_forcing
from .subsystems.gas_path import extended_gas_path_kernel

__all__ = [
    "ProcessFaultValues",
    "Algebraic",
    "EngineModel",
    "solve_algebraic",
    "algebraic_at_speed",
    "ALG_FIELDS",
    "PF_FIELDS",
    "HEALTHY_PF",
    "solve_algebraic_kernel",
]

# The process-fault vector of compiled code: one value per equation term of the fault registry, in its order.
PF_FIELDS: tuple[str, ...] = tuple(t.name for t in TERMS)
HEALTHY_PF = np.array([t.healthy for t in TERMS])
ALG_FIELDS = (
    "n",
    "torque",
    "p6",
    "T6",
    "p_max",
    "m1",
    "s_sl",
    "T_in",
    "T_out",
    "T1",
    "T_co",
    "lam",
    "mdot_g",
    "Pi_turbo",
    "h3",
    "h4",
    "T_cyl",
    "T_t",
    "T_c",
    "mdot_bp",
    "wg_frac",
    "mdot_c",
    "T_exh",
)
N_ALG = len(ALG_FIELDS)


def _as_array(self, n: int) -> np.ndarray:
    """The values as a contiguous (n, len(PF_FIELDS)) array in the order of ``PF_FIELDS``."""
    out = np.empty((n, len(PF_FIELDS)))
    for j, name in enumerate(PF_FIELDS):
        out[:, j] = getattr(self, name)
    return out


ProcessFaultValues = make_dataclass(
    "ProcessFaultValues",
    [(t.name, "np.ndarray | float", field(default=t.healthy)) for t in TERMS],
    namespace={"as_array": _as_array},
)
ProcessFaultValues.__module__ = __name__
ProcessFaultValues.__doc__ = (
    "Values of the model's fault terms at one instant, healthy by default: one field per term of "
    ":data:`~marine_fdi_env.engine.fault_registry.TERMS` (f_u: fuel-setting factor, 1 healthy; dV1_m3: bore "
    "damage added to V1 [m3]; phi_tur, phi_int: seal leaks f_x = phi x on x3, x4; dT_sl_K, dT_inl_K, dT_c_K: "
    "added to T_sl, T_inl, the compressor outlet [K]; phi_rec: the share of the gas flow leaving the exhaust "
    "receiver past the turbine), scalars or arrays over engines."
)


HEALTHY = ProcessFaultValues()


@dataclass
class Algebraic:
    """All algebraic and output variables at one instant (SI units), arrays over engines."""

    n: np.ndarray  # engine speed [rev/s]
    torque: np.ndarray  # z3^(2) [N m]
    p6: np.ndarray  # z1^(2), cylinder pressure at exhaust opening [Pa]
    T6: np.ndarray  # z2^(2), cylinder temperature at exhaust opening [K]
    p_max: np.ndarray  # maximum cylinder pressure p3 [Pa]
    m1: np.ndarray  # trapped mass per cylinder and cycle, incl. bore damage [kg]
    s_sl: np.ndarray  # slip ratio [-]
    T_in: np.ndarray  # z1^(3), turbine inlet temperature where its thermocouple reads it [K]
    T_out: np.ndarray  # z2^(3), turbine outlet temperature [K]
    T1: np.ndarray  # z1^(4), inlet air temperature [K]
    T_co: np.ndarray  # z2^(4), compressor outlet temperature [K]
    lam: np.ndarray  # air excess ratio [-]
    mdot_g: np.ndarray  # exhaust mass flow through turbine and waste gate (incl. bypass air) [kg/s]
    Pi_turbo: np.ndarray  # turbine expansion term (p_ex/x3)^((κg-1)/κg)
    h3: np.ndarray  # receiver forcing [Pa/s]
    h4: np.ndarray  # compressor forcing [Pa/s]
    T_cyl: np.ndarray  # gas leaving the cylinders (exhaust and slip air, before heat loss and bypass) [K]
    T_t: np.ndarray  # gas entering the turbine [K]
    T_c: np.ndarray  # charge-air cooler outlet [K]
    mdot_bp: np.ndarray  # bypass air flow [kg/s]
    wg_frac: np.ndarray  # fraction of the exhaust through the waste gate [-]
    mdot_c: np.ndarray  # compressor air flow [kg/s]
    T_exh: np.ndarray  # exhaust after the waste-gate junction [K]

    @classmethod
    def from_array(cls, a: np.ndarray) -> "Algebraic":
        return cls(*(a[:, j] for j in range(N_ALG)))

    def power(self) -> np.ndarray:
        """Brake power 2π n z3 [W]."""
        return 2.0 * np.pi * self.n * self.torque


@jit_inline
def _gas_exchange(c, csm, x1, x3, x4, pf, T1, n, torque, p6, T6, p_max, m1_cyl, out, ov_wg, ov_bp):
    """Σ3 and Σ4 after Σ2 (base functions, or the extended gas path when a submodel is on); fills ``out``.
    csm: the full constants for the gas-path submodels, or None (see :func:`kernel_constants`)."""
    # Gas exchange (Σ3, Σ4) uses the nominal V1 as in eq. 3.17-3.22 and 3.32: bore damage acts on
    # the cylinder process (Σ2) only, the variables of table 3.1.
    m1 = x4 * c.V1_m3 / (c.R_a_J_per_kgK * T1)
    s_sl = slip_ratio(x3, x4, m1, max(n, 1e-9), c)
    share = 1.0 - pf[I_PHI_REC]  # of the cylinders' gas flow through the turbine (1 when healthy)
    out[0] = n
    out[1] = torque
    out[2] = p6
    out[3] = T6
    out[4] = p_max
    out[5] = m1_cyl
    out[6] = s_sl
    out[9] = T1
    out[11] = air_excess_ratio(m1_cyl, x1, c)
    if csm is not None:  # compiled only where a gas-path submodel may be on
        if c.sm_on != 0.0:
            T_c = cooler_outlet_temperature(x4, c)
            g = extended_gas_path_kernel(
                x1, x3, x4, m1, s_sl, n, T6, p6, c.T_sl_K + pf[I_DT_SL], T_c, pf[I_DT_C], c, csm, ov_wg, ov_bp, share
            )
            out[14] = g[0]
            out[7] = g[1]
            out[8] = g[2]
            out[13] = g[3]
            out[12] = g[4]
            out[15] = g[5]
            out[10] = g[6]
            out[16] = g[7]
            out[17] = g[8]
            out[18] = T_c
            out[19] = g[9]
            out[20] = g[10]
            out[21] = g[11]
            out[22] = g[12]
            return
    h3, T_in, T_out, Pi, mdot = receiver_and_turbine(x1, x3, x4, m1, s_sl, n, T6, p6, c.T_sl_K + pf[I_DT_SL], c, share)
    d_f = delta_f(x1, m1, s_sl) * share  # the turbine's share of the flow in the power balance (eq. 3.31, 3.38)
    out[7] = T_in
    out[8] = T_out
    out[10] = compressor_outlet_temperature(d_f, T_in, T_out, pf[I_DT_C], c)
    out[12] = mdot
    out[13] = Pi
    out[14] = h3
    out[15] = compressor_forcing(x4, d_f, T_in, Pi, c)
    out[16] = T_in
    out[17] = T_in
    out[18] = cooler_outlet_temperature(x4, c)
    out[19] = 0.0
    out[20] = 0.0
    out[21] = (1.0 + s_sl) * m1 * n * c.cycles_per_rev
    out[22] = T_out


@jit_inline
def solve_algebraic_kernel(c, csm, x1, x3, x4, pf, n_guess, sweeps, out):
    """:func:`solve_algebraic` with the constants of :func:`kernel_constants` (``c`` floats only,
    ``csm`` the full constants or None): the compiled kernels' form, the same numbers."""
    T1 = inlet_air_temperature_at(pf[I_DT_INL], x4, c)
    n, torque, p6, T6, p_max, m1_cyl = engine_block(x1, x4, T1, c.V1_m3 + pf[I_DV1], n_guess, c, sweeps)
    _gas_exchange(c, csm, x1, x3, x4, pf, T1, n, torque, p6, T6, p_max, m1_cyl, out, math.nan, math.nan)


@jit
def solve_algebraic(c, x1, x3, x4, pf, n_guess, sweeps, out):
    """Solve the algebraic equations of Σ2-Σ4 for one engine (eq. 3.7-3.38).

    ``pf`` is the process-fault vector (order ``PF_FIELDS``); the results are written to ``out``
    in the order of ``ALG_FIELDS``.
    """
    solve_algebraic_kernel(c, c, x1, x3, x4, pf, n_guess, sweeps, out)


@jit
def algebraic_at_speed(c, x1, x3, x4, n, pf, out, ov_wg=math.nan, ov_bp=math.nan):
    """The algebraic equations of Σ2-Σ4 at a given engine speed n [rev/s] (no load law), for the
    steady-state solver of :mod:`marine_fdi_env.engine.operating_point`; fills ``out`` (``ALG_FIELDS``).
    ov_wg, ov_bp : valve openings overriding the schedules (NaN: the schedules)."""
    T1 = inlet_air_temperature_at(pf[I_DT_INL], x4, c)
    torque, p6, T6, p_max, m1_cyl = engine_block_at_speed(x1, x4, T1, c.V1_m3 + pf[I_DV1], n, c)
    _gas_exchange(c, c, x1, x3, x4, pf, T1, n, torque, p6, T6, p_max, m1_cyl, out, ov_wg, ov_bp)


@jit
def linear_rates(pf, c):
    """Diagonal linear parts a1, a3, a4 [1/s] (eq. 3.4, 3.15, 3.30 with the seal-leak faults)."""
    return -1.0 / c.tau_X_s, -(1.0 + pf[I_PHI_TUR]) / c.tau_pd_s, -(1.0 + pf[I_PHI_INT]) / c.tau_TC_s


@jit_inline
def forcings(u, pf, alg, c):
    """Forcings F1 [kg/s] (eq. 3.4), F3 = h3, F4 = h4 [Pa/s] of one engine."""
    return fuel_pump_forcing(u, pf[I_F_U], c), alg[14], alg[15]


@jit
def algebraic_batch(c, csm, x1, x3, x4, pf, n_guess, sweeps, out):
    for i in range(x1.shape[0]):
        solve_algebraic_kernel(c, csm, x1[i], x3[i], x4[i], pf[i], n_guess[i], sweeps, out[i])


def _vec(v, n: int) -> np.ndarray:
    """A writable, contiguous float64 copy of shape (n,): compiled code is specialised on array
    flags, and one specialisation for every input keeps results independent of the batch."""
    return np.array(np.broadcast_to(np.asarray(v, dtype=np.float64), (n,)), dtype=np.float64, order="C")


@dataclass
class EngineModel:
    """The coupled model of one parameter set; methods take arrays over engines."""

    params: EngineParams
    speed_sweeps: int = 3
    constants: ModelConstants = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.constants = model_constants(self.params)

    def algebraic(
        self, x1, x3, x4, pf: ProcessFaultValues = HEALTHY, n_guess=None, sweeps: int | None = None
    ) -> Algebraic:
        """Solve the algebraic equations of Σ2-Σ4 for given states (eq. 3.7-3.38).

        ``sweeps`` overrides ``speed_sweeps`` of the speed loop (see :func:`engine_block`).
        """
        n = int(np.size(np.asarray(x1)))
        if n_guess is None:
            n_guess = self.params.n_nom_rev_s
        out = np.empty((n, N_ALG))
        kc, csm = kernel_constants(self.constants)
        algebraic_batch(
            kc,
            csm,
            _vec(x1, n),
            _vec(x3, n),
            _vec(x4, n),
            pf.as_array(n),
            _vec(n_guess, n),
            self.speed_sweeps if sweeps is None else int(sweeps),
            out,
        )
        return Algebraic.from_array(out)

    def linear_coefficients(self, pf: ProcessFaultValues = HEALTHY):
        """Diagonal linear parts a1, a3, a4 [1/s] (eq. 3.4, 3.15, 3.30 with the seal-leak faults)."""
        p = self.params
        return (
            -1.0 / p.tau_X_s,
            -(1.0 + np.asarray(pf.phi_tur)) / p.tau_pd_s,
            -(1.0 + np.asarray(pf.phi_int)) / p.tau_TC_s,
        )

    def forcing(self, u, alg: Algebraic, pf: ProcessFaultValues = HEALTHY):
        """Forcings F1 [kg/s], F3 = h3 [Pa/s], F4 = h4 [Pa/s]."""
        p = self.params
        return (p.x1_nom_kg / p.tau_X_s) * np.asarray(pf.f_u) * np.asarray(u), alg.h3, alg.h4

    def derivatives(self, x1, x3, x4, u, pf: ProcessFaultValues = HEALTHY, n_guess=None):
        """Time derivatives of the three states and the algebraic solution (for reference solvers)."""
        alg = self.algebraic(x1, x3, x4, pf, n_guess)
        a1, a3, a4 = self.linear_coefficients(pf)
        F1, F3, F4 = self.forcing(u, alg, pf)
        return (a1 * np.asarray(x1) + F1, a3 * np.asarray(x3) + F3, a4 * np.asarray(x4) + F4), alg
