"""Every fault of the benchmark, declared once: the equation terms faults act through and one record per fault.

Everything else derives from the two tables here (thesis tables 3.1, 3.2, 6.3, 6.4):

* :data:`TERMS`, the equation terms through which process faults act, is the compiled model's fault input:
  the simulator hands the kernels an array ``(samples, engines, len(TERMS))`` of term values, and each
  subsystem equation reads its terms by the indices ``I_*`` below (:mod:`.model`, :mod:`.integrators`,
  :mod:`.operating_point`).  :class:`~marine_fdi_env.engine.model.ProcessFaultValues` has one field per term.
* :data:`FAULT_TYPES`, one :class:`FaultType` per fault: the 19 sensor faults (one per sensor of
  :mod:`.sensors`, eq. 3.3, 5.1), the process faults of table 6.4, then the faults of plugins (below).
  :mod:`.faults` (ids, defaults, ``fault_class``, the term values of a schedule), the diagnosis structure
  (``diagnosis.modules.EQUATION_FAULTS``, the signature matrices: a process fault enters the equations of its
  term), the environments' hypotheses and the suites' fault lists read these records.

Decision (the compiled simulator's fault inputs): the kernels take *term* values, not per-fault values.  A
fault maps onto one term through its law (below), and the numpy code that fills the term array per block of
samples (:meth:`~marine_fdi_env.engine.faults.CompiledSchedule.process_values`) combines the faults that share
a term (added, or multiplied for a factor).  So the compiled code depends on :data:`TERMS` only: a new fault
on an existing term changes no compiled function and needs no compilation; a new term is one :class:`Term`
here and its use in the subsystem equation that reads it.  The kernels read a term as one float of the
engine's row (copied once per sample into a scratch row, see ``integrators._advance_range``), a healthy term
adds 0 or multiplies by 1, so the healthy numbers are those of a model without the term, bit for bit.

Laws (value of the fault's own contribution at time s after its window opened, β = 1 - exp(-κ s), eq. 2.4):

============  ===================  ==================  ===========================================
law           contribution         term combines by    fault value recorded (``fault_value``)
============  ===================  ==================  ===========================================
``fraction``  1 - β φ              multiplication      1 - contribution (= β φ)
``ramp``      β R s                addition            the contribution
``level``     β φ                  addition            the contribution
============  ===================  ==================  ===========================================

Plugins: faults declared outside the package join the registry when it is first read (at the import of
:mod:`.faults`), from the entry-point group ``marine_fdi_env.faults`` of installed packages and from the
environment variable ``MARINE_FDI_FAULTS`` (module names or ``.py`` files, separated by ``os.pathsep``); each
names a module with ``FAULTS``, a sequence of :class:`FaultType`.  A plugin module imports only this module.
Their measured tables (detectability limit, sure and sized cells) are read from the folder
``MARINE_FDI_TABLES`` when it is set (:func:`measured_table`); the repository's fault-table command
(:data:`TABLES_COMMAND`, docs/extending.md) makes them.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import math
import os
from dataclasses import astuple, dataclass
from functools import lru_cache
from importlib import resources
from pathlib import Path

from ..errors import DataFileError
from .sensors import SENSORS

__all__ = [
    "Term",
    "TERMS",
    "TERM_INDEX",
    "EQUATION_IDS",
    "I_F_U",
    "I_DV1",
    "I_PHI_TUR",
    "I_DT_SL",
    "I_PHI_INT",
    "I_DT_INL",
    "I_DT_C",
    "I_PHI_REC",
    "FaultType",
    "SHIPPED_FAULT_TYPES",
    "FAULT_TYPES",
    "LAWS",
    "registered_fault_types",
    "fault_type",
    "suite_fault_ids",
    "registry_key",
    "ENTRY_POINT_GROUP",
    "FAULTS_ENV",
    "TABLES_ENV",
    "MissingFaultTable",
    "measured_table",
    "check_table_faults",
    "TABLES_COMMAND",
]

ENTRY_POINT_GROUP = "marine_fdi_env.faults"
FAULTS_ENV = "MARINE_FDI_FAULTS"
TABLES_ENV = "MARINE_FDI_TABLES"
TABLES_COMMAND = "python -m studies.fault_tables --faults {faults} --out DIR"

# Ids of the model equations (the diagnosis structure's, diagnosis.modules) a term may enter.
EQUATION_IDS = ("fuel", "cycle", "torque", "speed", "receiver", "mixing", "turbine", "charge", "inlet", "comp_out")


@dataclass(frozen=True)
class Term:
    """One equation term through which process faults act: a float per engine and sample in the kernels.

    name : field of ``ProcessFaultValues`` and column of the kernels' term array.
    subsystem : Σ1-Σ4.  equations : the model equations it enters (``EQUATION_IDS``; the diagnosis
    structure's sensitivities derive from them).  combine : ``add`` or ``multiply``, how the contributions of
    several faults on the term combine.  healthy : its value without a fault (0 or 1).  unit : its unit.
    where : how it enters the equations (the thesis's equation).
    """

    name: str
    subsystem: int
    equations: tuple[str, ...]
    combine: str
    healthy: float
    unit: str
    where: str

    def __post_init__(self) -> None:
        if self.combine not in ("add", "multiply"):
            raise ValueError(f"term {self.name}: combine must be 'add' or 'multiply', got {self.combine!r}")
        if self.healthy != (0.0 if self.combine == "add" else 1.0):
            raise ValueError(f"term {self.name}: healthy must be {0.0 if self.combine == 'add' else 1.0}")
        bad = [e for e in self.equations if e not in EQUATION_IDS]
        if bad or not self.equations:
            raise ValueError(f"term {self.name}: equations must be some of {EQUATION_IDS}, got {self.equations!r}")


# The order is the column order of the kernels' term array.
TERMS: tuple[Term, ...] = (
    Term(
        "f_u",
        1,
        ("fuel",),
        "multiply",
        1.0,
        "-",
        "factor of the fuel setting: x1' = -x1/τ_X + x1_nom f_u u/τ_X (eq. 3.4)",
    ),
    Term(
        "dV1_m3",
        2,
        ("cycle", "torque", "speed"),
        "add",
        0.0,
        "m3",
        "added to the cylinder volume V1 of the Seiliger cycle and the torque (eq. 3.7-3.13); the gas exchange "
        "keeps the nominal V1",
    ),
    Term("phi_tur", 3, ("receiver",), "add", 0.0, "-", "x3' = -(1 + φ_tur) x3/τ_pd + h3 (eq. 3.15, table 3.2)"),
    Term("dT_sl_K", 3, ("mixing",), "add", 0.0, "K", "added to the slip-air temperature T_sl (eq. 3.20-3.23)"),
    Term("phi_int", 4, ("charge",), "add", 0.0, "-", "x4' = -(1 + φ_int) x4/τ_TC + h4 (eq. 3.30, table 3.2)"),
    Term("dT_inl_K", 4, ("inlet",), "add", 0.0, "K", "added to T_inl: T1 = T_c + ε_inl (T_inl + f - T_c) (eq. 3.37)"),
    Term("dT_c_K", 4, ("comp_out",), "add", 0.0, "K", "added to the compressor outlet temperature (eq. 3.38)"),
    Term(
        "phi_rec",
        3,
        ("receiver", "mixing", "charge", "comp_out"),
        "add",
        0.0,
        "-",
        "fraction of the cylinders' gas flow ṁ_g that leaves the exhaust receiver other than through the "
        "turbine: the turbine passes (1 - φ_rec) ṁ_g in the flow law (eq. 3.16) and the mixing temperature "
        "(eq. 3.20-3.23), and the turbocharger power balance sees δ_f (1 - φ_rec) (eq. 3.31, 3.38)",
    ),
)
TERM_INDEX: dict[str, int] = {t.name: i for i, t in enumerate(TERMS)}
# column of each term, for the compiled equations (numba freezes these module constants)
I_F_U = TERM_INDEX["f_u"]
I_DV1 = TERM_INDEX["dV1_m3"]
I_PHI_TUR = TERM_INDEX["phi_tur"]
I_DT_SL = TERM_INDEX["dT_sl_K"]
I_PHI_INT = TERM_INDEX["phi_int"]
I_DT_INL = TERM_INDEX["dT_inl_K"]
I_DT_C = TERM_INDEX["dT_c_K"]
I_PHI_REC = TERM_INDEX["phi_rec"]

LAWS: dict[str, str] = {"fraction": "multiply", "ramp": "add", "level": "add"}  # law -> the combine it needs


@dataclass(frozen=True)
class FaultType:
    """One fault, declared once.

    id : the fault id (``S4.2``, ``bore_damage``).  kind : ``sensor`` or ``process``.
    subsystem : Σ1-Σ4 (the agent of the diagnosis it belongs to).
    term : a process fault's :data:`TERMS` name (the equation term it drives); a sensor fault's sensor id.
    symbol : the thesis's symbol (``f_u``, ``f_z,V1``; ``f_j`` for sensor j of the subsystem).
    unit : unit of the magnitude.  law : a process fault's :data:`LAWS` entry; ``sensor`` for a sensor fault
    (its kinds: offset, drift, stuck, gain, precision, :mod:`.faults`).
    onset_s, kappa, magnitude : defaults (table 6.4; a sensor fault: no onset, abrupt, the table 6.3 offset).
    magnitude_range, kappa_range : allowed magnitudes and evolution rates κ [1/s] (closed intervals) of a
    process fault.  label : short column label of the docs' tables.  suite_version : the suites from this
    version (``-vN``) on draw the fault; published suites keep the faults they were built with (None: no
    shipped suite, a plugin's own suites only).  description : what fails.
    """

    id: str
    kind: str
    subsystem: int
    term: str
    symbol: str
    unit: str
    law: str
    magnitude: float
    onset_s: float | None = None
    kappa: float = math.inf
    magnitude_range: tuple[float, float] = (0.0, math.inf)
    kappa_range: tuple[float, float] = (0.0, math.inf)
    label: str = ""
    suite_version: int | None = None
    description: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.id, str) or not self.id or any(c in self.id for c in "@,:= "):
            raise ValueError(f"fault id must be a non-empty string without '@,:= ' or spaces, got {self.id!r}")
        if self.kind not in ("sensor", "process"):
            raise ValueError(f"fault {self.id}: kind must be 'sensor' or 'process', got {self.kind!r}")
        if self.subsystem not in (1, 2, 3, 4):
            raise ValueError(f"fault {self.id}: subsystem must be 1-4, got {self.subsystem!r}")
        if self.kind == "process":
            if self.term not in TERM_INDEX:
                raise ValueError(f"fault {self.id}: term must be one of {', '.join(TERM_INDEX)}, got {self.term!r}")
            if self.law not in LAWS:
                raise ValueError(f"fault {self.id}: law must be one of {', '.join(LAWS)}, got {self.law!r}")
            combine = TERMS[TERM_INDEX[self.term]].combine
            if LAWS[self.law] != combine:
                raise ValueError(
                    f"fault {self.id}: law {self.law!r} needs a term that combines by {LAWS[self.law]}; "
                    f"{self.term} combines by {combine}"
                )
            lo, hi = self.magnitude_range
            if not (0.0 <= lo <= self.magnitude <= hi):
                raise ValueError(f"fault {self.id}: magnitude {self.magnitude} outside magnitude_range {lo, hi}")
            if self.onset_s is None or not (math.isfinite(self.onset_s) and self.onset_s >= 0):
                raise ValueError(f"fault {self.id}: onset_s must be a finite number >= 0, got {self.onset_s!r}")
            klo, khi = self.kappa_range
            if not (0.0 <= klo <= self.kappa <= khi and self.kappa > 0):
                raise ValueError(f"fault {self.id}: kappa {self.kappa} must be > 0 and inside kappa_range {klo, khi}")
        elif self.law != "sensor":
            raise ValueError(f"fault {self.id}: a sensor fault's law is 'sensor', got {self.law!r}")
        if not self.label:
            object.__setattr__(self, "label", self.id)

    @property
    def thesis_symbol(self) -> str:
        """The symbol with its subsystem, as tables 6.5-6.8 print it (``f_u^(1)``, ``f_2^(4)``)."""
        return f"{self.symbol}^({self.subsystem})"

    @property
    def equations(self) -> tuple[str, ...]:
        """The model equations a process fault enters (its term's); none for a sensor fault."""
        return TERMS[TERM_INDEX[self.term]].equations if self.kind == "process" else ()


def _sensor_fault(s) -> FaultType:
    return FaultType(
        s.id,
        "sensor",
        int(s.id[1]),
        s.id,
        f"f_{s.id.split('.')[1]}",
        s.unit,
        "sensor",
        s.fault_magnitude,
        label=s.id,
        suite_version=1,
        description=f"{s.description}: offset, drift, stuck-at, gain or precision (eq. 3.3, 5.1)",
    )


# Table 6.4 (symbol, onset, κ, magnitude) and tables 3.1, 3.2 (the term).  Table 6.4 gives φ_u = 25 "%"; we
# read it as the fraction 0.25 (a multiplier 1 - 25 would be meaningless).  Magnitudes have no upper bound: a
# valve seizing beyond 1 cuts the fuel to nothing and stalls the engine, which the tests of engine failures use.
_TABLE_6_4 = dict(kind="process", suite_version=1)
SHIPPED_FAULT_TYPES: tuple[FaultType, ...] = tuple(_sensor_fault(s) for s in SENSORS) + (
    FaultType(
        "valve_seizing", subsystem=1, term="f_u", law="fraction", symbol="f_u", unit="-",
        onset_s=20.0, kappa=1e-2, magnitude=0.25, label="f_u",
        description="fuel valve seizing: the pump delivers 1 - β φ of the fuel setting", **_TABLE_6_4,
    ),
    FaultType(
        "bore_damage", subsystem=2, term="dV1_m3", law="ramp", symbol="f_z,V1", unit="m3/s",
        onset_s=15.0, kappa=1e-5, magnitude=3e-3, label="f_V1",
        description="cylinder bore damage: the cylinder volume grows by β R s", **_TABLE_6_4,
    ),
    FaultType(
        "turbine_seal_leak", subsystem=3, term="phi_tur", law="ramp", symbol="f_x,tur", unit="1/s",
        onset_s=15.0, kappa=2e-5, magnitude=3.5e-4, label="f_xtur",
        description="turbine seal leak: the receiver pressure leaks at the rate φ_tur x3/τ_pd", **_TABLE_6_4,
    ),
    FaultType(
        "turbine_lubrication_loss", subsystem=3, term="dT_sl_K", law="ramp", symbol="f_z,Tsl", unit="K/s",
        onset_s=30.0, kappa=1e3, magnitude=1.25, label="f_Tsl",
        description="turbine lubrication loss: the slip air heats up by β R s", **_TABLE_6_4,
    ),
    FaultType(
        "compressor_seal_leak", subsystem=4, term="phi_int", law="ramp", symbol="f_x,int", unit="1/s",
        onset_s=30.0, kappa=1e-4, magnitude=5e-2, label="f_xint",
        description="compressor seal leak: the charge-air pressure leaks at the rate φ_int x4/τ_TC", **_TABLE_6_4,
    ),
    FaultType(
        "compressor_lubrication_loss", subsystem=4, term="dT_inl_K", law="ramp", symbol="f_z,Tinl", unit="K/s",
        onset_s=30.0, kappa=1e3, magnitude=2.5, label="f_Tinl",
        description="compressor lubrication loss: the inlet air heats up by β R s", **_TABLE_6_4,
    ),
    FaultType(
        "intercooler_blockage", subsystem=4, term="dT_c_K", law="ramp", symbol="f_z,Tc", unit="K/s",
        onset_s=30.0, kappa=1e-3, magnitude=2.0, label="f_Tc",
        description="intercooler blockage: the compressor outlet temperature rises by β R s", **_TABLE_6_4,
    ),
)  # fmt: skip


# ----------------------------------------------------------------------------- plugins
def _plugin_modules() -> list:
    mods = []
    try:
        from importlib.metadata import entry_points

        for ep in entry_points(group=ENTRY_POINT_GROUP):
            mods.append((f"entry point {ep.name} ({ep.value})", ep.load()))
    except Exception as e:  # a broken plugin names itself
        raise ImportError(f"fault plugins of the entry-point group {ENTRY_POINT_GROUP}: {e}") from e
    for name in filter(None, (x.strip() for x in os.environ.get(FAULTS_ENV, "").split(os.pathsep))):
        where = f"{FAULTS_ENV} entry {name!r}"
        try:
            if name.endswith(".py"):
                path = Path(name)
                spec = importlib.util.spec_from_file_location(f"marine_fdi_fault_plugin_{path.stem}", path)
                if spec is None or not path.is_file():
                    raise FileNotFoundError(f"no file {name}")
                mod = importlib.util.module_from_spec(spec)
                spec.loader.exec_module(mod)
            else:
                mod = importlib.import_module(name)
        except Exception as e:
            raise ImportError(f"{where}: {e}") from e
        mods.append((where, mod))
    return mods


_LOADING: list = []


@lru_cache(maxsize=1)
def registered_fault_types() -> tuple[FaultType, ...]:
    """The shipped fault types, then those of the plugins (module docstring), checked for unique ids."""
    if _LOADING:
        raise ImportError("a fault plugin module must import only marine_fdi_env.engine.fault_registry")
    _LOADING.append(True)
    try:
        out = list(SHIPPED_FAULT_TYPES)
        for where, mod in _plugin_modules():
            items = getattr(mod, "FAULTS", None)
            if callable(items):
                items = items()
            if items is None or isinstance(items, (str, FaultType)):
                raise ImportError(f"{where}: the module must define FAULTS, a sequence of FaultType")
            for f in items:
                if not isinstance(f, FaultType):
                    raise ImportError(f"{where}: FAULTS must hold FaultType records, got {f!r}")
                if f.kind != "process":
                    raise ImportError(
                        f"{where}: fault {f.id}: a plugin declares process faults (a sensor fault is a sensor)"
                    )
                out.append(f)
    finally:
        _LOADING.clear()
    seen: set = set()
    for f in out:
        if f.id in seen:
            raise ImportError(f"fault id {f.id!r} is declared twice in the fault registry")
        seen.add(f.id)
    return tuple(out)


FAULT_TYPES: tuple[FaultType, ...] = registered_fault_types()
_BY_ID = {f.id: f for f in FAULT_TYPES}


def fault_type(fault_id: str) -> FaultType:
    """The record of a registered fault; ``ValueError`` naming the ids for an unknown one."""
    from ..suggest import lookup

    return lookup(_BY_ID, fault_id, "fault id")


def suite_fault_ids(version: int, kind: str | None = None) -> tuple[str, ...]:
    """The faults the suites of version ``version`` (``-vN``) draw from (``suite_version`` <= version), in
    registry order; only those of ``kind`` (``sensor``, ``process``) if given."""
    return tuple(
        f.id
        for f in FAULT_TYPES
        if f.suite_version is not None and f.suite_version <= version and kind in (None, f.kind)
    )


def registry_key() -> str:
    """A short hash of the registry's content (terms and fault types): recorded with the measured tables."""
    h = hashlib.sha256(repr([astuple(t) for t in TERMS] + [astuple(f) for f in FAULT_TYPES]).encode())
    return h.hexdigest()[:16]


# ----------------------------------------------------------------------------- measured tables
class MissingFaultTable(DataFileError):
    """A registered fault has no entry in a measured table (detectability limit, sure or sized cells)."""

    def __init__(self, table: str, faults, where: str):
        self.table, self.faults = table, tuple(faults)
        ids = " ".join(self.faults)
        super().__init__(
            f"fault{'s' if len(self.faults) > 1 else ''} {', '.join(map(repr, self.faults))} "
            f"{'have' if len(self.faults) > 1 else 'has'} no entry in the measured table {table} ({where}); "
            f"make it with: {TABLES_COMMAND.format(faults=ids)} and set {TABLES_ENV}=DIR (docs/extending.md)"
        )


def measured_table(rel: str):
    """The measured table ``rel`` (relative to the package's ``data/``, e.g. ``env/detectability.json``): the
    file of the folder ``MARINE_FDI_TABLES`` when it has one, else the package's."""
    root = os.environ.get(TABLES_ENV)
    if root:
        p = Path(root) / rel
        if p.is_file():
            return p
    return resources.files("marine_fdi_env").joinpath("data", *rel.split("/"))


def check_table_faults(rel: str, table_faults, fault_ids) -> None:
    """Refuse by name the faults of ``fault_ids`` that the measured table ``rel`` lacks
    (:class:`MissingFaultTable`)."""
    have = set(table_faults)
    missing = [f for f in fault_ids if f not in have]
    if missing:
        root = os.environ.get(TABLES_ENV)
        where = f"{TABLES_ENV}={root}" if root else "the package's data"
        raise MissingFaultTable(rel, missing, where)
