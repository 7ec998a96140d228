"""The shipped models' key settings, pinned: what docs/learned_agents.md and the README report is
what ``training/models/`` holds (a retrained model that changes one of them must update the docs)."""

from __future__ import annotations

import json

import pytest

pytest.importorskip("torch")
pytest.importorskip("stable_baselines3")

from marine_fdi_env.benchmark.agent_api import load_agent  # noqa: E402
from marine_fdi_env.envs.reward import RewardConfigV1  # noqa: E402
from tests.paths import ROOT

MODELS = ROOT / "training" / "models"


def _cfg(name: str) -> dict:
    return json.loads((MODELS / name / "config.json").read_text())


def test_classifier_v1_alone_is_the_shipped_rule_and_its_threshold_is_pinned():
    cfg = _cfg("classifier-v1")
    d = cfg["declaration"]
    assert d["use_reference"] is False  # the row "classifier": its own alarm and faults
    assert d["alarm_threshold"] == pytest.approx(0.941011, abs=1e-6)  # zero-false-alarm calibration + margin
    assert d["isolation_threshold"] == 0.5 and d["calibration"]["margin_logodds"] == 0.5
    assert d["calibration"]["target_false_alarms_per_hour"] == 0.0
    assert cfg["hyperparams"]["drop_features"] == ["time_fraction"]
    assert cfg["architecture"]["ewma_taus"] == [5.0, 20.0, 60.0]
    # the command that made the model, as recorded in its config (`marine-fdi train ...` makes new models;
    # training/NOTES.md)
    assert cfg["command"] == "python -m training.train --algo classifier --seed 0 --out training/models/classifier"
    agent = load_agent(str(MODELS / "classifier-v1"))
    assert agent.name == "classifier-v1" and agent.use_reference is False and agent.features is None


def test_classifier_v1_plus_reference_is_the_same_model_with_the_reference():
    meta = json.loads((MODELS / "classifier-v1+reference" / "agent.json").read_text())
    assert meta["kwargs"] == {"model": "../classifier-v1", "use_reference": "first"}
    hybrid, alone = load_agent(str(MODELS / "classifier-v1+reference")), load_agent(str(MODELS / "classifier-v1"))
    assert hybrid.name == "classifier-v1+reference" and hybrid.use_reference == "first"
    assert hybrid.alarm_threshold == alone.alarm_threshold


def test_ppo_v1_is_pure_rl_on_v1_within_budget():
    cfg = _cfg("ppo-v1")
    assert cfg["env_id"] == "MarineFDI-v1" and cfg["reward"] == RewardConfigV1().to_dict()
    assert cfg["observation"]["reference_features"] is False  # the observation features only
    assert cfg["action_mode"] == "gated" and cfg["features"]["drop"] == ["time_fraction"]
    assert cfg["features"]["previous_alarm"] is True and cfg["features"]["taus"] == [5.0, 20.0, 60.0]
    assert cfg["machine"]["cpus"] == 2
    # the command that made the model (remeasured after the layout move: the same weights, bit for bit)
    assert cfg["command"] == (
        "python -m marine_fdi_env.training.train --algo ppo --env MarineFDI-v1 --seed 0 "
        "--out training/models/ppo --no-cache"
    )
    assert (MODELS / "ppo-v1" / "learning_curve.png").is_file()
    agent = load_agent(str(MODELS / "ppo-v1"))
    assert agent.features is not None and not agent.with_reference and agent.action_mode == "gated"
    assert agent.features.noise_window == 0 and agent.name == "ppo-v1"


def test_ppo_v1_training_was_within_the_30_cpu_minute_budget():
    """The budget, data simulation included (the training measures its own CPU time)."""
    cfg = _cfg("ppo-v1")
    assert cfg["cpu_minutes"] <= 30.0 and cfg["cpu_s"] == pytest.approx(60 * cfg["cpu_minutes"], abs=1.0)
    assert cfg["cpu_s_data"] > 0  # simulating the training episodes is part of the budget (counted from a cache too)


def test_robust_classifier_seeds_are_one_command_within_budget():
    """The noise-invariant classifier: seeds 0-2 of one hyperparameter entry, each within 30 CPU minutes
    (data simulation and calibrations included), with noise-scaled inputs and conformal isolation."""
    cfgs = [_cfg(f"classifier/seed{s}") for s in (0, 1, 2)]
    for s, cfg in enumerate(cfgs):
        assert cfg["name"] == "classifier" and cfg["seed"] == s and cfg["hyperparams_entry"] == "robust"
        assert (
            cfg["command"] == f"marine-fdi train --algo classifier --hyperparams robust --seed {s} "
            f"--out training/models/classifier/seed{s}"
        )
        assert cfg["cpu_minutes"] <= 30.0 and cfg["cpu_s_data"] > 0
        assert cfg["features"]["noise_window"] == 4 and cfg["declaration"]["isolation_conformal"]["alpha"] == 0.05
        assert sorted({x for d in cfg["datasets"] for x in d["noise_scales"]}) == [0.5, 0.75, 1.0, 1.25, 1.5]
        # two fault-pair exports of 1024 episodes each, with their own seeds (no episode twice)
        pairs = [d for d in cfg["datasets"] if d["preset"] == "multi"]
        assert [d["episodes"] for d in pairs] == [1024, 1024] and len({d["seed"] for d in pairs}) == 2
    assert all(c["hyperparams"] == cfgs[0]["hyperparams"] for c in cfgs)  # the same command, seed aside
    agent = load_agent(str(MODELS / "classifier"))  # the folder: its default seed
    assert agent.name == "classifier" and agent.training_seed == 0


def test_robust_ppo_seeds_are_one_command_within_budget():
    """The noise-invariant PPO: seeds 0-2 of one hyperparameter entry, each within 30 CPU minutes (its replayed
    episodes' simulation counted), on the noise-scaled inputs of the robust classifier."""
    cfgs = [_cfg(f"ppo/seed{s}") for s in (0, 1, 2)]
    for s, cfg in enumerate(cfgs):
        assert cfg["seed"] == s and cfg["hyperparams_entry"] == "robust" and cfg["algo"] == "ppo"
        assert (
            cfg["command"]
            == f"marine-fdi train --algo ppo --hyperparams robust --seed {s} --out training/models/ppo/seed{s}"
        )
        assert cfg["cpu_minutes"] <= 30.0 and cfg["cpu_s_data"] > 0
        assert cfg["features"]["noise_window"] == 4
        # a supervised start on the training episodes' ground truth, then PPO, then the alarm quiet before
        # every training onset (training/pretrain.py): no false alarm on its own held-in episodes
        assert cfg["hyperparams"]["pretrain"]["epochs"] == 4 and cfg["hyperparams"]["final_alarm_margin"] == 1.0
        assert cfg["pretraining"]["decisions_before_onset"] == cfg["final_alarm"]["decisions_before_onset"] > 0
        assert cfg["validation"]["val_false_alarm_episodes"] == 0
    assert all(c["hyperparams"] == cfgs[0]["hyperparams"] for c in cfgs)  # the same command, seed aside
    agent = load_agent(str(MODELS / "ppo"))  # the folder: its default seed
    assert agent.name == "ppo" and agent.training_seed == 0


# ----------------------------------------------------------------------------- the shipped models score as recorded
RESULTS = ROOT / "docs" / "data" / "results"
# (model folder, agent name, its results files' stem): one file per training seed of a multi-seed agent
SHIPPED = [
    ("ppo-v1", "ppo-v1", "ppo-v1"),
    ("classifier-v1", "classifier-v1", "classifier-v1"),
    ("classifier-v1+reference", "classifier-v1+reference", "classifier-v1+reference"),
] + [(f"{a}/seed{s}", a, f"{a}_s{s}") for a in ("classifier", "ppo") for s in (0, 1, 2)]


@pytest.mark.parametrize("folder,name,stem", SHIPPED)
def test_a_shipped_model_scores_a_few_episodes_as_recorded(folder, name, stem):
    """CI never retrains: every shipped model loads and declares, on the first episodes of two suites,
    exactly what its recorded results (docs/data/results, written by studies.agents.compare) hold."""
    from marine_fdi_env.benchmark.evaluate import run_episodes, suite_env_kwargs
    from marine_fdi_env.benchmark.suites import load_suite

    agent = load_agent(str(MODELS / folder))
    assert agent.name == name
    for suite_name in ("single-v1", "transfer-v3"):
        recorded = json.loads((RESULTS / f"{stem}_{suite_name}.json").read_text())
        assert recorded["agent"] == name and recorded["training_seed"] == agent.training_seed
        suite = load_suite(suite_name)
        env_kwargs, _ = suite_env_kwargs(suite, None if suite["env"].get("reward") else "v1")
        got = run_episodes(agent, suite.scenarios[:2], env_kwargs, suite=suite_name)
        for g, r in zip(got, recorded["episodes"][:2], strict=True):
            assert g["scenario_id"] == r["scenario_id"]
            assert g["declared_changes"] == r["declared_changes"], (folder, suite_name, g["scenario_id"])
            assert g["return"] == pytest.approx(r["return"], abs=1e-9)  # the same decisions: the same sum
