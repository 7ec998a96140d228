"""Optional submodels of the one engine model: inert submodels reproduce the base model, each submodel moves
the physics the way it should, the two steady-state solvers agree, fitted-engine files round-trip, and the
dynamic simulator settles where the steady-state solver says."""

from __future__ import annotations

import json

import numpy as np
import pytest

from marine_fdi_env.engine.model import ALG_FIELDS, EngineModel
from marine_fdi_env.engine.operating_point import MODE_F, MODE_P, MODE_U, solve_points, speed_of_power
from marine_fdi_env.engine.params import engine_file_dict, load_params
from marine_fdi_env.engine.simulator import Simulator
from marine_fdi_env.engine.steady_state import steady_state
from marine_fdi_env.engine.submodels import (
    NO_SUBMODELS,
    BypassValve,
    CombinatorSpeed,
    CylinderHeatLoss,
    EngineSubmodels,
    ExhaustHeatLoss,
    ExtraFriction,
    Intercooler,
    Schedule,
    TurbineEfficiencyBSR,
    TurbineFlowLaw,
    WasteGate,
)
from marine_fdi_env.engine.turbocharger_speed import turbocharger_speed_rpm

SETS = ("thesis-12v28", "man-12v32-40", "wartsila-6l46")
U = np.array([0.3, 0.55, 0.8, 1.0, 1.1])
# every submodel on, but inert: the extended gas path must give the base model's numbers (to rounding)
INERT = EngineSubmodels(
    waste_gate=WasteGate(Schedule.constant(0.0)),
    bypass_valve=BypassValve(Schedule.constant(0.0)),
    turbine_flow_law=TurbineFlowLaw(1.0, 2.0),
    turbine_efficiency_bsr=TurbineEfficiencyBSR(1.0, 0.0),
    exhaust_heat_loss=ExhaustHeatLoss(0.0, 0.2),
    friction=ExtraFriction(0.0, 0.0),
    intercooler=Intercooler(1.0, 0.0),
)
ALL_ON = EngineSubmodels(
    waste_gate=WasteGate(Schedule((0.6, 1.0), (0.0, 0.2))),
    bypass_valve=BypassValve(Schedule((0.3, 0.6), (0.1, 0.0))),
    turbine_flow_law=TurbineFlowLaw(0.85, 2.6),
    turbine_efficiency_bsr=TurbineEfficiencyBSR(0.9, 0.4),
    exhaust_heat_loss=ExhaustHeatLoss(0.06, 0.3),
    friction=ExtraFriction(4e4, 1e4),
    intercooler=Intercooler(0.8, -6.0),
    cylinder_heat_loss=CylinderHeatLoss(1.37, 0.02),
    speed_law=CombinatorSpeed(0.75, 1.0),
)


def _ss(params, u=U):
    ss = steady_state(EngineModel(params), u)
    assert ss.converged.all()
    return ss


@pytest.mark.parametrize("name", SETS)
def test_inert_submodels_reproduce_the_base_model(name):
    p = load_params(name)
    base, ext = _ss(p), _ss(p.replace(submodels=INERT))
    # the extended gas path rebuilds the base equations in another order: equal to rounding (1e-12)
    for f in ("x3", "x4"):
        np.testing.assert_allclose(getattr(ext, f), getattr(base, f), rtol=1e-12)
    for f in ALG_FIELDS:
        np.testing.assert_allclose(getattr(ext.alg, f), getattr(base.alg, f), rtol=1e-12, atol=1e-12, err_msg=f)


@pytest.mark.parametrize("name", SETS)
@pytest.mark.parametrize("sub", [NO_SUBMODELS, ALL_ON], ids=["base", "all-submodels"])
def test_operating_point_solver_agrees_with_steady_state(name, sub):
    """The validation's 3-unknown solver (fuel, power or fuel flow fixed) and the simulator's steady state agree to
    1e-9 relative in every output (both solve the same compiled equations to ~1e-12)."""
    p = load_params(name).replace(submodels=sub)
    ss = _ss(p)
    op = solve_points(p, MODE_U, U)
    assert op.converged.all()
    for i in range(U.size):
        a, b = ss.summary(p, i), op.summary(i)
        for k, v in a.items():
            assert b[k] == pytest.approx(v, rel=1e-9, abs=1e-12), k
    P = op.values["power_W"]
    by_power = solve_points(p, MODE_P, P)
    np.testing.assert_allclose(by_power.values["fuel_setting"], U, rtol=1e-9)
    by_fuel = solve_points(p, MODE_F, op.values["fuel_mass_flow_kg_s"])
    np.testing.assert_allclose(by_fuel.values["power_W"], P, rtol=1e-9)


def test_prescribed_speed_moves_only_the_speed_law():
    p = load_params("wartsila-6l46")
    op = solve_points(p, MODE_U, U)
    n = op.values["engine_speed_rev_s"]
    same = solve_points(p, MODE_U, U, n, prescribed_speed=True)
    np.testing.assert_allclose(same.values["power_W"], op.values["power_W"], rtol=1e-9)
    faster = solve_points(p, MODE_U, U, 1.05 * n, prescribed_speed=True)
    assert np.all(faster.values["engine_speed_rev_s"] > n)


def _at_power(p, loads=(0.3, 0.6, 0.9, 1.05)):
    P = np.asarray(loads) * p.P_nom_W
    op = solve_points(p, MODE_P, P)
    assert op.converged.all()
    return op.values


def test_waste_gate_spills_exhaust_and_caps_the_charge_pressure():
    p = load_params("wartsila-6l46")
    base = _at_power(p)
    wg = _at_power(p.replace(submodels=EngineSubmodels(waste_gate=WasteGate(Schedule.constant(0.2)))))
    # the gate passes a/(1 + a) of the exhaust (same flow law as the turbine)
    np.testing.assert_allclose(wg["waste_gate_fraction"], 0.2 / 1.2, rtol=1e-12)
    assert np.all(wg["charge_air_pressure_Pa"] < base["charge_air_pressure_Pa"])
    assert np.all(wg["exhaust_receiver_pressure_Pa"] < base["exhaust_receiver_pressure_Pa"])
    # the bypassed hot gas rejoins after the turbine outlet thermocouple: the mixture is hotter than the outlet
    assert np.all(wg["exhaust_after_waste_gate_temperature_K"] > wg["turbine_outlet_temperature_K"])
    assert np.all(wg["sfc_kg_per_J"] > base["sfc_kg_per_J"])  # less air, more pumping: worse fuel economy


def test_bypass_valve_adds_air_and_junction_decides_what_the_thermocouple_reads():
    p = load_params("wartsila-6l46")
    base = _at_power(p)
    rec = _at_power(p.replace(submodels=EngineSubmodels(bypass_valve=BypassValve(Schedule.constant(0.1), "receiver"))))
    tur = _at_power(p.replace(submodels=EngineSubmodels(bypass_valve=BypassValve(Schedule.constant(0.1), "turbine"))))
    for v in (rec, tur):
        assert np.all(v["bypass_air_flow_kg_s"] > 0)
        assert np.all(v["air_mass_flow_kg_s"] > base["air_mass_flow_kg_s"])
        # the turbine gets cool air mixed in
        assert np.all(v["turbine_gas_inlet_temperature_K"] < v["cylinder_outlet_temperature_K"])
    # junction in the receiver: the thermocouple reads the mixture; junction at the turbine: the exhaust alone
    np.testing.assert_allclose(rec["turbine_inlet_temperature_K"], rec["turbine_gas_inlet_temperature_K"])
    np.testing.assert_allclose(tur["turbine_inlet_temperature_K"], tur["cylinder_outlet_temperature_K"])


def test_turbine_flow_law_area_and_exponent():
    p = load_params("wartsila-6l46")
    base = _at_power(p)
    small = _at_power(p.replace(submodels=EngineSubmodels(turbine_flow_law=TurbineFlowLaw(0.85, 2.0))))
    assert np.all(small["exhaust_receiver_pressure_Pa"] > base["exhaust_receiver_pressure_Pa"])
    assert np.all(small["charge_air_pressure_Pa"] > base["charge_air_pressure_Pa"])
    # a larger exponent passes more at low pressure ratio: the receiver pressure falls most at part load
    nozzle = _at_power(p.replace(submodels=EngineSubmodels(turbine_flow_law=TurbineFlowLaw(1.0, 3.5))))
    drop = 1.0 - (nozzle["exhaust_receiver_pressure_Pa"] - p.p_ex_Pa) / (
        base["exhaust_receiver_pressure_Pa"] - p.p_ex_Pa
    )
    assert np.all(drop > 0) and drop[0] > drop[-1]


def test_exhaust_heat_loss_grows_as_the_flow_falls():
    p = load_params("wartsila-6l46")
    v = _at_power(p.replace(submodels=EngineSubmodels(exhaust_heat_loss=ExhaustHeatLoss(0.05, 0.3))))
    loss = (v["cylinder_outlet_temperature_K"] - v["turbine_inlet_temperature_K"]) / (
        v["cylinder_outlet_temperature_K"] - p.T_amb_K
    )
    assert np.all(np.diff(loss) < 0)  # loads increase: the relative loss falls
    i_nom = 2  # near nominal flow the relative loss is close to loss_fraction_nom
    assert 0.03 < loss[i_nom] < 0.07


def test_bsr_factor_is_one_at_the_nominal_point_with_its_optimum_there():
    """With r_opt = 1 the blade-speed-ratio factor is 1 at the base model's nominal point (r = 1), so the nominal
    point does not move; with r_opt != 1 it does."""
    p = load_params("thesis-12v28")
    base = _ss(p, np.array([1.0]))
    at = _ss(
        p.replace(submodels=EngineSubmodels(turbine_efficiency_bsr=TurbineEfficiencyBSR(1.0, 0.6))), np.array([1.0])
    )
    assert at.x4[0] == pytest.approx(base.x4[0], rel=2e-3)
    off = _ss(
        p.replace(submodels=EngineSubmodels(turbine_efficiency_bsr=TurbineEfficiencyBSR(0.8, 0.6))), np.array([0.5])
    )
    assert abs(off.x4[0] / _ss(p, np.array([0.5])).x4[0] - 1) > 1e-3


def test_combinator_speed_line_and_friction():
    p = load_params("man-12v32-40")
    sub = p.replace(submodels=EngineSubmodels(speed_law=CombinatorSpeed(0.75, 1.0)))
    v = _at_power(sub)
    np.testing.assert_allclose(
        v["engine_speed_rev_s"], p.n_nom_rev_s * (0.75 + 0.25 * v["power_W"] / p.P_nom_W), rtol=1e-9
    )
    np.testing.assert_allclose(speed_of_power(sub, v["power_W"]), v["engine_speed_rev_s"], rtol=1e-12)
    fr = _at_power(p.replace(submodels=EngineSubmodels(friction=ExtraFriction(5e4, 0.0))))
    base = _at_power(p)
    rel = fr["fuel_mass_flow_kg_s"] / base["fuel_mass_flow_kg_s"] - 1
    assert np.all(rel > 0) and rel[0] > rel[-1]  # a constant fmep weighs most at part load


def test_intercooler_follows_the_compressor_outlet():
    p = load_params("wartsila-6l46")
    v = _at_power(p.replace(submodels=EngineSubmodels(intercooler=Intercooler(0.7, -8.0))))
    assert np.all(np.diff(v["charge_air_cooler_outlet_temperature_K"]) > 0)
    base = _at_power(p)
    assert np.all(base["charge_air_cooler_outlet_temperature_K"] == p.T_c_K)


@pytest.mark.parametrize(
    "bad, match",
    [
        (lambda: Schedule((1.0, 0.5), (0.1, 0.2)), "strictly increasing"),
        (lambda: Schedule((0.5,), (-0.1,)), ">= 0"),
        (lambda: Schedule((0.5, 1.0), (0.1,)), "as many openings as knots"),
        (lambda: TurbineFlowLaw(0.1, 2.0), r"area_scale must lie in"),
        (lambda: BypassValve(Schedule.constant(0.1), "elsewhere"), "junction must be one of"),
        (lambda: EngineSubmodels.from_dict({"waste_gates": {}}), "unknown submodel 'waste_gates'"),
        (lambda: EngineSubmodels.from_dict({"waste_gate": {"openness": 1}}), "unknown field"),
    ],
)
def test_submodel_errors_name_the_field(bad, match):
    with pytest.raises(ValueError, match=match):
        bad()


def test_engine_file_round_trip(tmp_path):
    p = load_params("wartsila-6l46")
    eng = p.replace(name="fitted", A_eff_m2=0.9 * p.A_eff_m2, submodels=ALL_ON)
    f = tmp_path / "engine.json"
    f.write_text(json.dumps(engine_file_dict(eng, "wartsila-6l46", {"dataset": "test"})))
    back = load_params(str(f))
    assert back == eng
    assert load_params(f) == eng  # a Path works too
    d = json.loads(f.read_text())
    assert d["base"] == "wartsila-6l46" and set(d["overrides"]) == {"A_eff_m2"}


@pytest.mark.parametrize(
    "content, match",
    [
        ("{", "not valid JSON"),
        ('{"format": "other"}', "not an engine file"),
        ('{"format": "marine_fdi_env.engine/1", "base": "nope"}', "field 'base'"),
        (
            '{"format": "marine_fdi_env.engine/1", "base": "wartsila-6l46", "overrides": {"A_eff": 1}}',
            "unknown parameter",
        ),
        ('{"format": "marine_fdi_env.engine/1", "base": "wartsila-6l46", "overrides": {"A_eff_m2": -1}}', "A_eff_m2"),
    ],
)
def test_bad_engine_files(tmp_path, content, match):
    f = tmp_path / "e.json"
    f.write_text(content)
    with pytest.raises(ValueError, match=match):
        load_params(str(f))
    with pytest.raises(ValueError, match="no such engine file"):
        load_params(str(tmp_path / "missing.json"))


def test_fitted_engine_settles_where_the_steady_state_solver_says():
    """The dynamic simulator with valve schedules, a re-matched turbine and other submodels, after a fuel step,
    settles on the equilibrium of the steady-state solver the fits use: every state and output within 0.1 %
    (after 12 charge-air time constants the transient is below 1e-5 of the step)."""
    p = load_params("wartsila-6l46")
    eng = p.replace(
        name="fitted",
        A_eff_m2=0.8 * p.A_eff_m2,
        submodels=EngineSubmodels(
            waste_gate=WasteGate(Schedule((0.6, 0.8, 1.0), (0.0, 0.1, 0.2))),
            bypass_valve=BypassValve(Schedule((0.35, 0.5), (0.08, 0.0))),
            turbine_flow_law=TurbineFlowLaw(1.0, 2.5),
            exhaust_heat_loss=ExhaustHeatLoss(0.04, 0.3),
            intercooler=Intercooler(0.85, -5.0),
        ),
    )
    u_end = np.array([0.9, 0.4])
    sim = Simulator(
        eng, n_engines=2, seeds=[0, 1], profiles=[f"step:u0=0.6,u1={u:g},t=5" for u in u_end], noise_scale=0.0
    )
    res = sim.run(12 * eng.tau_TC_s, record=True)
    assert not res.failures
    op = solve_points(eng, MODE_U, u_end)
    truth = res.truth[-1]  # (engines, variables) at the end
    from marine_fdi_env.engine.simulator import TRUTH_VARIABLES

    idx = {v: k for k, v in enumerate(TRUTH_VARIABLES)}
    pairs = {
        "x3": "exhaust_receiver_pressure_Pa",
        "x4": "charge_air_pressure_Pa",
        "n": "engine_speed_rev_s",
        "power": "power_W",
        "p_max": "p_max_Pa",
        "T_in": "turbine_inlet_temperature_K",
        "T_out": "turbine_outlet_temperature_K",
        "T_co": "compressor_outlet_temperature_K",
        "T1": "inlet_air_temperature_K",
    }
    for var, key in pairs.items():
        np.testing.assert_allclose(truth[:, idx[var]], op.values[key], rtol=1e-3, err_msg=var)
    assert op.values["waste_gate_fraction"][0] > 0.05 and op.values["bypass_air_flow_kg_s"][1] > 0


def test_turbocharger_speed_law_on_the_protocol():
    """N = N_nom sqrt(Δh_c,is / Δh_c,is,nom), calibrated on the protocol's 100 % row only: at the other rows (measured
    charge-air pressure, ambient pressure and compressor inlet temperature) it predicts the measured rotor speed
    within 2.5 % (the measured isentropic head coefficient varies by ±2.6 % over the loads, so about ±1.3 % in
    speed; the 50 % row's inlet temperature, recorded as 0 C, is replaced by the median of the others)."""
    from marine_fdi_env.validation import load_shipped

    with pytest.warns(Warning):
        ds = load_shipped("birka_me1_test_protocol")
    p = load_params("wartsila-6l46")
    N = turbocharger_speed_rpm(p, ds.values["charge_air_pressure_Pa"], ds.boundary["p_amb_Pa"], ds.boundary["T_amb_K"])
    meas = ds.raw["turbocharger_speed_rpm"]
    rel = N / meas - 1
    assert abs(rel[4]) < 1e-3  # the calibration row
    assert np.max(np.abs(rel)) < 0.025
    assert float(turbocharger_speed_rpm(p, 1.025e5 + 3.08e5, 1.025e5, 307.15)) == pytest.approx(22142.0, rel=1e-12)


def test_reference_diagnoser_plant_runs_with_the_submodels():
    """The diagnoser's residual generators use the engine's submodels (waste gate, bypass valve, flow law,
    heat loss, intercooler, BSR, friction, heat loss in the cylinders, combinator speed): on noise-free,
    fault-free data of such an engine every module stays inside its threshold, while a diagnoser that
    assumed the base engine would see the submodels as faults (its Σ3/Σ4 modules cross their thresholds)."""
    from marine_fdi_env.diagnosis.agent import ReferenceDiagnoser
    from marine_fdi_env.diagnosis.modules import MODULE_IDS
    from marine_fdi_env.diagnosis.residuals import residuals_for_run

    p = load_params("thesis-12v28")
    eng = p.replace(name="with-submodels", submodels=ALL_ON)
    sim = Simulator(eng, n_engines=2, seeds=[0, 1], profiles=["constant:u0=0.95", "constant:u0=0.45"], noise_scale=0.0)
    res = sim.run(60.0)
    assert not res.failures
    settled = slice(int(10.0 / sim.dt), None)  # after the observers' start-up
    own, base = ReferenceDiagnoser(eng).c, ReferenceDiagnoser(p).c
    worst_base = 0.0
    for i in range(2):
        y, u = res.measurements[:, i], res.truth_of("u")[:, i]
        tr = residuals_for_run(own, y, u, sim.dt)
        ratio = np.abs(tr.residuals[settled]) / tr.thresholds[settled]
        worst = ratio.max(axis=0)
        assert np.all(worst < 1.0), {m: round(float(w), 3) for m, w in zip(MODULE_IDS, worst) if w >= 1.0}
        tb = residuals_for_run(base, y, u, sim.dt)
        worst_base = max(worst_base, float((np.abs(tb.residuals[settled]) / tb.thresholds[settled]).max()))
    assert worst_base > 1.0
