"""Detectability limit of every fault: the scale on which scenario fault magnitudes are drawn.

The limit of a fault is the smallest magnitude that the reference diagnoser
(:class:`marine_fdi_env.diagnosis.ReferenceDiagnoser`) detects - some module violated, first at or
after the onset - before the end of a 300 s run in *every* one of a few noise seeds (4), at the
constant nominal fuel setting 1.0.  That is, detected within ``300 s - onset``:

* sensor faults (``S1.1`` .. ``S4.6``): abrupt positive offsets with onset 50 s, so within 250 s;
  unit: the sensor's unit;
* process faults: their table 6.4 fault functions (rates, evolution κ) with their default onsets
  (15-30 s); unit: the table 6.4 unit of the magnitude.

It is found by bisection on a log scale (bracketed from the table 6.3 / 6.4 magnitude by factors
of 2, then bisected to a 5 % bracket; the limit is the upper, detected end) with
the repository's minimum-detectable study (its command: docs/environment.md), which regenerates
``marine_fdi_env/data/env/detectability.json`` (the fault-table command of docs/extending.md for some faults;
the table of the folder ``MARINE_FDI_TABLES`` is read when it has one,
:func:`~marine_fdi_env.engine.fault_registry.measured_table`).  A fault never detected at any magnitude
tried (``turbine_seal_leak``: its effect on the receiver pressure stays far below the sensor noise) has
``"detected": false`` and its table magnitude as limit, so it is sampled relative to that.

The limit is a *scale* for sampling scenarios (e.g. magnitudes 0.5x .. 4x the limit: some below,
some well above what the reference diagnoser can see); it is not a guarantee.  Another seed, load
profile, onset or run length, and other faults acting at the same time, move the threshold; a
fault at 2x the limit is detected in practice, at 0.5x it often is not, but neither is promised.
"""

from __future__ import annotations

import copy
import json
import math
from functools import lru_cache

from ..engine.fault_registry import check_table_faults, measured_table
from ..engine.faults import FAULT_IDS

__all__ = ["detectability_limit", "detectability_table", "sampling_scale", "TABLE", "SCALE_FLOOR"]

# Scenario magnitudes are drawn relative to max(limit, SCALE_FLOOR x table magnitude).  Without the
# floor, the inlet-air-temperature sensors S4.3/S4.4 (limits 3.5e-3 K and 6.7e-4 K against a 22 K
# table offset) and compressor_lubrication_loss (1e-4 K/s against 2.5 K/s) would be sampled at
# physically invisible sizes: their module (M4.(3,4)) compares T1 with a constant model value,
# so with bounded uniform noise *any* positive offset crosses the threshold eventually, and the
# measured "limit" reflects run length and noise luck, not sensitivity.  2 % of the table
# magnitude is below every other measured limit but valve_seizing (0.5 %) and S1.1 (1.9 %),
# which it raises only slightly.
SCALE_FLOOR = 0.02

TABLE = "env/detectability.json"  # relative to the package's data/ (or MARINE_FDI_TABLES, fault_registry)


@lru_cache(maxsize=1)
def _load() -> dict:
    data = json.loads(measured_table(TABLE).read_text())
    faults = data["faults"]
    check_table_faults(TABLE, faults, FAULT_IDS)  # a registered fault without its limit is refused by name
    for f in FAULT_IDS:
        lim = faults[f].get("limit")
        if not (isinstance(lim, (int, float)) and math.isfinite(lim) and lim > 0):
            raise RuntimeError(f"{TABLE}: limit of {f} must be a positive finite number, got {lim!r}")
    return data


def detectability_table() -> dict:
    """``{fault_id: {"limit", "unit", "source", "table_magnitude", "detected", ...}}`` for every registered
    fault, in ``FAULT_IDS`` order (a fresh copy of the cached file)."""
    faults = _load()["faults"]
    return {f: copy.deepcopy(faults[f]) for f in FAULT_IDS}


def detectability_limit(fault_id: str) -> float:
    """Detectability limit of one fault (unit of its magnitude); ``ValueError`` for an unknown id."""
    faults = _load()["faults"]
    if fault_id not in FAULT_IDS:
        raise ValueError(f"unknown fault id {fault_id!r}; allowed: {', '.join(FAULT_IDS)}")
    return float(faults[fault_id]["limit"])


def sampling_scale(fault_id: str) -> float:
    """The magnitude that scenario sampling calls "1x": max(limit, SCALE_FLOOR x table magnitude)."""
    lim = detectability_limit(fault_id)
    table = _load()["faults"][fault_id].get("table_magnitude")
    if isinstance(table, (int, float)) and math.isfinite(table) and table > 0:
        return max(lim, SCALE_FLOOR * float(table))
    return lim
