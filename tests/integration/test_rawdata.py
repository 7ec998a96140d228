"""Raw-data suites in the LiU-ICE / DX'25 layout: export-raw, predict-raw, score-raw."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from test_env_evaluate import SCENARIOS
from test_scale_out import _subset, _suite_file

from marine_fdi_env.benchmark.evaluate import evaluate
from marine_fdi_env.benchmark.rawdata import OUTPUT_COLUMNS, belief_to_dx
from marine_fdi_env.benchmark.rawscore import score_raw
from marine_fdi_env.benchmark.suites import load_suite
from marine_fdi_env.cli import main as cli_main
from marine_fdi_env.engine.simulator import Simulator
from tests.paths import ROOT


@pytest.fixture(scope="module")
def tiny_raw(tmp_path_factory):
    """The test scenarios (one engine stalls) exported raw, and the reference's predictions."""
    d = tmp_path_factory.mktemp("raw")
    suite = _suite_file(d / "tiny-v1.json", "tiny-v1", SCENARIOS)
    assert cli_main(["export-raw", "--suite", str(suite), "--out", str(d / "new" / "raw"), "--no-progress"]) == 0
    assert (
        cli_main(
            [
                "predict-raw",
                "--agent",
                "reference",
                "--data",
                str(d / "new" / "raw"),
                "--out",
                str(d / "pred"),
                "--no-progress",
            ]
        )
        == 0
    )
    return suite, d / "new" / "raw", d / "pred"


def test_exported_samples_are_the_simulators(tiny_raw):
    suite, raw, _ = tiny_raw
    man = json.loads((raw / "manifest.json").read_text())
    assert [c["name"] for c in man["data_columns"]][:3] == ["time", "fuel_setting", "S1.1"]
    assert {c["name"]: c["unit"] for c in man["data_columns"]}["S2.1"] == "Pa"
    truth = {s["scenario_id"]: s for s in json.loads((raw / "ground_truth.json").read_text())["scenarios"]}
    for sc in load_suite(str(suite)).scenarios:
        data = np.loadtxt(raw / "data" / f"{sc.scenario_id}.csv", delimiter=",", skiprows=1)
        sim = Simulator("thesis-12v28", seeds=[sc.noise_seed], faults=list(sc.faults), profiles=sc.profile)
        run = sim.run(sc.duration_s)
        n = len(data)
        assert np.array_equal(data[:, 2:], run.measurements[:n, 0]), sc.scenario_id  # 17 digits: bit for bit
        assert np.array_equal(data[:, 0], run.t[:n])
        assert truth[sc.scenario_id]["faults"] == sc.truth() and truth[sc.scenario_id]["n_samples"] == n
        if sc.scenario_id == "stall":  # the data stop where the engine left its range
            fail = truth["stall"]["engine_failure"]
            assert fail is not None and data[-1, 0] == pytest.approx(fail["time_s"]) and n < len(run.t)
        else:
            assert n == len(run.t) and truth[sc.scenario_id]["engine_failure"] is None


def test_belief_to_dx_follows_the_kits_conventions():
    b = np.zeros((3, 28), dtype=np.float32)
    b[1, [0, 5]] = 1.0  # a double-fault declaration
    b[2, 27] = 1.0  # detected, not isolated
    b[2, 3] = 0.49  # a tie kept below the declaration threshold
    det, ranks = belief_to_dx(b)
    assert det.tolist() == [0, 1, 1]
    assert ranks[0].sum() == 0.0 and ranks[1].sum() == pytest.approx(1.0) and ranks[2].sum() == pytest.approx(1.0)
    assert ranks[1, 0] == ranks[1, 5] == 0.5 and ranks[2, 26] == pytest.approx(1 / 1.49)


def _evaluate_vs_score(tmp_path, suite_file: Path):
    raw, pred = tmp_path / "raw", tmp_path / "pred"
    assert cli_main(["export-raw", "--suite", str(suite_file), "--out", str(raw), "--no-progress"]) == 0
    assert cli_main(["predict-raw", "--data", str(raw), "--out", str(pred), "--no-progress"]) == 0
    ev = evaluate("reference", str(suite_file), tmp_path / "ev.json", progress=False)
    sc = score_raw(str(suite_file), pred, data_dir=raw, progress=False)
    return ev, sc


EXACT = (
    "n_episodes",
    "n_faulty",
    "n_false_alarms",
    "false_alarm_rate",
    "false_alarm_episode_rate",
    "detection_rate",
    "isolation_rate",
    "isolation_accuracy",
    "fault_free_hours",
)
DELAYS = (
    "median_detection_delay_s",
    "p90_detection_delay_s",
    "median_detection_delay_censored_s",
    "median_isolation_delay_s",
    "p90_isolation_delay_s",
)


@pytest.mark.parametrize("suite,idx", [("thesis-v1", (0, 10)), ("single-v1", (30, 100, 128))])
def test_round_trip_reference_outputs_score_like_evaluate(suite, idx, tmp_path):
    """A suite exported raw, scored with the reference's own outputs in the DX layout, gives
    evaluate's metrics: rates and counts exactly, delays to float rounding (the reference raises
    no alarm before an onset, so the sample grid finds the same decision times), belief on the
    truth within the documented bound (per onset, at most one decision period of samples holds the
    previous declaration: |difference| <= mean over faulty episodes of onsets x 1 s / active time)."""
    f = _subset(tmp_path, suite, idx)
    ev, sc = _evaluate_vs_score(tmp_path, f)
    m, s = ev["metrics"], sc["metrics"]
    assert m["detection_rate"] > 0  # a non-trivial comparison
    for k in EXACT:
        assert s[k] == pytest.approx(m[k], rel=1e-12, abs=0), k
    for k in DELAYS:
        assert (s[k] is None) == (m[k] is None), k
        if m[k] is not None:
            assert s[k] == pytest.approx(m[k], abs=1e-6), k
    bounds = [
        len(e["faults"]) * 1.0 / (e["duration_s"] - min(x["onset_s"] for x in e["faults"]))
        for e in ev["episodes"]
        if e["faults"]
    ]
    assert abs(s["belief_on_truth"] - m["belief_on_truth"]) <= np.mean(bounds) + 1e-12
    dx = sc["dx_metrics"]
    assert 0 < dx["true_detection_rate"] <= 1 and dx["false_alarm_rate"] == 0.0
    assert 0 < dx["fault_isolation_accuracy"] <= 1
    check_dx_bound(ev, dx)


def dx_bound(episodes: list[dict], dx: dict) -> dict:
    """How far evaluate's DX metrics per decision (1 s) may lie from score-raw's per 100 Hz sample.

    The samples in [t_k, t_k + 1 s) carry decision k (predict-raw), so a decision interval counts the
    same in both unless the truth changes inside it: at a fault's onset (or end), in the interval before
    the first decision (samples from t = 0, never alarmed) and in the last one (one sample, at the end).
    Per episode at most B_e = faults + 2 intervals differ, each by at most one decision's worth of
    samples in a numerator and a denominator: a ratio A/N moves by at most 2 B / (N - B), B = sum B_e
    and N the ratio's denominator in decisions."""
    B = sum(len(e["faults"]) + 2 for e in episodes)

    def tol(n):
        return 2 * B / (n - B) if n > B else 1.0

    alarmed = dx["true_detection_rate"] * dx["n_fault_decisions"]
    return {
        "true_detection_rate": tol(dx["n_fault_decisions"]),
        "false_alarm_rate": tol(dx["n_fault_free_decisions"]),
        "fault_isolation_accuracy": tol(alarmed),
    }


def check_dx_bound(ev: dict, raw_dx: dict) -> None:
    """evaluate's DX metrics (from its records) within :func:`dx_bound` of score-raw's 100 Hz ones."""
    mine = ev["dx_metrics"]
    bound = dx_bound(ev["episodes"], mine)
    for k, tol in bound.items():
        assert tol < 0.1, (k, tol)  # a bound that says something
        assert abs(mine[k] - raw_dx[k]) <= tol, (k, mine[k], raw_dx[k], tol)


def _bad(pred: Path, tmp_path: Path, name: str) -> Path:
    d = tmp_path / name
    shutil.copytree(pred, d)
    return d


def _score_err(suite, raw, pred, capsys) -> str:
    assert (
        cli_main(["score-raw", "--suite", str(suite), "--predictions", str(pred), "--data", str(raw), "--no-progress"])
        == 2
    )
    return capsys.readouterr().err


def _rewrite(path: Path, fn) -> None:
    lines = path.read_text().splitlines()
    path.write_text("\n".join(fn(lines)) + "\n")


def test_bad_predictions_name_the_file_row_and_column(tiny_raw, tmp_path, capsys):
    suite, raw, pred = tiny_raw
    assert (
        cli_main(["score-raw", "--suite", str(suite), "--predictions", str(pred), "--data", str(raw), "--no-progress"])
        == 0
    )
    assert capsys.readouterr().out.strip().splitlines()[-1].startswith("scored 4 scenarios of tiny-v1")

    d = _bad(pred, tmp_path, "missing")
    (d / "output_pair.csv").unlink()
    err = _score_err(suite, raw, d, capsys)
    assert "1 of 4 scenarios have no predictions file: output_pair.csv" in err

    d = _bad(pred, tmp_path, "columns")
    _rewrite(d / "output_s42.csv", lambda ls: [ls[0].replace("unknown_rank", "unknown")] + ls[1:])
    err = _score_err(suite, raw, d, capsys)
    assert "output_s42.csv: line 1 (header)" in err and "'unknown_rank'" in err and "'unknown'" in err

    col = OUTPUT_COLUMNS.index("S4.2_rank")

    def unnormalised(ls):
        row = ls[1001].split(",")  # sample row 1000 (t = 10 s): S4.2 detected and isolated
        assert row[2] == "1" and float(row[col]) == 1.0
        row[col] = "0.7"
        return ls[:1001] + [",".join(row)] + ls[1002:]

    d = _bad(pred, tmp_path, "sum")
    _rewrite(d / "output_s42.csv", unnormalised)
    err = _score_err(suite, raw, d, capsys)
    assert "output_s42.csv: line 1002 (sample row 1000, sample_time 10)" in err
    assert "the ranks sum to 0.7, must be 1 when detection = 1" in err and "'S1.1_rank ... unknown_rank'" in err

    def nan(ls):
        row = ls[51].split(",")
        row[OUTPUT_COLUMNS.index("S2.1_rank")] = "nan"
        return ls[:51] + [",".join(row)] + ls[52:]

    d = _bad(pred, tmp_path, "nan")
    _rewrite(d / "output_free.csv", nan)
    err = _score_err(suite, raw, d, capsys)
    assert "output_free.csv: line 52 (sample row 50, sample_time 0.5), column 'S2.1_rank': not a finite number" in err

    def text(ls):
        row = ls[11].split(",")
        row[OUTPUT_COLUMNS.index("detection")] = "yes"
        return ls[:11] + [",".join(row)] + ls[12:]

    d = _bad(pred, tmp_path, "text")
    _rewrite(d / "output_free.csv", text)
    err = _score_err(suite, raw, d, capsys)
    assert "output_free.csv: line 12 (sample row 10), column 'detection': not a number ('yes')" in err

    d = _bad(pred, tmp_path, "short")
    _rewrite(d / "output_pair.csv", lambda ls: ls[:-5])
    err = _score_err(suite, raw, d, capsys)
    assert "output_pair.csv: line 1998: has 1996 sample rows, the data have 2001" in err


def test_worked_example_runs_end_to_end(tiny_raw, tmp_path, capsys):
    """docs/examples/dx_pair_diagnoser.py: an external diagnoser reading raw samples one at a time."""
    suite, raw, _ = tiny_raw
    out = tmp_path / "pairs"
    subprocess.run(
        [sys.executable, str(ROOT / "docs" / "examples" / "dx_pair_diagnoser.py"), str(raw), str(out)],
        check=True,
        capture_output=True,
    )
    assert (
        cli_main(
            [
                "score-raw",
                "--suite",
                str(suite),
                "--predictions",
                str(out),
                "--data",
                str(raw),
                "--name",
                "pairs",
                "--out",
                str(tmp_path / "pairs.json"),
                "--no-progress",
            ]
        )
        == 0
    )
    res = json.loads((tmp_path / "pairs.json").read_text())
    ep = {e["scenario_id"]: e for e in res["episodes"]}
    assert ep["s42"]["declared_changes"][-1][1] == ["S4.2"]  # the offset twin found, not its healthy twin
    assert not any(a for _, _, a in ep["free"]["declared_changes"])
    assert res["dx_metrics"]["false_alarm_rate"] == 0.0
