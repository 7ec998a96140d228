"""The multi-agent track's environments (marine_fdi_env.multiagent): PettingZoo's parallel API test,
full-horizon determinism, the simulation and scoring identical to the single-agent environment's,
the batched form equal to one ParallelEnv per slot, the message budgets and the rewards."""

import numpy as np
import pytest

from marine_fdi_env.envs.fdi_env import MarineFDIEnv
from marine_fdi_env.envs.hypotheses import N_HYPOTHESES, one_hot
from marine_fdi_env.envs.scenario_sampler import ScenarioConfig, ScenarioSpec
from marine_fdi_env.multiagent import BUDGETS, LOCAL_AGENTS, MessageBudget, MultiAgentBatchEnv, parallel_env
from marine_fdi_env.multiagent.batch import visible_faults
from marine_fdi_env.multiagent.roles import local_columns, local_sensors

pytest.importorskip("pettingzoo")

SHORT = ScenarioConfig(
    name="short", duration_s=20.0, onset_range_s=(2.0, 12.0), second_onset_gap_s=(0.0, 4.0), load_range=(0.7, 1.0)
)
STALL = ScenarioSpec(faults=("valve_seizing@3:0.97,kappa=inf",), profile="constant", noise_seed=5, duration_s=20.0)


def random_actions(env, rng):
    """Seeded actions of every agent of a ParallelEnv (spaces' own sampling is seeded apart)."""
    out = {}
    for a in env.possible_agents:
        sp = env.action_space(a)
        if a == "global":
            out[a] = (rng.random(N_HYPOTHESES) < 0.05).astype(np.float32)
        elif sp.__class__.__name__ == "MultiBinary":
            out[a] = rng.integers(0, 2, sp.n).astype(np.int8)
        else:
            out[a] = rng.uniform(sp.low, sp.high).astype(np.float32)
    return out


def rollout(env, seed, budget_seed=0):
    rng = np.random.default_rng(budget_seed)
    obs, infos = env.reset(seed=seed)
    steps = [(obs, infos)]
    while env.agents:
        steps.append(env.step(random_actions(env, rng)))
    return steps


def test_parallel_api_test_passes():
    from pettingzoo.test import parallel_api_test

    for budget in ("decision", "features"):
        env = parallel_env(scenario_config=SHORT, message_budget=budget)
        parallel_api_test(env, num_cycles=100)  # an episode of 20 decisions: 21 steps, then every agent ends


def test_full_horizon_determinism_bit_for_bit():
    """Same seed, same actions: the same observations, rewards, ends and infos over a whole 300 s
    episode (default scenarios), and another seed differs."""
    a = rollout(parallel_env(message_budget="scalar"), seed=11)
    b = rollout(parallel_env(message_budget="scalar"), seed=11)
    assert len(a) == len(b) == 1 + 301  # the reset, 300 decisions and the hop of the last declaration
    for x, y in zip(a, b):
        for part_x, part_y in zip(x, y):
            for agent in part_x:
                vx, vy = part_x[agent], part_y[agent]
                if isinstance(vx, np.ndarray):
                    assert vx.dtype == vy.dtype and np.array_equal(vx, vy)
                else:
                    assert str(vx) == str(vy)
    c = rollout(parallel_env(message_budget="scalar"), seed=12)
    assert not all(np.array_equal(x[0]["local_2"], y[0]["local_2"]) for x, y in zip(a, c))


@pytest.mark.parametrize("scenario", [None, STALL])
def test_simulation_and_scoring_identical_to_the_single_agent_env(scenario):
    """Locals see their columns of MarineFDI-v1's observation, state() is that observation, and the
    global's declaration for decision k, made one hop later, is scored as the single env scores it at
    decision k: the same reward, decision time and episode end (also through an engine failure)."""
    options = None if scenario is None else {"scenario": scenario}
    single = MarineFDIEnv(scenario_config=SHORT, reward="v1")
    ma = parallel_env(scenario_config=SHORT)
    rng = np.random.default_rng(3)
    o1, _ = single.reset(seed=4, options=options)
    obs, infos = ma.reset(seed=4, options=options)
    cols = {a: local_columns(a, single.feature_names) for a in LOCAL_AGENTS}
    quiet = {a: np.zeros(ma.action_space(a).shape, np.int8) for a in LOCAL_AGENTS}
    expected, prev, done, scored = [], np.zeros(N_HYPOTHESES, np.float32), False, 0
    while ma.agents:
        belief = prev
        if not done:
            assert np.array_equal(ma.state(), o1)
            for a in LOCAL_AGENTS:
                assert np.array_equal(obs[a], o1[cols[a]])
            belief = (rng.random(N_HYPOTHESES) < 0.1).astype(np.float32)
            o1, r1, t1, tr1, i1 = single.step(belief)
            expected.append((r1, t1, tr1, i1["decision_time_s"]))
            done = t1 or tr1
        obs, rew, term, trunc, infos = ma.step({**quiet, "global": prev})
        if scored == 0 and not infos["global"]["scored"]:  # the first hop: no message had reached the global
            assert len(expected) == 1 and all(r == 0.0 for r in rew.values())
        else:
            r1, t1, tr1, dt = expected[scored]
            scored += 1
            assert infos["global"]["decision_time_s"] == dt
            assert all(r == r1 for r in rew.values())  # the team shares the reward
            assert all(t == t1 for t in term.values()) and all(t == tr1 for t in trunc.values())
        prev = belief
    assert scored == len(expected) and (expected[-1][1] if scenario is not None else expected[-1][2])


def test_batched_form_equals_one_parallel_env_per_slot():
    """Slot i of MultiAgentBatchEnv reset with seed s is the ParallelEnv reset with seed s + i, bit for bit."""
    n, seed = 3, 21
    batch = MultiAgentBatchEnv(n, scenario_config=SHORT, message_budget="decision")
    envs = [parallel_env(scenario_config=SHORT, message_budget="decision") for _ in range(n)]
    bo, _ = batch.reset(seed=seed)
    so = [e.reset(seed=seed + i)[0] for i, e in enumerate(envs)]
    rng = np.random.default_rng(0)
    while not batch.done.all():
        acts = {a: np.stack([random_actions(envs[0], rng)[a] for _ in range(n)]) for a in envs[0].possible_agents}
        for i, e in enumerate(envs):
            if e.agents:
                for a in e.possible_agents:
                    assert np.array_equal(bo[a][i], so[i][a])
        bo, br, bt, btr, _ = batch.step(acts)
        for i, e in enumerate(envs):
            if e.agents:
                so[i], r, t, tr, _ = e.step({a: acts[a][i] for a in e.possible_agents})
                assert all(br[a][i] == r[a] and bt[a][i] == t[a] and btr[a][i] == tr[a] for a in r)
    assert not any(e.agents for e in envs)


def test_message_budgets():
    assert [BUDGETS[b].bits_per_decision for b in ("decision", "scalar", "features")] == [19, 608, 3648]
    assert [BUDGETS["decision"].size(a) for a in LOCAL_AGENTS] == [2, 6, 5, 6]
    env = MultiAgentBatchEnv(1, scenario_config=SHORT, message_budget="decision")
    obs, _ = env.reset(seed=0)
    assert [obs[a].shape[1] for a in LOCAL_AGENTS] == [13, 37, 31, 37] and obs["global"].shape == (1, 19)
    ok = {a: np.zeros((1, BUDGETS["decision"].size(a))) for a in LOCAL_AGENTS} | {"global": np.zeros((1, 28))}
    with pytest.raises(ValueError, match="local_2: budget 'decision' sends bits"):
        env.step(ok | {"local_2": np.full((1, 6), 0.5)})
    with pytest.raises(ValueError, match="local_3: message must be 5 numbers"):
        env.step(ok | {"local_3": np.zeros((1, 6))})
    with pytest.raises(ValueError, match="missing global"):
        env.step({a: ok[a] for a in LOCAL_AGENTS})
    obs, *_ = env.step(ok | {"local_1": np.array([[1, 0]])})
    assert obs["global"][0].tolist() == [1.0] + [0.0] * 18  # local_1's bits first, in agent order
    scalar = MultiAgentBatchEnv(1, scenario_config=SHORT, message_budget=MessageBudget("two", "numbers", 2))
    scalar.reset(seed=0)
    msg = {a: np.zeros((1, scalar.budget.size(a))) for a in LOCAL_AGENTS} | {"global": np.zeros((1, 28))}
    with pytest.raises(ValueError, match="finite numbers within"):
        scalar.step(msg | {"local_4": np.full((1, 12), 7.0)})
    with pytest.raises(ValueError, match="kind must be one of bits, numbers"):
        MessageBudget("x", "floats", 1)
    # with observe_sensors a local also sees its table 6.2 sensors (own and interconnection) and u
    assert local_sensors("local_1") == ("S1.1", "S1.2")
    assert local_sensors("local_2") == tuple(f"S{k}" for k in "1.1 1.2 2.1 2.2 2.3 2.4 2.5 2.6 4.1 4.2 4.3 4.4".split())
    wide = MultiAgentBatchEnv(1, scenario_config=SHORT, observe_sensors=True)
    assert wide.observation_spaces["local_1"].shape == (13 + 2 + 1,)


def test_local_rewards_score_each_local_as_a_detector_of_its_own_faults():
    """rewards='local': a local raising its alarm before the onset of a fault it can see pays the false
    alarm; one whose modules cannot see the fault is scored against a fault-free episode."""
    sc = ScenarioSpec(faults=("S4.2@5:3e4",), profile="constant", noise_seed=3, duration_s=10.0)
    assert visible_faults("local_4")[list(one_hot(["S4.2"])[:26]).index(1.0)]
    assert not visible_faults("local_1")[list(one_hot(["S4.2"])[:26]).index(1.0)]
    env = MultiAgentBatchEnv(1, scenario_config=SHORT, rewards="local")
    env.reset(options={"scenarios": [sc]})
    alarm = {a: np.ones((1, BUDGETS["decision"].size(a))) for a in LOCAL_AGENTS} | {"global": np.zeros((1, 28))}
    _, rew, *_ = env.step(alarm)  # decision 0 at t = 1 s: before the onset
    assert rew["local_4"][0] == -40.0 and rew["local_1"][0] == -40.0 and rew["global"][0] == 0.0
    total = {a: 0.0 for a in rew}
    while not env.done.all():
        _, rew, *_ = env.step(alarm)
        total = {a: total[a] + rew[a][0] for a in rew}
    assert total["local_4"] == 0.0 and total["local_1"] == 0.0  # detected at once; one false alarm only
    assert total["global"] < 0  # the global declared nothing: the v1 detection delay and the miss
    with pytest.raises(ValueError, match="rewards must be one of team, local"):
        MultiAgentBatchEnv(1, rewards="mine")
