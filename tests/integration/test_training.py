"""Smoke tests of the learned diagnosers (training/): tiny seeded runs only, full training stays out of CI."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("stable_baselines3")

from marine_fdi_env.benchmark.agent_api import load_agent  # noqa: E402
from marine_fdi_env.benchmark.evaluate import run_episodes  # noqa: E402
from marine_fdi_env.envs.hypotheses import N_HYPOTHESES  # noqa: E402
from marine_fdi_env.envs.observation import observation_size  # noqa: E402
from marine_fdi_env.envs.scenario_sampler import ScenarioConfig  # noqa: E402
from marine_fdi_env.training.agents import ClassifierAgent, SB3Agent  # noqa: E402
from marine_fdi_env.training.classifier import calibrate_threshold, train_classifier  # noqa: E402
from marine_fdi_env.training.train import _observation_meta, load_hyperparams, save_meta, train_sb3  # noqa: E402
from marine_fdi_env.training.vec_adapter import SB3VecEnv, to_belief  # noqa: E402
from tests.paths import ROOT  # noqa: E402

# fault-free 12 s episodes: no dependence on the detectability table, and episode ends happen
SHORT = ScenarioConfig(
    name="short", duration_s=12.0, fault_count_weights=(1.0, 0.0, 0.0), onset_range_s=(2.0, 5.0)
).to_dict()
NF = observation_size(False)  # features per decision (module features + clock)
TINY = dict(
    n_envs=2,
    n_timesteps=48,
    n_steps=12,
    batch_size=24,
    n_epochs=1,
    scenario_config=SHORT,
    policy_kwargs="dict(net_arch=[16])",
)


def _params(model) -> list[np.ndarray]:
    return [p.detach().cpu().numpy().copy() for p in model.policy.parameters()]


def test_adapter_autoreset_and_actions():
    env = SB3VecEnv(2, scenario_config=SHORT, action_mode="box", seed=3)
    obs = env.reset()
    assert obs.shape == (2, NF) and obs.dtype == np.float32
    for k in range(12):
        obs, rew, done, infos = env.step(np.full((2, N_HYPOTHESES), -1.0, dtype=np.float32))
        assert obs.shape == (2, NF)
    assert done.all() and all("terminal_observation" in i for i in infos)
    assert all(i["TimeLimit.truncated"] for i in infos)
    # the new episodes started at once: time fraction of the first decision period
    assert np.allclose(obs[:, -1], 1.0 / 12.0, atol=1e-6)
    b = to_belief(np.array([[-1.0] * 27 + [1.0]]), "box")
    assert b[0, -1] == 1.0 and b[0, 0] == 0.0
    d = to_belief(np.array([26, 0]), "discrete")
    assert d[0, 26] == 1.0 and d[1, 0] == 1.0 and d.sum() == 2.0
    with pytest.raises(ValueError, match="action_mode"):
        SB3VecEnv(1, scenario_config=SHORT, action_mode="multi")
    # env_method reaches the shared batched env once, one result per index
    drawn = env.env_method("_draw", 0, indices=[0, 1])
    assert len(drawn) == 2 and drawn[0] is drawn[1] and drawn[0].duration_s == 12.0
    with pytest.raises(ValueError, match="no method"):
        env.env_method("fly")


def test_ppo_same_seed_same_weights(tmp_path):
    hp = load_hyperparams("ppo", overrides=TINY)
    m1, cfg = train_sb3("ppo", 7, hp, tmp_path / "a", log=None)
    m2, _ = train_sb3("ppo", 7, hp, None, log=None)
    m3, _ = train_sb3("ppo", 8, hp, None, log=None)
    for a, b in zip(_params(m1), _params(m2)):
        np.testing.assert_array_equal(a, b)
    assert any(not np.array_equal(a, b) for a, b in zip(_params(m1), _params(m3)))
    assert (tmp_path / "a" / "model.zip").is_file() and (tmp_path / "a" / "learning_curve.csv").is_file()
    assert cfg["seed"] == 7 and cfg["observation"]["size"] == NF


def test_recurrent_ppo_smoke_and_agent(tmp_path):
    pytest.importorskip("sb3_contrib")
    hp = load_hyperparams("ppo_lstm", overrides=dict(TINY, policy_kwargs="dict(lstm_hidden_size=8)"))
    out = tmp_path / "lstm"
    _, cfg = train_sb3("ppo_lstm", 1, hp, out, log=None)
    save_meta(out, cfg, "marine_fdi_env.training.agents:SB3Agent")
    agent = load_agent(str(out))
    assert isinstance(agent, SB3Agent)
    recs = run_episodes(agent, [ScenarioConfig.from_dict(SHORT).sample(5, scenario_id="x")])
    assert recs[0]["duration_s"] == 12.0


def test_frame_stacked_ppo_agent(tmp_path):
    hp = load_hyperparams("ppo", overrides=dict(TINY, frame_stack=3, action_mode="box"))
    out = tmp_path / "fs"
    _, cfg = train_sb3("ppo", 2, hp, out, log=None)
    save_meta(out, cfg, "marine_fdi_env.training.agents:SB3Agent")
    agent = load_agent(str(out))
    assert agent.frame_stack == 3 and agent.model.observation_space.shape == (3 * NF,)
    rec = run_episodes(agent, [ScenarioConfig.from_dict(SHORT).sample(6, scenario_id="y")])[0]
    assert rec["duration_s"] == 12.0


def test_reference_features_from_infos_and_ppo_agent_reading_them(tmp_path):
    from marine_fdi_env.training.vec_adapter import N_REFERENCE_FEATURES, reference_features

    ref = {
        "detected": np.array([False, True, True]),
        "diagnoses": np.array([[], [["S3.4"], ["S3.2"]], [["S1.1", "bore_damage"]]], dtype=object),
    }
    f = reference_features(ref, 3)
    assert f.shape == (3, 27) and not f[0].any()
    assert f[1, 0] == 1 and f[1, 1 + 11] == 0.5 and f[1, 1 + 9] == 0.5 and f[1].sum() == 2.0  # S3.4, S3.2
    assert f[2, 1 + 0] == 1.0 and f[2, 1 + 20] == 1.0  # S1.1 and bore_damage in the one diagnosis
    hp = load_hyperparams("ppo", overrides=dict(TINY, reference_features=True))
    out = tmp_path / "ref"
    _, cfg = train_sb3("ppo", 4, hp, out, log=None)
    save_meta(out, cfg, "marine_fdi_env.training.agents:SB3Agent")
    agent = load_agent(str(out))
    assert agent.with_reference and agent.model.observation_space.shape == (NF + N_REFERENCE_FEATURES,)
    rec = run_episodes(agent, [ScenarioConfig.from_dict(SHORT).sample(8, scenario_id="r")])[0]
    assert rec["duration_s"] == 12.0


def _tiny_data() -> dict:
    rng = np.random.default_rng(0)
    obs = rng.random((6, 10, NF)).astype(np.float32)
    active = np.zeros((6, 10, 26), dtype=bool)
    active[:3, 5:, 4] = True
    return {"obs": obs, "active": active, "valid": np.ones((6, 10), dtype=bool)}


def test_classifier_cosine_schedule_starts_at_the_learning_rate_and_anneals_it():
    """Epoch 1 runs at ``lr`` under both schedules (the same weights after it, bit for bit: one minibatch
    per epoch here, whose loss is measured before its step); epoch 2's smaller cosine rate gives other
    weights, so epoch 3's loss differs; an unknown schedule is refused by name."""
    data = _tiny_data()
    const = train_classifier(data, seed=0, hidden=8, embed=8, epochs=3, log=None)
    cosine = train_classifier(data, seed=0, hidden=8, embed=8, epochs=3, lr_schedule="cosine", log=None)
    assert const.curve[1]["train_loss"] == cosine.curve[1]["train_loss"]
    assert const.curve[2]["train_loss"] != cosine.curve[2]["train_loss"]
    w_const, w_cos = const.model.state_dict()["head.weight"], cosine.model.state_dict()["head.weight"]
    assert not torch.equal(w_const, w_cos)
    with pytest.raises(ValueError, match="lr_schedule must be 'constant' or 'cosine'"):
        train_classifier(data, seed=0, hidden=8, embed=8, epochs=1, lr_schedule="step", log=None)


def _tiny_classifier(tmp_path) -> Path:
    data = _tiny_data()
    r1 = train_classifier(data, seed=0, hidden=8, embed=8, epochs=2, log=None)
    r2 = train_classifier(data, seed=0, hidden=8, embed=8, epochs=2, log=None)
    for (k, a), (_, b) in zip(r1.model.state_dict().items(), r2.model.state_dict().items()):
        assert torch.equal(a, b), k
    out = tmp_path / "clf"
    out.mkdir()
    torch.save(r1.model.state_dict(), out / "model.pt")
    cfg = {
        "name": "classifier",
        "algo": "classifier",
        "observation": _observation_meta(),
        "architecture": {"kind": "gru", "n_features": NF, "hidden": 8, "embed": 8},
        "declaration": {"alarm_threshold": 0.99, "isolation_threshold": 0.5},
    }
    save_meta(out, cfg, "marine_fdi_env.training.agents:ClassifierAgent")
    return out


def test_classifier_seeded_and_agent(tmp_path):
    out = _tiny_classifier(tmp_path)
    agent = load_agent(str(out))
    assert isinstance(agent, ClassifierAgent)
    agent.reset([0, 1])
    b = agent.act(np.zeros((2, NF), dtype=np.float32), {})
    assert b.shape == (2, N_HYPOTHESES) and b.dtype == np.float32


def test_calibration_threshold_above_fault_free_peaks():
    p = np.array([[0.1, 0.3, 0.2], [0.05, 0.6, 0.1]])
    cal = calibrate_threshold(p, np.ones_like(p, dtype=bool), margin=0.0)
    assert cal["alarm_threshold"] == pytest.approx(0.6)
    assert calibrate_threshold(p, np.ones_like(p, dtype=bool), margin=1.0)["alarm_threshold"] > 0.6


def test_model_loading_errors(tmp_path):
    out = _tiny_classifier(tmp_path)
    # missing weights
    bad = tmp_path / "missing"
    shutil.copytree(out, bad)
    (bad / "model.pt").unlink()
    with pytest.raises(ValueError, match=r"model\.pt: missing"):
        load_agent(str(bad))
    # corrupt weights
    bad = tmp_path / "corrupt"
    shutil.copytree(out, bad)
    (bad / "model.pt").write_bytes(b"\x00garbage" * 10)
    with pytest.raises(ValueError, match=r"model\.pt: corrupt"):
        load_agent(str(bad))
    # another observation space (the sensor features too, observe_sensors=True)
    bad = tmp_path / "other_space"
    shutil.copytree(out, bad)
    cfg = json.loads((bad / "config.json").read_text())
    cfg["observation"] = _observation_meta(True)
    cfg["observation"]["observe_sensors"] = False
    (bad / "config.json").write_text(json.dumps(cfg))
    with pytest.raises(ValueError, match=r"config\.json: model made for another observation space"):
        load_agent(str(bad))
    # missing / corrupt SB3 archive
    bad = tmp_path / "sb3"
    bad.mkdir()
    save_meta(
        bad,
        {"algo": "ppo", "action_mode": "discrete", "observation": _observation_meta()},
        "marine_fdi_env.training.agents:SB3Agent",
    )
    with pytest.raises(ValueError, match=r"model\.zip: missing"):
        load_agent(str(bad))
    (bad / "model.zip").write_bytes(b"PK\x03\x04 not really a zip")
    with pytest.raises(ValueError, match=r"model\.zip: corrupt"):
        load_agent(str(bad))
    # corrupt config
    (bad / "config.json").write_text("{not json")
    with pytest.raises(ValueError, match=r"config\.json: not a readable model config"):
        load_agent(str(bad))


@pytest.mark.parametrize("name", ["classifier-v1", "ppo-v1"] + [f"classifier/seed{s}" for s in (0, 1, 2)])
def test_shipped_models_load(name):
    d = ROOT / "training" / "models" / name
    assert (d / "agent.json").is_file(), f"{d} is not shipped"
    agent = load_agent(str(d))
    agent.reset([0, 1])
    b = agent.act(
        np.zeros((2, NF), dtype=np.float32), {"reference": {"detected": np.zeros(2, bool), "diagnoses": [[], []]}}
    )
    assert b.shape == (2, N_HYPOTHESES)
    cfg = json.loads((d / "config.json").read_text())
    # the command recorded when the shipped model was made (older spellings of `marine-fdi train`)
    assert cfg["command"].split(" --")[0] in (
        "python -m training.train",
        "python -m marine_fdi_env.training.train",
        "marine-fdi train",
    )


def test_classifier_ewma_inputs_streaming_equals_episode():
    """The EWMA inputs of the signed means are causal: one decision at a time gives the whole-episode logits."""
    from marine_fdi_env.envs.observation import feature_names
    from marine_fdi_env.training.classifier import GRUDiagnoser

    names = feature_names(False)
    idx = [i for i, n in enumerate(names) if n.endswith(".signed_mean_ratio")]
    assert len(idx) == 19
    torch.manual_seed(0)
    m = GRUDiagnoser(NF, hidden=8, embed=8, ewma_idx=idx, ewma_taus=(5.0, 20.0)).eval()
    assert m.n_inputs == NF + 2 * 19
    x = torch.randn(3, 7, NF)
    xa, _ = m.augment(x)
    # the first EWMA input of the first signed feature: s_t = s_{t-1} + (x_t - s_{t-1}) / 5, s_{-1} = 0
    s, ref = 0.0, []
    for t in range(7):
        s = s + (float(x[0, t, idx[0]]) - s) / 5.0
        ref.append(s)
    np.testing.assert_allclose(xa[0, :, NF].numpy(), ref, rtol=1e-5, atol=1e-6)
    with torch.no_grad():
        whole, _ = m(x)
        h, steps = None, []
        for t in range(7):
            y, h = m(x[:, t : t + 1], h)
            steps.append(y)
    torch.testing.assert_close(torch.cat(steps, 1), whole, rtol=1e-5, atol=1e-5)


def test_make_vec_env_works_unchanged_and_the_gated_wrapper_declares():
    """SB3's make_vec_env asks for render_mode="rgb_array": the env warns and renders nothing."""
    import warnings

    from stable_baselines3.common.env_util import make_vec_env

    from marine_fdi_env.envs.wrappers import GatedAction

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        venv = make_vec_env("marine_fdi_env:MarineFDI-v1", n_envs=2, seed=0, env_kwargs={"scenario_config": SHORT})
    assert any("rendering is off" in str(w.message) for w in caught)
    assert venv.reset().shape == (2, NF) and venv.render_mode is None
    with warnings.catch_warnings(record=True) as caught:  # the same render_mode warning, said once above
        warnings.simplefilter("always")
        gated = make_vec_env(
            "marine_fdi_env:MarineFDI-v1",
            n_envs=2,
            seed=0,
            wrapper_class=GatedAction,
            env_kwargs={"scenario_config": SHORT},
        )
    assert any("rendering is off" in str(w.message) for w in caught)
    gated.reset()
    _, rew, _, infos = gated.step(np.array([[0, 5, 9], [1, 0, 0]]))  # quiet; alarm with no fault named
    assert infos[0]["declared"] == [] and not infos[0]["alarm"]
    assert infos[1]["declared"] == [] and infos[1]["alarm"]  # unknown: the alarm, no fault
    assert rew[1] < 0 == rew[0]  # a false alarm on a fault-free episode costs, quiet costs nothing here
    _, _, _, infos = gated.step(np.array([[1, 3, 0], [1, 3, 21]]))  # one fault; a pair
    assert infos[0]["declared"] == ["S2.1"] and infos[1]["declared"] == ["S2.1", "bore_damage"]  # 1 + k = fault k
    with pytest.raises(ValueError, match="3 integers"):
        GatedAction(gymnasium_env()).action(np.array([2, 0, 0]))


def gymnasium_env():
    import gymnasium

    return gymnasium.make("marine_fdi_env:MarineFDI-v1", scenario_config=SHORT)


def test_save_sb3_agent_makes_an_agent_that_evaluates(tmp_path):
    from stable_baselines3 import PPO

    from marine_fdi_env.training import SB3VecEnv as Exported
    from marine_fdi_env.training import save_sb3_agent

    assert Exported is SB3VecEnv
    venv = SB3VecEnv(2, scenario_config=SHORT, action_mode="gated", reference_features=True, seed=0)
    model = PPO(
        "MlpPolicy", venv, n_steps=12, batch_size=24, n_epochs=1, seed=0, device="cpu", policy_kwargs={"net_arch": [8]}
    )
    model.learn(24)
    folder = save_sb3_agent(model, tmp_path / "mine")
    cfg = json.loads((folder / "config.json").read_text())
    assert cfg["name"] == "mine" and cfg["action_mode"] == "gated" and cfg["observation"]["reference_features"]
    agent = load_agent(str(folder))
    recs = run_episodes(agent, [ScenarioConfig.from_dict(SHORT).sample(1, scenario_id="x")], {"scenario_config": SHORT})
    assert recs[0]["agent"] == "mine" and recs[0]["n_decisions"] == 12
    # the saved agent acts as the policy does on the adapter's inputs (observation + reference features)
    from marine_fdi_env.training.vec_adapter import reference_features

    raw, infos = venv.venv.reset(seed=5)
    x = np.concatenate([raw, reference_features(infos["reference"], len(raw))], axis=1)
    agent.reset([0, 1])
    assert np.array_equal(agent.act(raw, infos), to_belief(model.predict(x, deterministic=True)[0], "gated"))


def test_progress_line_prints_progress_and_changes_nothing_in_the_training():
    """The README block's ProgressLine: lines with the steps done of the total, and the same policy as without it."""
    import io

    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import VecNormalize

    from marine_fdi_env.training import ProgressLine

    def trained(callback):
        torch.set_num_threads(1)
        venv = SB3VecEnv(num_envs=4, scenario_config=SHORT, action_mode="gated", reference_features=True, seed=0)
        model = PPO("MlpPolicy", VecNormalize(venv, norm_obs=False, gamma=0.5), n_steps=16, batch_size=32,
                    n_epochs=2, gamma=0.5, seed=0, device="cpu")  # fmt: skip
        model.learn(total_timesteps=128, callback=callback)
        return torch.cat([p.detach().flatten() for p in model.policy.parameters()])

    stream = io.StringIO()
    with_line = trained(ProgressLine(every_s=1e-6, stream=stream))
    assert torch.equal(with_line, trained(None))
    lines = stream.getvalue().splitlines()
    assert len(lines) >= 2 and lines[-1].startswith("ppo: 128/128 steps (100 %), ")
    assert "reward per decision" in lines[0]  # the mean since the previous line (none after the last)
    with pytest.raises(ValueError, match="every_s"):
        ProgressLine(every_s=0)
