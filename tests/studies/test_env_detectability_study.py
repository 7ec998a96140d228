"""The environment's detectability table: coverage, units, lookup, and one check against the diagnoser."""

from __future__ import annotations

import math

import pytest

from marine_fdi_env.engine.faults import FaultSpec
from marine_fdi_env.envs.detectability import detectability_limit


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
        return [
            {
                "detected": s[0].magnitude >= thresholds[s[0].fault_id],
                "first_detection_time_s": s[0].onset_s + 1.0,
                "failures": [],
            }
            for s in schedules
        ]

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
    assert (
        table["faults"]["S4.1"]["unit"] == "Pa"
        and table["faults"]["S4.1"]["source"] == "bisection, 2 seeds, command cmd"
    )
