"""The 19 monitoring modules M(l,q) of thesis table 6.2 and the model structure behind each ARR.

Every module checks one analytical redundancy relation (ARR) built from one model equation:

* state-based modules (M1.1, M1.2, M3.1, M3.2, M4.1, M4.2) run a Lipschitz observer of their
  subsystem's state (eq. 5.4) and compare it with the state's sensor (eq. 5.6, 5.17);
* algebraic modules compare an algebraic variable's sensor with the value the model computes from
  the other sensors of the set (eq. 5.6-5.7, 5.18).

The structure recorded here is what the fault signature matrices are derived from
(:mod:`marine_fdi_env.diagnosis.structure`): the sensors an ARR reads (its own sensor set and the
interconnection sensors of table 6.2) and the model equations it evaluates.  A sensor fault
affects an ARR iff the ARR reads that sensor; a process fault affects an ARR iff the fault enters
one of the equations the ARR evaluates (table 3.1 and the fault equations of each subsystem).

Model equations (ids used below):

=========  ==================================================================  =================
eq id      equation                                                             process faults
=========  ==================================================================  =================
fuel       x1' = -x1/τ_X + x1_nom f_u u/τ_X (eq. 3.4)                           valve_seizing
cycle      Seiliger cycle p6, T6, p_max of (x1, x4, T1, V1 + f_V1, n) (3.7-3.9)   bore_damage
torque     z3 = m1 w(...) i_e/(2π k_e) - Q_loss(n) (eq. 3.10)                     bore_damage
speed      n from the propeller law with the cycle's torque (eq. 3.10-3.13)      bore_damage
receiver   x3' = -(1 + φ_tur) x3/τ_pd + h3(x1, x3, x4, T1, T_in, n) (3.15-3.19)  turbine_seal_leak
mixing     T_in = (ψ2 (T_sl + f) + ψ̃3 T6)/(ψ2 + ψ3) (eq. 3.20-3.23)              turbine_lubrication_loss
turbine    T_out = T_in (1 - η_t(x4)(1 - Π(x3))) (eq. 3.24-3.26)                 -
charge     x4' = -(1 + φ_int) x4/τ_TC + h4(x1, x3, x4, T1, T_in, n) (3.30-3.35) compressor_seal_leak
inlet      T1 = T_c + ε_inl (T_inl + f - T_c) (eq. 3.37)                         compressor_lubrication_loss
comp_out   T_co = T_amb + η_com χ_g δ_f (T_in - T_out) + f (eq. 3.38)            intercooler_blockage
=========  ==================================================================  =================

The engine speed n is not measured: modules of Σ3 and Σ4 obtain it from Σ2's equations
(``speed``) fed with their interconnection sensors x1, x4, T1, so the bore damage, which changes
the cylinder process and hence the speed, enters those ARRs too.  The thesis states that process
faults never propagate between agents; with the speed dependence of eq. 3.16-3.18 they do, and
the derived signature matrices say so (docs/diagnosis_structure.md lists every cell that differs).
"""

from __future__ import annotations

from dataclasses import dataclass

from ..engine.fault_registry import EQUATION_IDS, fault_type
from ..engine.faults import PROCESS_FAULT_IDS
from ..engine.sensors import SENSOR_IDS

__all__ = ["ModuleSpec", "MODULES", "MODULE_IDS", "EQUATION_FAULTS", "module_index", "AGENTS"]


@dataclass(frozen=True)
class ModuleSpec:
    """One monitoring module M(agent, q) and its ARR.

    id : ``M<agent>.<q>``.  kind : ``state`` (observer) or ``algebraic``.
    checked_sensor : the sensor whose reading the ARR compares with the model.
    sensors : the module's own sensor set S^(l,q) (table 6.2).
    interconnection : the interconnection sensors of table 6.2.
    equations : the model equations the ARR evaluates (see module docstring).
    """

    id: str
    agent: int
    kind: str
    checked_sensor: str
    sensors: tuple[str, ...]
    interconnection: tuple[str, ...]
    equations: tuple[str, ...]

    @property
    def all_sensors(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(self.sensors + self.interconnection))


MODULES: tuple[ModuleSpec, ...] = (
    ModuleSpec("M1.1", 1, "state", "S1.1", ("S1.1",), (), ("fuel",)),
    ModuleSpec("M1.2", 1, "state", "S1.2", ("S1.2",), (), ("fuel",)),
    ModuleSpec("M2.1", 2, "algebraic", "S2.1", ("S2.1",), ("S1.1", "S4.1", "S4.3"), ("cycle", "speed")),
    ModuleSpec("M2.2", 2, "algebraic", "S2.2", ("S2.2",), ("S1.2", "S4.2", "S4.4"), ("cycle", "speed")),
    ModuleSpec("M2.3", 2, "algebraic", "S2.3", ("S2.3",), ("S1.1", "S4.1", "S4.3"), ("cycle", "speed")),
    ModuleSpec("M2.4", 2, "algebraic", "S2.4", ("S2.4",), ("S1.2", "S4.2", "S4.4"), ("cycle", "speed")),
    ModuleSpec("M2.5", 2, "algebraic", "S2.5", ("S2.3", "S2.5"), ("S1.1", "S4.1", "S4.3"), ("cycle", "torque")),
    ModuleSpec("M2.6", 2, "algebraic", "S2.6", ("S2.4", "S2.6"), ("S1.2", "S4.2", "S4.4"), ("cycle", "torque")),
    ModuleSpec("M3.1", 3, "state", "S3.1", ("S3.1", "S3.3"), ("S1.1", "S4.1", "S4.3"), ("receiver", "speed")),
    ModuleSpec("M3.2", 3, "state", "S3.2", ("S3.2", "S3.4"), ("S1.2", "S4.2", "S4.4"), ("receiver", "speed")),
    ModuleSpec(
        "M3.3", 3, "algebraic", "S3.3", ("S3.1", "S3.3"), ("S1.1", "S2.1", "S2.3", "S4.1", "S4.3"), ("mixing", "speed")
    ),
    ModuleSpec(
        "M3.4", 3, "algebraic", "S3.4", ("S3.2", "S3.4"), ("S1.2", "S2.2", "S2.4", "S4.2", "S4.4"), ("mixing", "speed")
    ),
    ModuleSpec("M3.5", 3, "algebraic", "S3.5", ("S3.2", "S3.4", "S3.5"), ("S4.2",), ("turbine",)),
    ModuleSpec("M4.1", 4, "state", "S4.1", ("S4.1", "S4.3"), ("S1.1", "S3.1", "S3.3"), ("charge", "speed")),
    ModuleSpec("M4.2", 4, "state", "S4.2", ("S4.2", "S4.4"), ("S1.2", "S3.2", "S3.4"), ("charge", "speed")),
    ModuleSpec("M4.3", 4, "algebraic", "S4.3", ("S4.3",), (), ("inlet",)),
    ModuleSpec("M4.4", 4, "algebraic", "S4.4", ("S4.4",), (), ("inlet",)),
    ModuleSpec(
        "M4.5",
        4,
        "algebraic",
        "S4.5",
        ("S4.1", "S4.3", "S4.5"),
        ("S1.1", "S3.1", "S3.3", "S3.5"),
        ("comp_out", "speed"),
    ),
    ModuleSpec(
        "M4.6",
        4,
        "algebraic",
        "S4.6",
        ("S4.2", "S4.4", "S4.6"),
        ("S1.2", "S3.2", "S3.4", "S3.5"),
        ("comp_out", "speed"),
    ),
)

MODULE_IDS: tuple[str, ...] = tuple(m.id for m in MODULES)
AGENTS: dict[int, tuple[str, ...]] = {a: tuple(m.id for m in MODULES if m.agent == a) for a in (1, 2, 3, 4)}

# Which process faults enter which model equation: those whose term (table 3.1, eq. 3.4-3.38 as implemented)
# enters it, from the fault registry.
EQUATION_FAULTS: dict[str, tuple[str, ...]] = {
    eq: tuple(f for f in PROCESS_FAULT_IDS if eq in fault_type(f).equations) for eq in EQUATION_IDS
}

_INDEX = {m: i for i, m in enumerate(MODULE_IDS)}


def module_index(module_id: str) -> int:
    try:
        return _INDEX[module_id]
    except KeyError:
        raise ValueError(f"unknown module {module_id!r}; allowed: {', '.join(MODULE_IDS)}") from None


def _check() -> None:
    for m in MODULES:
        for s in m.all_sensors:
            assert s in SENSOR_IDS, s
        for e in m.equations:
            assert e in EQUATION_FAULTS, e
    for faults in EQUATION_FAULTS.values():
        for f in faults:
            assert f in PROCESS_FAULT_IDS, f


_check()
