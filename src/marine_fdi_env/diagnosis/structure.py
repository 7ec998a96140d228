"""Fault signature matrices derived from the model structure, structural detectability and
isolability, and the comparison with the thesis's tables 6.5-6.8.

Everything here is *derived* from :mod:`marine_fdi_env.diagnosis.modules` (which sensors each ARR
reads, which model equations it evaluates) and ``EQUATION_FAULTS`` (which process faults enter
which equation); no signature is typed by hand.  The only hand-typed tables are the thesis's
own (:func:`thesis_tables`), transcribed for the comparison.

Rules (the fault signature matrix, FSM, rows = 19 modules, columns = 26 faults):

* a sensor fault ``S<l>.<j>`` affects the ARR of module M iff M reads that sensor (its own sensor
  set or an interconnection sensor of table 6.2, ``ModuleSpec.all_sensors``);
* a process fault affects the ARR of M iff it enters one of the equations M evaluates
  (``ModuleSpec.equations`` and ``EQUATION_FAULTS``).

A True cell means *may be affected* (structural sensitivity), not *will fire*: whether a fault of a
given size crosses the threshold is a numeric question (the thesis marks the uncertain cells with
``*``).  Consistency-based diagnosis without exoneration (:mod:`.decision`) needs only the
structural support; exoneration needs to know which cells fire for sure.

Per-agent layout (thesis tables 6.5-6.8): the rows are the agent's modules; the columns are the
agent's own sensor faults, then the sensor faults propagated from other agents (interconnection
sensors), then process faults of other subsystems that reach the agent (not in the thesis, which
says process faults do not propagate; ours do through the engine speed), then the agent's own
process faults.

Global propagation matrix F^chi (eq. 5.20-5.22; the thesis's table 6.9 is missing): rows = agents
1-4, columns = faults; 1 if the fault belongs to the agent's subsystem and some module of the agent
sees it, ``*`` (stored as 2) if it belongs to another subsystem and reaches the agent, 0 otherwise.

Isolability (single faults, no exoneration, the standard structural definition): fault i is
isolable from fault j iff some ARR is sensitive to i and not to j, i.e. column i is not a subset
of column j.  Faults with identical columns are mutually non-isolable.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ..engine.fault_registry import fault_type
from ..engine.faults import FAULT_IDS, PROCESS_FAULT_IDS
from ..engine.sensors import SENSOR_IDS, SENSORS
from .modules import AGENTS, EQUATION_FAULTS, MODULE_IDS, MODULES, ModuleSpec

__all__ = [
    "STAR",
    "fault_signature_matrix",
    "fault_support",
    "fault_modules",
    "fault_agent",
    "AgentMatrix",
    "agent_signature_matrices",
    "global_propagation_matrix",
    "fault_reach",
    "detectability",
    "isolability_matrix",
    "non_isolable_pairs",
    "identical_signature_groups",
    "isolability_report",
    "multiple_fault_signature",
    "checked_sensor_matrix",
    "ThesisTable",
    "THESIS_SYMBOLS",
    "thesis_tables",
    "thesis_signature_matrix",
    "thesis_global_propagation_matrix",
    "CellDifference",
    "compare_with_thesis",
    "structural_model",
    "module_equation_sets",
    "toolbox_crosscheck",
    "markdown_tables",
]

STAR = 2  # code of the thesis's '*' ("may be affected") in integer matrices

N_MODULES = len(MODULE_IDS)
N_FAULTS = len(FAULT_IDS)
_FAULT_INDEX = {f: i for i, f in enumerate(FAULT_IDS)}
_MODULE_INDEX = {m: i for i, m in enumerate(MODULE_IDS)}
_MODULE_BY_ID = {m.id: m for m in MODULES}


def _fault_index(fault_id: str) -> int:
    try:
        return _FAULT_INDEX[fault_id]
    except KeyError:
        raise ValueError(f"unknown fault id {fault_id!r}; allowed: {', '.join(FAULT_IDS)}") from None


def _module(module_id: str) -> ModuleSpec:
    try:
        return _MODULE_BY_ID[module_id]
    except KeyError:
        raise ValueError(f"unknown module {module_id!r}; allowed: {', '.join(MODULE_IDS)}") from None


def fault_agent(fault_id: str) -> int:
    """The subsystem/agent a fault belongs to (its registry record's: l of ``S<l>.<j>``, table 6.4's for a
    process fault)."""
    _fault_index(fault_id)
    return fault_type(fault_id).subsystem


# ----------------------------------------------------------------------------- the derived FSM
def _module_faults(m: ModuleSpec) -> tuple[str, ...]:
    sens = set(m.all_sensors)
    proc = {f for eq in m.equations for f in EQUATION_FAULTS[eq]}
    return tuple(f for f in FAULT_IDS if f in sens or f in proc)


@functools.lru_cache(maxsize=None)
def _fsm() -> np.ndarray:
    fsm = np.zeros((N_MODULES, N_FAULTS), dtype=bool)
    for i, m in enumerate(MODULES):
        for f in _module_faults(m):
            fsm[i, _FAULT_INDEX[f]] = True
    fsm.setflags(write=False)
    return fsm


def fault_signature_matrix() -> tuple[np.ndarray, tuple[str, ...], tuple[str, ...]]:
    """(FSM, module_ids, fault_ids): bool (19, 26), FSM[m, f] = ARR of module m sensitive to fault f.

    Derived from ``MODULES`` and ``EQUATION_FAULTS`` (see the module docstring); a fresh writable
    copy each call.
    """
    return _fsm().copy(), MODULE_IDS, FAULT_IDS


def fault_support(module_id: str) -> tuple[str, ...]:
    """Faults the ARR of a module is sensitive to (row of the FSM), in ``FAULT_IDS`` order."""
    i = _MODULE_INDEX[_module(module_id).id]
    return tuple(f for f, s in zip(FAULT_IDS, _fsm()[i]) if s)


def fault_modules(fault_id: str) -> tuple[str, ...]:
    """Modules whose ARR is sensitive to a fault (column of the FSM), in ``MODULE_IDS`` order."""
    j = _fault_index(fault_id)
    return tuple(m for m, s in zip(MODULE_IDS, _fsm()[:, j]) if s)


def checked_sensor_matrix() -> np.ndarray:
    """Bool (19, 26): the cells where a fault *surely* violates an ARR, from structure alone: a
    sensor fault on the sensor the module checks (``ModuleSpec.checked_sensor``; the residual is
    that reading minus the model's value, so the offset enters it with unit gain and an offset
    larger than the threshold width fires it).  No process-fault cell is certain structurally
    (incipient faults, magnitude-dependent).  A safe exoneration matrix for :mod:`.decision`."""
    out = np.zeros((N_MODULES, N_FAULTS), dtype=bool)
    for i, m in enumerate(MODULES):
        out[i, _FAULT_INDEX[m.checked_sensor]] = True
    return out


def multiple_fault_signature(fault_ids) -> np.ndarray:
    """Bool (19,): modules structurally affected by a set of faults (union of their columns)."""
    out = np.zeros(N_MODULES, dtype=bool)
    for f in fault_ids:
        out |= _fsm()[:, _fault_index(f)]
    return out


# ----------------------------------------------------------------------------- per-agent matrices
@dataclass(frozen=True)
class AgentMatrix:
    """Local fault signature matrix of agent M^(l) in the thesis's layout (tables 6.5-6.8).

    ``matrix`` is bool (modules x columns); the column groups are listed separately and
    ``columns`` is their concatenation.
    """

    agent: int
    module_ids: tuple[str, ...]
    local_sensor_faults: tuple[str, ...]
    propagated_sensor_faults: tuple[str, ...]
    propagated_process_faults: tuple[str, ...]
    local_process_faults: tuple[str, ...]
    matrix: np.ndarray

    @property
    def columns(self) -> tuple[str, ...]:
        return (
            self.local_sensor_faults
            + self.propagated_sensor_faults
            + self.propagated_process_faults
            + self.local_process_faults
        )

    def column_group(self, fault_id: str) -> str:
        for name in (
            "local_sensor_faults",
            "propagated_sensor_faults",
            "propagated_process_faults",
            "local_process_faults",
        ):
            if fault_id in getattr(self, name):
                return name
        raise ValueError(f"fault {fault_id!r} is not a column of agent {self.agent}'s matrix")


def agent_signature_matrices() -> dict[int, AgentMatrix]:
    """The four local matrices F^(l) (eq. 5.20 context), derived from the FSM.

    Local columns: all sensors / process faults of subsystem l.  Propagated columns: faults of
    other subsystems that affect at least one module of agent l (ordered by subsystem, then id).
    """
    fsm = _fsm()
    out = {}
    for a, mods in AGENTS.items():
        rows = [_MODULE_INDEX[m] for m in mods]
        reach = fsm[rows].any(axis=0)
        loc_s = tuple(s for s in SENSOR_IDS if fault_agent(s) == a)
        loc_p = tuple(p for p in PROCESS_FAULT_IDS if fault_agent(p) == a)
        prop_s = tuple(s for s in SENSOR_IDS if fault_agent(s) != a and reach[_FAULT_INDEX[s]])
        prop_p = tuple(p for p in PROCESS_FAULT_IDS if fault_agent(p) != a and reach[_FAULT_INDEX[p]])
        cols = [_FAULT_INDEX[f] for f in loc_s + prop_s + prop_p + loc_p]
        mat = fsm[np.ix_(rows, cols)].copy()
        out[a] = AgentMatrix(a, mods, loc_s, prop_s, prop_p, loc_p, mat)
    return out


def global_propagation_matrix() -> tuple[np.ndarray, tuple[int, ...], tuple[str, ...]]:
    """(F^chi int8 (4, 26), agents, fault_ids): 1 = own fault seen by the agent, 2 (``*``) = fault of
    another subsystem that reaches the agent, 0 = not seen.  The missing table 6.9, derived."""
    fsm = _fsm()
    agents = tuple(sorted(AGENTS))
    out = np.zeros((len(agents), N_FAULTS), dtype=np.int8)
    for r, a in enumerate(agents):
        rows = [_MODULE_INDEX[m] for m in AGENTS[a]]
        reach = fsm[rows].any(axis=0)
        for j, f in enumerate(FAULT_IDS):
            if reach[j]:
                out[r, j] = 1 if fault_agent(f) == a else STAR
    return out, agents, FAULT_IDS


def fault_reach() -> dict[str, tuple[int, ...]]:
    """Agents whose modules a fault reaches (nonzero rows of its F^chi column)."""
    g, agents, _ = global_propagation_matrix()
    return {f: tuple(a for a, v in zip(agents, g[:, j]) if v) for j, f in enumerate(FAULT_IDS)}


# ----------------------------------------------------------------------------- detectability / isolability
def detectability(fsm: np.ndarray | None = None) -> dict[str, bool]:
    """Structural detectability: a fault is detectable iff some ARR is sensitive to it."""
    fsm = _fsm() if fsm is None else np.asarray(fsm, dtype=bool)
    return {f: bool(fsm[:, j].any()) for j, f in enumerate(FAULT_IDS)}


def isolability_matrix(fsm: np.ndarray | None = None) -> np.ndarray:
    """Bool (26, 26): I[i, j] = fault i is isolable from fault j (some ARR sensitive to i and not
    to j; single faults, no exoneration).  The diagonal is False.

    Note: ``faultdiagnosistoolbox`` returns the complement (its ``im[i, j] = 1`` means *not*
    isolable, diagonal 1).
    """
    fsm = _fsm() if fsm is None else np.asarray(fsm, dtype=bool)
    a = fsm.astype(np.int64)
    # count of ARRs sensitive to i and not to j
    n = a.T @ (1 - a)
    return n > 0


def non_isolable_pairs(fsm: np.ndarray | None = None) -> list[tuple[str, str]]:
    """Ordered pairs (i, j), i != j, with fault i not isolable from fault j (column i ⊆ column j)."""
    iso = isolability_matrix(fsm)
    return [(FAULT_IDS[i], FAULT_IDS[j]) for i in range(N_FAULTS) for j in range(N_FAULTS) if i != j and not iso[i, j]]


def identical_signature_groups(fsm: np.ndarray | None = None) -> list[tuple[str, ...]]:
    """Groups (size >= 2) of faults with identical columns: mutually non-isolable."""
    fsm = _fsm() if fsm is None else np.asarray(fsm, dtype=bool)
    groups: dict[bytes, list[str]] = {}
    for j, f in enumerate(FAULT_IDS):
        groups.setdefault(fsm[:, j].tobytes(), []).append(f)
    return [tuple(g) for g in groups.values() if len(g) > 1]


def isolability_report(fsm: np.ndarray | None = None) -> dict:
    """Summary: undetectable faults, identical-column groups, and for every fault the faults it is
    not isolable from (its column is a subset of theirs), with the modules that make the difference
    missing."""
    fsm = _fsm() if fsm is None else np.asarray(fsm, dtype=bool)
    det = detectability(fsm)
    iso = isolability_matrix(fsm)
    not_iso = {}
    for i, f in enumerate(FAULT_IDS):
        js = [FAULT_IDS[j] for j in range(N_FAULTS) if j != i and not iso[i, j]]
        if js:
            not_iso[f] = js
    fully = [f for i, f in enumerate(FAULT_IDS) if det[f] and all(iso[i, j] for j in range(N_FAULTS) if j != i)]
    return {
        "undetectable": [f for f, d in det.items() if not d],
        "identical_groups": identical_signature_groups(fsm),
        "not_isolable_from": not_iso,
        "isolable_from_all": fully,
        "n_non_isolable_ordered_pairs": int(sum(len(v) for v in not_iso.values())),
    }


# ----------------------------------------------------------------------------- thesis tables 6.5-6.8
THESIS_SYMBOLS: dict[str, str] = {f: fault_type(f).thesis_symbol for f in FAULT_IDS}


@dataclass(frozen=True)
class ThesisTable:
    """One of the thesis's tables 6.5-6.8 as printed: rows ε(l,q) = modules, columns = faults
    (ids of ``FAULT_IDS``; ``symbols`` holds the thesis's symbols), values 0, 1 or '*'."""

    table: str
    agent: int
    rows: tuple[str, ...]
    columns: tuple[str, ...]
    values: tuple[tuple, ...]

    @property
    def symbols(self) -> tuple[str, ...]:
        return tuple(THESIS_SYMBOLS[c] for c in self.columns)

    def value(self, module_id: str, fault_id: str):
        """The printed cell; 0 for a fault that is not a column of the table."""
        if fault_id not in self.columns:
            return 0
        return self.values[self.rows.index(module_id)][self.columns.index(fault_id)]


_S = "*"


def thesis_tables() -> dict[str, ThesisTable]:
    """Tables 6.5-6.8 of the thesis (lines 1331-1370), transcribed cell by cell as printed."""
    t65 = ThesisTable("6.5", 1, ("M1.1", "M1.2"), ("S1.1", "S1.2", "valve_seizing"), ((1, 0, 1), (0, 1, 1)))
    t66 = ThesisTable(
        "6.6",
        2,
        AGENTS[2],
        ("S2.1", "S2.2", "S2.3", "S2.4", "S2.5", "S2.6", "S1.1", "S1.2", "S4.1", "S4.2", "S4.3", "S4.4", "bore_damage"),
        (
            (1, 0, 0, 0, 0, 0, 1, 0, 1, 0, 0, 0, 1),
            (0, 1, 0, 0, 0, 0, 0, 1, 0, 1, 0, 0, 1),
            (0, 0, 1, 0, 0, 0, 1, 0, 1, 0, 1, 0, 1),
            (0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 0, 1, 1),
            (0, 0, _S, 0, 1, 0, _S, 0, _S, 0, _S, 0, _S),
            (0, 0, 0, _S, 0, 1, 0, _S, 0, _S, 0, _S, _S),
        ),
    )
    t67 = ThesisTable(
        "6.7",
        3,
        AGENTS[3],
        (
            "S3.1",
            "S3.2",
            "S3.3",
            "S3.4",
            "S3.5",
            "S1.1",
            "S1.2",
            "S2.1",
            "S2.2",
            "S2.3",
            "S2.4",
            "S4.1",
            "S4.2",
            "S4.3",
            "S4.4",
            "turbine_seal_leak",
            "turbine_lubrication_loss",
        ),
        (
            (1, 0, _S, 0, 0, 1, 0, 0, 0, 0, 0, _S, 0, _S, 0, 1, 0),
            (0, 1, 0, _S, 0, 0, 1, 0, 0, 0, 0, 0, _S, 0, _S, 1, 0),
            (_S, 0, 1, 0, 0, _S, 0, _S, 0, _S, 0, _S, 0, _S, 0, 0, 1),
            (0, _S, 0, 1, 0, 0, _S, 0, _S, 0, _S, 0, _S, 0, _S, 0, 1),
            (_S, 0, 1, 1, 1, 0, 0, 0, 0, 0, 0, _S, _S, 0, 0, 0, 0),
        ),
    )
    t68 = ThesisTable(
        "6.8",
        4,
        AGENTS[4],
        (
            "S4.1",
            "S4.2",
            "S4.3",
            "S4.4",
            "S4.5",
            "S4.6",
            "S1.1",
            "S1.2",
            "S3.1",
            "S3.2",
            "S3.3",
            "S3.4",
            "S3.5",
            "compressor_seal_leak",
            "compressor_lubrication_loss",
            "intercooler_blockage",
        ),
        (
            (1, 0, _S, 0, 0, 0, _S, 0, 1, 0, _S, 0, 0, 1, 0, 0),
            (0, 1, 0, _S, 0, 0, 0, _S, 0, 1, 0, _S, 0, 1, 0, 0),
            (0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 0),
            (0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 0),
            (_S, 0, _S, 0, 1, 0, _S, 0, _S, 0, _S, 0, _S, 0, 0, 1),
            (0, _S, 0, _S, 0, 1, _S, _S, 0, _S, 0, _S, 0, 0, 0, 1),
        ),
    )
    tables = {t.table: t for t in (t65, t66, t67, t68)}
    for t in tables.values():
        assert all(len(r) == len(t.columns) for r in t.values) and len(t.values) == len(t.rows), t.table
    return tables


def thesis_signature_matrix() -> np.ndarray:
    """Tables 6.5-6.8 assembled into one int8 (19, 26) matrix in our order: 0, 1, or 2 (= '*').
    A fault that is not a column of an agent's table is 0 on that agent's rows."""
    out = np.zeros((N_MODULES, N_FAULTS), dtype=np.int8)
    for t in thesis_tables().values():
        for r, m in enumerate(t.rows):
            for c, f in enumerate(t.columns):
                v = t.values[r][c]
                out[_MODULE_INDEX[m], _FAULT_INDEX[f]] = STAR if v == _S else int(v)
    return out


def thesis_global_propagation_matrix() -> np.ndarray:
    """F^chi int8 (4, 26) built from tables 6.5-6.8 by the thesis's rule (section 5.3.3): 1 for a
    fault of the agent's own subsystem that its table marks, '*' (2) for a fault of another
    subsystem that its table marks, 0 otherwise.  Our reconstruction of the missing table 6.9."""
    th = thesis_signature_matrix()
    agents = tuple(sorted(AGENTS))
    out = np.zeros((len(agents), N_FAULTS), dtype=np.int8)
    for r, a in enumerate(agents):
        rows = [_MODULE_INDEX[m] for m in AGENTS[a]]
        reach = (th[rows] != 0).any(axis=0)
        for j, f in enumerate(FAULT_IDS):
            if reach[j]:
                out[r, j] = 1 if fault_agent(f) == a else STAR
    return out


@dataclass(frozen=True)
class CellDifference:
    """A cell where the derived FSM and the thesis's tables disagree on sensitivity.

    ours: derived FSM cell.  thesis: printed value (0, 1 or '*'; 0 also for a column the table
    does not have).  kind: 'ours_only' (we are sensitive, the thesis says 0) or 'thesis_only'.
    """

    table: str
    module: str
    fault: str
    thesis_symbol: str
    ours: bool
    thesis: object
    kind: str
    reason: str


def _sensor_phrase(m: ModuleSpec) -> str:
    own = ", ".join(m.sensors)
    ic = ", ".join(m.interconnection) or "none"
    return f"table 6.2 gives S({m.id[1:].replace('.', ',')}) = {{{own}}} with interconnection sensors {{{ic}}}"


# Notes on specific cells, keyed by (module, fault): what else the thesis's tables say about the
# same fault/sensor, to show the printed cell is a slip rather than a modelling choice.
_CELL_NOTES: dict[tuple[str, str], str] = {
    ("M2.1", "S4.3"): (
        "the Seiliger cycle needs the inlet temperature T1 (S4.3) to compute p6; table 6.6 "
        "marks f_3^(4) in row ε(2,3), whose module reads the same interconnection sensors, "
        "but leaves it 0 in row ε(2,1)"
    ),
    ("M2.2", "S4.4"): (
        "the Seiliger cycle needs T1 (S4.4) to compute p6; table 6.6 marks f_4^(4) in row "
        "ε(2,4), same interconnection sensors, but leaves it 0 in row ε(2,2)"
    ),
    ("M3.5", "S3.2"): (
        "M3.5 evaluates T_out = T_in (1 - η_t(x4)(1 - Π(x3))) and takes x3 from S3.2; table "
        "6.7 row ε(3,5) marks f_1^(3) instead, i.e. it mixes the primary chain into the "
        "redundant-chain module"
    ),
    ("M3.5", "S3.1"): (
        "M3.5 is a redundant-chain (even-index) module: x3 comes from S3.2, not S3.1; table "
        "6.7 row ε(3,5) contradicts table 6.2"
    ),
    ("M3.5", "S3.3"): (
        "M3.5 takes T_in from S3.4 only; table 6.7 row ε(3,5) marks both f_3^(3) and f_4^(3) "
        "although table 6.2 lists only S3.4"
    ),
    ("M3.5", "S4.1"): (
        "M3.5 takes x4 (turbine efficiency η_t(x4)) from S4.2 only; table 6.7 row ε(3,5) "
        "marks both f_1^(4) and f_2^(4) although table 6.2 lists only S4.2"
    ),
    ("M4.6", "S1.1"): (
        "M4.6 is a redundant-chain module reading x1 from S1.2 only; table 6.8 row ε(4,6) "
        "marks both f_1^(1) and f_2^(1) although table 6.2 lists only S1.2"
    ),
    ("M4.6", "S3.5"): (
        "T_out (S3.5) enters eq. 3.38 of M4.6 exactly as in M4.5, where table 6.8 marks "
        "f_5^(3) with '*'; row ε(4,6) leaves it 0"
    ),
}


def _reason(m: ModuleSpec, fault: str, ours: bool, table: str, in_table: bool) -> str:
    sym = THESIS_SYMBOLS[fault]
    parts = []
    if fault in SENSOR_IDS:
        if ours:
            role = "its own sensor set" if fault in m.sensors else "an interconnection sensor"
            parts.append(f"{m.id} reads {fault} ({role}): {_sensor_phrase(m)}")
        else:
            parts.append(f"{m.id} does not read {fault}: {_sensor_phrase(m)}")
    else:
        eqs = [e for e in m.equations if fault in EQUATION_FAULTS[e]]
        if ours:
            if eqs == ["speed"]:
                parts.append(
                    f"{fault} ({sym}) changes the cylinder process of Σ2 and so the engine speed n, which is "
                    f"not measured; {m.id} computes n from Σ2's speed equation (propeller law with the cycle "
                    f"torque, eq. 3.10-3.13) fed with its interconnection sensors, so the fault enters its ARR "
                    f"(the thesis states that process faults do not propagate between agents)"
                )
            else:
                parts.append(f"{fault} enters equation(s) {', '.join(eqs)} evaluated by {m.id}")
        else:
            parts.append(f"{fault} enters none of the equations {', '.join(m.equations)} of {m.id}")
    note = _CELL_NOTES.get((m.id, fault))
    if note:
        parts.append(note)
    if not in_table:
        parts.append(f"table {table} has no column {sym}")
    return "; ".join(parts)


def compare_with_thesis() -> list[CellDifference]:
    """Every cell where the derived FSM's sensitivity differs from the thesis's tables 6.5-6.8
    ('1' and '*' both count as sensitive), with the reason.  Cells of a fault that is not a column
    of an agent's table count as 0 for the thesis."""
    fsm = _fsm()
    out = []
    for t in thesis_tables().values():
        for m_id in t.rows:
            m = _module(m_id)
            i = _MODULE_INDEX[m_id]
            for j, f in enumerate(FAULT_IDS):
                ours = bool(fsm[i, j])
                tv = t.value(m_id, f)
                theirs = tv != 0
                if ours == theirs:
                    continue
                out.append(
                    CellDifference(
                        table=t.table,
                        module=m_id,
                        fault=f,
                        thesis_symbol=THESIS_SYMBOLS[f],
                        ours=ours,
                        thesis=tv,
                        kind="ours_only" if ours else "thesis_only",
                        reason=_reason(m, f, ours, t.table, f in t.columns),
                    )
                )
    return out


# ----------------------------------------------------------------------------- structural model (toolbox cross-check)
# Physical structure of the model equations, used only to cross-check the derived FSM with
# faultdiagnosistoolbox.  Each equation carries the equation id of modules.EQUATION_FAULTS it
# belongs to (None: an auxiliary relation without faults), so its faults are not retyped here.
# Variables follow the implementation (subsystems/*.py, model.solve_algebraic):
#   n, m1_cyl, p6, T6 from engine_block(x1, x4, T1, V1 + f_V1) (speed loop = propeller law),
#   torque_given_speed(x1, x4, T1, T6, n), gas-exchange m1 = x4 V1 / (R T1) (nominal V1),
#   s_sl = slip_ratio(x3, x4, m1, n), receiver_and_turbine(x1, x3, x4, m1, s_sl, n, T6, p6, T_sl),
#   T_out(T_in, x3, x4), h4(x4, δ_f(x1, m1, s_sl), T_in, Π(x3)), T_co(δ_f, T_in, T_out), T1(T_inl).
_STATES = ("x1", "x3", "x4")
_MODEL_EQUATIONS: tuple[tuple[str, str | None, tuple[str, ...]], ...] = (
    # (name, EQUATION_FAULTS id, unknowns and known inputs)
    ("fuel", "fuel", ("dx1", "x1", "u")),
    ("speed", "speed", ("n", "x1", "x4", "T1")),
    ("cycle_p6", "cycle", ("p6", "x1", "x4", "T1", "n")),
    ("cycle_T6", "cycle", ("T6", "x1", "x4", "T1", "n")),
    ("torque", "torque", ("torque", "x1", "x4", "T1", "T6", "n")),
    ("gas_m1", None, ("m1", "x4", "T1")),
    ("slip", None, ("s_sl", "x3", "x4", "m1", "n")),
    ("receiver", "receiver", ("dx3", "x3", "x1", "m1", "s_sl", "n", "T_in")),
    ("mixing", "mixing", ("T_in", "x1", "x3", "x4", "m1", "s_sl", "n", "T6", "p6")),
    ("turbine", "turbine", ("T_out", "T_in", "x3", "x4")),
    ("charge", "charge", ("dx4", "x4", "x1", "m1", "s_sl", "T_in", "x3")),
    ("inlet", "inlet", ("T1",)),
    ("comp_out", "comp_out", ("T_co", "x1", "m1", "s_sl", "T_in", "T_out")),
)
_UNKNOWNS = (
    "x1",
    "dx1",
    "x3",
    "dx3",
    "x4",
    "dx4",
    "n",
    "m1",
    "s_sl",
    "p6",
    "T6",
    "torque",
    "T_in",
    "T_out",
    "T1",
    "T_co",
)
# sensors.py variable names -> structural unknowns
_SENSOR_VARIABLE = {
    "x1": "x1",
    "p6": "p6",
    "T6": "T6",
    "torque": "torque",
    "x3": "x3",
    "T_in": "T_in",
    "T_out": "T_out",
    "x4": "x4",
    "T1": "T1",
    "T_co": "T_co",
}


def _fault_entries() -> dict[str, list[str]]:
    """Model equations (names) each process fault enters, through ``EQUATION_FAULTS``."""
    out: dict[str, list[str]] = {}
    for name, eq_id, _ in _MODEL_EQUATIONS:
        for f in EQUATION_FAULTS[eq_id] if eq_id is not None else ():
            out.setdefault(f, []).append(name)
    return out


def structural_model() -> dict:
    """The engine's structural model in faultdiagnosistoolbox's ``VarStruc`` format.

    Unknowns x: the physical variables (states, their derivatives, the algebraic variables and the
    unmeasured speed n, trapped mass m1, slip ratio s_sl); known z: the 19 sensor readings
    ``y_<id>`` and the fuel setting ``u``; faults f: the 26 fault ids.  Equations: the 13 model
    relations (faults from ``EQUATION_FAULTS``), three differential constraints dx = d/dt x, and
    one measurement equation y_s = var(s) + f_s per sensor.  The toolbox expects every fault in
    exactly one equation (its ``DetectabilityAnalysis`` fails otherwise), so a process fault that
    enters several relations (bore damage: speed, cycle, torque) becomes an unknown parameter
    ``theta_<fault>`` of those relations plus one relation ``theta = nominal + fault``.
    ``eq_names`` (extra key, remove before passing the dict to the toolbox) names the equations.
    """
    entries = _fault_entries()
    shared = {f for f, eqs in entries.items() if len(eqs) > 1}
    rels: list = []
    names: list[str] = []
    for name, eq_id, variables in _MODEL_EQUATIONS:
        faults = EQUATION_FAULTS[eq_id] if eq_id is not None else ()
        rels.append(list(variables) + [("theta_" + f if f in shared else f) for f in faults])
        names.append(name)
    for f in sorted(shared, key=FAULT_IDS.index):
        rels.append(["theta_" + f, f])
        names.append("fault_" + f)
    for s in _STATES:
        rels.append(["d" + s, s, "diff"])  # faultdiagnosistoolbox.DiffConstraint(dx, x)
        names.append("D" + s)
    for s in SENSORS:
        rels.append(["y_" + s.id, _SENSOR_VARIABLE[s.variable], s.id])
        names.append("sensor_" + s.id)
    unknowns = list(_UNKNOWNS) + ["theta_" + f for f in sorted(shared, key=FAULT_IDS.index)]
    return {
        "type": "VarStruc",
        "x": unknowns,
        "f": list(FAULT_IDS),
        "z": ["u"] + ["y_" + s for s in SENSOR_IDS],
        "rels": rels,
        "eq_names": names,
    }


def _eq_tags() -> list[tuple[str, str | None]]:
    """(kind, tag) per equation of :func:`structural_model`: ('model', eq id), ('fault', fault id),
    ('diff', state), ('sensor', sensor id)."""
    entries = _fault_entries()
    shared = [f for f in FAULT_IDS if len(entries.get(f, ())) > 1]
    tags: list[tuple[str, str | None]] = [("model", eq_id) for _, eq_id, _ in _MODEL_EQUATIONS]
    tags += [("fault", f) for f in shared]
    tags += [("diff", s) for s in _STATES]
    tags += [("sensor", s) for s in SENSOR_IDS]
    return tags


def module_equation_sets(mso_sets=None) -> dict[str, list[int]]:
    """For each module, the equations of :func:`structural_model` that form its ARR: the MSO set
    (of the model restricted to the module's sensors and the equations of its ``equations`` ids,
    auxiliary relations and differential constraints) that uses all the module's sensors and at
    least one equation of each of its equation ids.  Needs faultdiagnosistoolbox (MSO search);
    ``ValueError`` if a module has no such MSO or more than one."""
    import faultdiagnosistoolbox as fdt  # optional dependency

    md = structural_model()
    tags = _eq_tags()
    out: dict[str, list[int]] = {}
    for m in MODULES:
        allowed = [
            k
            for k, (kind, tag) in enumerate(tags)
            if (kind == "model" and (tag is None or tag in m.equations))
            or kind in ("diff", "fault")
            or (kind == "sensor" and tag in m.all_sensors)
        ]
        sub = dict(md, rels=[md["rels"][k] for k in allowed])
        sub.pop("eq_names")
        model = fdt.DiagnosisModel(sub, name=m.id)
        found = []
        for mso in model.MSO():
            eqs = sorted(allowed[int(k)] for k in mso)
            used_sensors = {tags[k][1] for k in eqs if tags[k][0] == "sensor"}
            used_ids = {tags[k][1] for k in eqs if tags[k][0] == "model" and tags[k][1] is not None}
            if used_sensors == set(m.all_sensors) and used_ids == set(m.equations):
                found.append(eqs)
        if len(found) != 1:
            raise ValueError(
                f"module {m.id}: {len(found)} MSO sets of the structural model match its sensors "
                f"{m.all_sensors} and equations {m.equations}; expected exactly one"
            )
        out[m.id] = found[0]
    return out


def toolbox_crosscheck() -> dict:
    """Cross-check with faultdiagnosistoolbox (optional; ``ImportError`` if it is not installed).

    Returns: ``accepted`` (the VarStruc model was parsed: incidence matrices of the right shape),
    ``module_msos`` (equation names of each module's ARR), ``fsm`` (bool (19, 26) from the
    toolbox's ``FSM`` of those sets), ``fsm_equal`` (equals :func:`fault_signature_matrix`),
    ``isolability_equal`` (toolbox ``IsolabilityAnalysisArrs`` vs :func:`isolability_matrix`),
    ``model_detectable`` / ``model_undetectable`` (``DetectabilityAnalysis`` of the whole model),
    ``model_isolability`` (bool (26, 26), isolable, from ``IsolabilityAnalysis``: what all MSO sets
    of the model could achieve, an upper bound for the 19 ARRs) and ``gained_pairs`` (pairs isolable
    at model level but not with the 19 ARRs), ``lost_pairs`` (the converse, expected empty) and
    ``model_redundancy`` (structural redundancy of the whole model).
    """
    import faultdiagnosistoolbox as fdt  # optional dependency

    md = structural_model()
    names = md.pop("eq_names")
    model = fdt.DiagnosisModel(md, name="MVFP engine")
    ne = len(md["rels"])
    accepted = (
        model.X.shape == (ne, len(md["x"]))
        and model.F.shape == (ne, len(md["f"]))
        and model.Z.shape == (ne, len(md["z"]))
        and int(model.F.sum()) > 0
        and int(model.X.sum()) > 0
    )
    sets = module_equation_sets()
    arrs = [np.asarray(sets[m], dtype=np.int64) for m in MODULE_IDS]
    fsm_tb = model.FSM(arrs).astype(bool)
    im_not = model.IsolabilityAnalysisArrs(arrs)  # 1 = NOT isolable
    iso_tb = np.asarray(im_not) == 0
    df, ndf = model.DetectabilityAnalysis()
    im_model_not = model.IsolabilityAnalysis()
    iso_model = np.asarray(im_model_not) == 0
    ours = isolability_matrix()
    gained = [
        (FAULT_IDS[i], FAULT_IDS[j])
        for i in range(N_FAULTS)
        for j in range(N_FAULTS)
        if i != j and iso_model[i, j] and not ours[i, j]
    ]
    lost = [
        (FAULT_IDS[i], FAULT_IDS[j])
        for i in range(N_FAULTS)
        for j in range(N_FAULTS)
        if i != j and ours[i, j] and not iso_model[i, j]
    ]
    return {
        "accepted": bool(accepted),
        "module_msos": {m: [names[k] for k in sets[m]] for m in MODULE_IDS},
        "fsm": fsm_tb,
        "fsm_equal": bool(np.array_equal(fsm_tb, _fsm())),
        "isolability_equal": bool(np.array_equal(iso_tb, ours)),
        "model_detectable": list(df),
        "model_undetectable": list(ndf),
        "model_isolability": iso_model,
        "gained_pairs": gained,
        "lost_pairs": lost,
        # the whole model's MSO sets are not enumerated: with structural redundancy 19 there are
        # too many (the toolbox ran for more than 10 minutes); the per-module searches are local
        "model_redundancy": int(model.Redundancy()),
    }


# ----------------------------------------------------------------------------- markdown (docs)
def _cell(v) -> str:
    if v is True or (isinstance(v, (int, np.integer)) and v == 1):
        return "1"
    if v == STAR or v == _S:
        return "*"
    return "."


def _short(f: str) -> str:
    return fault_type(f).label


def _md_table(header: list[str], rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join(["---"] * len(header)) + "|"]
    lines += ["| " + " | ".join(r) + " |" for r in rows]
    return "\n".join(lines)


def markdown_tables() -> dict[str, str]:
    """The tables of docs/diagnosis_structure.md, rendered from the derived structure (a test checks
    that the document contains them verbatim, so the document cannot drift from the code)."""
    fsm = _fsm()
    out: dict[str, str] = {}
    out["fsm"] = _md_table(
        ["module"] + [_short(f) for f in FAULT_IDS],
        [[m] + [_cell(bool(v)) for v in fsm[i]] for i, m in enumerate(MODULE_IDS)],
    )
    for a, am in agent_signature_matrices().items():
        header = ["module"] + [_short(f) for f in am.columns]
        rows = [[m] + [_cell(bool(v)) for v in am.matrix[r]] for r, m in enumerate(am.module_ids)]
        groups = (
            f"local sensors: {', '.join(am.local_sensor_faults)}; propagated sensors: "
            f"{', '.join(am.propagated_sensor_faults) or '-'}; propagated process faults: "
            f"{', '.join(am.propagated_process_faults) or '-'}; local process faults: "
            f"{', '.join(am.local_process_faults) or '-'}"
        )
        out[f"agent{a}"] = groups + "\n\n" + _md_table(header, rows)
    g, agents, _ = global_propagation_matrix()
    out["global"] = _md_table(
        ["agent"] + [_short(f) for f in FAULT_IDS],
        [[f"M({a})"] + [_cell(int(v)) for v in g[r]] for r, a in enumerate(agents)],
    )
    tg = thesis_global_propagation_matrix()
    out["thesis_global"] = _md_table(
        ["agent"] + [_short(f) for f in FAULT_IDS],
        [[f"M({a})"] + [_cell(int(v)) for v in tg[r]] for r, a in enumerate(agents)],
    )
    rep = isolability_report()
    rows = []
    for f, js in rep["not_isolable_from"].items():
        rows.append([f, ", ".join(js), ", ".join(fault_modules(f))])
    out["isolability"] = _md_table(["fault", "not isolable from", "its ARRs"], rows)
    diffs = compare_with_thesis()
    out["comparison"] = _md_table(
        ["table", "row", "fault (thesis symbol)", "ours", "thesis", "reason"],
        [
            [d.table, d.module, f"{d.fault} ({d.thesis_symbol})", "1" if d.ours else "0", str(d.thesis), d.reason]
            for d in diffs
        ],
    )
    return out
