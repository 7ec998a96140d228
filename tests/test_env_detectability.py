"""The environment's detectability table: coverage, units, lookup, and one check against the diagnoser."""

from __future__ import annotations

import math

import pytest

from marine_fdi_env.envs.detectability import detectability_limit, detectability_table
from marine_fdi_env.engine.faults import FAULT_IDS, PROCESS_FAULT_DEFAULTS, FaultSpec, fault_class
from marine_fdi_env.engine.sensors import SENSORS, sensor_index


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


@pytest.mark.parametrize("fid", ["S2.3", "S4.1"])
def test_limit_separates_detected_from_undetected(fid):
    """Real diagnoser, one seed not used by the bisection: 2x the limit is detected within
    250 s of a 50 s onset, 0.25x is not (and nothing fires before the onset)."""
    from studies.diagnosis.kpis import LIMIT_SENSOR_ONSET_S, diagnose_batch

    lim = detectability_limit(fid)
    onset = LIMIT_SENSOR_ONSET_S
    scheds = [[FaultSpec(fid, onset, magnitude=k * lim, kind="offset")] for k in (2.0, 0.25)]
    hi, lo = diagnose_batch(scheds, [777, 777])
    assert hi["detected"] and hi["first_detection_time_s"] >= onset
    assert not lo["detected"]


def test_bisection_brackets_and_converges(monkeypatch):
    """The bracketing log-space bisection on a fake diagnoser with known thresholds."""
    from studies.diagnosis import kpis

    thresholds = {"S4.1": 3000.0, "bore_damage": 2e-5, "turbine_seal_leak": math.inf}
    calls = []

    def fake(schedules, seeds, profile="constant", duration_s=300.0):
        calls.append(len(schedules))
        return [{"detected": s[0].magnitude >= thresholds[s[0].fault_id],
                 "first_detection_time_s": s[0].onset_s + 1.0, "failures": []} for s in schedules]

    monkeypatch.setattr(kpis, "diagnose_batch", fake)
    out = kpis.detectability_limits(2, fault_ids=tuple(thresholds), rtol=1.05, max_up=3)
    for f in ("S4.1", "bore_damage"):
        lo, hi = out[f]["bracket"]
        assert out[f]["detected"] and lo < thresholds[f] <= hi and hi / lo <= 1.05
    assert out["turbine_seal_leak"]["limit"] is None and not out["turbine_seal_leak"]["detected"]
    assert out["turbine_seal_leak"]["evaluations"][-1][0] == pytest.approx(8 * 3.5e-4)
    assert calls[0] == 3 * 2  # every fault and seed of one iteration in one batch
    table = kpis.env_table(out, "cmd", 2)
    assert table["faults"]["turbine_seal_leak"]["limit"] == 3.5e-4
    assert table["faults"]["S4.1"]["unit"] == "Pa" and table["faults"]["S4.1"]["source"] == "bisection, 2 seeds, command cmd"
