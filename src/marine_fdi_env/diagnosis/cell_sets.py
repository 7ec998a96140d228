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
diagnoses do.
"""

from __future__ import annotations

from .decision import DiagnosisState
from .sized_cells import SIZED_FILES, load_sized_cells
from .sized_decision import SizedDiagnosisState
from .sure_cells import SureCells, load_sure_cells

__all__ = ["CELL_SETS", "DEFAULT_CELLS", "check_cells", "size_blind_cells", "decision_state"]

CELL_SETS = ("thesis", "grid", "sized")
DEFAULT_CELLS = "sized"
_GRID_FILES = {"reference": "sure_cells.json", "sequential": "sequential_sure_cells.json"}
_THESIS_FILE = "sure_cells_table_magnitudes.json"


def check_cells(cells: str) -> str:
    """``cells`` if it names a cell set; ValueError naming the allowed ones otherwise."""
    if cells not in CELL_SETS:
        raise ValueError(f"cells must be one of {', '.join(CELL_SETS)}, got {cells!r}")
    return cells


def size_blind_cells(diagnoser: str, cells: str) -> SureCells:
    """The ``thesis`` or ``grid`` cells of ``reference`` or ``sequential``."""
    if check_cells(cells) == "grid":
        return load_sure_cells(_GRID_FILES[diagnoser])
    if cells == "thesis":
        return (
            load_sure_cells(_THESIS_FILE)
            if diagnoser == "reference"
            else load_sized_cells(SIZED_FILES[diagnoser]).top_band()
        )
    raise ValueError("the sized cells are not size-blind: use decision_state")


def decision_state(diagnoser: str, cells: str, max_cardinality: int | None = 2) -> DiagnosisState:
    """A fresh decision state of a diagnoser (``reference`` or ``sequential``) with a cell set:
    exoneration by sure cells, grace periods and the time order."""
    if diagnoser not in _GRID_FILES:
        raise ValueError(f"diagnoser must be 'reference' or 'sequential', got {diagnoser!r}")
    if check_cells(cells) == "sized":
        return SizedDiagnosisState(load_sized_cells(SIZED_FILES[diagnoser]), max_cardinality=max_cardinality)
    sc = size_blind_cells(diagnoser, cells)
    return DiagnosisState(
        exoneration=sc.sure,
        max_cardinality=max_cardinality,
        temporal=True,
        settle_s=sc.settle_times(),
        grace_s=sc.grace_times(),
    )
