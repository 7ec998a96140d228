"""What a named sensor calibration leaves on its channel (validation/select/calibration_scan.py and its use in the final
unexplained analysis of the selection)."""

from __future__ import annotations

import numpy as np
import pytest

from marine_fdi_env.validation.select.calibration_scan import shape_dictionary, structure_scan
from marine_fdi_env.validation.select.window_scan import window_excess
from tests.paths import ROOT

LOADS = np.array([0.30, 0.41, 0.52, 0.60, 0.70, 0.81, 0.93, 1.05])
READING = 300.0 + 200.0 * LOADS  # a temperature channel, °C
TOL = 5.0


def _calibrated_residual(meas: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares gain and offset of the reading fitted to ``meas``: (residual model - measurement, reading)."""
    A = np.column_stack([np.ones_like(READING), READING])
    pred = A @ np.linalg.lstsq(A, meas, rcond=None)[0]
    return pred - meas, pred


def test_the_dictionary_has_steps_kinks_and_windows_where_they_act():
    shapes, where = shape_dictionary(LOADS)
    kinds = [w[0] for w in where]
    assert kinds.count("step") == 7 and kinds.count("window") == 7 + 6 + 5
    assert kinds.count("kink") == 2 * (6 + 7)  # every inner point and every midpoint, bending either way
    k = kinds.index("step")
    assert where[k][1:] == (0.41, 1.05) and shapes[k].tolist() == [0, 1, 1, 1, 1, 1, 1, 1]


def test_a_gain_and_offset_error_leaves_nothing():
    res, pred = _calibrated_residual(1.04 * READING + 7.0)
    b = structure_scan(res, LOADS, pred, TOL)
    assert b["z"] < 1e-6 and b["p"] > 0.99


@pytest.mark.parametrize("n", [pytest.param(1000, marks=pytest.mark.study), 150])
def test_it_holds_its_level_on_noise_after_a_fitted_calibration(n):
    """Gaussian noise at the tolerance, gain and offset fitted: reported at p < 0.05 in 5 % of channels (4 binomial
    sigmas over n channels; 1000 in the study run, 150 by default)."""
    rng = np.random.default_rng(7)
    hits = 0
    for _ in range(n):
        res, pred = _calibrated_residual(1.03 * READING + rng.normal(0.0, TOL, LOADS.size))
        hits += structure_scan(res, LOADS, pred, TOL)["p"] < 0.05
    assert abs(hits / n - 0.05) < 4 * np.sqrt(0.05 * 0.95 / n)


def test_a_step_that_a_calibration_absorbs_is_found_where_the_window_scan_is_not():
    """A 30 K step above 65 % load, noise 1.5 K, tolerance 5 K (the pipeline floors the noise at the tolerance):
    after the gain and offset it is a sawtooth of about 2 tolerances.  Over 200 noise draws the scan reports it at
    p < 0.01 and at least one tolerance in almost all (measured: 300/300), the window scan in few (30/300)."""
    rng = np.random.default_rng(0)
    n, scan_hits, window_hits = 200, 0, 0
    for _ in range(n):
        res, pred = _calibrated_residual(READING + 30.0 * (LOADS > 0.65) + rng.normal(0.0, 1.5, LOADS.size))
        b = structure_scan(res, LOADS, pred, TOL)
        w = window_excess(res, LOADS, TOL)
        scan_hits += b["p"] < 0.01 and abs(b["d"]) >= TOL
        window_hits += w["p"] < 0.01 and abs(w["d"]) >= TOL
    assert scan_hits / n > 0.9 and window_hits / n < 0.3
    # where: the step's own points above the split
    res, pred = _calibrated_residual(READING + 30.0 * (LOADS > 0.65))
    b = structure_scan(res, LOADS, pred, TOL)
    assert b["kind"] == "step" and b["load_range"] == [0.70, 1.05] and b["positions"] == [4, 5, 6, 7]


def test_too_few_points_give_no_verdict():
    assert structure_scan([1.0, 2.0, np.nan, 3.0, 4.0], [0.3, 0.5, 0.6, 0.8, 1.0], [1, 2, 3, 4, 5], 1.0) is None


def test_the_report_says_what_each_named_calibration_leaves():
    """The protocol's report (shipped in docs): the named cylinder-outlet calibration leaves a kink above 80 % load
    that the channel's local finding already reports; the Markdown says so, and says "nothing significant left"
    when the scan is not significant, "reported above" when the scan's own finding is listed."""
    import copy
    import json

    from marine_fdi_env.validation.report.build import markdown_summary

    path = ROOT / "docs/figures/validation/birka_me1_test_protocol.json"
    rep = json.loads(path.read_text())
    col = "cylinder_exhaust_temperature_mean_C"
    scan = rep["calibration_scans"][col]
    assert scan["kind"] == "kink" and scan["load_range"][0] >= 0.75 and scan["p"] < 1e-3
    assert abs(scan["d"]) > 5 * scan["tolerance"]

    def line(r):
        return next(x for x in markdown_summary(r).splitlines() if x.startswith(f"* `{col}`: a "))

    assert line(rep).endswith("structure left; the channel's local finding above already reports it")
    quiet = copy.deepcopy(rep)
    quiet["calibration_scans"][col]["p"] = 0.4
    assert line(quiet).endswith("nothing significant left")
    own = copy.deepcopy(rep)
    own["unexplained"] = [
        dict(u, left_by="sensor_calibration") if u["channel"] == col and u["kind"] == "local" else u
        for u in own["unexplained"]
    ]
    assert line(own).endswith("structure left, reported above")
