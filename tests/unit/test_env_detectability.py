"""The environment's detectability table: coverage, units, lookup, and one check against the diagnoser."""

from __future__ import annotations

import math

import pytest

from marine_fdi_env.engine.faults import FAULT_IDS, PROCESS_FAULT_DEFAULTS, FaultSpec, fault_class
from marine_fdi_env.engine.sensors import SENSORS, sensor_index
from marine_fdi_env.envs.detectability import detectability_limit, detectability_table


def test_table_covers_exactly_the_fault_ids():
    table = detectability_table()
    assert list(table) == list(FAULT_IDS)
    assert len(table) == 26


@pytest.mark.parametrize("fid", FAULT_IDS)
def test_limits_positive_finite_with_the_fault_class_unit(fid):
    v = detectability_table()[fid]
    lim = detectability_limit(fid)
    assert lim == v["limit"]
    assert math.isfinite(lim) and lim > 0
    assert v["table_magnitude"] > 0
    assert v["source"].startswith("bisection, ")
    if fault_class(fid) == "sensor":
        assert v["unit"] == SENSORS[sensor_index(fid)].unit
        assert v["table_magnitude"] == pytest.approx(FaultSpec(fid, 0.0, kind="offset").resolved_magnitude)
    else:
        assert v["unit"] == PROCESS_FAULT_DEFAULTS[fid].unit
        assert v["table_magnitude"] == pytest.approx(PROCESS_FAULT_DEFAULTS[fid].magnitude)
    if v.get("detected", True):
        lo, hi = v["bracket"]
        assert hi == pytest.approx(lim) and (lo is None or lo < hi)
    else:
        assert lim == v["table_magnitude"] and v["note"]


def test_undetectable_turbine_seal_leak_falls_back_to_table_magnitude():
    v = detectability_table()["turbine_seal_leak"]
    assert v["detected"] is False
    assert v["limit"] == PROCESS_FAULT_DEFAULTS["turbine_seal_leak"].magnitude


def test_unknown_fault_id_raises():
    with pytest.raises(ValueError, match="S9.9"):
        detectability_limit("S9.9")
    with pytest.raises(ValueError, match="unknown fault id"):
        detectability_limit("bore-damage")


def test_table_is_a_copy():
    detectability_table()["S1.1"]["limit"] = -1.0
    assert detectability_limit("S1.1") > 0
