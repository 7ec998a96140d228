"""The extended steady-state model and the mechanism library (validation, slice 2).

The extended model must equal the base model's steady state when no hook is active (the first
test); each mechanism must move the quantities it claims to touch and leave the base model when its
parameters sit at the base values; the synthetic-data generator must write loadable data whose
sidecar does not give the hidden mechanism away.
"""

from __future__ import annotations

import json
import math
import time
import warnings

import numpy as np
import pytest

from marine_fdi_env import load_params
from marine_fdi_env.model import EngineModel
from marine_fdi_env.steady_state import steady_state
from marine_fdi_env.validation import DataWarning, load_dataset, load_shipped
from marine_fdi_env.validation.extended_model import SUMMARY_KEYS, ExtendedModel, Hooks
from marine_fdi_env.validation.matching import match_operating_points
from marine_fdi_env.validation.mechanisms import (
    MECHANISM_IDS, PHYSICAL_MECHANISMS, BypassValve, CylinderHeatLoss, SensorCalibration, get_mechanism, hooks_for,
    library, parse_mechanism_spec,
)
from marine_fdi_env.validation.selection import Problem
from marine_fdi_env.validation.synthesize import DEFAULT_COLUMNS, synthesize, synthesize_main

SETS = ["thesis-12v28", "man-12v32-40", "wartsila-6l46"]
U = np.linspace(0.2, 1.15, 12)


# --------------------------------------------------------------------------------------- base reproduction
@pytest.mark.parametrize("name", SETS)
def test_no_hooks_reproduces_steady_state(name):
    """With no hook active the extended model is the base model's steady state (rel 1e-9)."""
    p = load_params(name)
    ss = steady_state(EngineModel(p), U)
    ext = ExtendedModel(p).at_fuel_setting(U)
    assert ext.converged.all()
    for i in range(U.size):
        ref, got = ss.summary(p, i), ext.summary(i)
        assert set(ref) <= set(got)
        for k, v in ref.items():
            assert got[k] == pytest.approx(v, rel=1e-9, abs=1e-300), (name, U[i], k)


@pytest.mark.parametrize("name", SETS)
def test_power_and_fuel_flow_modes_agree_with_fuel_setting_mode(name):
    p = load_params(name)
    m = ExtendedModel(p)
    base = m.at_fuel_setting(U)
    P, mf = base.values["power_W"], base.values["fuel_mass_flow_kg_s"]
    for pts in (m.at_power(P), m.at_fuel_flow(mf)):
        assert pts.converged.all()
        for k in SUMMARY_KEYS:
            np.testing.assert_allclose(pts.values[k], base.values[k], rtol=1e-9, err_msg=k)
    # prescribed speed equal to the propeller-law speed changes nothing
    pr = ExtendedModel(p, Hooks(speed_law="prescribed")).at_fuel_setting(U, base.values["engine_speed_rev_s"])
    np.testing.assert_allclose(pr.values["power_W"], P, rtol=1e-9)


def test_matching_hook_gives_the_same_predictions_as_the_fast_path():
    """``steady_function`` plugged into match_operating_points == Problem.predict (the fit's fast path)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        ds = load_shipped("birka_6l46_shop_test")
    hooks = hooks_for([(get_mechanism("turbocharger_map"), {"eta_scale": 1.05, "curvature": 0.2})], ds.params)
    em = ExtendedModel(ds.params, hooks)
    m = match_operating_points(ds, steady=em.steady_function())
    pr = Problem(ds)
    pred, conv = pr.predict(hooks)
    assert conv.all()
    for j, c in enumerate(pr.channels):
        np.testing.assert_allclose(pred[:, j], m.predicted[c], rtol=1e-7, err_msg=c)
    np.testing.assert_allclose(pr.match_result(hooks).model_si["compressor_outlet_temperature_K"],
                               m.model_si["compressor_outlet_temperature_K"], rtol=1e-7)


def test_solve_is_fast_enough_for_fitting():
    """A fit evaluates the model thousands of times: < 2 ms per point (cold), warm starts faster."""
    p = load_params("man-12v32-40")
    m = ExtendedModel(p, Hooks(tc_map=True, tc_eta_scale=1.02, tc_curvature=0.2, bypass_max_fraction=0.05,
                               bypass_threshold_rel=0.7))
    P = np.linspace(0.25, 1.1, 30) * p.P_nom_W
    first = m.at_power(P)
    t0 = time.perf_counter()
    for _ in range(20):
        m.at_power(P)
    cold = (time.perf_counter() - t0) / (20 * P.size)
    t0 = time.perf_counter()
    for _ in range(20):
        m.at_power(P, guess=first.state)
    warm = (time.perf_counter() - t0) / (20 * P.size)
    assert first.converged.all()
    assert cold < 2e-3 and warm < cold


# --------------------------------------------------------------------------------------- mechanisms
def test_library_is_complete_and_documented():
    assert set(MECHANISM_IDS) == {"cpp_load", "friction_losses", "ambient_conditions", "turbocharger_map",
                                  "bypass_valve", "intercooler_effectiveness", "cylinder_heat_loss",
                                  "sensor_calibration"}
    for m in library(["turbine_outlet_temperature_C"], {"turbine_outlet_temperature_C": 350.0}):
        d = m.describe()
        assert len(d["explanation"]) > 200, m.id  # a physical explanation, not a stub
        assert d["touches"] and 1 <= len(m.params) <= 2
        for prm in m.params:
            lo, hi = prm.bounds
            assert prm.unit and prm.description and prm.tolerance > 0
            assert lo <= prm.default <= hi, (m.id, prm.name)
            for a, b in prm.draw:
                assert lo <= a <= b <= hi, (m.id, prm.name)


@pytest.mark.parametrize("mech", [m.id for m in PHYSICAL_MECHANISMS] + ["sensor_calibration"])
def test_each_mechanism_moves_the_quantities_it_touches(mech):
    p = load_params("man-12v32-40")
    P = np.array([0.3, 0.6, 0.9, 1.05]) * p.P_nom_W
    base = ExtendedModel(p).at_power(P)
    rng = np.random.default_rng(3)
    m = get_mechanism(mech, "turbine_outlet_temperature_C", 350.0) if mech == "sensor_calibration" \
        else get_mechanism(mech)
    vals = m.sample(rng)
    h = m.apply(Hooks(), vals, p)
    assert h.active(), mech
    ext = ExtendedModel(p, h).at_power(P)
    assert ext.converged.all()
    if mech == "sensor_calibration":
        assert h.sensors == (("turbine_outlet_temperature_C", vals["gain"], vals["offset"]),)
        return
    moved = [q for q in m.touches if q in ext.values
             and np.max(np.abs(ext.values[q] / base.values[q] - 1.0)) > 1e-3]
    assert moved, (mech, vals)
    if mech == "cpp_load":
        assert "engine_speed_rev_s" in moved


def test_base_values_of_nested_mechanisms_give_the_base_model():
    p = load_params("wartsila-6l46")
    P = np.linspace(0.3, 1.0, 5) * p.P_nom_W
    ref = ExtendedModel(p).at_power(P).values
    nested = [
        (get_mechanism("friction_losses"), {"fmep_offset_bar": 0.0, "fmep_speed2_bar": 0.0}),
        (get_mechanism("ambient_conditions"), {"dT_amb_K": 0.0, "dp_amb_kPa": 0.0}),
        (get_mechanism("intercooler_effectiveness"), {"effectiveness": 1.0}),
        (get_mechanism("bypass_valve"), {"max_fraction": 0.0, "threshold_rel": 0.7}),
        (CylinderHeatLoss(), {"n_comp": p.kappa_a, "dn_exp": 0.0}),
    ]
    for m, v in nested:
        got = ExtendedModel(p, m.apply(Hooks(), v, p)).at_power(P).values
        for k in ("fuel_mass_flow_kg_s", "charge_air_pressure_Pa", "turbine_outlet_temperature_K"):
            np.testing.assert_allclose(got[k], ref[k], rtol=1e-9, err_msg=(m.id, k))


def test_bypass_balances_mass_and_cools_the_turbine_inlet():
    p = load_params("man-12v32-40")
    P = np.array([0.4, 1.0]) * p.P_nom_W
    base = ExtendedModel(p).at_power(P).values
    h = BypassValve().apply(Hooks(), {"max_fraction": 0.12, "threshold_rel": 0.6}, p)
    v = ExtendedModel(p, h).at_power(P).values
    # compressor air + fuel = turbine flow, with and without bypass
    for x in (base, v):
        np.testing.assert_allclose(x["air_mass_flow_kg_s"] + x["fuel_mass_flow_kg_s"], x["exhaust_mass_flow_kg_s"],
                                   rtol=1e-12)
    assert v["bypass_fraction"][0] == 0.0 and v["bypass_fraction"][1] == pytest.approx(0.12)
    assert v["turbine_inlet_temperature_K"][1] < base["turbine_inlet_temperature_K"][1] - 10.0
    assert v["air_mass_flow_kg_s"][1] > base["air_mass_flow_kg_s"][1]


def test_parse_mechanism_spec():
    assert parse_mechanism_spec("none") == ("none", {}, None)
    assert parse_mechanism_spec("bypass_valve:max_fraction=0.1") == ("bypass_valve", {"max_fraction": 0.1}, None)
    assert parse_mechanism_spec("sensor_calibration:channel=speed_rpm,gain=1.02") == \
        ("sensor_calibration", {"gain": 1.02}, "speed_rpm")
    for bad, msg in [("warp_drive", "unknown mechanism"), ("bypass_valve:max_fraction", "param=value"),
                     ("bypass_valve:max_fraction=x", "must be a number"), ("cpp_load:pitch=1", "unknown parameter"),
                     ("none:a=1", "takes no parameters")]:
        with pytest.raises(ValueError, match=msg):
            parse_mechanism_spec(bad)


# --------------------------------------------------------------------------------------- synthesis
def test_synthesized_data_load_and_hide_the_mechanism(tmp_path):
    syn = synthesize("man-12v32-40", ["bypass_valve:max_fraction=0.1"], points=12, noise=0.01, seed=5)
    assert syn.truth[0]["id"] == "bypass_valve" and syn.truth[0]["values"]["max_fraction"] == 0.1
    assert 0.55 <= syn.truth[0]["values"]["threshold_rel"] <= 0.8  # drawn from the mechanism's draw range
    path = syn.write(tmp_path / "s.csv", tmp_path / "truth.json")
    meta_text = (tmp_path / "s.meta.json").read_text()
    for mid in MECHANISM_IDS:
        assert mid not in meta_text
    assert "bypass" not in meta_text.lower()
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataWarning)
        ds = load_dataset(path)
    assert ds.columns == DEFAULT_COLUMNS and ds.n_points == 12
    assert json.loads((tmp_path / "truth.json").read_text())["mechanisms"][0]["id"] == "bypass_valve"
    # same seed, same data; set points exact, the rest noisy
    again = synthesize("man-12v32-40", ["bypass_valve:max_fraction=0.1"], points=12, noise=0.01, seed=5)
    tot = "turbine_outlet_temperature_C"
    np.testing.assert_array_equal(again.columns[tot], syn.columns[tot])
    np.testing.assert_array_equal(syn.columns["power_kW"], syn.clean["power_kW"])
    rel = np.std(syn.columns["charge_air_pressure_bar_abs"] - syn.clean["charge_air_pressure_bar_abs"]) / \
        np.mean(syn.clean["charge_air_pressure_bar_abs"])
    assert 0.004 < rel < 0.02


def test_synthesize_cli(tmp_path, capsys):
    out = tmp_path / "d.csv"
    assert synthesize_main(["--params", "wartsila-6l46", "--mechanism", "sensor_calibration:channel=speed_rpm",
                            "--points", "8", "--noise", "0.005", "--seed", "2", "--engines", "2", "--out", str(out),
                            "--truth", str(tmp_path / "t.json")]) == 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        ds = load_dataset(out)
    assert ds.engine_ids() == ["E1", "E2"] and ds.n_points == 16
    assert json.loads((tmp_path / "t.json").read_text())["mechanisms"][0]["channel"] == "speed_rpm"
    bad = [
        (["--params", "nope", "--out", str(out)], "unknown parameter set"),
        (["--params", "man-12v32-40", "--mechanism", "warp", "--out", str(out)], "unknown mechanism"),
        (["--params", "man-12v32-40", "--mechanism", "cpp_load:x=1", "--out", str(out)], "unknown parameter"),
        (["--params", "man-12v32-40", "--points", "2", "--out", str(out)], "--points"),
        (["--params", "man-12v32-40", "--noise", "-1", "--out", str(out)], "--noise"),
        (["--params", "man-12v32-40", "--columns", "speed_rpm,bogus_col", "--out", str(out)], "unknown column"),
        (["--params", "man-12v32-40", "--columns", "fuel_rack,power_kW", "--out", str(out)], "no model counterpart"),
        (["--params", "man-12v32-40", "--mechanism", "none", "--mechanism", "cpp_load", "--out", str(out)],
         "cannot be combined"),
        (["--params", "man-12v32-40", "--mechanism", "sensor_calibration:channel=power_kW", "--out", str(out)],
         "not a written measurement"),
        (["--params", "man-12v32-40", "--out", str(tmp_path / "nodir" / "x.csv")], "does not exist"),
        (["--params", "man-12v32-40"], "--out"),
    ]
    capsys.readouterr()
    for argv, msg in bad:
        assert synthesize_main(argv) == 2, argv
        err = capsys.readouterr().err
        assert msg in err and "Traceback" not in err, (argv, err)
