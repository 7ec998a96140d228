"""The reinforcement-learning agent's plumbing: replayed episodes equal the live environment, its
own input preprocessing, a tiny seeded training run, and the shipped model's key settings."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("stable_baselines3")

from marine_fdi_env.benchmark.agent_api import load_agent  # noqa: E402
from marine_fdi_env.benchmark.dataset import export_dataset  # noqa: E402
from marine_fdi_env.benchmark.evaluate import run_episodes  # noqa: E402
from marine_fdi_env.envs.observation import feature_names  # noqa: E402
from marine_fdi_env.envs.scenario_sampler import ScenarioConfig, ScenarioSpec  # noqa: E402
from marine_fdi_env.envs.vector import MarineFDIVectorEnv  # noqa: E402
from marine_fdi_env.training.features import AgentFeatures  # noqa: E402
from marine_fdi_env.training.replay import ReplayVecEnv, load_episodes  # noqa: E402
from marine_fdi_env.training.vec_adapter import to_belief  # noqa: E402

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


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    d = tmp_path_factory.mktemp("rec")
    export_dataset(SCENARIOS, d, {}, progress=False)
    return load_episodes([d])


def test_replayed_episodes_equal_the_live_environment_bit_for_bit(recorded):
    n = len(SCENARIOS)
    live = MarineFDIVectorEnv(num_envs=n, reward="v1")
    lobs, _ = live.reset(options={"scenarios": SCENARIOS})
    rep = ReplayVecEnv(recorded, n, "pair", order="sequential")
    robs = rep.reset()
    assert np.array_equal(lobs, robs)
    rng = np.random.default_rng(0)
    running = np.ones(n, dtype=bool)
    live_return = np.zeros(n)
    for _ in range(25):
        act = np.stack([rng.integers(0, 28, n), rng.integers(0, 27, n)], axis=1)
        act[rng.random(n) < 0.5] = (26, 0)  # quiet half of the time: alarm edges happen
        lobs, lrew, lterm, ltrunc, _ = live.step(to_belief(act, "pair"))
        robs, rrew, rdone, rinfos = rep.step(act)
        live_return += np.where(running, lrew, 0.0)
        for i in np.flatnonzero(running):
            assert np.float32(lrew[i]) == rrew[i], (SCENARIOS[i].scenario_id, lrew[i], rrew[i])  # SB3's float32
            assert bool(lterm[i] or ltrunc[i]) == bool(rdone[i])
            if rdone[i]:
                assert rinfos[i]["TimeLimit.truncated"] == bool(ltrunc[i])
                assert rinfos[i]["episode"]["r"] == live_return[i]  # float64 sums, bit for bit
                if ltrunc[i]:  # (after an engine failure the live env's last observation covers the
                    # failing period, which a dataset does not record; SB3 bootstraps only truncations)
                    assert np.array_equal(rinfos[i]["terminal_observation"], lobs[i])
                running[i] = False
            else:
                assert np.array_equal(lobs[i], robs[i])
    assert not running.any()
    assert rep.lengths[3] < 20  # the stalling engine's episode ended early, as live


def test_agent_features_are_causal_and_restart_per_episode(recorded):
    names = feature_names(False)
    f = AgentFeatures(names)
    assert f.size == len(names) - 1 + 19 * 3 + 1 and "time_fraction" not in [names[i] for i in f.keep]
    obs = recorded["obs"][:2]
    st = f.initial_state(2)
    first = [f.raw(obs[:, k], st) for k in range(5)]
    st2 = f.initial_state(2)
    again = [f.raw(obs[:, k], st2) for k in range(3)]  # a prefix gives the same inputs (causal)
    assert all(np.array_equal(a, b) for a, b in zip(first, again))
    f.restart(st2, [0])
    np.testing.assert_array_equal(f.raw(obs[:, 0], st2)[0], first[0][0])
    f.set_alarm(st2, np.array([True, False]))
    assert f.raw(obs[:, 1], st2)[:, -1].tolist() == [1.0, 0.0]
    g = AgentFeatures.from_dict(f.fit(recorded["obs"], recorded["valid"]).to_dict(), names)
    np.testing.assert_array_equal(g.mean, f.mean)


def test_tiny_replay_ppo_is_seeded_and_runs_as_an_agent(tmp_path, monkeypatch):
    """Seeded, evaluates as an agent, and without ``pretrain`` (every entry but robust) never pretrains."""
    import marine_fdi_env.training.datasets as ds
    import marine_fdi_env.training.pretrain as pre
    from marine_fdi_env.training.rl import train_ppo_replay
    from marine_fdi_env.training.train import load_hyperparams, save_meta

    monkeypatch.setattr(ds, "CACHE", tmp_path / "cache")

    def refuse(*a, **k):
        raise AssertionError("pretraining ran")

    monkeypatch.setattr(pre, "pretrain_policy", refuse)
    short = {"name": "short", "duration_s": 12.0, "onset_range_s": [2.0, 5.0], "second_onset_gap_s": [0.0, 2.0]}
    hp = load_hyperparams(
        "ppo",
        "MarineFDI-v1",
        dict(
            datasets=[{"config": short, "episodes": 6, "seed": 1}],
            n_envs=4,
            n_timesteps=64,
            n_steps=8,
            batch_size=16,
            n_epochs=1,
            eval_every=1,
            validation_fraction=0.34,
            policy_kwargs="dict(net_arch=[16])",
        ),
    )
    m1, cfg = train_ppo_replay(3, hp, tmp_path / "a", log=None)
    m2, _ = train_ppo_replay(3, hp, None, log=None)
    for a, b in zip(m1.policy.parameters(), m2.policy.parameters()):
        assert torch.equal(a, b)
    assert cfg["env_id"] == "MarineFDI-v1" and cfg["validation_episodes"] == 2 and cfg["cpu_s_data"] > 0
    assert "pretraining" not in cfg and "pretrain" not in cfg["hyperparams"] and "final_alarm" not in cfg
    with pytest.raises(AssertionError, match="pretraining ran"):
        train_ppo_replay(3, dict(hp, pretrain={"epochs": 1}), None, log=None)
    assert (tmp_path / "a" / "learning_curve.csv").is_file()
    save_meta(tmp_path / "a", dict(cfg, command="test"), "marine_fdi_env.training.agents:SB3Agent")
    agent = load_agent(str(tmp_path / "a"))
    sc = ScenarioConfig.from_dict({k: tuple(v) if isinstance(v, list) else v for k, v in short.items()})
    rec = run_episodes(agent, [sc.sample(9, scenario_id="x")], {"reward": "v1"})[0]
    assert rec["duration_s"] == 12.0


def test_pretrained_policy_is_quiet_before_every_onset_and_names_the_faults(recorded):
    """The supervised start on recorded episodes: the deterministic policy raises no alarm before
    any onset of them, and ignores its previous-alarm input until PPO trains it."""
    from stable_baselines3 import PPO

    from marine_fdi_env.training.pretrain import gated_targets, policy_inputs, pretrain_policy

    names = feature_names(False)
    f = AgentFeatures(names, noise_window=4).fit(recorded["obs"], recorded["valid"])
    env = ReplayVecEnv(recorded, 2, "gated", features=f)
    model = PPO("MlpPolicy", env, seed=0, device="cpu", policy_kwargs=dict(net_arch=[32]))
    spec = {"epochs": 30, "batch_size": 16, "learning_rate": 3e-3, "alarm_margin": 0.5}
    info = pretrain_policy(model.policy, f, recorded, spec, seed=0)
    assert info["cross_entropy"][-1] < 0.5 * info["cross_entropy"][0]
    valid = recorded["valid"].astype(bool)
    x = torch.as_tensor(policy_inputs(f, recorded["obs"])[valid])
    with torch.no_grad():
        act, _, _ = model.policy(x, deterministic=True)
        x_alarm = x.clone()
        x_alarm[:, -1] = 1.0 / float(f.scale[-1]) * (1.0 - float(f.mean[-1]))  # the previous alarm on
        act_alarm, _, _ = model.policy(x_alarm, deterministic=True)
    act = act.numpy()
    before = (recorded["t_s"] < recorded["first_onset"][:, None])[valid]
    assert info["decisions_before_onset"] == int(before.sum()) > 0
    assert not act[before, 0].any()  # no false alarm on the episodes it was fitted to
    assert np.array_equal(act, act_alarm.numpy())  # the previous alarm does not matter yet
    y = gated_targets(recorded["active"])[valid]
    assert np.mean(act[~before, 1] == y[~before, 1]) > 0.5  # it has learned to name faults
    with pytest.raises(ValueError, match="unknown keys"):
        pretrain_policy(model.policy, f, recorded, {"epoch": 1}, seed=0)


def test_final_alarm_calibration_silences_the_policy_before_every_onset(recorded):
    """After PPO: an alarm-happy policy that also reads its previous alarm raises none before any onset of the
    episodes it is calibrated on, in the replayed environment (its own previous alarm fed back)."""
    from stable_baselines3 import PPO

    from marine_fdi_env.envs.reward import RewardConfigV1
    from marine_fdi_env.training.pretrain import before_onset, final_quiet_alarm
    from marine_fdi_env.training.rl import evaluate_on_episodes

    f = AgentFeatures(feature_names(False), noise_window=4).fit(recorded["obs"], recorded["valid"])
    model = PPO("MlpPolicy", ReplayVecEnv(recorded, 2, "gated", features=f), seed=0, policy_kwargs=dict(net_arch=[32]))
    with torch.no_grad():
        model.policy.action_net.bias[1] += 5.0
        model.policy.mlp_extractor.policy_net[0].weight[:, -1] = 1.0
    scored = evaluate_on_episodes(model, recorded, f, "gated", RewardConfigV1())
    assert scored["val_false_alarm_episodes"] == int(before_onset(recorded).any(axis=1).sum()) == 4  # every one
    info = final_quiet_alarm(model.policy, f, recorded, margin=0.5)
    assert info["alarm_logit_shift"] > 5.0
    assert evaluate_on_episodes(model, recorded, f, "gated", RewardConfigV1())["val_false_alarm_episodes"] == 0
