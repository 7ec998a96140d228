"""The three cell sets of the diagnosers' exoneration, one switch (``cells``):

* ``thesis``: the cells measured at the table 6.3/6.4 sizes only, the thesis's way (reference:
  ``sure_cells_table_magnitudes.json``, every single fault at its table size, 50 seeds x 2
  profiles; sequential: the table-size level of its sized cells, 6 seeds x 2 profiles x 2 signs).
  Right for faults of that size; a smaller fault is exonerated by a module it does not fire.
* ``grid``: sure at every size from 0.5x the detectability limit to the table size
  (``sure_cells.json``, ``sequential_sure_cells.json``): size-blind, so a large fault is
  exonerated only as if it might be small.
* ``sized`` (default): the cells of the size the evidence bounds the fault to, per fault and fired
  module (:mod:`.sized_cells`, :mod:`.sized_decision`).  The default because it keeps the grid's
  safety at small sizes (a fault is judged at least as large as its evidence requires, never
  larger than the measured runs allow) and the thesis's exoneration where the evidence shows a
  large fault.

The residuals, thresholds and module decisions do not depend on the cell set; only the minimal
diagnoses do, so one diagnoser can decide with several cell sets on the same residuals
(:class:`CellDecisions`, one per cell set).

Cells are measured for the thresholds they decide with: a reading of the observers' thresholds other
than ``local`` (:mod:`.thresholds`) has its own ``grid`` and ``sized`` cells, measured by the same
certainty grid at its thresholds (``data/diagnosis/thresholds/<reading>/``, :func:`cell_files`), and
its ``thesis`` cells are the top band of its sized cells (the table sizes' level, as the sequential
diagnoser's).
"""

from __future__ import annotations

import numpy as np

from .decision import DiagnosisState
from .modules import MODULE_IDS
from .sized_cells import SIZED_FILES, load_sized_cells
from .sized_decision import SizedDiagnosisState
from .sure_cells import SureCells, load_sure_cells
from .thresholds import DEFAULT_THRESHOLDS, check_thresholds

__all__ = [
    "CELL_SETS",
    "DEFAULT_CELLS",
    "check_cells",
    "cell_files",
    "size_blind_cells",
    "decision_state",
    "CellDecisions",
    "DecidesWithCellSets",
]

CELL_SETS = ("thesis", "grid", "sized")
DEFAULT_CELLS = "sized"
_GRID_FILES = {"reference": "sure_cells.json", "sequential": "sequential_sure_cells.json"}
_THESIS_FILE = "sure_cells_table_magnitudes.json"


def check_cells(cells: str) -> str:
    """``cells`` if it names a cell set; ValueError naming the allowed ones otherwise."""
    if cells not in CELL_SETS:
        raise ValueError(f"cells must be one of {', '.join(CELL_SETS)}, got {cells!r}")
    return cells


def cell_files(diagnoser: str, thresholds: str = DEFAULT_THRESHOLDS) -> dict[str, str | None]:
    """The cell files (relative to ``data/diagnosis/``) of a diagnoser deciding with a threshold
    reading: {"grid": ..., "sized": ..., "thesis": ... or None (the top band of the sized cells)}."""
    if diagnoser not in _GRID_FILES:
        raise ValueError(f"diagnoser must be 'reference' or 'sequential', got {diagnoser!r}")
    if check_thresholds(thresholds) == DEFAULT_THRESHOLDS:
        return {
            "grid": _GRID_FILES[diagnoser],
            "sized": SIZED_FILES[diagnoser],
            "thesis": _THESIS_FILE if diagnoser == "reference" else None,
        }
    if diagnoser != "reference":
        raise ValueError(f"the {diagnoser} diagnoser decides with the local thresholds only, got {thresholds!r}")
    return {
        "grid": f"thresholds/{thresholds}/{_GRID_FILES[diagnoser]}",
        "sized": f"thresholds/{thresholds}/{SIZED_FILES[diagnoser]}",
        "thesis": None,
    }


def size_blind_cells(diagnoser: str, cells: str, thresholds: str = DEFAULT_THRESHOLDS) -> SureCells:
    """The ``thesis`` or ``grid`` cells of ``reference`` or ``sequential`` (with a threshold reading)."""
    files = cell_files(diagnoser, thresholds)
    if check_cells(cells) == "grid":
        return load_sure_cells(files["grid"])
    if cells == "thesis":
        return load_sure_cells(files["thesis"]) if files["thesis"] else load_sized_cells(files["sized"]).top_band()
    raise ValueError("the sized cells are not size-blind: use decision_state")


def decision_state(
    diagnoser: str, cells: str, max_cardinality: int | None = 2, thresholds: str = DEFAULT_THRESHOLDS
) -> DiagnosisState:
    """A fresh decision state of a diagnoser (``reference`` or ``sequential``) with a cell set
    (measured at the threshold reading ``thresholds``): exoneration by sure cells, grace periods and
    the time order."""
    files = cell_files(diagnoser, thresholds)
    if check_cells(cells) == "sized":
        return SizedDiagnosisState(load_sized_cells(files["sized"]), max_cardinality=max_cardinality)
    sc = size_blind_cells(diagnoser, cells, thresholds)
    return DiagnosisState(
        exoneration=sc.sure,
        max_cardinality=max_cardinality,
        temporal=True,
        settle_s=sc.settle_times(),
        grace_s=sc.grace_times(),
    )


class CellDecisions:
    """The decision states of N engines with one cell set: the part of a diagnoser (``reference``
    or ``sequential``) that depends on its cells.

    ``exoneration`` as :class:`~marine_fdi_env.diagnosis.agent.ReferenceDiagnoser` (``"sure"``: the
    cells ``cells`` measured at the threshold reading ``thresholds``; ``"none"`` or ``"all"``: no
    cells).  Per engine, ``next_expiry`` [s] is the
    next time a grace period of its state ends and ``next_peak`` (19,) the running peak ratios above
    which a size band moves up (sized cells; inf: none pending): until then an update that fires no
    new module changes nothing, so the diagnosers skip it.
    """

    def __init__(
        self,
        diagnoser: str,
        n: int,
        cells: str,
        exoneration: str,
        max_cardinality: int | None,
        thresholds: str = DEFAULT_THRESHOLDS,
    ) -> None:
        self.diagnoser, self.n, self.cells = diagnoser, int(n), check_cells(cells)
        self.exoneration, self.max_cardinality = exoneration, max_cardinality
        self.thresholds = check_thresholds(thresholds)
        self.sized = exoneration == "sure" and self.cells == "sized"
        self.reset()

    def new_state(self) -> DiagnosisState:
        """A fresh decision state of one engine."""
        if self.exoneration == "sure":
            return decision_state(self.diagnoser, self.cells, self.max_cardinality, self.thresholds)
        return DiagnosisState(
            exoneration=True if self.exoneration == "all" else None, max_cardinality=self.max_cardinality
        )

    def reset(self) -> None:
        self.decisions = [self.new_state() for _ in range(self.n)]
        self.next_expiry = np.full(self.n, np.inf)
        self.next_peak = np.full((self.n, len(MODULE_IDS)), np.inf)

    def reset_engines(self, engines) -> None:
        for i in np.asarray(engines, dtype=np.int64).reshape(-1):
            self.decisions[i] = self.new_state()
            self.next_expiry[i] = np.inf
            self.next_peak[i] = np.inf

    def declarations(self, slots) -> tuple[np.ndarray, np.ndarray]:
        """(detected (k,) bool, diagnoses (k,) object: lists of sorted fault-id lists, empty when
        not detected) of the engines ``slots``: the environment's ``info["reference"]`` /
        ``info["sequential"]``."""
        det = np.zeros(len(slots), dtype=bool)
        diag = np.empty(len(slots), dtype=object)
        for j, s in enumerate(slots):
            st = self.decisions[s]
            det[j] = bool(st.detected)
            diag[j] = [sorted(d) for d in st.diagnoses] if st.detected else []
        return det, diag


class DecidesWithCellSets:
    """A diagnoser's cell sets: ``cells`` (the constructor's, first) and those :meth:`add_cells`
    adds, each with its :class:`CellDecisions` (``_deciders``, made by ``_decider(cells)``) fed the
    same stream.  ``_started``: whether a block has been fed since the last reset."""

    cells: str
    cell_sets: tuple[str, ...]
    _deciders: list

    def add_cells(self, cells: str) -> None:
        """Decide with the cell set ``cells`` too, on the same stream (its conclusions:
        :meth:`decider`); before the first block."""
        if self._started:
            raise RuntimeError("add_cells before the first block: a cell set decides from the first sample")
        if check_cells(cells) not in self.cell_sets:
            self.cell_sets += (cells,)
            self._deciders.append(self._decider(cells))

    def decider(self, cells: str | None = None) -> CellDecisions:
        """The decisions with the cell set ``cells`` (default: the constructor's)."""
        c = self.cells if cells is None else cells
        if c not in self.cell_sets:
            raise ValueError(f"cells must be one of the cell sets decided ({', '.join(self.cell_sets)}), got {c!r}")
        return self._deciders[self.cell_sets.index(c)]

    @property
    def needs_peaks(self) -> bool:
        """Whether a cell set decided is sized (its size bands follow the running peak ratios)."""
        return any(d.sized for d in self._deciders)

    @property
    def decisions(self) -> list[DiagnosisState]:
        """The engines' decision states with the constructor's cell set."""
        return self._deciders[0].decisions
