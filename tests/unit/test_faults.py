"""Fault specifications, thesis defaults (tables 6.3, 6.4) and the compiled time profiles (eq. 2.3-2.6)."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from marine_fdi_env.engine.faults import (
    FAULT_IDS,
    PROCESS_FAULT_DEFAULTS,
    PROCESS_FAULT_IDS,
    CompiledSchedule,
    FaultSpec,
    parse_fault_spec,
)
from marine_fdi_env.engine.sensors import SENSOR_IDS, SENSORS, sensor_index
from marine_fdi_env.engine.simulator import Simulator

INF = math.inf

# ----------------------------------------------------------------------------- thesis tables
# Table 6.3 (thesis line ~1185), transcribed by hand: sensor -> (noise bound, fault magnitude).
TABLE_6_3 = {
    "S1.1": (4.5e-5, 1.8e-4),
    "S1.2": (4.5e-5, 1.8e-4),
    "S2.1": (2e4, 9e4),
    "S2.2": (2e4, 9e4),
    "S2.3": (17.0, 55.0),
    "S2.4": (17.0, 55.0),
    "S2.5": (0.75e3, 7.125e3),
    "S2.6": (0.75e3, 7.125e3),
    "S3.1": (0.99e3, 5e3),
    "S3.2": (0.99e3, 5e3),
    "S3.3": (8.0, 48.0),
    "S3.4": (8.0, 48.0),
    "S3.5": (6.0, 25.0),
    "S4.1": (5.5e3, 5e4),
    "S4.2": (5.5e3, 5e4),
    "S4.3": (5.0, 22.0),
    "S4.4": (5.0, 22.0),
    "S4.5": (5.0, 25.0),
    "S4.6": (5.0, 25.0),
}

# Table 6.4 (thesis line ~1312): id -> (initialisation time t1 [s], kappa [1/s], magnitude).
# phi_u = 25 "%" is read as the fraction 0.25 (documented in faults.py).
TABLE_6_4 = {
    "turbine_seal_leak": (15.0, 2e-5, 3.5e-4),
    "turbine_lubrication_loss": (30.0, 1e3, 1.25),
    "compressor_seal_leak": (30.0, 1e-4, 5e-2),
    "intercooler_blockage": (30.0, 1e-3, 2.0),
    "compressor_lubrication_loss": (30.0, 1e3, 2.5),
    "bore_damage": (15.0, 1e-5, 3e-3),
    "valve_seizing": (20.0, 1e-2, 0.25),
}


# ----------------------------------------------------------------------------- parsing
def test_parse_basic_spec():
    assert parse_fault_spec("S4.2@235:5e4") == FaultSpec("S4.2", 235.0, 5e4)
    # no magnitude -> None (the thesis default is resolved later)
    f = parse_fault_spec("bore_damage@5")
    assert f == FaultSpec("bore_damage", 5.0)
    assert f.magnitude is None and f.resolved_kind == "process"


def test_parse_options():
    f = parse_fault_spec("S2.1@20:3e4,kind=drift,end=80,period=20,duty=0.25,kappa=0.5")
    assert f == FaultSpec("S2.1", 20.0, 3e4, kind="drift", kappa=0.5, end_s=80.0, period_s=20.0, duty=0.25)
    g = parse_fault_spec("valve_seizing@20:0.1,kappa=0.05")
    assert (g.fault_id, g.onset_s, g.magnitude, g.kappa) == ("valve_seizing", 20.0, 0.1, 0.05)
    # kappa=inf is allowed: an abrupt fault
    assert parse_fault_spec("S1.1@50,kind=offset,kappa=inf").resolved_kappa == INF
    # magnitude may also come as an option
    assert parse_fault_spec("S3.3@10,magnitude=12").magnitude == 12.0
    for kind in ("offset", "drift", "stuck", "gain", "precision"):
        assert parse_fault_spec(f"S3.3@10,kind={kind}").resolved_kind == kind


@pytest.mark.parametrize(
    "text, field",
    [
        ("X9.9@10", r"fault id"),  # unknown fault id
        ("not_a_fault@10", r"fault id"),
        ("S4.2@-1", r"onset_s"),  # negative onset
        ("S4.2@nan", r"onset_s"),
        ("S4.2@abc", r"onset"),
        ("bore_damage@1:-1e-3", r"magnitude"),  # negative process magnitude
        ("valve_seizing@1:-0.1", r"magnitude"),
        ("S4.2@1:nan", r"magnitude"),
        ("S4.2@1:inf", r"magnitude"),
        ("bore_damage@1:inf", r"magnitude"),
        ("S4.2@1:xyz", r"magnitude"),
        ("S4.2@10,end=10", r"end_s"),  # end <= onset
        ("S4.2@10,end=5", r"end_s"),
        ("S4.2@1,period=2,duty=1.5", r"duty"),  # duty > 1
        ("S4.2@1,period=2,duty=0", r"duty"),
        ("S4.2@1,period=2", r"period_s"),  # period without duty
        ("S4.2@1,duty=0.5", r"period_s"),
        ("S4.2@1,period=0,duty=0.5", r"period_s"),
        ("S4.2@1,kappa=0", r"kappa"),
        ("S4.2@1,kappa=nan", r"kappa"),
        ("S4.2@1,kind=wobble", r"kind"),
        ("bore_damage@1,kind=offset", r"kind"),  # process faults have no sensor kinds
        ("S4.2@1:-1,kind=precision", r"magnitude"),
        ("S4.2", r"ID@ONSET"),  # malformed text
        ("", r"ID@ONSET"),
        ("S4.2@1,foo=2", r"key=value"),
        ("S4.2@1,kappa", r"key=value"),
        ("S4.2@1,end=soon", r"end"),
    ],
)
def test_parse_rejects_bad_specs_naming_the_field(text, field):
    with pytest.raises(ValueError, match=re.compile(field)):
        parse_fault_spec(text)


def test_parse_rejects_non_string():
    with pytest.raises(ValueError, match="ID@ONSET"):
        parse_fault_spec(None)  # type: ignore[arg-type]


# ----------------------------------------------------------------------------- defaults
def test_sensor_table_matches_thesis_table_6_3():
    assert list(SENSOR_IDS) == list(TABLE_6_3)
    for s in SENSORS:
        bound, mag = TABLE_6_3[s.id]
        assert s.noise_bound == bound, s.id
        assert s.fault_magnitude == mag, s.id


@pytest.mark.parametrize("sid", SENSOR_IDS)
def test_sensor_offset_default_is_table_6_3(sid):
    f = FaultSpec(sid, 10.0)
    assert f.resolved_kind == "offset"
    assert f.resolved_kappa == INF  # sensor faults are abrupt by default
    # exact equality: the default is the tabulated number itself, no arithmetic
    assert f.resolved_magnitude == TABLE_6_3[sid][1]
    assert f.resolved_magnitude == SENSORS[sensor_index(sid)].fault_magnitude


@pytest.mark.parametrize("fid", PROCESS_FAULT_IDS)
def test_process_defaults_are_table_6_4(fid):
    t1, kappa, mag = TABLE_6_4[fid]
    d = PROCESS_FAULT_DEFAULTS[fid]
    assert (d.onset_s, d.kappa, d.magnitude) == (t1, kappa, mag)
    f = FaultSpec(fid, 0.0)
    assert f.resolved_kappa == kappa
    assert f.resolved_magnitude == mag


def test_process_defaults_cover_all_process_faults():
    assert set(PROCESS_FAULT_DEFAULTS) == set(PROCESS_FAULT_IDS) == set(TABLE_6_4)
    assert FAULT_IDS == SENSOR_IDS + PROCESS_FAULT_IDS
    assert len(FAULT_IDS) == 26


def test_bore_damage_defaults_explicitly():
    # the example named in the brief: bore damage kappa 1e-5 1/s, R 3e-3 m^3/s
    f = parse_fault_spec("bore_damage@15")
    assert f.resolved_kappa == 1e-5 and f.resolved_magnitude == 3e-3


# ----------------------------------------------------------------------------- time profiles
def _sensor_value(sched: CompiledSchedule, t: float) -> np.ndarray:
    """beta * magnitude of every scheduled sensor fault (0 where inactive) - an offset's value."""
    s, beta = sched.sensor_fault_state(t)
    return np.where(np.isnan(s), 0.0, beta * sched.s_params["mag"])


def test_permanent_abrupt_offset_is_exact_step():
    sched = CompiledSchedule.compile([[FaultSpec("S4.2", 235.0, 5e4)]])
    for t in (0.0, 100.0, 234.99, 234.999999):
        assert _sensor_value(sched, t)[0] == 0.0
        assert np.isnan(sched.sensor_fault_state(t)[0][0])
    for t in (235.0, 235.01, 300.0, 1e6):
        # beta = 1 exactly for kappa = inf: no rounding is acceptable
        assert _sensor_value(sched, t)[0] == 5e4
    assert sched.sensor_fault_state(240.0)[0][0] == pytest.approx(5.0, abs=1e-12)


def test_transient_fault_turns_off_at_end():
    sched = CompiledSchedule.compile([[FaultSpec("S1.1", 50.0, 2e-4, end_s=80.0)]])
    assert _sensor_value(sched, 49.99)[0] == 0.0
    assert _sensor_value(sched, 50.0)[0] == 2e-4
    assert _sensor_value(sched, 79.99)[0] == 2e-4
    # windows are half-open [onset, end): off at end and after
    assert _sensor_value(sched, 80.0)[0] == 0.0
    assert _sensor_value(sched, 500.0)[0] == 0.0
    assert list(sched.breakpoints) == [50.0, 80.0]


def test_intermittent_on_off_pattern():
    # on for duty*period = 5 s every 20 s from onset 10 s: [10,15), [30,35), [50,55), ...
    # all boundary times are exactly representable, so exact window edges are checked
    sched = CompiledSchedule.compile([[FaultSpec("S3.3", 10.0, 30.0, period_s=20.0, duty=0.25)]])
    on_times = [10.0, 12.5, 14.99, 30.0, 34.0, 50.0, 1010.0]
    off_times = [0.0, 9.99, 15.0, 20.0, 29.99, 35.0, 49.0, 1015.0]
    for t in on_times:
        assert _sensor_value(sched, t)[0] == 30.0, t
    for t in off_times:
        assert _sensor_value(sched, t)[0] == 0.0, t
    # the window time restarts in every window
    s, _ = sched.sensor_fault_state(32.0)
    assert s[0] == pytest.approx(2.0, abs=1e-12)


def test_intermittent_with_end_stops():
    sched = CompiledSchedule.compile([[FaultSpec("S3.3", 10.0, 30.0, period_s=20.0, duty=0.5, end_s=45.0)]])
    assert _sensor_value(sched, 31.0)[0] == 30.0
    assert _sensor_value(sched, 44.0)[0] == 0.0  # off phase of the second window
    assert _sensor_value(sched, 50.0)[0] == 0.0  # would be on, but after end
    assert _sensor_value(sched, 55.0)[0] == 0.0


def test_process_fault_intermittent_value():
    # a process fault in an intermittent window: value restarts at 0 in each window
    sched = CompiledSchedule.compile(
        [[FaultSpec("intercooler_blockage", 10.0, 2.0, kappa=INF, period_s=10.0, duty=0.5)]]
    )
    assert sched.process_values(12.0).dT_c_K[0] == pytest.approx(4.0, rel=1e-12)  # R s with s = 2
    assert sched.process_values(16.0).dT_c_K[0] == 0.0  # off phase
    assert sched.process_values(21.0).dT_c_K[0] == pytest.approx(2.0, rel=1e-12)  # s = 1 in window 2


# The hand formula uses 1 - exp(-kappa s) literally; for kappa s >= 1e-5 its cancellation error is
# at most eps / (kappa s) ~ 2e-11 relative, so rtol = 1e-9 checks the formula, not rounding.
_RTOL_FORMULA = 1e-9


@pytest.mark.parametrize(
    "fid, field",
    [
        ("bore_damage", "dV1_m3"),
        ("turbine_seal_leak", "phi_tur"),
        ("turbine_lubrication_loss", "dT_sl_K"),
        ("compressor_seal_leak", "phi_int"),
        ("compressor_lubrication_loss", "dT_inl_K"),
        ("intercooler_blockage", "dT_c_K"),
    ],
)
def test_incipient_process_fault_value(fid, field):
    onset = 15.0
    kappa, R = PROCESS_FAULT_DEFAULTS[fid].kappa, PROCESS_FAULT_DEFAULTS[fid].magnitude
    # engine 1 has the fault, engines 0 and 2 are healthy
    sched = CompiledSchedule.compile([[], [FaultSpec(fid, onset)], []])
    for t in (0.0, 14.99):
        assert np.all(getattr(sched.process_values(t), field) == 0.0)
    assert getattr(sched.process_values(onset), field)[1] == 0.0  # s = 0
    for s in (1.0, 10.0, 100.0, 300.0, 5000.0):
        v = getattr(sched.process_values(onset + s), field)
        expected = (1.0 - math.exp(-kappa * s)) * R * s
        assert v[1] == pytest.approx(expected, rel=_RTOL_FORMULA), (fid, s)
        assert v[0] == 0.0 and v[2] == 0.0
        assert v[1] > 0.0


def test_valve_seizing_multiplier():
    onset, kappa, phi = 20.0, 1e-2, 0.25
    sched = CompiledSchedule.compile([[FaultSpec("valve_seizing", onset)], []])
    assert np.all(sched.process_values(19.99).f_u == 1.0)
    assert sched.process_values(onset).f_u[0] == 1.0
    for s in (1.0, 10.0, 100.0, 280.0, 1e4):
        f_u = sched.process_values(onset + s).f_u
        expected = 1.0 - (1.0 - math.exp(-kappa * s)) * phi
        # 1 - beta phi is O(1): only rounding of the exponential matters
        assert f_u[0] == pytest.approx(expected, rel=1e-12, abs=0.0)
        assert f_u[1] == 1.0
    # long after onset the valve is stuck at 1 - phi
    assert sched.process_values(1e5).f_u[0] == pytest.approx(0.75, abs=1e-12)


def test_abrupt_process_fault_kappa_inf():
    sched = CompiledSchedule.compile([[FaultSpec("valve_seizing", 5.0, 0.4, kappa=INF)]])
    assert sched.process_values(4.99).f_u[0] == 1.0
    assert sched.process_values(5.0).f_u[0] == pytest.approx(0.6, abs=1e-15)


def test_healthy_schedule_has_no_process_or_sensor_faults():
    sched = CompiledSchedule.compile([[], []])
    assert sched.process == {}
    assert len(sched.s_engine) == 0


# ----------------------------------------------------------------------------- scheduling
@pytest.mark.parametrize("fid", ["S4.2", "bore_damage"])
def test_same_fault_twice_for_one_engine_rejected(fid):
    twice = [FaultSpec(fid, 10.0), FaultSpec(fid, 50.0)]
    with pytest.raises(ValueError, match="twice"):
        CompiledSchedule.compile([[], twice])
    with pytest.raises(ValueError, match="twice"):
        Simulator(n_engines=1, faults=[twice], noise_scale=0.0)


def test_same_fault_on_different_engines_allowed():
    sched = CompiledSchedule.compile([[FaultSpec("S4.2", 1.0)], [FaultSpec("S4.2", 2.0)]])
    assert list(sched.s_engine) == [0, 1]
    # different faults on one engine are fine too
    CompiledSchedule.compile([[FaultSpec("S4.2", 1.0), FaultSpec("S4.1", 1.0), FaultSpec("bore_damage", 1.0)]])


def test_compile_rejects_non_faultspec():
    with pytest.raises(ValueError, match="FaultSpec"):
        CompiledSchedule.compile([["S4.2@1"]])
