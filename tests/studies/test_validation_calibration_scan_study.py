"""What a named sensor calibration leaves on its channel (validation/select/calibration_scan.py and its use in the final
unexplained analysis of the selection)."""

from __future__ import annotations

import numpy as np
import pytest

from studies.validation.study import trial

LOADS = np.array([0.30, 0.41, 0.52, 0.60, 0.70, 0.81, 0.93, 1.05])
READING = 300.0 + 200.0 * LOADS  # a temperature channel, °C
TOL = 5.0


@pytest.mark.slow
def test_the_study_trial_whose_step_was_named_a_calibration_now_reports_it():
    """Open-world trial e152 (development seed): a 5.5 % charge-air pressure step above 65 % load is named as that
    sensor's calibration; what the gain and offset leave is reported as unexplained on the channel, above the
    step."""
    r = trial("e", 152)
    assert r["selected"] == ["sensor_calibration[charge_air_pressure_bar_gauge]"]
    left = [u for u in r["unexplained"] if u["channel"] == "charge_air_pressure_bar_gauge"]
    assert left and left[0]["kind"] == "local" and r["unexplained_right_region"]


def test_a_named_calibration_is_scanned_at_the_level_of_its_own_claim():
    """Open-world trial e222 (development seed; about 5 s): a 6 % fuel-flow dip around 48 % load is named as the
    flow meter's calibration.  What the gain and offset leave is a window at 44-57 % load with scan p = 0.027: above
    5 % / 13 channels (at that level nothing is reported) and below 5 % / 1 named calibration, the level of the one
    claim being tested: it is reported on the right channel, in the right region."""
    r = trial("e", 222)
    assert r["selected"] == ["sensor_calibration[fuel_flow_kg_per_h]"]
    left = [u for u in r["unexplained"] if u["channel"] == "fuel_flow_kg_per_h"]
    assert len(left) == 1 and left[0]["kind"] == "local" and left[0]["left_by"] == "sensor_calibration"
    scan = r["calibration_scan"]["fuel_flow_kg_per_h"]  # recorded whether reported or not
    assert 0.05 / 13 < scan["p"] < 0.05 and abs(scan["d"]) >= scan["tolerance"]
    lo, hi = left[0]["load_range"]
    assert 0.40 < lo < hi < 0.60, left[0]
    assert r["unexplained_right_channel"] and r["unexplained_right_region"]


def test_the_study_counts_true_calibrations_the_scan_says_leave_structure():
    """The scan's price, in the study summary: of the trials whose true sensor calibration was named, those whose
    report says the calibration leaves structure on its channel."""
    from studies.validation.study import summarise

    def rec(seed, named, left):
        truth = [
            {
                "id": "sensor_calibration",
                "label": "sensor_calibration[fuel_flow_kg_per_h]",
                "channel": "fuel_flow_kg_per_h",
            }
        ]
        sel = ["sensor_calibration[fuel_flow_kg_per_h]"] if named else ["friction_losses"]
        unex = [{"channel": "fuel_flow_kg_per_h", "kind": "local", "left_by": "sensor_calibration"}] if left else []
        return {
            "condition": "a",
            "control": False,
            "seed": seed,
            "outcome": "identified" if named else "wrong",
            "truth": truth,
            "selected": sel,
            "exact": named,
            "named_any": True,
            "unexplained": unex,
            "calibration_scan": {},
            "mechanisms": ["sensor_calibration"],
        }

    out = summarise([rec(1, True, True), rec(2, True, False), rec(3, False, True), rec(4, True, False)], "a")
    assert out["true_calibration_left_by_it"] == "1/3"  # seed 3's calibration was not named: not counted
    old = [dict(rec(5, True, True))]
    del old[0]["calibration_scan"]  # files written before the scan was recorded: no count
    assert "true_calibration_left_by_it" not in summarise(old, "a")
