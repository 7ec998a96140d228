"""Benchmark report: loading, table order and formatting, plots."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from marine_fdi_env.benchmark.metrics import compute_metrics
from marine_fdi_env.benchmark.report import agent_sort_key, load_results, markdown_table, write_report
from marine_fdi_env.cli.report import report_main
from marine_fdi_env.errors import MissingExtra


def episode(agent: str, suite: str, delay: float | None, sid: str = "e") -> dict:
    changes = [[1.0, [], False]]
    if delay is not None:
        changes.append([5.0 + delay, ["S1.1"], True])
    return {
        "scenario_id": sid,
        "suite": suite,
        "seed": 0,
        "agent": agent,
        "duration_s": 20.0,
        "decision_period_s": 1.0,
        "n_samples": 1000,
        "profile": "constant",
        "faults": [{"id": "S1.1", "class": "sensor", "onset_s": 5.0, "magnitude": 1.0, "end_s": None}],
        "declared_changes": changes,
        "terminated": False,
        "failure_reason": None,
        "compute_s": 0.0125,
        "return": 0.0,
        "reward_terms": {},
        "feature_compute_s": 0.0100,
        "agent_compute_s": 0.0025,
        "n_decisions": 10,
    }


def write_result(tmp: Path, agent: str, suite: str, delays, *, with_metrics: bool = True) -> Path:
    eps = [episode(agent, suite, d, sid=f"{suite}-{i}") for i, d in enumerate(delays)]
    data = {"agent": agent, "suite": suite, "suite_version": "1", "episodes": eps}
    if with_metrics:
        data["metrics"] = compute_metrics(eps)
    p = tmp / f"{suite}-{agent}.json"
    p.write_text(json.dumps(data))
    return p


@pytest.fixture
def result_files(tmp_path: Path) -> list[Path]:
    return [
        write_result(tmp_path, "oracle", "b", [0, 0]),
        write_result(tmp_path, "zeta", "a", [1, 3]),
        write_result(tmp_path, "reference", "a", [2, None], with_metrics=False),
        write_result(tmp_path, "oracle", "a", [0, 0]),
        write_result(tmp_path, "alpha", "a", [4, 4]),
        write_result(tmp_path, "null", "a", [None, None]),
        write_result(tmp_path, "random", "b", [1, None]),
    ]


def test_agent_order():
    names = ["oracle", "zeta", "reference", "alpha", "random", "null"]
    assert sorted(names, key=agent_sort_key) == ["null", "random", "reference", "alpha", "zeta", "oracle"]


def test_table_rows_order_and_formatting(result_files):
    table = markdown_table(load_results(result_files))
    lines = table.strip().splitlines()
    assert lines[0].startswith("| Suite | Agent | Episodes | Detection |")
    assert "Features [µs/sample]" in lines[0] and "Agent [µs/decision]" in lines[0]
    rows = [[c.strip() for c in line.strip("|").split("|")] for line in lines[2:]]
    assert [(r[0], r[1]) for r in rows] == [
        ("a", "null"),
        ("a", "reference"),
        ("a", "alpha"),
        ("a", "zeta"),
        ("a", "oracle"),
        ("b", "random"),
        ("b", "oracle"),
    ]
    ref = dict(zip([c.strip() for c in lines[0].strip("|").split("|")], rows[1]))
    assert ref["Episodes"] == "2"
    assert ref["Detection"] == "50.0 %"
    assert ref["Median det. delay [s]"] == "2.0"
    assert ref["False alarms [1/h]"] == "0.00"
    assert ref["Features [µs/sample]"] == "10.0" and ref["Agent [µs/decision]"] == "250.0"
    assert ref["Censored median det. delay [s]"] == "–"  # one of two detected: half not reached
    null = dict(zip([c.strip() for c in lines[0].strip("|").split("|")], rows[0]))
    assert null["Detection"] == "0.0 %" and null["Median det. delay [s]"] == "–"


def test_load_errors_name_the_path(tmp_path):
    missing = tmp_path / "nope.json"
    with pytest.raises(ValueError, match="nope.json"):
        load_results([missing])
    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    with pytest.raises(ValueError, match="bad.json"):
        load_results([bad])
    noagent = tmp_path / "noagent.json"
    noagent.write_text(json.dumps({"suite": "a", "episodes": []}))
    with pytest.raises(ValueError, match="noagent.json.*'agent'"):
        load_results([noagent])
    badep = tmp_path / "badep.json"
    ep = episode("x", "a", 1)
    del ep["seed"]
    badep.write_text(json.dumps({"agent": "x", "suite": "a", "episodes": [ep]}))
    with pytest.raises(ValueError, match="badep.json.*'seed'"):
        load_results([badep])


def test_duplicate_suite_agent_rejected(tmp_path):
    p1 = write_result(tmp_path, "x", "a", [1])
    p2 = tmp_path / "copy.json"
    p2.write_text(p1.read_text())
    with pytest.raises(ValueError, match="two results"):
        markdown_table(load_results([p1, p2]))


def test_write_report_without_plots(result_files, tmp_path):
    out = tmp_path / "rep"
    path = write_report(result_files, out, plots=False)
    text = path.read_text()
    assert path == out / "report.md"
    assert "## All episodes" in text and "## Sensor fault episodes" in text
    assert "## Process fault episodes" not in text and "## Fault-free episodes" not in text
    assert not (out / "summary.png").exists()


def test_write_report_with_plots(result_files, tmp_path):
    pytest.importorskip("matplotlib")
    out = tmp_path / "rep"
    assert report_main([*map(str, result_files), "--out", str(out)]) == 0
    for name in ("report.md", "detection_delay.png", "summary.png"):
        f = out / name
        assert f.exists() and f.stat().st_size > 0
    assert (out / "summary.png").read_bytes()[:4] == b"\x89PNG"
    assert "![summary](summary.png)" in (out / "report.md").read_text()


def test_report_main_error_exit_code(tmp_path, capsys):
    assert report_main([str(tmp_path / "missing.json"), "--out", str(tmp_path), "--no-plots"]) == 2
    assert "missing.json" in capsys.readouterr().err


def test_missing_matplotlib_gives_clear_error(result_files, tmp_path, monkeypatch, capsys):
    monkeypatch.setitem(__import__("sys").modules, "matplotlib", None)
    with pytest.raises(MissingExtra, match=r"plots needs matplotlib: pip install 'marine-fdi-env\[plots\]'"):
        write_report(result_files, tmp_path / "rep")
    assert report_main([*map(str, result_files), "--out", str(tmp_path / "r2")]) == 2
    assert "--no-plots" in capsys.readouterr().err
    assert report_main([*map(str, result_files), "--out", str(tmp_path / "r3"), "--no-plots"]) == 0


def _seeded(tmp: Path, agent: str, suite: str, delays, seed: int) -> Path:
    p = write_result(tmp, agent, suite, delays)
    data = json.loads(p.read_text())
    data["training_seed"] = seed
    q = tmp / f"{suite}-{agent}-s{seed}.json"
    q.write_text(json.dumps(data))
    p.unlink()
    return q


def test_training_seeds_are_pooled_with_intervals(tmp_path):
    files = [_seeded(tmp_path, "learner", "a", [1, 2, None, 3], s) for s in (0, 1)]
    files.append(_seeded(tmp_path, "learner", "a", [1, None, None, None], 2))
    table = markdown_table(load_results(files), intervals=True)
    head, _, row = table.strip().splitlines()
    cells = dict(zip([c.strip() for c in head.strip("|").split("|")], [c.strip() for c in row.strip("|").split("|")]))
    assert cells["Seeds"] == "3" and cells["Episodes"] == "12"
    assert cells["Detection"].startswith("58.3 % (")  # 7 of 12, with its interval
    lo, hi = (float(x) for x in cells["Detection"].split("(")[1].rstrip(")").split("–"))
    assert lo < 58.3 < hi
    assert cells["False alarms [1/h]"].startswith("0.00 (0.00–")  # none: the exact Poisson bound
    # the same seed twice is refused, and so is a mix of seeded and unseeded results
    with pytest.raises(ValueError, match="training seed 0"):
        markdown_table(load_results(files + [files[0]]))
    with pytest.raises(ValueError, match="not all with a training_seed"):
        markdown_table(load_results(files + [write_result(tmp_path, "learner", "a", [1, 2, 3, 4])]))


def test_report_gives_normalised_scores(tmp_path):
    files = [
        write_result(tmp_path, "null", "a", [None, None]),
        write_result(tmp_path, "oracle", "a", [0, 0]),
        write_result(tmp_path, "alpha", "a", [1, None]),
    ]
    for f, ret in zip(files, (-2.0, 10.0, 4.0)):
        data = json.loads(f.read_text())
        for e in data["episodes"]:
            e["return"] = ret
        data.pop("metrics")
        f.write_text(json.dumps(data))
    text = write_report(files, tmp_path / "rep", plots=False).read_text()
    assert "## Normalised scores" in text
    row = next(line for line in text.splitlines() if line.startswith("| alpha |"))
    assert row.split("|")[2].strip().startswith("50.0")  # (4 + 2) / (10 + 2)
