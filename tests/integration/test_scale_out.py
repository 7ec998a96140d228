"""Backends (serial, process, Ray), sweeps, Parquet tables and agents by name."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from test_env_evaluate import SCENARIOS

from marine_fdi_env.benchmark import agent_registry
from marine_fdi_env.benchmark.agent_api import load_agent
from marine_fdi_env.benchmark.dataset import load_dataset
from marine_fdi_env.benchmark.evaluate import WALL_CLOCK_FIELDS, WALL_CLOCK_METRICS, evaluate
from marine_fdi_env.benchmark.metrics import compute_metrics
from marine_fdi_env.benchmark.records import read_records, read_results_parquet
from marine_fdi_env.benchmark.suites import load_suite
from marine_fdi_env.benchmark.sweep import run_sweep
from marine_fdi_env.cli import main as cli_main
from marine_fdi_env.outputs import prepare_out
from tests.paths import ROOT

SLOW_AGENT = f"{ROOT / 'tests' / 'agents_for_tests.py'}:SlowRandomAgent"
EXAMPLE_AGENT = "docs/examples/fired_modules_agent.py:FiredModulesAgent"


def _suite_file(path: Path, name: str, scenarios) -> Path:
    path.write_text(
        json.dumps(
            {
                "name": name,
                "version": 1,
                "description": "test",
                "env": {"decision_period_s": 1.0, "params": "thesis-12v28", "observe_sensors": False},
                "scenarios": [s.to_dict() for s in scenarios],
            }
        )
    )
    return path


def _subset(tmp_path: Path, name: str, idx) -> Path:
    """A suite file with some scenarios of a shipped suite (same name, so records compare as the suite's)."""
    sc = load_suite(name).scenarios
    return _suite_file(tmp_path / f"{name}-subset.json", name, [sc[i] for i in idx])


@pytest.fixture
def tiny(tmp_path):
    return _suite_file(tmp_path / "tiny-v1.json", "tiny-v1", SCENARIOS[:3])


def _no_clock(x):
    """Records or metrics without the wall-clock fields (compute times and the metrics made of them)."""
    if isinstance(x, dict):
        return {k: _no_clock(v) for k, v in x.items() if k not in WALL_CLOCK_FIELDS + WALL_CLOCK_METRICS}
    if isinstance(x, list):
        return [_no_clock(v) for v in x]
    return x


@pytest.fixture(scope="module")
def ray_local():
    ray = pytest.importorskip("ray")
    import logging

    ray.init(address="local", num_cpus=2, include_dashboard=False, logging_level=logging.WARNING, log_to_driver=False)
    yield ray
    ray.shutdown()


# ----------------------------------------------------------------------------- backends
@pytest.mark.parametrize(
    "suite,idx,agent",
    [
        # the reference on thesis-v1: the breadth version; the random agent shows the backends agree by default
        pytest.param("thesis-v1", (0, 5, 10, 15), "reference", marks=pytest.mark.study),
        ("single-v1", (0, 40, 80, 140), "random"),
    ],
)
def test_backends_give_the_same_results_bit_for_bit(suite, idx, agent, tmp_path, ray_local):
    """serial (one batch), process (2 workers, chunks of 1) and Ray (2 CPUs, chunks of 3): every
    episode record and every metric identical except the wall-clock compute time."""
    f = _subset(tmp_path, suite, idx)
    runs = {
        "serial": evaluate(agent, str(f), tmp_path / "s.json", backend="serial", batch_size=4, progress=False),
        "process": evaluate(
            agent, str(f), tmp_path / "p.json", backend="process", workers=2, batch_size=1, progress=False
        ),
        "ray": evaluate(agent, str(f), tmp_path / "r.json", backend="ray", workers=2, batch_size=3, progress=False),
    }
    ref = runs["serial"]
    assert ref["metrics"]["n_episodes"] == len(idx)
    if agent == "reference":
        assert ref["metrics"]["detection_rate"] == 1.0  # the thesis examples are detected: a non-trivial comparison
    for name, r in runs.items():
        assert _no_clock(r["episodes"]) == _no_clock(ref["episodes"]), name
        assert _no_clock(r["metrics"]) == _no_clock(ref["metrics"]), name


def test_ray_missing_names_the_extra(monkeypatch, tiny, tmp_path, capsys):
    import builtins

    real = builtins.__import__

    def no_ray(name, *a, **k):
        if name == "ray" or name.startswith("ray."):
            raise ImportError("no ray")
        return real(name, *a, **k)

    monkeypatch.delitem(sys.modules, "ray", raising=False)  # as if Ray were not installed
    monkeypatch.setattr(builtins, "__import__", no_ray)
    assert (
        cli_main(
            [
                "evaluate",
                "--agent",
                "null",
                "--suite",
                str(tiny),
                "--backend",
                "ray",
                "--out",
                str(tmp_path / "x.json"),
                "--no-progress",
            ]
        )
        == 2
    )
    assert "pip install 'marine-fdi-env[ray]'" in capsys.readouterr().err


def test_backend_options_are_checked(tiny, tmp_path, capsys):
    assert cli_main(["evaluate", "--suite", str(tiny), "--backend", "serial", "--ray-address", "auto"]) == 2
    assert "--ray-address needs --backend ray" in capsys.readouterr().err
    assert cli_main(["evaluate", "--suite", str(tiny), "--workers", "0"]) == 2
    assert "--workers must be a positive integer" in capsys.readouterr().err


# ----------------------------------------------------------------------------- Parquet
def test_evaluation_records_round_trip_through_parquet(tiny, tmp_path):
    js = evaluate("reference", str(tiny), tmp_path / "r.json", progress=False)
    pq = evaluate("reference", str(tiny), tmp_path / "r.parquet", progress=False)
    back = read_results_parquet(tmp_path / "r.parquet")
    assert back["episodes"] == pq["episodes"]  # exact, floats included
    assert compute_metrics(back["episodes"]) == back["metrics"] == pq["metrics"]
    assert _no_clock(back["episodes"]) == _no_clock(js["episodes"])
    assert cli_main(["report", str(tmp_path / "r.parquet"), "--out", str(tmp_path / "rep"), "--no-plots"]) == 0
    assert "| tiny-v1 | reference |" in (tmp_path / "rep" / "report.md").read_text()


def test_dataset_parquet_and_npz_give_the_same_arrays(tiny, tmp_path):
    assert cli_main(["dataset", "--suite", str(tiny), "--out", str(tmp_path / "a"), "--no-progress"]) == 0
    assert (
        cli_main(
            [
                "dataset",
                "--suite",
                str(tiny),
                "--out",
                str(tmp_path / "b"),
                "--format",
                "parquet",
                "--backend",
                "process",
                "--workers",
                "2",
                "--batch-size",
                "1",
                "--no-progress",
            ]
        )
        == 0
    )
    a, b = load_dataset(tmp_path / "a"), load_dataset(tmp_path / "b" / "dataset.parquet")
    assert set(a) == set(b) == {"obs", "active", "valid", "t_s", "feature_names", "fault_ids"}
    for k in a:
        assert a[k].dtype == b[k].dtype and np.array_equal(a[k], b[k]), k
    import pyarrow.parquet as pq

    t = pq.read_table(tmp_path / "b" / "dataset.parquet")
    assert t.num_rows == int(a["valid"].sum())  # long format: one row per valid decision
    assert {"episode", "scenario_id", "step", "t_s", "M1.1.fired", "active.S4.2", "no_fault"} <= set(t.column_names)
    assert not (tmp_path / "b" / "dataset.partial").exists()


def test_interrupted_dataset_export_resumes_from_kept_chunks(tiny, tmp_path):
    from marine_fdi_env.benchmark import dataset as ds

    full = load_dataset(
        ds.export_dataset(load_suite(str(tiny)).scenarios, tmp_path / "full", {}, batch_size=1, progress=False)
    )
    calls = []
    real = ds.dataset_chunk

    def stop_after_one(*a, **k):
        if calls:
            raise KeyboardInterrupt
        calls.append(1)
        return real(*a, **k)

    ds_scen = load_suite(str(tiny)).scenarios
    try:
        ds.dataset_chunk = stop_after_one
        with pytest.raises(KeyboardInterrupt):
            ds.export_dataset(ds_scen, tmp_path / "cut", {}, batch_size=1, progress=False)
    finally:
        ds.dataset_chunk = real
    assert len(list((tmp_path / "cut" / "dataset.partial").glob("chunk_*.npz"))) == 1
    again = load_dataset(ds.export_dataset(ds_scen, tmp_path / "cut", {}, batch_size=1, progress=False))
    for k in full:
        assert np.array_equal(full[k], again[k]), k


# ----------------------------------------------------------------------------- sweeps
def test_sweep_table_equals_evaluate_and_report_reads_it(tiny, tmp_path, capsys):
    out = tmp_path / "new" / "sweep"  # the parent is created, one level only
    assert (
        cli_main(
            [
                "sweep",
                "--agents",
                "reference",
                "random",
                "--suites",
                str(tiny),
                "--seed-offsets",
                "0",
                "3",
                "--out",
                str(out),
                "--batch-size",
                "2",
                "--no-progress",
            ]
        )
        == 0
    )
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert last.startswith(f"wrote {out / 'episodes.parquet'} (12 episodes, 2 agent x suite cells)")
    recs, meta = read_records(out / "episodes.parquet", keep_extra=True)
    assert meta["grid"] == {"agents": ["reference", "random"], "suites": [str(tiny)], "seed_offsets": [0, 3]}
    for agent in ("reference", "random"):
        for k in (0, 3):
            ev = evaluate(agent, str(tiny), tmp_path / f"{agent}{k}.json", seed_offset=k, progress=False)
            mine = [
                {x: v for x, v in r.items() if x not in ("agent_spec", "seed_offset")}
                for r in recs
                if r["agent_spec"] == agent and r["seed_offset"] == k
            ]
            assert _no_clock(mine) == _no_clock(ev["episodes"])
    metrics = json.loads((out / "metrics.json").read_text())
    cell = next(m for m in metrics["results"] if m["agent_spec"] == "reference")
    assert cell["seed_offsets"] == [0, 3] and cell["n_episodes"] == 6
    assert cell["metrics"] == compute_metrics(
        [
            {x: v for x, v in r.items() if x not in ("agent_spec", "seed_offset")}
            for r in recs
            if r["agent_spec"] == "reference"
        ]
    )
    assert cli_main(["report", str(out), "--out", str(tmp_path / "rep"), "--no-plots"]) == 0
    text = (tmp_path / "rep" / "report.md").read_text()
    assert (
        "| tiny-v1 | reference | 1 | 6 |" in text and "| tiny-v1 | random | 1 | 6 |" in text
    )  # 1 training seed, 6 episodes
    # a wider grid into the same folder runs only the new cells
    res = run_sweep(["reference", "random", "null"], [str(tiny)], [0, 3], out, progress=False)
    assert res["run"]["episodes_run"] == 6 and res["run"]["episodes_resumed"] == 12
    assert prepare_out(tmp_path / "a" / "b", is_dir=True).is_dir()
    with pytest.raises(ValueError, match="only the parent"):
        prepare_out(tmp_path / "x" / "y" / "z")


def ctrl_c_enabled() -> None:
    """In the child before exec: SIGINT at its default, so Python turns it into KeyboardInterrupt
    even when the tests run in a shell's background job (which starts with SIGINT ignored, and
    children inherit that)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_sweep_resumes_after_ctrl_c_without_losing_or_redoing_work(tiny, tmp_path, capsys):
    """Two agents scored in lockstep: a finished chunk keeps both agents' records."""
    out = tmp_path / "sw"
    cmd = [
        sys.executable,
        "-m",
        "marine_fdi_env.cli",
        "sweep",
        "--agents",
        SLOW_AGENT,
        "null",
        "--suites",
        str(tiny),
        "--out",
        str(out),
        "--batch-size",
        "1",
        "--backend",
        "serial",
        "--no-progress",
    ]
    env = dict(os.environ, SLOW_AGENT_SLEEP_S="0.1")  # 20 decisions: 2 s per chunk
    proc = subprocess.Popen(
        cmd, cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=ctrl_c_enabled
    )
    partial = out / "sweep.partial.jsonl"
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        if partial.exists() and len(partial.read_text().splitlines()) >= 3:  # header + the first chunk's two records
            break
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)  # Ctrl-C
    stdout, stderr = proc.communicate(timeout=60)
    assert proc.returncode == 130, stderr
    assert "interrupted" in stderr and "Traceback" not in stderr
    lines = partial.read_text().splitlines()
    kept = [json.loads(x) for x in lines[1:]]
    assert 2 <= len(kept) < 6 and len(kept) % 2 == 0 and not (out / "episodes.parquet").exists()
    assert sorted(r["agent"] for r in kept[:2]) == ["null", "slow-random"]
    assert kept[0]["scenario_id"] == kept[1]["scenario_id"]
    marked = dict(kept[0], compute_s=12345.0)  # a kept episode must not be recomputed
    partial.write_text("\n".join([lines[0], json.dumps(marked)] + lines[2:]) + "\n")
    res = run_sweep([SLOW_AGENT, "null"], [str(tiny)], [0], out, batch_size=1, progress=True)
    assert f"resuming at {len(kept)}/6" in capsys.readouterr().err
    assert res["run"]["episodes_run"] == 6 - len(kept)
    recs, _ = read_records(out / "episodes.parquet")
    assert (
        next(r for r in recs if r["scenario_id"] == marked["scenario_id"] and r["agent"] == marked["agent"])[
            "compute_s"
        ]
        == 12345.0
    )
    fresh = run_sweep([SLOW_AGENT, "null"], [str(tiny)], [0], tmp_path / "fresh", progress=False)
    assert _no_clock(recs) == _no_clock(read_records(tmp_path / "fresh" / "episodes.parquet")[0])
    assert fresh["run"]["episodes_run"] == 6 and not partial.exists()


# ----------------------------------------------------------------------------- agents by name
def test_agents_by_name_and_the_agents_command(capsys):
    assert cli_main(["agents"]) == 0
    text = capsys.readouterr().out
    for name in ("null", "random", "reference", "oracle", "classifier", "classifier-v1", "ppo-v1"):
        assert any(line.split()[0] == name for line in text.splitlines()[:-1]), name
    assert cli_main(["agents", "--json"]) == 0
    entries = json.loads(capsys.readouterr().out)
    models = {e["name"]: e for e in entries if e["kind"] == "model"}
    assert Path(models["classifier"]["spec"]) == agent_registry.models_dir() / "classifier"
    assert "3 training seeds (seed0, seed1, seed2)" in models["classifier"]["description"]
    agent = load_agent("classifier")  # the default of its training seeds
    assert agent.name == "classifier" and type(agent).__name__ == "ClassifierAgent" and agent.training_seed == 0
    assert load_agent("ppo-v1").name == "ppo-v1"


def test_registry_discovers_model_folders_and_their_config_names(tmp_path, monkeypatch):
    import shutil

    src = agent_registry.models_dir() / "classifier-v1"
    dst = tmp_path / "models" / "gru2"
    shutil.copytree(src, dst)
    cfg = json.loads((dst / "config.json").read_text())
    (dst / "config.json").write_text(json.dumps(dict(cfg, name="classifier+reference")))
    shutil.copytree(agent_registry.models_dir() / "ppo-v1", tmp_path / "models" / "ppo")
    (tmp_path / "models" / "notes").mkdir()  # a folder without agent.json is not an agent
    monkeypatch.setattr(agent_registry, "models_dir", lambda: tmp_path / "models")
    agent_registry._entries.cache_clear()
    try:
        names = [e.name for e in agent_registry.list_agents()]
        assert names[-2:] == ["classifier+reference", "ppo-v1"] and "notes" not in names
        assert agent_registry.find_agent("gru2").name == "classifier+reference"  # the folder name is an alias
        assert load_agent("classifier+reference").name == "classifier+reference"
    finally:
        agent_registry._entries.cache_clear()


def test_custom_agent_file_runs_with_evaluate(tiny, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(ROOT)
    out = tmp_path / "custom.json"
    assert (
        cli_main(
            [
                "evaluate",
                "--agent",
                EXAMPLE_AGENT,
                "--suite",
                str(tiny),
                "--out",
                str(out),
                "--no-progress",
                "--backend",
                "process",
                "--workers",
                "2",
                "--batch-size",
                "1",
            ]
        )
        == 0
    )
    assert "| tiny-v1 | fired-modules |" in capsys.readouterr().out
    res = json.loads(out.read_text())
    ep = {e["scenario_id"]: e for e in res["episodes"]}
    assert any(alarm for _, _, alarm in ep["s42"]["declared_changes"])  # the obvious S4.2 offset fires modules
    assert not any(alarm for _, _, alarm in ep["free"]["declared_changes"])
    assert cli_main(["evaluate", "--agent", "docs/examples/fired_modules_agent.py:Nope", "--suite", str(tiny)]) == 2
    assert "has no 'Nope'" in capsys.readouterr().err
    assert cli_main(["evaluate", "--agent", "no/such/file.py:X", "--suite", str(tiny)]) == 2
    assert "no such file" in capsys.readouterr().err


@pytest.mark.parametrize("cmd", ["agents", "sweep", "export-raw", "predict-raw", "score-raw"])
def test_new_commands_have_help_and_reject_bad_input(cmd, capsys, tmp_path):
    assert cli_main([cmd, "--help"]) == 0
    assert f"marine-fdi {cmd}" in capsys.readouterr().out
    if cmd == "agents":
        return
    deep = str(tmp_path / "no" / "such" / "dir")  # only the parent of --out is created, never more levels
    args = {
        "sweep": ["--agents", "null", "--suites", "thesis-v1", "--out", deep],
        "export-raw": ["--suite", "thesis-v1", "--out", deep],
        "predict-raw": ["--data", str(tmp_path), "--out", deep],
        "score-raw": ["--suite", "thesis-v1", "--predictions", str(tmp_path), "--out", deep + "/r.json"],
    }[cmd]
    assert cli_main([cmd, *args]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"marine-fdi {cmd}: error: --out: folder") and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "no").exists()
