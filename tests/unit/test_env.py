"""MarineFDI-v0: API conformance, reproducibility, vector/single equality, bad input."""

from __future__ import annotations

import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest

import marine_fdi_env  # noqa: F401  (registers the environment)
from marine_fdi_env.envs.fdi_env import MarineFDIEnv
from marine_fdi_env.envs.hypotheses import HYPOTHESES, N_HYPOTHESES, one_hot
from marine_fdi_env.envs.scenario_sampler import PRESETS, ScenarioConfig, ScenarioSpec
from marine_fdi_env.envs.vector import MarineFDIVectorEnv
from marine_fdi_env.envs.wrappers import DiscreteHypothesis

# this module is about MarineFDI-v0, whose making Gymnasium flags as out of date beside v1: said once here
pytestmark = pytest.mark.filterwarnings("ignore:.*MarineFDI-v0 is out of date:DeprecationWarning")

# short episodes keep the suite fast; every fault kind, 0-2 faults, all profile families
SHORT = ScenarioConfig(
    name="short",
    duration_s=20.0,
    onset_range_s=(2.0, 12.0),
    second_onset_gap_s=(0.0, 4.0),
    profiles=(("constant", 1.0), ("step", 1.0), ("ramp", 1.0), ("random", 1.0), ("manoeuvring", 1.0)),
    sensor_kinds=tuple((k, 1.0) for k in ("offset", "drift", "stuck", "gain", "precision")),
    magnitude_range=(2.0, 8.0),
)
STALL = ScenarioSpec(faults=("valve_seizing@3:0.97,kappa=inf",), profile="constant", noise_seed=5, duration_s=20.0)


def rollout(env, seed, steps, policy=None, options=None):
    obs, info = env.reset(seed=seed, options=options)
    out = [(obs.copy(), None, None, None, info["true_faults"])]
    for k in range(steps):
        a = policy(obs, info) if policy else np.full(N_HYPOTHESES, 0.0, np.float32)
        obs, r, term, trunc, info = env.step(a)
        out.append((obs.copy(), r, term, trunc, info["reward_terms"]))
        if term or trunc:
            obs, info = env.reset()
            out.append((obs.copy(), None, None, None, info["true_faults"]))
    return out


def reference_policy(obs, info):
    ref = info["reference"]
    if not ref["detected"]:
        return np.zeros(N_HYPOTHESES, np.float32)
    return one_hot(ref["diagnoses"][0]) if len(ref["diagnoses"]) == 1 else one_hot(["unknown"])


def test_gymnasium_env_checker_passes_without_warnings():
    from gymnasium.utils.env_checker import check_env

    env = gym.make("marine_fdi_env:MarineFDI-v0", scenario_config=SHORT)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped)


def test_stable_baselines3_env_checker_passes_without_warnings():
    # One warning is allowed, and only this one: SB3 recommends a symmetric Box action space in
    # [-1, 1].  Our action is a belief per hypothesis, in [0, 1] by meaning (declared at >= 0.5,
    # "share of belief on the truth" is a metric), and every non-learned agent speaks it; learned
    # agents wrap the env in gymnasium.wrappers.RescaleAction(env, -1, 1), checked below to be
    # warning-free.
    sb3_checker = pytest.importorskip("stable_baselines3.common.env_checker")
    env = MarineFDIEnv(scenario_config=SHORT)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sb3_checker.check_env(env, warn=True)
    messages = [str(w.message) for w in caught]
    assert all("symmetric and normalized Box action space" in m for m in messages), messages
    assert len(messages) == 1
    rescaled = gym.wrappers.RescaleAction(MarineFDIEnv(scenario_config=SHORT), np.float32(-1.0), np.float32(1.0))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sb3_checker.check_env(rescaled, warn=True)


def test_make_and_make_vec_work():
    env = gym.make("marine_fdi_env:MarineFDI-v0", scenario_config="nominal")
    assert env.observation_space.shape == (115,) and env.action_space.shape == (28,)
    envs = gym.make_vec(
        "marine_fdi_env:MarineFDI-v0", num_envs=3, vectorization_mode="vector_entry_point", scenario_config=SHORT
    )
    assert isinstance(envs.unwrapped, MarineFDIVectorEnv)
    obs, infos = envs.reset(seed=1)
    assert obs.shape == (3, 115) and obs.dtype == np.float32
    obs, r, term, trunc, infos = envs.step(np.zeros((3, 28), np.float32))
    assert r.shape == (3,) and infos["t_s"].tolist() == pytest.approx([2.0, 2.0, 2.0])


def assert_same_info(infos: dict, i: int, info: dict, where: str) -> None:
    """Sub-env i's entries of vector infos equal a single env's info (None: engine -1 / NaN)."""
    assert {k for k in infos if not k.startswith("_") and infos["_" + k][i]} == set(info), where
    for key, v in info.items():
        got = (
            infos[key][i]
            if not isinstance(infos[key], dict)
            else {k: infos[key][k][i] for k in infos[key] if not k.startswith("_")}
        )
        if key == "engine_failure" and v is None:
            assert got["engine"] == -1 and np.isnan(got["time_s"]) and got["reason"] == "", where
        elif key == "engine_failure":  # "engine" is the sub-env index (0 in a single env)
            assert got == dict(v, engine=i), f"{where}: {got!r} != {v!r}"
        elif key == "belief_on_truth" and v is None:
            assert np.isnan(got), where
        else:
            assert got == v, f"{where}: {key} {got!r} != {v!r}"


def test_two_envs_with_one_seed_are_bit_identical():
    from gymnasium.utils.env_match import check_environments_match

    a = MarineFDIEnv(scenario_config=SHORT)
    b = MarineFDIEnv(scenario_config=SHORT)
    check_environments_match(a, b, num_steps=45, seed=11, skip_render=True)


def test_vector_env_equals_single_envs_seeded_seed_plus_i():
    # 45 steps of 20 s episodes cross two autoresets per sub-env; sub-env 2 runs the stalling
    # scenario first (terminated early), so slots restart at different times.
    n, seed, steps = 3, 40, 45
    venv = MarineFDIVectorEnv(num_envs=n, scenario_config=SHORT)
    singles = [MarineFDIEnv(scenario_config=SHORT) for _ in range(n)]
    first = [SHORT.sample(int(np.random.default_rng(seed + i).integers(0, 2**63 - 1))) for i in range(n)]
    first[2] = STALL
    obs, infos = venv.reset(seed=seed, options={"scenarios": first})
    s_obs = []
    for i, env in enumerate(singles):
        o, info = env.reset(seed=seed + i, options={"scenario": first[i]})
        assert_same_info(infos, i, info, f"reset env {i}")
        s_obs.append(o)
    assert np.array_equal(obs, np.stack(s_obs))
    pending = [False] * n
    ended = 0
    for k in range(steps):
        actions = np.stack(
            [reference_policy(None, {"reference": venv.batch.reference_declaration(i)}) for i in range(n)]
        )
        obs, r, term, trunc, infos = venv.step(actions)
        for i, env in enumerate(singles):
            if pending[i]:
                o, info = env.reset()
                assert_same_info(infos, i, info, f"autoreset step {k} env {i}")
                pending[i] = False
                assert r[i] == 0.0 and not term[i] and not trunc[i]
            else:
                o, ri, ti, tri, info = env.step(actions[i])
                assert (r[i], term[i], trunc[i]) == (ri, ti, tri), f"step {k} env {i}"
                assert_same_info(infos, i, info, f"step {k} env {i}")
                pending[i] = ti or tri
                ended += ti or tri
            assert np.array_equal(obs[i], o), f"step {k} env {i}"
    assert ended >= 5  # episodes really ended and restarted (one of them by engine failure)


def test_pickled_env_continues_identically():
    env = MarineFDIEnv(scenario_config=SHORT)
    env.reset(seed=5)
    for _ in range(4):
        env.step(np.zeros(N_HYPOTHESES, np.float32))
    clone = pickle.loads(pickle.dumps(env))
    for _ in range(30):
        a = env.action_space.sample()
        o1, r1, t1, tr1, _ = env.step(a)
        o2, r2, t2, tr2, _ = clone.step(a)
        assert np.array_equal(o1, o2) and r1 == r2 and (t1, tr1) == (t2, tr2)
        if t1 or tr1:
            break


def test_engine_failure_terminates_with_reason():
    env = MarineFDIEnv(scenario_config=SHORT)
    env.reset(seed=0, options={"scenario": STALL})
    for _ in range(20):
        obs, r, term, trunc, info = env.step(np.zeros(N_HYPOTHESES, np.float32))
        assert np.all(np.isfinite(obs))
        if term:
            break
    assert term and not trunc
    assert "stall" in info["termination_reason"] and info["engine_failure"]["time_s"] > 3.0
    with pytest.raises(RuntimeError, match="reset"):
        env.step(np.zeros(N_HYPOTHESES, np.float32))


def test_episode_length_and_info_ground_truth():
    sc = ScenarioSpec(faults=("S4.2@5:3e4",), profile="constant", noise_seed=3, duration_s=10.0)
    env = MarineFDIEnv(scenario_config=SHORT)
    obs, info = env.reset(seed=0, options={"scenario": sc})
    assert info["t_s"] == pytest.approx(1.0) and info["active_faults"] == []
    assert info["true_faults"] == [{"id": "S4.2", "class": "sensor", "onset_s": 5.0, "magnitude": 3e4, "end_s": None}]
    steps = 0
    while True:
        obs, r, term, trunc, info = env.step(one_hot(["S4.2"]))
        steps += 1
        t = info["decision_time_s"]
        if t < 5.0:  # declaring a fault before it exists is a false alarm
            assert info["reward_terms"]["false_alarm"] == -1.0 and r < 0
        else:
            assert info["reward_terms"]["isolation"] > 0 and info["belief_on_truth"] == 1.0
        if term or trunc:
            break
    assert steps == 10 and trunc and info["t_s"] == pytest.approx(10.0)


def test_reward_for_correct_isolation_decays_with_delay():
    sc = ScenarioSpec(faults=("S4.2@2:3e4",), profile="constant", noise_seed=3, duration_s=12.0)
    env = MarineFDIEnv(scenario_config=SHORT)
    env.reset(seed=0, options={"scenario": sc})
    iso = []
    for _ in range(12):
        *_, trunc, info = env.step(one_hot(["S4.2"]))
        if info["decision_time_s"] >= 2.0:
            iso.append(info["reward_terms"]["isolation"])
    assert iso[0] == pytest.approx(1.0) and all(a > b for a, b in zip(iso, iso[1:]))
    assert iso[-1] == pytest.approx(np.exp(-(12.0 - 2.0) / 30.0))


@pytest.mark.parametrize(
    "action, match",
    [
        (np.zeros(27, np.float32), "shape"),
        (np.zeros((1, 28), np.float32), "shape"),
        (np.array(["a"] * 28), "dtype"),
        (np.full(28, 2.0, np.float32), r"\[0, 1\]"),
        (np.full(28, np.nan, np.float32), "finite"),
    ],
)
def test_bad_actions_raise_value_error(action, match):
    env = MarineFDIEnv(scenario_config=SHORT)
    env.reset(seed=0)
    with pytest.raises(ValueError, match=match):
        env.step(action)


@pytest.mark.parametrize(
    "scenario, match",
    [
        ({"faults": ["S9.9@3"]}, "unknown fault id"),
        ({"faults": [{"fault_id": "bore_damage", "onset_s": 3.0, "magnitude": -1.0}]}, "magnitude"),
        ({"faults": ["S4.2@30"], "duration_s": 20.0}, "onset"),
        ({"faults": ["S4.2@3", "S4.2@5"]}, "faults"),
        ({"noise_seed": -1}, "noise_seed"),
        ({"profile": "warp"}, "profile"),
        ({"colour": "red"}, "colour"),
    ],
)
def test_bad_scenarios_raise_value_error_naming_the_field(scenario, match):
    env = MarineFDIEnv(scenario_config=SHORT)
    with pytest.raises(ValueError, match=match):
        env.reset(seed=0, options={"scenario": scenario})


@pytest.mark.parametrize(
    "field, value",
    [
        ("magnitude_range", (-1.0, 2.0)),
        ("onset_range_s", (10.0, 400.0)),
        ("fault_ids", ("S1.1", "nope")),
        ("fault_count_weights", (0.0, 0.0, 0.0)),
        ("profiles", (("warp", 1.0),)),
        ("duration_s", -5.0),
    ],
)
def test_bad_scenario_config_raises_value_error_naming_the_field(field, value):
    with pytest.raises(ValueError, match=field):
        ScenarioConfig(**{field: value})


def test_sampler_components_are_independent_seed_sequence_children():
    # Changing how one component is drawn must not change the others.
    a = PRESETS["default"]
    b = ScenarioConfig(name="other-profiles", profiles=(("manoeuvring", 1.0),))
    for entropy in range(20):
        x, y = a.sample(entropy), b.sample(entropy)
        assert x.faults == y.faults and x.noise_seed == y.noise_seed and x.magnitude_scales == y.magnitude_scales
        assert y.profile.startswith("manoeuvring")
    assert len({a.sample(e).noise_seed for e in range(20)}) == 20
    counts = [len(a.sample(e).faults) for e in range(200)]
    assert {0, 1, 2} <= set(counts)


def test_scenario_round_trips_through_json():
    import json

    sc = SHORT.sample(123, scenario_id="x")
    again = ScenarioSpec.from_dict(json.loads(json.dumps(sc.to_dict())))
    assert again == sc


def test_discrete_wrapper_declares_one_hypothesis():
    env = DiscreteHypothesis(MarineFDIEnv(scenario_config=SHORT))
    assert env.action_space.n == N_HYPOTHESES
    env.reset(seed=0)
    *_, info = env.step(HYPOTHESES.index("unknown"))
    assert info["alarm"] and info["declared"] == []
    *_, info = env.step(np.int64(HYPOTHESES.index("S2.1")))
    assert info["declared"] == ["S2.1"]
    with pytest.raises(ValueError, match="integer"):
        env.step(28)


def test_compiled_period_statistics_equal_the_numpy_reductions():
    # the observation's per-module statistics come from one compiled pass; they must equal the
    # numpy definitions in the observation docstring bit for bit (inf, NaN, zero thresholds included)
    from marine_fdi_env.diagnosis.peak_ratio import RATIO_CAP, period_stats

    rng = np.random.default_rng(0)
    for B in (1, 7, 100):
        R = rng.normal(size=(20, B, 19)) * rng.choice([1e-3, 1.0, 1e4], size=(20, B, 19))
        THR = np.abs(rng.normal(size=(20, B, 19)))
        R[0, 0, 0], R[1, 0, 1], R[4, 0, 4] = np.inf, np.nan, -np.inf
        R[2, 0, 2] = THR[2, 0, 2] = THR[3, 0, 3] = 0.0
        with np.errstate(invalid="ignore", divide="ignore"):
            signed = R / THR
        signed = np.where(np.isnan(signed), RATIO_CAP, np.clip(signed, -RATIO_CAP, RATIO_CAP))
        ratio = np.abs(signed)
        want = np.stack([ratio.max(axis=1), ratio.mean(axis=1), signed.mean(axis=1), (ratio > 1.0).mean(axis=1)], -1)
        got = np.empty((20, 19, 4))
        period_stats(R, THR, got)
        assert np.array_equal(got, want)
        # the same statistics from the reference diagnoser's one post-processing pass
        from marine_fdi_env.diagnosis.agent import _violations_and_peaks

        viol, peak, fused = np.empty((20, B, 19), dtype=bool), np.empty((20, 19)), np.empty((20, 19, 4))
        _violations_and_peaks(R, THR, viol, peak, fused, 0, 20)
        assert np.array_equal(fused, want)
