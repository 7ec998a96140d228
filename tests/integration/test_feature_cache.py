"""Feature caches: a suite's trajectories as a versioned Parquet table, scored without simulating,
and refused (never used) when made by other code, with other parameters, or damaged."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
from test_env_evaluate import suite_file  # noqa: F401  (a fixture: test_env_evaluate's SCENARIOS as a suite file)

from marine_fdi_env.benchmark import evaluate as ev
from marine_fdi_env.benchmark import feature_cache as fc
from marine_fdi_env.benchmark.evaluate import WALL_CLOCK_FIELDS, evaluate
from marine_fdi_env.benchmark.suites import load_suite
from marine_fdi_env.benchmark.sweep import run_sweep
from marine_fdi_env.cli import main as cli_main
from marine_fdi_env.envs import trajectory
from marine_fdi_env.errors import DataFileError

pytest.importorskip("pyarrow")


def _strip(episodes):
    return [{k: v for k, v in e.items() if k not in WALL_CLOCK_FIELDS} for e in episodes]


def _no_simulation(monkeypatch):
    def refuse(*a, **k):
        raise AssertionError("simulated although a cache was there")

    monkeypatch.setattr(ev, "simulate", refuse)


def _only_cache(d):
    files = sorted((d).glob("*.parquet"))
    assert len(files) == 1, files
    return files[0]


def test_a_written_cache_scores_any_agent_without_simulating(suite_file, tmp_path, monkeypatch):
    cache = tmp_path / "cache"
    null = evaluate(
        "null", str(suite_file), tmp_path / "n.json", cache="write", cache_dir=cache, batch_size=3, progress=False
    )
    assert "feature_cache" not in null and not list(cache.glob("*.parts"))
    f = _only_cache(cache)
    assert f.name.startswith("tiny-v1_o0_")
    agents = ("reference", "sequential", "sequential-thesis")
    plain = {a: evaluate(a, str(suite_file), tmp_path / f"{a}.json", progress=False) for a in agents}
    _no_simulation(monkeypatch)
    # sequential needs observe_sequential, sequential-thesis the thesis cells too: the cache has every option and
    # every cell set's conclusions
    for a in agents:
        got = evaluate(a, str(suite_file), tmp_path / f"{a}c.json", cache="use", cache_dir=cache, progress=False)
        assert got["feature_cache"] == [str(f)]
        assert _strip(got["episodes"]) == _strip(plain[a]["episodes"]), a
        assert got["metrics"]["n_episodes"] == 4 and got["episodes"][3]["terminated"]


def test_the_cache_holds_the_trajectory_bit_for_bit(suite_file, tmp_path):
    scs = load_suite(str(suite_file)).scenarios
    kw = {"observe_sensors": True, "observe_sequential": True, "diagnosis_cells": ["thesis", "grid", "sized"]}
    traj = trajectory.simulate(scs, kw)
    header = fc.cache_header("tiny-v1", 1, 0, kw, scs)
    f = fc.write_trajectory(tmp_path / "t.parquet", np.arange(4), traj, header)
    idx, back = fc.read_trajectory(f, header)
    assert idx.tolist() == [0, 1, 2, 3] and back.scenarios == traj.scenarios
    assert back.cell_sets == traj.cell_sets == ("thesis", "grid", "sized")
    for k in range(traj.steps):  # what an agent sees at every decision, with every cell set
        assert np.array_equal(back.observation(k), traj.observation(k))
        for cells in traj.cell_sets:
            a = back.info_arrays(k, back.active(k)[0], True, cells)
            b = traj.info_arrays(k, traj.active(k)[0], True, cells)
            assert json.dumps(a, default=lambda x: x.tolist()) == json.dumps(b, default=lambda x: x.tolist())
    for name in ("n_decisions", "terminated", "failure_step", "compute_s"):
        assert np.array_equal(getattr(back, name), getattr(traj, name)), name
    assert back.failures == traj.failures and back.failures[3]["reason"]


@pytest.mark.parametrize("change", ["code", "params", "content", "format"])
def test_a_cache_of_other_code_or_parameters_or_damaged_is_refused(change, suite_file, tmp_path, monkeypatch, capsys):
    cache = tmp_path / "cache"
    evaluate("null", str(suite_file), tmp_path / "n.json", cache="write", cache_dir=cache, progress=False)
    f = _only_cache(cache)
    if change == "code":  # the simulator, the diagnosers or the environment changed since
        real = fc.code_version()
        monkeypatch.setattr(fc, "code_version", lambda: dict(real, source_sha256="0" * 64))
        expect = "made by other code (code.source_sha256"
    elif change == "params":  # the file of another seed offset put where this one's belongs
        evaluate(
            "null", str(suite_file), tmp_path / "n3.json", seed_offset=3, cache="write", cache_dir=cache, progress=False
        )
        other = next(p for p in cache.glob("*.parquet") if p != f)
        shutil.copy(other, f)
        expect = "made with other parameters (params.seed_offset: 3 there, 0 here"
    elif change == "format":  # a cache of format 1, which held one cell set's conclusions only
        import pyarrow.parquet as pq

        t = pq.read_table(f)
        meta = json.loads(t.schema.metadata[fc.META_KEY])
        meta["header"]["format"] = 1
        pq.write_table(t.replace_schema_metadata({fc.META_KEY: json.dumps(meta).encode()}), f)
        expect = f"feature cache of format 1, this code reads {fc.FORMAT}"
    else:  # a value edited in place, metadata untouched
        import pyarrow as pa
        import pyarrow.parquet as pq

        t = pq.read_table(f)
        t2 = t.set_column(t.column_names.index("t_s"), "t_s", pa.array(t.column("t_s").to_numpy() + 1e-9))
        pq.write_table(t2.replace_schema_metadata(t.schema.metadata), f)
        expect = "checksum does not match its content"
    with pytest.raises(DataFileError, match="remove it, rebuild it with --cache write, or pass --cache off") as e:
        evaluate("reference", str(suite_file), tmp_path / "r.json", cache="use", cache_dir=cache, progress=False)
    assert expect in str(e.value) and str(f) in str(e.value)
    # the command line: one line, exit code 2; --cache off ignores the file
    args = ["evaluate", "--agent", "reference", "--suite", str(suite_file), "--cache-dir", str(cache), "--no-progress"]
    assert cli_main(args + ["--out", str(tmp_path / "c.json")]) == 2
    err = capsys.readouterr().err
    assert expect in err and len(err.strip().splitlines()) == 1
    assert cli_main(args + ["--out", str(tmp_path / "d.json"), "--cache", "off"]) == 0


def test_an_interrupted_cache_write_keeps_its_parts_and_resumes(suite_file, tmp_path, monkeypatch):
    cache = tmp_path / "cache"
    calls = []
    real = ev.evaluate_chunk

    def stop_after_one(*a, **k):
        if calls:
            raise KeyboardInterrupt
        calls.append(1)
        return real(*a, **k)

    monkeypatch.setattr(ev, "evaluate_chunk", stop_after_one)
    with pytest.raises(KeyboardInterrupt):
        evaluate(
            "null", str(suite_file), tmp_path / "n.json", cache="write", cache_dir=cache, batch_size=1, progress=False
        )
    parts = list(next(cache.glob("*.parts")).glob("part_*.parquet"))
    assert len(parts) == 1 and not list(cache.glob("*.parquet"))
    monkeypatch.setattr(ev, "evaluate_chunk", real)
    evaluate("null", str(suite_file), tmp_path / "n.json", cache="write", cache_dir=cache, batch_size=1, progress=False)
    f = _only_cache(cache)
    plain = evaluate("random", str(suite_file), tmp_path / "r0.json", cache="off", progress=False)
    _no_simulation(monkeypatch)
    got = evaluate("random", str(suite_file), tmp_path / "r.json", cache="use", cache_dir=cache, progress=False)
    assert got["feature_cache"] == [str(f)] and _strip(got["episodes"]) == _strip(plain["episodes"])


def test_a_sweep_writes_and_then_reads_the_caches(suite_file, tmp_path, monkeypatch):
    cache = tmp_path / "cache"
    a = run_sweep(
        ["null", "reference", "sequential"],
        [str(suite_file)],
        [0, 2],
        tmp_path / "a",
        cache="write",
        cache_dir=cache,
        progress=False,
    )
    assert len(a["run"]["caches_written"]) == 2 and not a["run"]["caches_read"]
    _no_simulation(monkeypatch)
    b = run_sweep(
        ["null", "reference", "sequential", "oracle"],
        [str(suite_file)],
        [0, 2],
        tmp_path / "b",
        cache="use",
        cache_dir=cache,
        progress=False,
    )
    assert len(b["run"]["caches_read"]) == 2
    from marine_fdi_env.benchmark.records import read_records

    ra = read_records(tmp_path / "a" / "episodes.parquet", keep_extra=True)[0]
    rb = [r for r in read_records(tmp_path / "b" / "episodes.parquet", keep_extra=True)[0] if r["agent"] != "oracle"]
    assert _strip(ra) == _strip(rb) and len(ra) == 24
