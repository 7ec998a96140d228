"""Simulate once, score every agent: the shared-trajectory evaluation equals each agent alone on
the vector environment, bit for bit (records and metrics, except the wall-clock fields)."""

from __future__ import annotations

import numpy as np
import pytest
from test_env_evaluate import SCENARIOS
from test_scale_out import _no_clock

from marine_fdi_env.benchmark.agent_api import load_agent
from marine_fdi_env.benchmark.evaluate import plan_passes, run_agents, suite_env_kwargs
from marine_fdi_env.benchmark.metrics import compute_metrics
from marine_fdi_env.benchmark.suites import SUITE_NAMES, load_suite
from marine_fdi_env.envs.trajectory import simulate
from tests import env_runner
from tests.paths import ROOT

pytest.importorskip("torch")  # the shipped models

# every shipped agent: the baselines (the diagnosers with each cell set), the shipped models, and the hybrid that
# reads info["reference"]
AGENTS = (
    "null",
    "random",
    "reference",
    "reference-thesis",
    "reference-grid",
    "sequential",
    "sequential-thesis",
    "sequential-grid",
    "oracle",
    "ppo-v1",
    "classifier-v1",
    "classifier",
    "classifier-v1+reference",
)


def _assert_lockstep_equals_alone(scenarios, env_kwargs, suite, seed_offset=0, batch_size=32):
    agents = [load_agent(a) for a in AGENTS]
    together, _ = run_agents(agents, scenarios, env_kwargs, suite=suite, seed_offset=seed_offset, batch_size=batch_size)
    for name, mine in zip(AGENTS, together):
        alone = env_runner.run_episodes(
            load_agent(name), scenarios, env_kwargs, suite=suite, seed_offset=seed_offset, batch_size=batch_size
        )
        assert _no_clock(mine) == _no_clock(alone), name
        assert _no_clock(compute_metrics(mine)) == _no_clock(compute_metrics(alone)), name
    return together


@pytest.mark.study  # the breadth version (every shipped suite); fast: the tests below, noise scales included
def test_every_shipped_agent_scored_together_equals_it_alone():
    """The first episode of every shipped suite (one batch; transfer-v2's and transfer-v3's noise scales in theirs),
    every shipped agent in one pass (``sequential`` asks for observe_sequential, the ``-thesis`` and
    ``-grid`` agents for other cell sets: each gets the columns and infos it has alone)."""
    suites = [load_suite(name) for name in SUITE_NAMES]
    env_kwargs = {k: v for k, v in suite_env_kwargs(suites[0])[0].items()}
    assert all(suite_env_kwargs(s)[0] == env_kwargs for s in suites)  # one environment: one comparison
    assert len(plan_passes([load_agent(a) for a in AGENTS], env_kwargs)) == 1
    firsts = [s.scenarios[0] for s in suites]
    recs = _assert_lockstep_equals_alone(firsts, env_kwargs, "first-episodes")
    # the cell sets matter on these episodes: some conclusion differs between them
    traces = {
        a: [r["declared_changes"] for r in recs[AGENTS.index(a)]]
        for a in AGENTS
        if a.startswith(("reference", "sequential"))
    }
    assert traces["reference"] != traces["reference-thesis"] or traces["reference"] != traces["reference-grid"]
    assert traces["sequential"] != traces["sequential-thesis"] or traces["sequential"] != traces["sequential-grid"]
    oracle = recs[AGENTS.index("oracle")]
    # a non-trivial comparison: the oracle isolates (its trace changes) on every faulty episode
    assert all(len(r["declared_changes"]) >= 2 for r, sc in zip(oracle, firsts) if sc.faults)
    assert sum(1 for sc in firsts if sc.faults) >= 5 and {sc.noise_scale for sc in firsts} == {1.0, 0.7, 1.3}


def test_noise_scales_of_one_batch_scored_together_equal_each_agent_alone():
    """Episodes at the transfer suites' noise scales (0.7, 1.3) beside the nominal one, in one batch."""
    from dataclasses import replace

    scenarios = [replace(SCENARIOS[0], noise_scale=0.7), replace(SCENARIOS[1], noise_scale=1.3)]
    _assert_lockstep_equals_alone(scenarios, {}, "noise-scales")


def test_a_batch_with_an_engine_failure_and_a_seed_offset():
    """Four episodes in one batch (one ends early by an engine failure, the others go on), under
    v0 and v1, with a seed offset and with batches of one episode."""
    recs = _assert_lockstep_equals_alone(SCENARIOS, {"reward": "v1"}, "tiny", seed_offset=3)
    stall = [r["scenario_id"] for r in recs[0]].index("stall")
    assert recs[0][stall]["terminated"] and recs[0][stall]["n_decisions"] < 20
    assert all(not r["terminated"] for i, r in enumerate(recs[0]) if i != stall)
    _assert_lockstep_equals_alone(SCENARIOS, {"reward": "v0"}, "tiny", batch_size=1)


def test_observation_options_share_one_pass_and_other_arguments_get_their_own():
    class Wants:
        name = "wants"

        def __init__(self, **kw):
            self.env_kwargs = kw

    passes = plan_passes(
        [
            Wants(),
            Wants(observe_sequential=True),
            Wants(observe_sensors=True),
            Wants(decision_period_s=2.0),
            Wants(diagnosis_cells="sized"),
            Wants(diagnosis_cells="grid"),
        ],
        {"decision_period_s": 1.0, "observe_sensors": False},
    )
    # an option at the environment's default value (decision_period_s 1.0) makes the same simulation as one left
    # out; the cell sets change only the diagnosers' conclusions: one pass decides with each one asked for
    assert [p.agents for p in passes] == [(0, 1, 2, 4, 5), (3,)]
    assert passes[0].env_kwargs == {
        "observe_sensors": True,
        "observe_sequential": True,
        "diagnosis_cells": ["grid", "sized"],
    }
    assert passes[0].agent_env[4]["diagnosis_cells"] == "grid"
    assert passes[1].env_kwargs == {"decision_period_s": 2.0, "observe_sensors": False}
    # only the default cell set: left out
    assert plan_passes([Wants(), Wants(diagnosis_cells="sized")], {})[0].env_kwargs == {}
    everything = plan_passes([Wants()], {}, all_options=True)[0].env_kwargs
    assert everything == {
        "observe_sensors": True,
        "observe_sequential": True,
        "diagnosis_cells": ["thesis", "grid", "sized"],
    }


def test_an_agent_with_sensor_features_sees_its_own_columns():
    """A trajectory with every option gives an agent without them exactly its observation."""
    sc = SCENARIOS[:2]
    full = simulate(sc, {"observe_sensors": True, "observe_sequential": True})
    plain = simulate(sc, {})
    assert full.obs.shape[2] == plain.obs.shape[2] + 20 + 19 * 4
    np.testing.assert_array_equal(full.obs[:, :, : plain.obs.shape[2]], plain.obs)
    assert np.array_equal(full.reference_detected, plain.reference_detected)
    assert [[list(map(list, d)) for d in row] for row in full.reference_diagnoses] == [
        [list(map(list, d)) for d in row] for row in plain.reference_diagnoses
    ]
    agent = load_agent(f"{ROOT / 'docs' / 'examples' / 'fired_modules_agent.py'}:FiredModulesAgent")
    _assert_one(agent, sc)


def _assert_one(agent, scenarios):
    mine, _ = run_agents([agent, load_agent("sequential")], scenarios, {"reward": "v1"}, suite="x")
    alone = env_runner.run_episodes(agent, scenarios, {"reward": "v1"}, suite="x")
    assert _no_clock(mine[0]) == _no_clock(alone)


def test_threshold_readings_get_passes_of_their_own_and_equal_themselves_alone():
    """A reading of the observers' thresholds changes the observation, so each gets its own simulation pass;
    scored with the reference in one call, each equals itself alone."""
    from marine_fdi_env.benchmark.evaluate import run_agents as run

    suite = load_suite("thesis-v1")
    env_kwargs = suite_env_kwargs(suite)[0]
    names = ("reference", "reference-lipschitz", "reference-table-6.1-m4")
    agents = [load_agent(a) for a in names]
    assert len(plan_passes(agents, env_kwargs)) == 3
    scenarios = [suite.scenarios[k] for k in (10, 11)]  # two 6.4.3 episodes: the compressor seal leak
    together, _ = run(agents, scenarios, env_kwargs, suite="thesis-v1")
    for name, mine in zip(names, together):
        alone = env_runner.run_episodes(load_agent(name), scenarios, env_kwargs, suite="thesis-v1")
        assert _no_clock(mine) == _no_clock(alone), name
    # table 6.1's constants in M4.q name the leak earlier than the local thresholds
    for k in range(len(scenarios)):
        named = {
            n: min((c[0] for c in r[k]["declared_changes"] if "compressor_seal_leak" in c[1]), default=np.inf)
            for n, r in zip(names, together)
        }
        assert named["reference-table-6.1-m4"] < named["reference"]
