"""The mechanism library, the validation problem (per-row boundary conditions), the fits (nuisance, valve
supports found by relaxation and confirmation) and the synthetic-data generator."""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from marine_fdi_env.cli.synthesize import synthesize_main
from marine_fdi_env.engine.params import load_params
from marine_fdi_env.validation import DataWarning, load_measured, load_shipped
from marine_fdi_env.validation.fit.fitting import Combination, fit_combination, predict_setting
from marine_fdi_env.validation.fit.mechanisms import (
    MECHANISM_IDS,
    PHYSICAL_MECHANISMS,
    BypassValveM,
    Param,
    SensorCalibration,
    WasteGateM,
    equivalents,
    parse_mechanism_spec,
)
from marine_fdi_env.validation.fit.nuisance import NUISANCE
from marine_fdi_env.validation.fit.problem import BASE_SETTING, FitProblem
from marine_fdi_env.validation.fit.synthesize import DEFAULT_COLUMNS, synthesize


def _quiet(f, *a, **k):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        return f(*a, **k)


def test_library_is_complete_and_documented():
    assert set(MECHANISM_IDS) == {
        "cpp_load",
        "friction_losses",
        "ambient_conditions",
        "turbocharger_map",
        "intercooler_effectiveness",
        "cylinder_heat_loss",
        "turbine_flow_law",
        "turbine_efficiency_bsr",
        "exhaust_heat_loss",
        "waste_gate",
        "bypass_valve",
        "sensor_calibration",
    }
    for m in list(PHYSICAL_MECHANISMS) + [SensorCalibration(channel="speed_rpm", reference=400.0)]:
        d = m.describe()
        assert len(d["explanation"]) > 150, m.id  # a physical explanation, not a label
        assert d["touches"]
        for p in m.params:
            lo, hi = p.bounds
            assert lo < p.default <= hi or lo <= p.default < hi, (m.id, p.name)
            for a, b in p.draw:  # the synthetic draw lies inside the plausible range
                assert lo <= a < b <= hi, (m.id, p.name)
            assert p.tolerance > 0 and p.unit
    assert equivalents("turbocharger_map") == {"turbine_efficiency_bsr"} and not equivalents("waste_gate")


def test_pinned_only_at_bounds_that_are_not_natural():
    p = Param("x", "-", 1.0, (0.0, 2.0), ((0.5, 1.5),), 0.1, "a parameter", natural=(True, False))
    assert p.pinned(0.0) is None  # a natural limit (e.g. a flat map) may be the answer
    assert p.pinned(2.0) == "upper"  # the end of what is plausible: the data want more than the mechanism gives
    assert p.pinned(1.0) is None


def test_parse_mechanism_spec():
    assert parse_mechanism_spec("none") == ("none", {}, None)
    assert parse_mechanism_spec("turbocharger_map:eta_scale=1.1") == ("turbocharger_map", {"eta_scale": 1.1}, None)
    assert parse_mechanism_spec("waste_gate:above=0.8,opening=0.2") == (
        "waste_gate",
        {"above": 0.8, "opening": 0.2},
        None,
    )
    assert parse_mechanism_spec("sensor_calibration:channel=speed_rpm,gain=1.05")[2] == "speed_rpm"
    for bad, msg in (
        ("nope", "unknown mechanism"),
        ("turbocharger_map:eta=1", "unknown parameter"),
        ("turbocharger_map:eta_scale=x", "must be a number"),
        ("none:a=1", "takes no parameters"),
    ):
        with pytest.raises(ValueError, match=msg):
            parse_mechanism_spec(bad)


@pytest.mark.parametrize("mech", [m.id for m in PHYSICAL_MECHANISMS])
def test_each_mechanism_moves_the_channels_it_touches(mech):
    """Noise-free data with the mechanism at its draw range differ from the base model's by more than the
    tolerance (1 % / 5 K) on at least one channel it touches, and not at all on the set points."""
    kw = dict(points=6, noise=0.0, seed=3)
    base = synthesize("wartsila-6l46", ["none"], **kw)
    ext = synthesize("wartsila-6l46", [mech], **kw)
    np.testing.assert_array_equal(ext.columns["power_kW"], base.columns["power_kW"])
    moved = []
    for c in DEFAULT_COLUMNS:
        if c in ("load_fraction", "power_kW"):
            continue
        d = np.max(np.abs(ext.clean[c] - base.clean[c]))
        tol = 5.0 if c.endswith("_C") else 0.01 * np.mean(np.abs(base.clean[c]))
        if d > tol:
            moved.append(c)
    assert moved, mech


def test_problem_runs_each_row_at_its_own_boundary_conditions():
    """The protocol's rows run at their recorded ambient pressure, compressor inlet temperature and back pressure:
    the model's compressor outlet moves one to one with the inlet temperature, and the 50 % row (inlet recorded as
    0 C, a recording error) runs at the other rows' median instead."""
    ds = _quiet(load_shipped, "birka_me1_test_protocol")
    pr = FitProblem(ds)
    assert pr.target == "power"
    assert "turbocharger_speed_rpm" in pr.channels and "relative_humidity_percent" not in pr.channels
    vals, conv = pr.solve(BASE_SETTING)
    assert conv.all()
    T_in = ds.boundary["T_amb_K"]
    # the boundary conditions reach the engine of each row
    for i in range(ds.n_points):
        e = pr.point_engine(BASE_SETTING, i)
        assert e.T_amb_K == pytest.approx(T_in[i]) and e.p_amb_Pa == pytest.approx(ds.boundary["p_amb_Pa"][i])
        assert e.p_ex_Pa == pytest.approx(ds.boundary["p_ex_Pa"][i])
    assert pr.point_engine(BASE_SETTING, 1).T_amb_K == pytest.approx(305.15)
    # mean channels of per-cylinder groups carry the cylinders' standard error in their tolerance
    j = pr.channels.index("cylinder_exhaust_temperature_mean_C")
    assert np.all(pr.tolerance_cells[:, j] > pr.tolerance[j])
    # the rows are grouped by their boundary conditions once per set of rows (a fit solves the same rows thousands of
    # times: the second call must hit the cache), each row in one group
    rows = np.arange(ds.n_points)
    assert pr._groups(rows) is pr._groups(rows)
    assert sorted(i for _, idx in pr._groups(rows) for i in idx) == list(rows)


@pytest.fixture(scope="module")
def bypass_data():
    """Noise-free data with a bypass open below load 0.55 at 7 points and an untouched turbine."""
    syn = synthesize(
        "wartsila-6l46", ["bypass_valve:below=0.55,opening=0.12"], points=7, noise=0.0, seed=11, columns=DEFAULT_COLUMNS
    )
    return syn


def test_valve_support_found_without_enumeration(bypass_data, tmp_path):
    """Relaxation with the sparsity penalty and confirmation find exactly the points where the valve acts, with the
    right openings, in one fit (no search over the 2^7 subsets)."""
    path = tmp_path / "bp.csv"
    bypass_data.write(path)
    pr = FitProblem(_quiet(load_measured, path))
    fit = fit_combination(pr, Combination((BypassValveM(),)))
    true = np.array(bypass_data.truth[0]["openings"])
    assert sorted(fit.support["bypass_valve"]) == [int(i) for i in np.flatnonzero(true > 0)]
    np.testing.assert_allclose(fit.openings["bypass_valve"], true, atol=0.01)
    # its predictions reproduce the data (noise-free: to the solver's tolerance, well inside 0.1 tolerance)
    r = pr.normalised_residuals(predict_setting(pr, fit, np.arange(pr.n_points)))
    assert np.nanmax(np.abs(r)) < 0.1
    # the schedule through the fitted points predicts them too (what the fitted engine does)
    s = fit.schedules()["bypass_valve"]
    assert len(s.u) == pr.n_points and np.all(np.diff(s.u) > 0)
    r2 = pr.normalised_residuals(pr.predict(fit.schedule_setting(pr))[0])
    assert np.nanmax(np.abs(r2)) < 0.1


def test_waste_gate_with_rematched_turbine_recovered(tmp_path):
    syn = synthesize(
        "wartsila-6l46", ["waste_gate:above=0.7,opening=0.25,turbine_area_scale=0.8"], points=7, noise=0.0, seed=5
    )
    path = tmp_path / "wg.csv"
    syn.write(path)
    pr = FitProblem(_quiet(load_measured, path))
    fit = fit_combination(pr, Combination((WasteGateM(),)))
    assert fit.values()["waste_gate.turbine_area_scale"] == pytest.approx(0.8, abs=0.02)
    true = np.array(syn.truth[0]["openings"])
    assert sorted(fit.support["waste_gate"]) == [int(i) for i in np.flatnonzero(true > 0)]


def test_nuisance_absorbs_small_model_error_within_its_box():
    """Data from an engine whose turbine area is 4 % smaller: the calibrated base finds it (the nuisance's
    turbine_area near 0.96), within the box of ±6 %."""
    p = load_params("wartsila-6l46")
    syn = synthesize(p.replace(A_eff_m2=0.96 * p.A_eff_m2, name="wartsila-6l46"), ["none"], points=7, noise=0.0, seed=2)
    import tempfile
    from pathlib import Path

    from marine_fdi_env.validation.measured.loader import write_measured

    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "ne.csv"
        write_measured(path, syn.columns, syn.meta, digits=9)
        pr = FitProblem(_quiet(load_measured, path))
    fit = fit_combination(pr, Combination())
    got = dict(zip([g.name for g in NUISANCE], fit.nuisance))
    assert got["turbine_area"] == pytest.approx(0.96, abs=0.01)
    assert all(0.94 - 1e-9 <= v <= 1.06 + 1e-9 for v in fit.nuisance)


def test_synthesized_data_load_and_hide_the_effect(tmp_path):
    syn = synthesize(
        "wartsila-6l46",
        ["turbocharger_map", "sensor_calibration:channel=turbine_outlet_temperature_C"],
        points=6,
        noise=0.01,
        seed=1,
        perturb=0.03,
    )
    path = tmp_path / "s.csv"
    syn.write(path, tmp_path / "truth.json")
    text = path.read_text() + (tmp_path / "s.meta.json").read_text()
    assert "turbocharger_map" not in text and "sensor_calibration" not in text
    truth = json.loads((tmp_path / "truth.json").read_text())
    assert [m["id"] for m in truth["mechanisms"]] == ["turbocharger_map", "sensor_calibration"]
    assert set(truth["settings"]["model_error"]) == {
        "A_eff_m2",
        "a_eta_per_Pa2",
        "eta_com",
        "eta_comb",
        "X_cv_nom",
        "X_ct_nom",
        "s_sl_nom",
    }
    ds = _quiet(load_measured, path)
    assert ds.n_points == 6 and set(ds.columns) == set(DEFAULT_COLUMNS)


def test_synthesize_cli(tmp_path, capsys):
    out = tmp_path / "new" / "d.csv"  # the parent of --out is created
    assert (
        synthesize_main(
            [
                "--params",
                "man-12v32-40",
                "--mechanism",
                "waste_gate:above=0.8",
                "--points",
                "5",
                "--out",
                str(out),
                "--truth",
                str(tmp_path / "t.json"),
            ]
        )
        == 0
    )
    assert out.exists() and (tmp_path / "t.json").exists()
    for argv, msg in (
        (["--params", "nope", "--out", str(tmp_path / "x.csv")], "unknown parameter set"),
        (["--params", "man-12v32-40", "--mechanism", "nope", "--out", str(tmp_path / "x.csv")], "unknown mechanism"),
        (["--params", "man-12v32-40", "--out", str(tmp_path / "a" / "b" / "x.csv")], "does not exist"),
    ):
        capsys.readouterr()
        assert synthesize_main(argv) == 2
        assert msg in capsys.readouterr().err
