"""The shipped sure cells of a diagnoser: which modules surely fire for which fault (the thesis's
'1' versus '*'), how far their firing times spread (the settle times of the time-order check) and
how long a silent sure module is still awaited (the grace periods).

The files are written by the repository's certainty study (docs/diagnosis.md: the measurement over a grid of
fault magnitudes, profiles and seeds); this module only reads them, so that the diagnosers
(:mod:`.agent`, :mod:`.sequential`) do not depend on the simulation code that measures them.

File format (JSON): ``module_ids``, ``fault_ids``; ``sure`` (19 x 26 bool) and ``lag_s``
(19 x 26, the largest delay of a sure module after the fault's first fired module over the
measured runs); ``spread_s`` (26,), the settle time's basis: the largest delay of a fault's sure
modules after its first fired module (in a file of the first format: their spread among themselves);
``settings`` and ``command`` say how it is measured.  A file without ``format`` holds fire counts
at the table magnitudes only: ``fire_counts``, ``runs_per_fault`` (or ``runs`` per fault), ``sure_lag_s``,
``sure_spread_s``; it is read too.

The files are read from the package's ``data/diagnosis/`` or the folder ``MARINE_FDI_TABLES``
(:func:`~marine_fdi_env.engine.fault_registry.measured_table`); a file may hold more faults than are
registered (those are read), and a registered fault it lacks is refused by name
(:class:`~marine_fdi_env.engine.fault_registry.MissingFaultTable`).  :func:`select_faults` and
:func:`merge_faults` pick and join the per-fault columns (the fault-table command of docs/extending.md).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..engine.fault_registry import check_table_faults, measured_table
from ..engine.faults import FAULT_IDS, fault_class
from .modules import MODULE_IDS
from .structure import fault_signature_matrix

__all__ = [
    "SureCells",
    "load_sure_cells",
    "sure_cells",
    "settle_times",
    "grace_times",
    "SURE_CELLS_FILE",
    "SENSOR_MAX_LAG_S",
    "FAULT_AXES",
    "select_faults",
    "merge_faults",
]

SURE_CELLS_FILE = "sure_cells.json"
# An abrupt sensor fault surely fires a module only if it does so promptly: a module that fired in
# every run but up to minutes after the others did so by chance of the noise (e.g. M3.3 for S2.1,
# which may as well stay silent in a shorter run).  Applies to the first file format; the grid
# measurement decides with its own rule (certainty.derive_sure_cells).
SENSOR_MAX_LAG_S = 30.0
_IS_SENSOR = np.array([fault_class(f) == "sensor" for f in FAULT_IDS])


@dataclass(frozen=True)
class SureCells:
    """sure (19, 26) bool; lag_s (19, 26); spread_s (26,); data: the file's content."""

    sure: np.ndarray
    lag_s: np.ndarray
    spread_s: np.ndarray
    data: dict

    def settle_times(self, margin_s: float = 2.0, factor: float = 1.5) -> np.ndarray:
        """Per-fault settle times (26,) for the temporal check: ``spread_s`` (see the module
        docstring) times ``factor`` plus ``margin_s``; process faults (incipient, their spread grows
        with the fault's size) get no temporal constraint (inf)."""
        out = factor * self.spread_s + margin_s
        return np.where(_IS_SENSOR, out, np.inf)

    def grace_times(self, margin_s: float = 2.0, factor: float = 1.5) -> np.ndarray:
        """Grace periods (19, 26): how long after a fault's first fired module a silent sure module
        is still awaited before it exonerates the fault (its measured largest lag behind the
        fault's first fired module x ``factor`` + ``margin_s``)."""
        return factor * self.lag_s + margin_s


# the axis of every per-fault field of a sure-cell file (both formats)
FAULT_AXES = {
    "sure": 1,
    "lag_s": 1,
    "spread_s": 0,
    "detected_runs": 0,
    "runs": 0,
    "fire_counts": 1,
    "sure_lag_s": 1,
    "sure_spread_s": 0,
}


def _take(value, axis: int, idx: list[int]):
    if axis == 0:
        return [value[j] for j in idx]
    return [_take(v, axis - 1, idx) for v in value]


def select_faults(data: dict, fault_ids, axes: dict = FAULT_AXES) -> dict:
    """A cell file's content restricted to ``fault_ids`` (in that order; every one must be in the file):
    the per-fault fields (``axes``: field -> fault axis) subset, the rest kept.  The content itself when the
    file holds exactly those faults in that order."""
    fault_ids = list(fault_ids)
    if data["fault_ids"] == fault_ids:
        return data
    idx = [data["fault_ids"].index(f) for f in fault_ids]
    out = dict(data, fault_ids=fault_ids)
    for key, axis in axes.items():
        if key in data:
            out[key] = _take(data[key], axis, idx)
    return out


def merge_faults(base: dict, new: dict, fault_ids, axes: dict = FAULT_AXES) -> dict:
    """The cell file of ``fault_ids``: each fault's fields from ``new`` if it has the fault, else from
    ``base`` (per-fault measurements do not depend on the other faults); the other fields, ``settings`` and
    ``command`` from ``new`` (with ``merged_from`` naming the faults of each)."""
    if base["module_ids"] != new["module_ids"]:
        raise ValueError("merge_faults: the two cell files have different module ids")
    fault_ids = list(fault_ids)
    src = [new if f in new["fault_ids"] else base for f in fault_ids]
    missing = [f for f, d in zip(fault_ids, src) if f not in d["fault_ids"]]
    if missing:
        raise ValueError(f"merge_faults: no cells for {', '.join(missing)}")
    out = dict(new, fault_ids=fault_ids)
    for key, axis in axes.items():
        if key in new:
            cols = [_take(d[key], axis, [d["fault_ids"].index(f)]) for f, d in zip(fault_ids, src)]
            out[key] = _concat(cols, axis)
    out["merged_from"] = {
        "new": [f for f in fault_ids if f in new["fault_ids"]],
        "base": [f for f in fault_ids if f not in new["fault_ids"]],
    }
    return out


def _concat(cols: list, axis: int):
    """Join single-fault pieces (each with a fault axis of length 1 at ``axis``) along that axis."""
    if axis == 0:
        return [c[0] for c in cols]
    return [_concat([c[i] for c in cols], axis - 1) for i in range(len(cols[0]))]


def _read(name: str) -> dict:
    rel = f"diagnosis/{name}"
    path = measured_table(rel)
    try:
        data = json.loads(path.read_text())
    except FileNotFoundError:
        raise ValueError(f"no sure-cell file {name!r} in marine_fdi_env/data/diagnosis") from None
    if data["module_ids"] != list(MODULE_IDS):
        raise ValueError(f"{name} does not match the current module ids; regenerate it")
    check_table_faults(rel, data["fault_ids"], FAULT_IDS)  # a registered fault without cells: refused by name
    return select_faults(data, FAULT_IDS)


@lru_cache(maxsize=None)
def load_sure_cells(name: str = SURE_CELLS_FILE) -> SureCells:
    """The sure cells of ``data/diagnosis/<name>`` (cached)."""
    data = _read(name)
    support, _, _ = fault_signature_matrix()
    if "sure" in data:
        sure = np.asarray(data["sure"], dtype=bool) & support
        lag = np.asarray(data["lag_s"], dtype=float)
        spread = np.asarray(data["spread_s"], dtype=float)
    else:  # the first format: fire counts at the table magnitudes
        counts = np.asarray(data["fire_counts"])
        lag = np.asarray(data.get("sure_lag_s", np.zeros(counts.shape)), dtype=float)
        runs = np.asarray(data.get("runs", data["runs_per_fault"]))  # per fault when faults were added later
        sure = (counts == runs) & support & ~(_IS_SENSOR[None, :] & (lag > SENSOR_MAX_LAG_S))
        spread = np.asarray(data.get("sure_spread_s", [0.0] * len(FAULT_IDS)), dtype=float)
    for a in (sure, lag, spread):
        a.setflags(write=False)
    return SureCells(sure, lag, spread, data)


def sure_cells(name: str = SURE_CELLS_FILE) -> np.ndarray:
    """Bool (19, 26): the cells that surely fire (within the structural support)."""
    return load_sure_cells(name).sure.copy()


def settle_times(margin_s: float = 2.0, factor: float = 1.5, name: str = SURE_CELLS_FILE) -> np.ndarray:
    """See :meth:`SureCells.settle_times`."""
    return load_sure_cells(name).settle_times(margin_s, factor)


def grace_times(margin_s: float = 2.0, factor: float = 1.5, name: str = SURE_CELLS_FILE) -> np.ndarray:
    """See :meth:`SureCells.grace_times`."""
    return load_sure_cells(name).grace_times(margin_s, factor)
