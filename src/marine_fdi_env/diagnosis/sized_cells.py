"""Sure cells by fault size: the ``sized`` cell set of the diagnosers (docs/diagnosis.md,
"Exoneration").

The grid cells (:mod:`.sure_cells`) are sure at *every* size from 0.5x the detectability limit to
the table size, because the diagnoser does not know the size; a large fault is then exonerated
only as if it might be small.  Here the size comes from the evidence: a fault f can explain a
fired module m only at a size at which f makes m's running peak ratio ``q_m = max |r_m|/threshold``
as large as it is.  The certainty grid (:mod:`.certainty`) measured, per fault and size level j,
the largest running peak each module reached over its runs; ``peak[j, m, f]`` is the largest over
the levels up to j (an envelope that grows with j).  If ``q_m > margin * peak[j, m, f]`` for the
levels j = 0 .. n-1, no run of f at those sizes made m's peak that large, so f, if it explains m,
is larger than level n-1's size: the **band** of (m, f) is ``k = max(n - 1, 0)``, and the cells,
settle times and grace periods used for f as an explanation of m are those measured over the runs
at levels k and above (at or above the bound).  Band 0 is every size of the grid: the grid cells.

Validity: the bound holds for the profiles, sizes and run length (300 s from the onset) the grid
covers; a fault larger than the table size is treated as the table size (the top band); see
docs/diagnosis.md for the failure modes.

File format (JSON, ``format`` 3): ``module_ids``, ``fault_ids``; ``n_levels`` (26,);
``magnitudes`` (26 lists, ascending); per band k < max levels: ``sure`` (K x 19 x 26, 0/1),
``lag_s`` (K x 19 x 26: a sure module's largest delay after the fault's first fired module over
the runs at levels >= k), ``peak`` (K x 19 x 26, null where level k does not exist for a fault),
``never_fired`` (19 x 26: support cells no run of the fault fired, at any size), ``detected_runs``
and ``runs`` (K x 26); ``margin``, ``rule``; ``settings`` and ``command``.
Bands past a fault's levels repeat its top band.
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
from .sure_cells import SureCells, merge_faults, select_faults

__all__ = ["SizedCells", "load_sized_cells", "SIZED_FILES", "FAULT_AXES", "select_sized_faults", "merge_sized_faults"]

SIZED_FILES = {"reference": "sized_cells.json", "sequential": "sequential_sized_cells.json"}
_IS_SENSOR = np.array([fault_class(f) == "sensor" for f in FAULT_IDS])


@dataclass(frozen=True)
class SizedCells:
    """Sure cells by size band (module docstring).

    sure : (K, 19, 26) bool; lag_s : (K, 19, 26) [s], a sure module's largest delay behind the
    fault's first fired module; never_fired : (19, 26) bool, support cells that fired in no run
    of the fault at any size; peak : (K, 19, 26) peak-ratio envelope [-] (inf past a fault's
    levels); n_levels : (26,); margin : factor on the envelope's excess [-]; data : the file's
    content.
    """

    sure: np.ndarray
    lag_s: np.ndarray
    never_fired: np.ndarray
    peak: np.ndarray
    n_levels: np.ndarray
    margin: float
    data: dict
    rule: str = "excess"

    def __post_init__(self) -> None:
        object.__setattr__(self, "_thr", self.threshold)
        object.__setattr__(self, "_lag_t", np.ascontiguousarray(self.lag_s.transpose(0, 2, 1)))  # (K, 26, 19)

    @property
    def threshold(self) -> np.ndarray:
        """(K, 19, 26): the running peak above which (m, f) is past level k's sizes."""
        if self.rule == "ratio":
            return self.margin * self.peak
        return 1.0 + self.margin * np.maximum(self.peak - 1.0, 0.0)

    @property
    def n_bands(self) -> int:
        return self.sure.shape[0]

    def bands(self, peaks) -> np.ndarray:
        """Int (19, 26): the band of every (module, fault) given the modules' running peaks (19,);
        a module the fault never fired, at any size, puts it in its top band."""
        q = np.asarray(peaks, dtype=float)
        n = (self._thr < q[None, :, None]).sum(axis=0)
        return np.where(self.never_fired, self.n_levels[None, :] - 1, np.maximum(n - 1, 0))

    def next_peak(self, peaks, rows) -> np.ndarray:
        """(19,): for the modules in ``rows`` (bool (19,)), the running peak above which the band
        of some fault of its support moves up (inf: none); inf elsewhere."""
        q = np.asarray(peaks, dtype=float)
        n = (self._thr < q[None, :, None]).sum(axis=0)  # (19, 26)
        nxt = np.take_along_axis(
            np.concatenate([self._thr, np.full((1,) + self.peak.shape[1:], np.inf)]),
            np.minimum(n, self.n_bands)[None],
            axis=0,
        )[0]
        nxt = np.where(_SUPPORT, nxt, np.inf).min(axis=1)
        return np.where(rows, nxt, np.inf)

    def timings(
        self, band: np.ndarray, rows: np.ndarray, margin_s: float = 2.0, factor: float = 1.5
    ) -> tuple[np.ndarray, np.ndarray]:
        """Grace and settle times (r, 26, 19 sure modules) [s] of every fault as the explanation of
        the fired modules ``rows`` (r,), in their bands ``band`` (r, 26): how long after such a
        module m each sure module of the fault may still fire (a silent one then exonerates the
        fault as m's explanation; one that fired later was not fired by it).  Its largest delay
        behind the fault's first fired module x ``factor`` + ``margin_s`` (the fault's first module
        fired no later than m); ``margin_s`` alone where the fault never fired m at any size (in
        every run its sure modules fired before the run ended, m not at all).  Settle times: process
        faults (incipient) get no time order (inf)."""
        g = factor * self._lag_t[band, np.arange(len(FAULT_IDS))[None, :]] + margin_s
        g = np.where(self.never_fired[rows][:, :, None], margin_s, g)
        return g, np.where(_IS_SENSOR[None, :, None], g, np.inf)

    def top_band(self) -> SureCells:
        """The cells of each fault's largest size alone (the table size), as size-blind cells."""
        top = self.n_levels - 1
        cols = np.arange(len(FAULT_IDS))
        sure = self.sure[top, :, cols].T.copy()
        lag = self.lag_s[top, :, cols].T.copy()
        spread = np.where(sure, lag, 0.0).max(axis=0)
        for a in (sure, lag, spread):
            a.setflags(write=False)
        return SureCells(sure, lag, spread, self.data)


_SUPPORT = fault_signature_matrix()[0]


def _array(data: dict, key: str, shape: tuple, name: str) -> np.ndarray:
    a = np.array(data[key], dtype=float)
    if a.shape != shape:
        raise ValueError(f"{name}: {key!r} must have shape {shape}, got {a.shape}")
    return a


# the axis of every per-fault field of a sized-cell file; the band axis of the banded ones is 0
FAULT_AXES = {
    "n_levels": 0,
    "magnitudes": 0,
    "sure": 2,
    "lag_s": 2,
    "peak": 2,
    "never_fired": 1,
    "detected_runs": 1,
    "runs": 1,
}
_BANDED = ("sure", "lag_s", "peak", "detected_runs", "runs")


def _bands(data: dict, k: int) -> dict:
    """The content with ``k`` bands: bands past a fault's levels repeat its top band (``peak``: null)."""
    out = dict(data)
    for key in _BANDED:
        rows = list(data[key][:k])
        while len(rows) < k:
            last = rows[-1]
            rows.append([[None] * len(r) for r in last] if key == "peak" else last)
        out[key] = rows
    return out


def select_sized_faults(data: dict, fault_ids) -> dict:
    """A sized-cell file's content restricted to ``fault_ids`` (:func:`~.sure_cells.select_faults`), with as
    many bands as its faults have levels."""
    out = select_faults(data, fault_ids, FAULT_AXES)
    k = max(out["n_levels"])
    return out if out is data or len(out["sure"]) == k else _bands(out, k)


def merge_sized_faults(base: dict, new: dict, fault_ids) -> dict:
    """The sized-cell file of ``fault_ids`` from two (:func:`~.sure_cells.merge_faults`)."""
    k = max(len(base["sure"]), len(new["sure"]))
    return select_sized_faults(merge_faults(_bands(base, k), _bands(new, k), fault_ids, FAULT_AXES), fault_ids)


@lru_cache(maxsize=None)
def load_sized_cells(name: str = SIZED_FILES["reference"]) -> SizedCells:
    """The sized cells of ``data/diagnosis/<name>`` (cached; ``MARINE_FDI_TABLES``, see
    :func:`~marine_fdi_env.engine.fault_registry.measured_table`)."""
    rel = f"diagnosis/{name}"
    try:
        data = json.loads(measured_table(rel).read_text())
    except FileNotFoundError:
        raise ValueError(f"no sized-cell file {name!r} in marine_fdi_env/data/diagnosis") from None
    if data.get("format") != 3 or data["module_ids"] != list(MODULE_IDS):
        raise ValueError(f"{name} is not a sized-cell file of the current module ids; regenerate it")
    check_table_faults(rel, data["fault_ids"], FAULT_IDS)  # a registered fault without cells: refused by name
    data = select_sized_faults(data, FAULT_IDS)
    n_levels = np.asarray(data["n_levels"], dtype=int)
    k = int(n_levels.max())
    shape = (k, len(MODULE_IDS), len(FAULT_IDS))
    sure = _array(data, "sure", shape, name).astype(bool) & _SUPPORT[None]
    lag = _array(data, "lag_s", shape, name)
    never = _array(data, "never_fired", shape[1:], name).astype(bool) & _SUPPORT
    peak = np.array([[[np.inf if v is None else v for v in row] for row in band] for band in data["peak"]], dtype=float)
    if peak.shape != shape:
        raise ValueError(f"{name}: 'peak' must have shape {shape}, got {peak.shape}")
    margin = float(data["margin"])
    if not margin >= 1.0:
        raise ValueError(f"{name}: 'margin' must be >= 1, got {margin}")
    rule = data.get("rule", "excess")
    if rule not in ("excess", "ratio"):
        raise ValueError(f"{name}: 'rule' must be 'excess' or 'ratio', got {rule!r}")
    for a in (sure, lag, never, peak, n_levels):
        a.setflags(write=False)
    return SizedCells(sure, lag, never, peak, n_levels, margin, data, rule)
