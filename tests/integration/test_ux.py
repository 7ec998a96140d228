"""A new user's first minutes: output folders, missing extras, the cold-cache notice,
Ctrl-C, progress lines, "did you mean", resume errors that name the field, report tables and
the confusion matrix."""

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

from marine_fdi_env.benchmark.dataset import load_dataset
from marine_fdi_env.benchmark.evaluate import evaluate
from marine_fdi_env.benchmark.metrics import compute_metrics
from marine_fdi_env.benchmark.report import NOTHING_LABEL, UNKNOWN_LABEL, confusion_matrix, load_results, write_report
from marine_fdi_env.cli import main as cli_main
from marine_fdi_env.outputs import differing_fields, prepare_out
from marine_fdi_env.progress import progress_bar
from marine_fdi_env.suggest import did_you_mean
from tests.paths import ROOT


@pytest.fixture
def tiny(tmp_path):
    p = tmp_path / "tiny-v1.json"
    p.write_text(
        json.dumps(
            {
                "name": "tiny-v1",
                "version": 1,
                "description": "test",
                "env": {"decision_period_s": 1.0, "params": "thesis-12v28", "observe_sensors": False},
                "scenarios": [s.to_dict() for s in SCENARIOS[:2]],
            }
        )
    )
    return p


def _no_new_entries(folder: Path, before: set) -> bool:
    return set(os.listdir(folder)) == before


# ----------------------------------------------------------------------------- output folders
def test_one_rule_for_output_folders(tmp_path, monkeypatch, capsys, tiny):
    """The parent of --out is created, never more levels; a failing command creates nothing."""
    monkeypatch.chdir(tmp_path)
    assert cli_main(["simulate", "--duration", "1", "--out", "runs/run.npz", "--no-progress"]) == 0
    assert (tmp_path / "runs" / "run.npz").is_file()
    before = set(os.listdir(tmp_path))
    cases = [
        ["simulate", "--duration", "1", "--out", "a/b/run.npz"],
        ["evaluate", "--agent", "null", "--suite", str(tiny), "--out", "a/b/x.json"],
        ["dataset", "--suite", str(tiny), "--out", "a/b/ds"],
        ["sweep", "--agents", "null", "--suites", str(tiny), "--out", "a/b/sw"],
        ["report", str(tmp_path / "none.json"), "--out", "a/b/rep", "--no-plots"],
        ["diagnose", "--run", "runs/run.npz", "--out", "a/b/d.json"],
        ["export-raw", "--suite", str(tiny), "--out", "a/b/raw"],
        ["score-raw", "--suite", str(tiny), "--predictions", "p", "--out", "a/b/s.json"],
        ["validate", "--data", "man_12v32_40_fpp_iso", "--out", "a/b/v.json"],
        ["validate", "--data", "man_12v32_40_fpp_iso", "--out", "v.json", "--plots", "a/b/plots"],
        ["synthesize-measurements", "--params", "thesis-12v28", "--out", "a/b/m.csv"],
    ]
    for argv in cases:
        assert cli_main(argv) == 2, argv
        err = capsys.readouterr().err
        opt = "--plots" if "--plots" in argv else "--out"
        assert opt in err and "'a' does not exist" in err and "Traceback" not in err, (argv, err)
        assert _no_new_entries(tmp_path, before), argv
    # bad input after a valid --out: no folder is left behind either
    assert cli_main(["evaluate", "--agent", "null", "--suite", "no-such-suite", "--out", "new/x.json"]) == 2
    assert cli_main(["sweep", "--agents", "nobody", "--suites", str(tiny), "--out", "new/sw"]) == 2
    assert cli_main(["diagnose", "--run", "runs/missing.npz", "--out", "new/d.json"]) == 2
    assert cli_main(["validate", "--data", "no-such-data", "--out", "new/v.json", "--plots", "new2/p"]) == 2
    assert cli_main(["synthesize-measurements", "--params", "nobody", "--out", "new/m.csv"]) == 2
    assert _no_new_entries(tmp_path, before)
    capsys.readouterr()
    # one level is created
    assert cli_main(["evaluate", "--agent", "null", "--suite", str(tiny), "--out", "res/x.json", "--no-progress"]) == 0
    assert (tmp_path / "res" / "x.json").is_file()
    assert cli_main(["synthesize-measurements", "--params", "thesis-12v28", "--points", "3", "--out", "syn/m.csv"]) == 0
    assert (tmp_path / "syn" / "m.csv").is_file()
    with pytest.raises(ValueError, match="--plots must be a folder"):
        prepare_out(tmp_path / "runs" / "run.npz", "--plots", is_dir=True)


def test_existing_results_and_datasets_are_not_overwritten_silently(tmp_path, capsys, tiny):
    out = tmp_path / "x.json"
    assert cli_main(["evaluate", "--agent", "null", "--suite", str(tiny), "--out", str(out), "--no-progress"]) == 0
    stamp = out.stat().st_mtime_ns
    assert cli_main(["evaluate", "--agent", "null", "--suite", str(tiny), "--out", str(out), "--no-progress"]) == 2
    assert "--force" in capsys.readouterr().err and out.stat().st_mtime_ns == stamp
    assert (
        cli_main(["evaluate", "--agent", "null", "--suite", str(tiny), "--out", str(out), "--no-progress", "--force"])
        == 0
    )
    ds = tmp_path / "ds"
    assert cli_main(["dataset", "--suite", str(tiny), "--out", str(ds), "--no-progress"]) == 0
    first = load_dataset(ds)
    assert cli_main(["dataset", "--suite", str(tiny), "--out", str(ds), "--no-progress", "--observe-sensors"]) == 2
    assert "already holds a dataset (dataset.npz); pass --force" in capsys.readouterr().err
    assert np.array_equal(load_dataset(ds)["obs"], first["obs"])  # untouched
    assert (
        cli_main(["dataset", "--suite", str(tiny), "--out", str(ds), "--no-progress", "--observe-sensors", "--force"])
        == 0
    )
    assert load_dataset(ds)["obs"].shape[2] > first["obs"].shape[2]
    # --episodes/--seed belong to --preset
    assert cli_main(["dataset", "--suite", str(tiny), "--episodes", "3", "--out", str(tmp_path / "d2")]) == 2
    assert "--preset" in capsys.readouterr().err


# ----------------------------------------------------------------------------- optional extras
@pytest.mark.parametrize(
    "module,argv,extra",
    [
        ("matplotlib", ["diagnose", "--run", "{run}", "--out", "{tmp}/d.json", "--plots", "{tmp}/plots"], "plots"),
        ("matplotlib", ["report", "{result}", "--out", "{tmp}/rep"], "plots"),
        (
            "matplotlib",
            ["validate", "--data", "man_12v32_40_fpp_iso", "--out", "{tmp}/v.json", "--plots", "{tmp}/vp"],
            "plots",
        ),
        ("pyarrow", ["evaluate", "--agent", "null", "--suite", "{tiny}", "--out", "{tmp}/x.parquet"], "parquet"),
        ("pyarrow", ["dataset", "--suite", "{tiny}", "--out", "{tmp}/ds", "--format", "parquet"], "parquet"),
        ("pyarrow", ["sweep", "--agents", "null", "--suites", "{tiny}", "--out", "{tmp}/sw"], "parquet"),
        (
            "ray",
            ["evaluate", "--agent", "null", "--suite", "{tiny}", "--out", "{tmp}/y.json", "--backend", "ray"],
            "ray",
        ),
    ],
)
def test_a_missing_extra_is_one_line_before_any_work(module, argv, extra, tmp_path, monkeypatch, capsys, tiny):
    run = tmp_path / "r.npz"
    assert cli_main(["simulate", "--duration", "2", "--out", str(run), "--no-progress"]) == 0
    result = tmp_path / "null.json"
    evaluate("null", str(tiny), result, progress=False)
    capsys.readouterr()

    def no_work(*a, **k):
        raise AssertionError("the command started working before checking its extras")

    import marine_fdi_env.benchmark.backends as backends
    import marine_fdi_env.benchmark.report as report
    import marine_fdi_env.cli.diagnose as cd

    monkeypatch.setattr(cd, "diagnose_run", no_work)
    monkeypatch.setattr(backends, "run_tasks", no_work)  # evaluate, dataset and sweep run their tasks through it
    monkeypatch.setattr(report, "load_results", no_work)
    import marine_fdi_env.cli.validate as vreport

    monkeypatch.setattr(vreport, "run_validation", no_work)
    monkeypatch.setitem(sys.modules, module, None)  # as if not installed: import raises ImportError
    args = [a.format(run=run, tmp=tmp_path, result=result, tiny=tiny) for a in argv]
    before = set(os.listdir(tmp_path))
    assert cli_main(args) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"pip install 'marine-fdi-env[{extra}]'" in err[0], err
    assert _no_new_entries(tmp_path, before)


# ----------------------------------------------------------------------------- cold numba cache
_PROBE = """
import sys
import numpy as np
from marine_fdi_env import coldstart
coldstart.enable("probe")
from marine_fdi_env.engine.profiles import _value_right
_value_right(np.array([0.0, 1.0]), np.array([1.0, 2.0]), 2, 0.5)
print("announced" if coldstart.announced() else "silent")
"""


def test_cold_cache_prints_one_line_and_a_warm_cache_none(tmp_path):
    """numba's compile event fires only on a cache miss: in a fresh cache folder the first run
    says "compiling the model" once, the second run (same folder) says nothing."""
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "numba-cache"))
    outs = [
        subprocess.run([sys.executable, "-c", _PROBE], cwd=ROOT, env=env, capture_output=True, text=True, timeout=300)
        for _ in range(2)
    ]
    for o in outs:
        assert o.returncode == 0, o.stderr
    assert outs[0].stdout.strip() == "announced" and outs[0].stderr.count("compiling the model") == 1
    assert "probe: compiling the model (first run only" in outs[0].stderr
    assert outs[1].stdout.strip() == "silent" and "compiling" not in outs[1].stderr


def test_the_notice_ignores_other_compilations():
    from marine_fdi_env import coldstart

    class Fake:
        def __init__(self, module, cache):
            self.py_func = type("F", (), {"__module__": module})()
            self._cache = cache

    from numba.core.caching import NullCache

    assert not coldstart._ours(Fake("someone_else.mod", object()))
    assert not coldstart._ours(Fake("marine_fdi_env.engine.model", NullCache()))  # not cached: compiles every run
    assert coldstart._ours(Fake("marine_fdi_env.engine.model", object()))
    assert not coldstart._ours(None)


def test_the_warm_up_episode_changes_no_number(tiny, tmp_path, monkeypatch):
    """Compile time is kept out of compute_s by a throw-away episode per process; the episodes'
    numbers are the same with and without it."""
    from marine_fdi_env.benchmark import evaluate as ev

    a = evaluate("random", str(tiny), tmp_path / "a.json", progress=False)
    monkeypatch.setitem(ev._WARM, "done", False)
    calls = []
    real = ev.warm_up
    monkeypatch.setattr(ev, "warm_up", lambda kw=None: (calls.append(1), real(kw)))
    b = evaluate("random", str(tiny), tmp_path / "b.json", progress=False)
    assert calls and ev._WARM["done"]
    strip = lambda r: [{k: v for k, v in e.items() if k not in ev.WALL_CLOCK_FIELDS} for e in r["episodes"]]  # noqa: E731
    assert strip(a) == strip(b)


# ----------------------------------------------------------------------------- Ctrl-C
def ctrl_c_enabled() -> None:
    """In the child before exec: SIGINT at its default, so Python turns it into KeyboardInterrupt
    even when the tests run in a shell's background job (which starts with SIGINT ignored, and
    children inherit that)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_ctrl_c_in_dataset_keeps_chunks_and_the_rerun_resumes(tmp_path):
    out = tmp_path / "ds"
    cmd = [
        sys.executable,
        "-m",
        "marine_fdi_env.cli",
        "dataset",
        "--preset",
        "default",
        "--episodes",
        "4",
        "--seed",
        "1",
        "--batch-size",
        "1",
        "--out",
        str(out),
        "--no-progress",
    ]
    proc = subprocess.Popen(
        cmd, cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=ctrl_c_enabled
    )
    part = out / "dataset.partial"
    deadline = time.monotonic() + 240
    while time.monotonic() < deadline and proc.poll() is None:
        if part.is_dir() and list(part.glob("chunk_*_1.npz")):
            break
        time.sleep(0.05)
    assert proc.poll() is None, "the export ended before it could be interrupted"
    proc.send_signal(signal.SIGINT)  # Ctrl-C
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stderr
    assert "interrupted" in stderr and "Traceback" not in stderr, stderr
    kept = len(list(part.glob("chunk_*_1.npz")))
    assert 1 <= kept < 4 and not (out / "dataset.npz").exists()
    again = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, timeout=600)
    assert again.returncode == 0, again.stderr
    assert f"dataset: resuming at {kept}/4" in again.stderr
    assert load_dataset(out)["valid"].shape[0] == 4 and not part.exists()


def test_ctrl_c_in_a_command_without_its_own_handler(monkeypatch, capsys, tmp_path):
    import marine_fdi_env.engine.simulator as sim_mod

    def interrupt(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(sim_mod.Simulator, "run", interrupt)
    assert cli_main(["simulate", "--duration", "1", "--out", str(tmp_path / "x.npz")]) == 130
    assert capsys.readouterr().err.strip() == "marine-fdi simulate: interrupted"
    import marine_fdi_env.benchmark.report as report

    monkeypatch.setattr(report, "load_results", interrupt)
    assert cli_main(["report", "x.json", "--out", str(tmp_path / "r"), "--no-plots"]) == 130
    assert "interrupted" in capsys.readouterr().err


# ----------------------------------------------------------------------------- progress
def test_progress_bar_ends_on_one_final_line_and_says_when_it_resumes(capsys):
    bar = progress_bar(3, 1, "demo")
    for _ in range(30):  # 2 episodes in fractions that do not add up exactly
        bar.advance(2 / 30 + 1e-9)
    bar.set_done(3)
    bar.close()
    err = capsys.readouterr().err
    assert err.splitlines()[0] == "demo: resuming at 1/3"
    segments = [s for s in err.replace("\r", "\n").splitlines() if "3.0/3" in s]
    assert len(segments) == 1, segments  # the final state is printed once
    assert "episodes" in segments[0] and "-00:00" not in err and "clamping" not in err
    assert "3.1/3" not in err and "3.0/3" in segments[0]


# ----------------------------------------------------------------------------- messages
def test_did_you_mean():
    assert did_you_mean("bore_damge", ["bore_damage", "valve_seizing"]) == " (did you mean 'bore_damage'?)"
    assert did_you_mean("s4.2", ["S4.2", "S4.6"]) == " (did you mean 'S4.2'?)"
    assert did_you_mean("xyz", ["bore_damage"]) == ""


def test_misspelled_names_get_a_suggestion(capsys):
    for argv, hint in [
        (["simulate", "--duration", "1", "--fault", "bore_damge@1", "--out", "x.npz"], "'bore_damage'"),
        (["evaluate", "--suite", "single-v2"], "'single-v1'"),
        (["evaluate", "--agent", "clasifier"], "'classifier'"),
        (["dataset", "--preset", "defualt", "--out", "d"], "'default'"),
    ]:
        assert cli_main(argv) == 2
        assert f"did you mean {hint}" in capsys.readouterr().err, argv


def test_resume_mismatch_names_only_the_differing_field(tiny, tmp_path, capsys):
    out = tmp_path / "x.json"
    partial = out.with_name(out.name + ".partial.jsonl")
    evaluate("null", str(tiny), tmp_path / "ref.json", progress=False)
    header = {
        k: v
        for k, v in json.loads((tmp_path / "ref.json").read_text()).items()
        if k in ("agent", "agent_spec", "suite", "suite_version", "seed_offset", "env_id", "env")
    }
    partial.write_text(json.dumps(dict(header, seed_offset=3)) + "\n")
    assert cli_main(["evaluate", "--agent", "null", "--suite", str(tiny), "--out", str(out), "--no-progress"]) == 2
    err = capsys.readouterr().err
    assert "seed_offset: 3 there, 0 here" in err and "env_id" not in err and "agent_spec" not in err
    assert differing_fields({"a": 1, "b": {"c": 2}}, {"a": 1, "b": {"c": 3}}) == "b.c: 2 there, 3 here"
    # dataset: another preset seed in the same folder
    ds = tmp_path / "ds"
    from marine_fdi_env.benchmark.dataset import export_dataset
    from marine_fdi_env.envs.scenario_sampler import get_preset

    cfg = get_preset("nominal")
    mk = lambda seed: [cfg.sample(seed, scenario_id=f"n/{seed}"), cfg.sample(seed + 1, scenario_id=f"n/{seed + 1}")]  # noqa: E731
    (ds / "dataset.partial").mkdir(parents=True)
    from marine_fdi_env.benchmark import dataset as dsmod

    head = {
        "key": "other",
        "env": dsmod._env_json({"scenario_config": cfg}),
        "n_episodes": 2,
        "scenario_ids": ["n/7", "n/8"],
    }
    (ds / "dataset.partial" / "header.json").write_text(json.dumps(head))
    with pytest.raises(ValueError, match=r"scenario 0: 'n/7' there, 'n/0' here.*--force"):
        export_dataset(mk(0), ds, {"scenario_config": cfg}, progress=False)


# ----------------------------------------------------------------------------- report
def _ep(sid: str, faults, changes) -> dict:
    return {
        "scenario_id": sid,
        "suite": "s",
        "seed": 0,
        "agent": "a",
        "profile": "constant",
        "duration_s": 20.0,
        "decision_period_s": 1.0,
        "n_samples": 2000,
        "faults": [
            {"id": f, "class": "process" if "_" in f else "sensor", "onset_s": 5.0, "magnitude": 1.0, "end_s": None}
            for f in faults
        ],
        "declared_changes": changes,
        "terminated": False,
        "failure_reason": None,
        "compute_s": 0.01,
        "return": 0.0,
        "reward_terms": {},
    }


def test_confusion_matrix_and_per_fault_tables(tmp_path):
    eps = [
        _ep("right", ["S1.1"], [[1.0, [], False], [7.0, ["S1.1"], True]]),
        _ep("wrong", ["S1.1"], [[1.0, [], False], [8.0, ["S2.1"], True]]),
        _ep("unnamed", ["bore_damage"], [[1.0, [], False], [9.0, [], True]]),
        _ep("missed", ["bore_damage"], [[1.0, [], False]]),
        _ep("pair", ["S1.1", "bore_damage"], [[1.0, [], False], [9.0, ["S1.1", "bore_damage"], True]]),
        _ep("quiet", [], [[1.0, [], False]]),
    ]
    res = {"agent": "a", "suite": "s", "episodes": eps}
    cm = confusion_matrix(res)
    assert cm["true"] == ["S1.1", "bore_damage", "no fault"]
    assert cm["declared"] == ["S1.1", "S2.1", "bore_damage", UNKNOWN_LABEL, NOTHING_LABEL]
    cell = {(t, d): c for i, t in enumerate(cm["true"]) for d, c in zip(cm["declared"], cm["counts"][i]) if c}
    # the pair adds to four cells; every other episode to one
    assert cell == {
        ("S1.1", "S1.1"): 2,
        ("S1.1", "S2.1"): 1,
        ("S1.1", "bore_damage"): 1,
        ("bore_damage", UNKNOWN_LABEL): 1,
        ("bore_damage", NOTHING_LABEL): 1,
        ("bore_damage", "S1.1"): 1,
        ("bore_damage", "bore_damage"): 1,
        ("no fault", NOTHING_LABEL): 1,
    }
    assert cm["episodes"] == [3, 3, 1]  # the pair is one episode in each of its two rows
    # on single-fault episodes the diagonal is the isolation accuracy
    single = [e for e in eps if len(e["faults"]) == 1]
    m = compute_metrics(single)
    cs = confusion_matrix({"episodes": single})
    diag = sum(cs["counts"][i][cs["declared"].index(t)] for i, t in enumerate(cs["true"]) if t in cs["declared"])
    assert diag == round(m["isolation_accuracy"] * m["n_faulty"])

    nominal = [_ep(f"n{i}", [], [[1.0, [], False]]) for i in range(3)]
    files = []
    for agent, e in (("a", eps), ("b", eps[:2])):
        p = tmp_path / f"{agent}.json"
        p.write_text(json.dumps({"agent": agent, "suite": "s", "episodes": [dict(x, agent=agent) for x in e]}))
        files.append(p)
    p = tmp_path / "nom.json"
    p.write_text(
        json.dumps(
            {"agent": "a", "suite": "nominal-test", "episodes": [dict(x, suite="nominal-test") for x in nominal]}
        )
    )
    files.append(p)
    pytest.importorskip("matplotlib")
    out = tmp_path / "rep"
    text = write_report(files, out).read_text()
    assert "## Per fault" in text and "| S1.1 | 2 | 100 / 50 / 2.5 | 100 / 50 / 2.5 |" in text
    assert "### Suite s, agent a" in text and "| S1.1 | 3 | **S1.1** 2, S2.1 1, bore_damage 1 |" in text
    assert "### Suite nominal-test, agent a" in text and "| no fault | 3 | **nothing** 3 |" in text
    saved = json.loads((out / "confusion.json").read_text())
    assert {(m["suite"], m["agent"]) for m in saved} == {("s", "a"), ("s", "b"), ("nominal-test", "a")}
    for name in ("summary.png", "detection_delay.png", "confusion_s.png", "confusion_nominal-test.png"):
        assert (out / name).read_bytes()[:4] == b"\x89PNG", name
    # a fault-free suite gets no (empty) delay panel; with only such suites there is no delay plot
    write_report([p], tmp_path / "rep2")
    assert not (tmp_path / "rep2" / "detection_delay.png").exists()
    assert "detection_delay.png" not in (tmp_path / "rep2" / "report.md").read_text()
    assert load_results([p])[0]["metrics"]["n_faulty"] == 0


def test_dataset_help_is_plain_text_and_documents_every_option(capsys):
    assert cli_main(["dataset", "--help"]) == 0
    text = capsys.readouterr().out
    assert "``" not in text and ":mod:" not in text
    from marine_fdi_env.cli.dataset import build_parser

    for action in build_parser()._actions:
        assert action.help, f"{action.option_strings} has no help"


# ----------------------------------------------------------------------------- a user's first hour
def _one_line_error(capsys, argv) -> str:
    """Run ``argv``; assert exit code 2 and one line on stderr without a traceback; return that line."""
    code = cli_main([str(a) for a in argv])
    out, err = capsys.readouterr()
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2, (argv, code, err)
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


@pytest.mark.parametrize("engines", ["100000000000", "1000000"])
def test_simulate_too_many_engines_names_the_memory_limit(capsys, tmp_path, engines):
    line = _one_line_error(
        capsys, ["simulate", "--engines", engines, "--duration", "300", "--out", tmp_path / "big.npz"]
    )
    assert "--engines" in line and "memory" in line and "available" in line
    assert not (tmp_path / "big.npz").exists()


def test_dataset_too_many_episodes_names_the_memory_limit(capsys, tmp_path):
    line = _one_line_error(
        capsys, ["dataset", "--preset", "default", "--episodes", "100000000000", "--out", tmp_path / "d"]
    )
    assert "--episodes" in line and "memory" in line and "available" in line
    assert not (tmp_path / "d").exists()


def test_the_memory_check_compares_with_what_the_machine_has(monkeypatch):
    from marine_fdi_env import costs

    monkeypatch.setattr(costs, "available_memory_bytes", lambda: 1_000_000)
    costs.check_memory(999_999, "x", "--n")
    with pytest.raises(ValueError, match=r"--n: x needs about 1\.5 MB of memory, more than the 1 MB available"):
        costs.check_memory(1_500_000, "x", "--n")


def test_simulate_refuses_to_overwrite_without_force(capsys, tmp_path):
    out = tmp_path / "run.npz"
    assert cli_main(["simulate", "--duration", "1", "--out", str(out), "--no-progress"]) == 0
    stamp = out.stat().st_mtime_ns
    line = _one_line_error(capsys, ["simulate", "--duration", "1", "--seed", "3", "--out", out])
    assert "--out" in line and "--force" in line and out.stat().st_mtime_ns == stamp
    assert cli_main(["simulate", "--duration", "1", "--seed", "3", "--out", str(out), "--no-progress", "--force"]) == 0
    assert out.stat().st_mtime_ns != stamp


@pytest.mark.parametrize(
    "argv, allowed",
    [
        (["evaluate", "--agent", "null", "--suite", "{tiny}", "--out", "{tmp}/r.txt"], ".json or .parquet"),
        (["simulate", "--duration", "1", "--out", "{tmp}/run.csv"], ".npz"),
        (["score-raw", "--suite", "{tiny}", "--predictions", "{tmp}", "--out", "{tmp}/s.csv"], ".json or .parquet"),
    ],
)
def test_out_extension_is_checked_against_the_format(capsys, tmp_path, tiny, argv, allowed):
    line = _one_line_error(capsys, [a.replace("{tmp}", str(tmp_path)).replace("{tiny}", str(tiny)) for a in argv])
    assert "--out" in line and allowed in line
    assert len(os.listdir(tmp_path)) == 1  # the suite file only: nothing written


@pytest.mark.parametrize(
    "content, field",
    [
        ({"agent": "a", "suite": "s", "episodes": []}, "'episodes' is empty"),
        ({"agent": "a", "suite": "s"}, "'episodes' is missing"),
        ({"agent": "a", "episodes": []}, "'suite' missing"),
        ({"agent": "a", "suite": "s", "episodes": [{"scenario_id": "x"}]}, "field 'suite' is missing"),
    ],
)
def test_report_names_what_a_results_file_lacks(capsys, tmp_path, content, field):
    f = tmp_path / "r.json"
    f.write_text(json.dumps(content))
    line = _one_line_error(capsys, ["report", f, "--out", tmp_path / "rep"])
    assert str(f) in line and field in line


def test_a_sidecar_field_is_validated_by_name(capsys, tmp_path):
    src = ROOT / "docs" / "examples" / "measured"
    (tmp_path / "e.csv").write_text((src / "example_engine.csv").read_text())
    meta = json.loads((src / "example_engine.meta.json").read_text())
    meta["ambient_temperature_C"] = "warm"
    (tmp_path / "e.meta.json").write_text(json.dumps(meta))
    for argv in (
        ["validate", "--data", tmp_path / "e.csv", "--check"],
        ["replicas", "--data", tmp_path / "e.csv", "--replicas", "1"],
    ):
        line = _one_line_error(capsys, argv)
        assert "e.meta.json" in line and "'ambient_temperature_C'" in line and "'warm'" in line


def test_an_operating_point_outside_the_envelope_warns(capsys):
    assert cli_main(["operating-point", "--params", "wartsila-6l46", "--fuel-setting", "0.05", "--json"]) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)["converged"]
    assert "below 25% of the rated 500 rpm" in err and "3,227 g/kWh" in err
    assert cli_main(["operating-point", "--params", "wartsila-6l46", "--fuel-setting", "1.0", "--json"]) == 0
    assert "warning" not in capsys.readouterr().err


def test_the_envelope_bounds():
    from marine_fdi_env.engine.envelope import envelope_warnings

    rated = 10.0
    assert envelope_warnings(rated, 200 / 3.6e9, rated) == []
    assert "below" in envelope_warnings(0.2 * rated, 200 / 3.6e9, rated)[0]
    assert "overspeed" in envelope_warnings(1.2 * rated, 200 / 3.6e9, rated)[0]
    assert "g/kWh" in envelope_warnings(rated, 400 / 3.6e9, rated)[0]
    assert "g/kWh" in envelope_warnings(rated, 120 / 3.6e9, rated)[0]


def test_evaluate_twice_shows_the_results_then_writes_beside_them(tmp_path, monkeypatch, capsys, tiny):
    monkeypatch.chdir(tmp_path)
    argv = ["evaluate", "--agent", "null", "--suite", str(tiny), "--no-progress"]
    assert cli_main(argv) == 0
    first = tmp_path / "results" / "null_tiny-v1.json"
    stamp = first.stat().st_mtime_ns
    capsys.readouterr()
    assert cli_main(argv) == 0  # the same run again: its results, shown
    out = capsys.readouterr().out
    assert "computed before" in out and "| tiny-v1 | null |" in out and first.stat().st_mtime_ns == stamp
    assert cli_main(argv + ["--seed-offset", "1"]) == 0  # another run: a new file beside the first
    assert "results/null_tiny-v1-2.json" in capsys.readouterr().out
    assert json.loads((tmp_path / "results" / "null_tiny-v1-2.json").read_text())["seed_offset"] == 1
    assert json.loads(first.read_text())["seed_offset"] == 0
    assert cli_main(argv + ["--seed-offset", "1"]) == 0  # that other run again: found beside, shown
    assert "results/null_tiny-v1-2.json (computed before" in capsys.readouterr().out
    assert not (tmp_path / "results" / "null_tiny-v1-3.json").exists()


def test_third_party_warnings_print_above_the_bar_not_inside_it(capsys):
    import logging
    import warnings

    lib = logging.getLogger("some_library")
    handler = logging.StreamHandler(sys.stderr)
    lib.addHandler(handler)
    try:
        bar = progress_bar(2, 0, "demo")
        bar.advance(0.5)
        # what warnings.showwarning does outside pytest (which records warnings instead of printing them)
        sys.stderr.write(warnings.formatwarning("a library's warning", UserWarning, "lib.py", 1))
        lib.warning("a library's log record")
        bar.advance(1.5)
        bar.close()
        lib.warning("after the bar")
    finally:
        lib.removeHandler(handler)
    err = capsys.readouterr().err
    for text in ("a library's warning", "a library's log record", "after the bar"):
        line = next(ln for ln in err.split("\n") if text in ln)
        visible = line.split("\r")[-1]  # what a terminal shows of the line: the bar was cleared first
        assert text in visible and "demo" not in visible, repr(line)
    assert sys.stderr is not None and not type(sys.stderr).__name__ == "_AboveBar"


def test_long_commands_say_their_cost_first(capsys, tmp_path):
    from marine_fdi_env.costs import CostEstimate, say_cost

    say_cost("marine-fdi x", "a grid", CostEstimate(600.0, 3e8, workers=2))
    assert capsys.readouterr().err.startswith("marine-fdi x: a grid: expect about ")
    say_cost("marine-fdi x", "a little", CostEstimate(5.0))
    assert capsys.readouterr().err == ""
    from marine_fdi_env.cli.raw import say_export_cost

    say_export_cost("thesis-v1")
    err = capsys.readouterr().err
    assert "marine-fdi export-raw: 20 scenarios of thesis-v1: expect about" in err and "MB" in err
    from marine_fdi_env.cli.sweep import say_sweep_cost

    say_sweep_cost(["all"], ["all"], 4, workers=2)  # every agent on every suite at four seed offsets
    from marine_fdi_env.benchmark.agent_registry import list_agents

    n_agents = len(list_agents())
    from marine_fdi_env.benchmark.suites import SUITE_NAMES, load_suite

    n_episodes = sum(len(load_suite(name).scenarios) for name in SUITE_NAMES)  # 587 with transfer-v3's 128
    assert capsys.readouterr().err.startswith(
        f"marine-fdi sweep: {n_agents} agents x {4 * n_episodes} episodes: expect about "
    )
    from marine_fdi_env.benchmark.agent_registry import models_dir
    from marine_fdi_env.cli.train import say_training_cost

    shipped = json.loads((models_dir() / "ppo-v1" / "config.json").read_text())["cpu_minutes"]
    say_training_cost("ppo", None)
    assert f"expect about {shipped:.0f} min" in capsys.readouterr().err
    data = json.loads((models_dir() / "ppo-v1" / "config.json").read_text())["cpu_s_data"] / 60.0
    say_training_cost("ppo", 7_000_000 // 100)  # a hundredth of the budget: mostly simulating the episodes
    assert f"expect about {data + (shipped - data) / 100:.0f} min" in capsys.readouterr().err
    robust = json.loads((models_dir() / "classifier" / "seed0" / "config.json").read_text())["cpu_minutes"]
    say_training_cost("classifier", None, "robust")  # --hyperparams robust: the noise-invariant classifier's cost
    assert f"expect about {robust:.0f} min" in capsys.readouterr().err


def test_a_fault_free_suite_confusion_plot_has_room_for_its_labels(tmp_path):
    """A one-row confusion matrix (a fault-free suite) gets a panel tall enough for tight_layout: no
    matplotlib warning among the report's output."""
    import warnings

    pytest.importorskip("matplotlib")
    from marine_fdi_env.benchmark.report import plot_confusion

    rs = load_results(sorted((ROOT / "docs" / "data" / "results").glob("*_nominal-v1.json")))
    assert len(rs) >= 2
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        plot_confusion(rs, tmp_path / "c.png")
    assert (tmp_path / "c.png").read_bytes()[:4] == b"\x89PNG"


def test_a_clone_relative_model_path_elsewhere_names_the_agent(tmp_path, monkeypatch, capsys, tiny):
    monkeypatch.chdir(tmp_path)
    line = _one_line_error(capsys, ["evaluate", "--agent", "training/models/ppo-v1", "--suite", tiny])
    assert "--agent ppo-v1" in line and "any folder" in line
