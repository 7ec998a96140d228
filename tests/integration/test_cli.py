"""The ``marine-fdi`` command line and the .npz run files (runio): in-process calls of cli.main."""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from marine_fdi_env import cli
from marine_fdi_env.engine.faults import FAULT_IDS, PROCESS_FAULT_DEFAULTS
from marine_fdi_env.engine.sensors import DEFAULT_FAULT_MAGNITUDES, SENSOR_IDS, sensor_index
from marine_fdi_env.engine.simulator import TRUTH_VARIABLES
from marine_fdi_env.runio import REQUIRED_ARRAYS, load_run
from marine_fdi_env.scenarios import SCENARIOS, get_scenario


def run_cli(capsys, *argv):
    code = cli.main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


# ----------------------------------------------------------------------------- operating-point
OP_KEYS = [
    "engine_speed_rev_s",
    "power_W",
    "torque_Nm",
    "fuel_per_cycle_kg",
    "sfc_kg_per_J",
    "charge_air_pressure_Pa",
    "exhaust_receiver_pressure_Pa",
    "p_max_Pa",
    "turbine_inlet_temperature_K",
    "turbine_outlet_temperature_K",
    "compressor_outlet_temperature_K",
    "inlet_air_temperature_K",
    "air_mass_flow_kg_s",
    "air_excess_ratio",
]


def test_operating_point_json_nominal(capsys):
    code, out, err = run_cli(capsys, "operating-point", "--params", "thesis-12v28", "--fuel-setting", "1.0", "--json")
    assert code == 0, err
    d = json.loads(out)
    assert d["params"] == "thesis-12v28"
    assert d["fuel_setting"] == 1.0
    for key in OP_KEYS:
        assert key in d and isinstance(d[key], float) and math.isfinite(d[key]), key
    assert d["engine_speed_rev_s"] == pytest.approx(16.71, rel=0.02)
    assert d["power_W"] == pytest.approx(5.4e6, rel=0.05)
    assert d["p_max_Pa"] == pytest.approx(188e5, rel=0.05)
    assert d["power_W"] == pytest.approx(2 * math.pi * d["engine_speed_rev_s"] * d["torque_Nm"], rel=1e-9)
    assert d["converged"] is True


def test_operating_point_table_and_idle_json_is_strict(capsys):
    code, out, _ = run_cli(capsys, "operating-point", "--params", "man-12v32-40", "--fuel-setting", "0.6")
    assert code == 0
    assert "man-12v32-40" in out and "rev/s" in out and "bar" in out and "p max" in out
    # at u = 0 the engine stands still; sfc is infinite and must come out as null, not Infinity
    code, out, err = run_cli(capsys, "operating-point", "--fuel-setting", "0", "--json")
    assert code == 0
    d = json.loads(out, parse_constant=lambda c: pytest.fail(f"non-standard JSON constant {c}"))
    assert d["sfc_kg_per_J"] is None and "does not run" in err


# ----------------------------------------------------------------------------- simulate + load_run
@pytest.fixture(scope="module")
def faulty_run(tmp_path_factory):
    """A 2 s run of two engines with a sensor offset and a process fault, written by the CLI."""
    path = tmp_path_factory.mktemp("runs") / "faulty.npz"
    code = cli.main(
        [
            "simulate",
            "--params",
            "thesis-12v28",
            "--duration",
            "2",
            "--seed",
            "7",
            "--engines",
            "2",
            "--fault",
            "S4.2@0.5:5e4",
            "--fault",
            "bore_damage@1",
            "--out",
            str(path),
            "--no-progress",
        ]
    )
    assert code == 0
    return path


def test_simulate_writes_loadable_run(faulty_run):
    run = load_run(faulty_run)
    T = 201
    assert run.t.shape == (T,) and run.t[-1] == pytest.approx(2.0)
    assert run.measurements.shape == (T, 2, 19)
    assert run.truth.shape == (T, 2, len(TRUTH_VARIABLES))
    assert run.fault_active.shape == run.fault_value.shape == (T, 2, len(FAULT_IDS))
    assert run.fault_active.dtype == bool
    assert run.sensor_ids == SENSOR_IDS and run.truth_variables == TRUTH_VARIABLES and run.fault_ids == FAULT_IDS
    assert set(run.by_sensor) == set(SENSOR_IDS) and run.by_sensor["S4.2"].shape == (T, 2)
    assert np.array_equal(run.sensor("S3.1", engine=1), run.measurements[:, 1, sensor_index("S3.1")])
    assert run.params_name == "thesis-12v28" and run.dt == 0.01 and run.n_engines == 2
    assert run.seeds == [7, 8] and run.noise_scale == 1.0
    assert run.metadata["command_line"].startswith("marine-fdi simulate")
    assert run.metadata["scenario"] is None and run.failures == []
    assert [p.values for p in run.profiles] == [(1.0,), (1.0,)]


def test_simulate_fault_ground_truth(faulty_run):
    run = load_run(faulty_run)
    faults = run.true_faults()
    assert [(f["engine"], f["id"], f["class"]) for f in faults] == [
        (0, "S4.2", "sensor"),
        (0, "bore_damage", "process"),
        (1, "S4.2", "sensor"),
        (1, "bore_damage", "process"),
    ]
    s42 = faults[0]
    assert s42["onset_s"] == 0.5 and s42["magnitude"] == 5e4 and s42["kind"] == "offset" and s42["unit"] == "Pa"
    assert s42["first_active_s"] == pytest.approx(0.5) and s42["active_in_run"]
    bore = run.true_faults(engine=1)[1]
    assert bore["magnitude"] == PROCESS_FAULT_DEFAULTS["bore_damage"].magnitude
    assert bore["first_active_s"] == pytest.approx(1.0)
    act = run.active("S4.2", engine=0)
    assert not act[:50].any() and act[50:].all()
    # the offset shows in the readings: S4.2 - S4.1 jumps by 5e4 Pa (noise bounds 5.5e3 Pa each)
    diff = run.sensor("S4.2") - run.sensor("S4.1")
    assert np.all(np.abs(diff[:50]) <= 2 * 5.5e3 + 1e-6)
    assert np.all(np.abs(diff[50:] - 5e4) <= 2 * 5.5e3 + 1e-6)
    # schedules round-trip through the metadata
    assert [(s.onset_s, s.resolved_magnitude) for s in run.schedules[0]] == [(0.5, 5e4), (1.0, 3e-3)]
    assert [s.fault_id for s in run.schedules[1]] == ["S4.2", "bore_damage"]


def test_simulate_is_reproducible(tmp_path, faulty_run):
    out = tmp_path / "again.npz"
    assert (
        cli.main(
            [
                "simulate",
                "--duration",
                "2",
                "--seed",
                "7",
                "--engines",
                "2",
                "--fault",
                "S4.2@0.5:5e4",
                "bore_damage@1",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    a, b = load_run(faulty_run), load_run(out)
    assert np.array_equal(a.measurements, b.measurements) and np.array_equal(a.fault_value, b.fault_value)


def test_simulate_scenario(tmp_path, capsys):
    out = tmp_path / "scen.npz"
    code, stdout, err = run_cli(capsys, "simulate", "--scenario", "thesis-6.4.1", "--duration", "1", "--out", out)
    assert code == 0, err
    assert str(out) in stdout and "thesis-6.4.1" in stdout
    assert "will not be active" in err  # onsets 175 s and 235 s lie after a 1 s run
    run = load_run(out)
    assert run.measurements.shape == (101, 1, 19)
    assert run.metadata["scenario"] == "thesis-6.4.1"
    faults = run.true_faults(engine=0)
    assert [(f["id"], f["onset_s"]) for f in faults] == [("S3.4", 175.0), ("S4.2", 235.0)]
    assert faults[0]["magnitude"] == DEFAULT_FAULT_MAGNITUDES[sensor_index("S3.4")]  # table 6.3
    assert not any(f["active_in_run"] for f in faults) and not run.fault_active.any()


def test_scenario_table():
    assert set(SCENARIOS) == {"thesis-6.4.1", "thesis-6.4.2", "thesis-6.4.3", "thesis-6.4.4"}
    expected = {
        "thesis-6.4.1": [("S3.4", 175.0), ("S4.2", 235.0)],
        "thesis-6.4.2": [("bore_damage", 5.0), ("valve_seizing", 200.0)],
        "thesis-6.4.3": [("S2.2", 20.0), ("compressor_seal_leak", 30.0)],
        "thesis-6.4.4": [("S3.2", 15.0), ("turbine_lubrication_loss", 30.0)],
    }
    for name, faults in expected.items():
        s = get_scenario(name)
        assert [(f.fault_id, f.onset_s) for f in s.fault_specs()] == faults
        assert s.duration_s == 300.0 and s.params == "thesis-12v28"
        assert all(f.magnitude is None for f in s.fault_specs())  # thesis default magnitudes
    with pytest.raises(ValueError, match="thesis-6.4.1"):
        get_scenario("thesis-9")


def test_info_and_listings(capsys, faulty_run):
    code, out, _ = run_cli(capsys, "info", faulty_run, "--json")
    assert code == 0
    info = json.loads(out)
    assert info["n_engines"] == 2 and len(info["true_faults"]) == 4
    code, out, _ = run_cli(capsys, "params")
    assert code == 0 and all(n in out for n in ("thesis-12v28", "man-12v32-40", "wartsila-6l46"))
    code, out, _ = run_cli(capsys, "params", "--name", "thesis-12v28")
    assert code == 0 and "p_max_nom_Pa" in out and "thesis table 4.1" in out
    code, out, _ = run_cli(capsys, "params", "--name", "thesis-12v28", "--json")
    assert json.loads(out)["parameters"]["n_nom_rev_s"]["unit"] == "rev/s"
    code, out, _ = run_cli(capsys, "scenarios")
    assert code == 0 and "thesis-6.4.4" in out
    code, out, _ = run_cli(capsys, "simulate", "--help")
    assert code == 0 and "ID@ONSET[:MAGNITUDE]" in out and "S4.2@235:5e4" in out


# ----------------------------------------------------------------------------- bad input
BAD_INPUTS = [
    (["operating-point", "--params", "nope", "--fuel-setting", "1"], ["--params", "thesis-12v28"]),
    (["operating-point", "--fuel-setting", "1.5"], ["--fuel-setting", "[0.0, 1.2]"]),
    (["operating-point", "--fuel-setting", "-0.1"], ["--fuel-setting"]),
    (["operating-point", "--fuel-setting", "nan"], ["--fuel-setting", "finite"]),
    (["operating-point", "--fuel-setting", "abc"], ["--fuel-setting"]),
    (["simulate", "--duration", "-1", "--out", "{tmp}/x.npz"], ["--duration", "positive"]),
    (["simulate", "--duration", "inf", "--out", "{tmp}/x.npz"], ["--duration", "finite"]),
    (["simulate", "--duration", "nan", "--out", "{tmp}/x.npz"], ["--duration"]),
    (["simulate", "--out", "{tmp}/x.npz"], ["--duration", "required"]),
    (["simulate", "--params", "nope", "--duration", "1", "--out", "{tmp}/x.npz"], ["--params", "allowed"]),
    (["simulate", "--duration", "1", "--fault", "X9.9@3", "--out", "{tmp}/x.npz"], ["--fault", "unknown fault id"]),
    (["simulate", "--duration", "1", "--fault", "S4.2", "--out", "{tmp}/x.npz"], ["--fault", "ID@ONSET"]),
    (["simulate", "--duration", "1", "--fault", "S4.2@-3", "--out", "{tmp}/x.npz"], ["--fault", "onset_s"]),
    (["simulate", "--duration", "1", "--fault", "S4.2@3,bogus=1", "--out", "{tmp}/x.npz"], ["--fault", "bogus"]),
    (["simulate", "--duration", "1", "--fault", "S4.2@3", "S4.2@5", "--out", "{tmp}/x.npz"], ["--fault", "twice"]),
    (["simulate", "--scenario", "thesis-6.4.1", "--fault", "S4.2@5", "--out", "{tmp}/x.npz"], ["--fault", "scenario"]),
    (["simulate", "--scenario", "nope", "--out", "{tmp}/x.npz"], ["--scenario", "thesis-6.4.1"]),
    (["simulate", "--duration", "1", "--profile", "zigzag", "--out", "{tmp}/x.npz"], ["--profile", "manoeuvring"]),
    (["simulate", "--duration", "1", "--profile", "2.0", "--out", "{tmp}/x.npz"], ["--profile", "1.2"]),
    (["simulate", "--duration", "1", "--noise-scale", "-1", "--out", "{tmp}/x.npz"], ["--noise-scale"]),
    (["simulate", "--duration", "1", "--engines", "0", "--out", "{tmp}/x.npz"], ["--engines"]),
    (["simulate", "--duration", "1", "--dt", "0", "--out", "{tmp}/x.npz"], ["--dt"]),
    (["simulate", "--duration", "1", "--seed", "-2", "--out", "{tmp}/x.npz"], ["--seed"]),
    (["simulate", "--duration", "1", "--out", "{tmp}/no/such/dir/x.npz"], ["--out", "does not exist"]),
    (["simulate", "--duration", "1"], ["--out"]),
    (["params", "--name", "nope"], ["--name", "thesis-12v28"]),
    (["info", "{tmp}/missing.npz"], ["does not exist"]),
    (["frobnicate"], ["frobnicate"]),
]


@pytest.mark.parametrize("argv, needles", BAD_INPUTS, ids=[" ".join(a[:3]) for a, _ in BAD_INPUTS])
def test_bad_input_exit_2(capsys, tmp_path, argv, needles):
    code, out, err = run_cli(capsys, *[a.replace("{tmp}", str(tmp_path)) for a in argv])
    assert code == 2
    assert "Traceback" not in err and "Traceback" not in out
    for needle in needles:
        assert needle in err, (needle, err)
    assert not (tmp_path / "x.npz").exists()


# ----------------------------------------------------------------------------- load_run validation
def _rewrite(src: Path, dst: Path, **changes) -> Path:
    with np.load(src) as z:
        arrays = {k: z[k] for k in z.files}
    for k, v in changes.items():
        if v is None:
            arrays.pop(k)
        else:
            arrays[k] = v
    np.savez(dst, **arrays)
    return dst


def test_load_run_names_nonfinite_sensor_and_sample(faulty_run, tmp_path):
    run = load_run(faulty_run)
    meas = run.measurements.copy()
    meas[123, 1, sensor_index("S3.2")] = np.nan
    meas[150, 0, sensor_index("S1.1")] = np.inf  # later sample: the first bad sample is reported
    bad = _rewrite(faulty_run, tmp_path / "nan.npz", measurements=meas)
    with pytest.raises(ValueError) as exc:
        load_run(bad)
    msg = str(exc.value)
    assert "sensor S3.2" in msg and "engine 1" in msg and "sample 123" in msg and "t=1.23 s" in msg
    ok = load_run(bad, allow_nonfinite=True)
    assert np.isnan(ok.by_sensor["S3.2"][123, 1])


@pytest.mark.parametrize("missing", ["measurements", "fault_active", "metadata"])
def test_load_run_missing_array(faulty_run, tmp_path, missing):
    assert missing in REQUIRED_ARRAYS
    bad = _rewrite(faulty_run, tmp_path / "missing.npz", **{missing: None})
    with pytest.raises(ValueError, match=f"lacks array.*{missing}"):
        load_run(bad)


def test_load_run_wrong_shapes_and_garbage(faulty_run, tmp_path):
    run = load_run(faulty_run)
    bad = _rewrite(faulty_run, tmp_path / "shape.npz", measurements=run.measurements[:, :, :18])
    with pytest.raises(ValueError, match=r"'measurements' must have shape \(T, N, 19\)"):
        load_run(bad)
    bad = _rewrite(faulty_run, tmp_path / "truth.npz", truth=run.truth[:-1])
    with pytest.raises(ValueError, match="'truth' must have shape"):
        load_run(bad)
    t = run.t.copy()
    t[5] = np.nan
    with pytest.raises(ValueError, match="'t' has a non-finite value at sample 5"):
        load_run(_rewrite(faulty_run, tmp_path / "t.npz", t=t))
    with pytest.raises(ValueError, match="'metadata' is not valid JSON"):
        load_run(_rewrite(faulty_run, tmp_path / "meta.npz", metadata=np.array("{not json")))
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"this is not a zip file")
    with pytest.raises(ValueError, match="not a readable .npz run file"):
        load_run(junk)


def test_save_run_roundtrip_in_process(tmp_path):
    from marine_fdi_env.engine.simulator import Simulator
    from marine_fdi_env.runio import save_run

    sim = Simulator(
        "thesis-12v28",
        n_engines=1,
        seeds=3,
        faults=["S2.3@0.2,kind=stuck", "S1.1@0.1:1e-4,kind=drift"],
        noise_scale=0.5,
    )
    res = sim.run(0.5)
    path = save_run(res, tmp_path / "run.data", command_line=["x", "y z"])
    assert path == tmp_path / "run.data" and path.exists()  # no .npz suffix appended
    run = load_run(path)
    assert np.array_equal(run.measurements, res.measurements) and np.array_equal(run.truth, res.truth)
    assert run.metadata["command_line"] == "x 'y z'" and run.noise_scale == 0.5
    assert json.loads(json.dumps(run.metadata)) == run.metadata  # strict JSON (inf/nan as strings)
    stuck, drift = sorted(run.true_faults(), key=lambda f: f["id"])[::-1]
    assert stuck["id"] == "S2.3" and stuck["magnitude"] is None and stuck["kappa"] == math.inf
    assert drift["unit"] == "kg/s" and drift["magnitude"] == 1e-4
    assert [s.to_dict()["kind"] for s in run.schedules[0]] == ["stuck", "drift"]


# ----------------------------------------------------------------------------- installed entry points
def test_console_script_help():
    script = shutil.which("marine-fdi") or str(Path(sys.executable).with_name("marine-fdi"))
    env = dict(os.environ, PYTHONWARNINGS="ignore")
    cmds = [[sys.executable, "-m", "marine_fdi_env.cli", "--help"]]
    if os.path.exists(script):
        cmds.insert(0, [script, "--help"])
    for cmd in cmds:
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=60, env=env)
        assert proc.returncode == 0, proc.stderr
        assert "operating-point" in proc.stdout and "simulate" in proc.stdout
    proc = subprocess.run(
        [sys.executable, "-m", "marine_fdi_env.cli", "operating-point", "--fuel-setting", "9"],
        capture_output=True,
        text=True,
        timeout=60,
        env=env,
    )
    assert proc.returncode == 2 and "--fuel-setting" in proc.stderr and "Traceback" not in proc.stderr


def test_validate_and_synthesize_are_wired(tmp_path, capsys):
    # the validation commands (issue #4) are reachable through the marine-fdi entry point
    from marine_fdi_env.cli import main

    data = tmp_path / "synth.csv"
    assert (
        main(
            [
                "synthesize-measurements",
                "--params",
                "man-12v32-40",
                "--mechanism",
                "none",
                "--points",
                "6",
                "--noise",
                "0.005",
                "--seed",
                "3",
                "--out",
                str(data),
            ]
        )
        == 0
    )
    out = tmp_path / "report.json"
    assert main(["validate", "--data", str(data), "--out", str(out), "--max-folds", "3"]) == 0
    rep = json.loads(out.read_text())
    for key in ("channels", "discrepancies", "candidates", "selected_causes", "unexplained", "parameters"):
        assert key in rep
    assert rep["selected_causes"] == []  # no hidden effect, nothing to explain
    assert main(["validate", "--data", str(tmp_path / "missing.csv"), "--out", str(out)]) == 2
