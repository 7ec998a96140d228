"""marine-fdi evaluate / dataset, the frozen suites and the baseline agents."""

from __future__ import annotations

import json

import numpy as np
import pytest

from marine_fdi_env.benchmark.agent_api import BUILTIN_AGENTS, load_agent
from marine_fdi_env.benchmark.evaluate import WALL_CLOCK_FIELDS, evaluate, run_episodes
from marine_fdi_env.benchmark.suites import SUITE_NAMES, build_suite, load_suite
from marine_fdi_env.cli import main as cli_main
from marine_fdi_env.envs.scenario_sampler import ScenarioSpec

SCENARIOS = [
    ScenarioSpec(faults=("S4.2@6:6e4",), profile="constant", noise_seed=1, duration_s=20.0, scenario_id="s42"),
    ScenarioSpec(faults=(), profile="step:u0=0.8,u1=0.9,t=5", noise_seed=2, duration_s=20.0, scenario_id="free"),
    ScenarioSpec(
        faults=("S2.1@4:8e5", "S3.5@9:80"), profile="constant", noise_seed=3, duration_s=20.0, scenario_id="pair"
    ),
    ScenarioSpec(
        faults=("valve_seizing@3:0.97,kappa=inf",),
        profile="constant",
        noise_seed=4,
        duration_s=20.0,
        scenario_id="stall",
    ),
]


@pytest.fixture
def suite_file(tmp_path):
    p = tmp_path / "tiny-v1.json"
    p.write_text(
        json.dumps(
            {
                "name": "tiny-v1",
                "version": 1,
                "description": "test",
                "env": {"decision_period_s": 1.0, "params": "thesis-12v28", "observe_sensors": False},
                "scenarios": [s.to_dict() for s in SCENARIOS],
            }
        )
    )
    return p


def _strip(episodes):
    return [{k: v for k, v in e.items() if k not in WALL_CLOCK_FIELDS} for e in episodes]


def test_oracle_is_the_ceiling_and_null_the_floor(suite_file, tmp_path):
    oracle = evaluate("oracle", str(suite_file), tmp_path / "o.json", progress=False)
    m = oracle["metrics"]
    assert m["detection_rate"] == 1.0 and m["false_alarm_rate"] == 0.0
    # the stalling engine ends its episode early: isolated while it ran, then terminated
    assert m["isolation_accuracy"] == 1.0 and m["median_detection_delay_s"] <= 1.0
    assert m["engine_failures"] == 1
    null = evaluate("null", str(suite_file), tmp_path / "n.json", progress=False)["metrics"]
    assert null["detection_rate"] == 0.0 and null["false_alarm_rate"] == 0.0 and null["isolation_accuracy"] == 0.0
    for key in (
        "detection_rate",
        "false_alarm_rate",
        "isolation_accuracy",
        "median_detection_delay_s",
        "median_isolation_delay_s",
        "compute_s_per_sample",
    ):
        assert key in m


def test_reference_agent_detects_and_isolates_an_obvious_fault(suite_file, tmp_path):
    res = evaluate("reference", str(suite_file), tmp_path / "r.json", progress=False)
    ep = {e["scenario_id"]: e for e in res["episodes"]}
    assert ep["s42"]["declared_changes"][-1][1] == ["S4.2"]
    assert not any(alarm for _, _, alarm in ep["free"]["declared_changes"])
    assert res["metrics"]["false_alarm_rate"] == 0.0


def test_results_do_not_depend_on_batch_size_or_workers(suite_file, tmp_path):
    a = evaluate("random", str(suite_file), tmp_path / "a.json", batch_size=4, progress=False)
    b = evaluate("random", str(suite_file), tmp_path / "b.json", batch_size=1, progress=False)
    c = evaluate("random", str(suite_file), tmp_path / "c.json", batch_size=1, workers=2, progress=False)
    assert _strip(a["episodes"]) == _strip(b["episodes"]) == _strip(c["episodes"])
    d = evaluate("random", str(suite_file), tmp_path / "d.json", seed_offset=7, progress=False)
    assert _strip(d["episodes"]) != _strip(a["episodes"])  # new noise and new agent draws


def test_interrupted_evaluation_resumes_without_rerunning(suite_file, tmp_path):
    out = tmp_path / "res.json"
    first = evaluate("reference", str(suite_file), tmp_path / "full.json", progress=False)
    # an interrupted run left its header and the first two episodes (one marked so we can tell)
    header = {k: first[k] for k in ("agent", "agent_spec", "suite", "suite_version", "seed_offset", "env_id", "env")}
    kept = dict(first["episodes"][0], reward_terms={"marker": 1.0})
    partial = tmp_path / "res.json.partial.jsonl"
    partial.write_text("\n".join(json.dumps(x) for x in (header, kept, first["episodes"][1])) + '\n{"cut')
    res = evaluate("reference", str(suite_file), out, progress=False)
    assert res["episodes"][0]["reward_terms"] == {"marker": 1.0}  # not recomputed
    assert _strip(res["episodes"][1:]) == _strip(first["episodes"][1:])
    assert not partial.exists() and json.loads(out.read_text())["n_scenarios"] == 4
    # a partial log of another evaluation is not silently mixed in
    partial.write_text(json.dumps(dict(header, agent="null")) + "\n")
    with pytest.raises(ValueError, match="another evaluation"):
        evaluate("reference", str(suite_file), out, progress=False)


def test_cli_evaluate_prints_table_and_rejects_bad_agents(suite_file, tmp_path, capsys):
    assert (
        cli_main(
            [
                "evaluate",
                "--agent",
                "oracle",
                "--suite",
                str(suite_file),
                "--out",
                str(tmp_path / "x.json"),
                "--no-progress",
            ]
        )
        == 0
    )
    assert "| tiny-v1 | oracle |" in capsys.readouterr().out
    assert cli_main(["evaluate", "--agent", "nonsense", "--suite", str(suite_file)]) == 2
    assert "unknown agent" in capsys.readouterr().err
    bad = tmp_path / "agentdir"
    bad.mkdir()
    (bad / "agent.json").write_text("{not json")
    assert cli_main(["evaluate", "--agent", str(bad), "--suite", str(suite_file)]) == 2
    assert "agent.json" in capsys.readouterr().err
    assert cli_main(["evaluate", "--suite", "no-such-suite"]) == 2


def test_dataset_export_labels_match_ground_truth(suite_file, tmp_path):
    assert cli_main(["dataset", "--suite", str(suite_file), "--out", str(tmp_path / "ds"), "--no-progress"]) == 0
    d = np.load(tmp_path / "ds" / "dataset.npz")
    assert d["obs"].shape == (4, 20, 115) and d["active"].shape == (4, 20, 26)
    fid = list(d["fault_ids"])
    s42 = d["active"][0, :, fid.index("S4.2")]
    assert not s42[d["t_s"][0] < 6.0].any() and s42[d["t_s"][0] >= 6.0].all()
    assert not d["active"][1].any()
    assert d["valid"][:3].all() and not d["valid"][3].all()  # the stalled engine's episode ended early
    assert np.isfinite(d["obs"]).all()


def test_dataset_from_preset_is_reproducible(tmp_path):
    for k in (1, 2):
        assert (
            cli_main(
                [
                    "dataset",
                    "--preset",
                    "nominal",
                    "--episodes",
                    "2",
                    "--seed",
                    "3",
                    "--out",
                    str(tmp_path / f"p{k}"),
                    "--no-progress",
                ]
            )
            == 0
        )
    a, b = np.load(tmp_path / "p1" / "dataset.npz"), np.load(tmp_path / "p2" / "dataset.npz")
    assert np.array_equal(a["obs"], b["obs"])


@pytest.mark.parametrize("name", SUITE_NAMES)
def test_shipped_suites_load_and_are_reproduced_by_their_builders(name):
    suite = load_suite(name)
    assert suite.name == name and len(suite.scenarios) >= 20
    assert [s.to_dict() for s in suite.scenarios] == build_suite(name)["scenarios"]


def test_suite_contents_match_their_description():
    single = load_suite("single-v1")
    assert len(single.scenarios) == 26 * 3 * 2 and all(len(s.faults) == 1 for s in single.scenarios)
    assert all(len(s.faults) == 2 for s in load_suite("multi-v1").scenarios)
    assert all(not s.faults for s in load_suite("nominal-v1").scenarios)
    thesis = load_suite("thesis-v1")
    assert {s.scenario_id.split("/")[0] for s in thesis.scenarios} == {f"thesis-6.4.{k}" for k in range(1, 5)}
    transfer = {s.profile.split(":")[0] for s in load_suite("transfer-v1").scenarios}
    assert transfer == {"manoeuvring", "random"}


def test_every_builtin_agent_loads():
    for name in BUILTIN_AGENTS:
        assert load_agent(name).name == name


def test_run_episodes_returns_records_in_scenario_order():
    recs = run_episodes(load_agent("null"), SCENARIOS[:2], {}, suite="x", batch_size=1)
    assert [r["scenario_id"] for r in recs] == ["s42", "free"]
