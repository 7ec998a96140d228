"""The sequential diagnoser: CUSUM tests on the reference residuals, streaming, detection of faults
below the worst-case thresholds, and its place in the environment and the evaluation."""

from __future__ import annotations

import numpy as np
import pytest

from marine_fdi_env.diagnosis.agent import ReferenceDiagnoser
from marine_fdi_env.diagnosis.batch import diagnose_batch
from marine_fdi_env.diagnosis.modules import MODULE_IDS
from marine_fdi_env.diagnosis.sequential import (
    SEQUENTIAL_FEATURES,
    SequentialCalibration,
    SequentialDiagnoser,
    load_calibration,
)
from marine_fdi_env.engine.faults import FaultSpec
from marine_fdi_env.engine.simulator import Simulator


def test_calibration_file_is_consistent():
    cal = load_calibration()
    assert cal.mean.shape == cal.scale.shape == (19, len(cal.u_nodes))
    assert np.all(cal.scale > 0) and np.all(cal.h > 0) and np.all(cal.k > 0)
    assert cal.data["fit"]["hours"] >= 100  # calibrated on at least 100 fault-free engine-hours
    with pytest.raises(ValueError, match="module ids"):
        SequentialCalibration.from_dict({**cal.data, "module_ids": list(MODULE_IDS[::-1])})


def test_streaming_in_blocks_equals_one_pass():
    res = Simulator(
        "thesis-12v28",
        2,
        seeds=[5, 6],
        faults=[[FaultSpec("intercooler_blockage", 30.0, magnitude=0.03)], []],
        profiles="constant",
    ).run(120.0)
    Y, U = res.measurements.transpose(1, 0, 2), res.truth_of("u").T
    outs = []
    for block in (Y.shape[1], 250, 77):
        d = SequentialDiagnoser(n_engines=2, dt=res.dt)
        for a in range(0, Y.shape[1], block):
            d.observe(Y[:, a : a + block], U[:, a : a + block])
        outs.append((d.stage.first.copy(), d.stage.st.copy(), [d.report(i) for i in range(2)]))
    for o in outs[1:]:
        assert np.array_equal(o[0], outs[0][0], equal_nan=True)
        assert np.allclose(o[1], outs[0][1], rtol=1e-12, atol=1e-12)
        assert o[2] == outs[0][2]


def test_detects_a_fault_below_the_worst_case_thresholds():
    """An intercooler blockage at a third of the reference's detectability limit (0.044 K/s, and
    2.5x below the thesis's table 6.10) within 300 s: the reference sees nothing, the sequential
    tests of M4.5/M4.6 do (measured 185-257 s after the onset)."""
    sched = [[FaultSpec("intercooler_blockage", 30.0, magnitude=0.015)]] * 3
    seeds = [101, 102, 103]
    ref = diagnose_batch(sched, seeds, "constant", 300.0, exoneration="none")
    seq = diagnose_batch(sched, seeds, "constant", 300.0, exoneration="none", diagnoser="sequential")
    assert not any(r["detected"] for r in ref)
    assert all(r["detected"] and r["first_detection_time_s"] > 30.0 for r in seq)
    assert all({m for m, t in r["module_detection_times_s"].items() if t is not None} <= {"M4.5", "M4.6"} for r in seq)


def test_environment_option_keeps_the_default_observation():
    from marine_fdi_env.envs.fdi_env import MarineFDIEnv

    plain = MarineFDIEnv(scenario_config="single")
    seq = MarineFDIEnv(scenario_config="single", observe_sequential=True)
    o1, i1 = plain.reset(seed=4)
    o2, i2 = seq.reset(seed=4)
    assert o1.shape == (115,) and o2.shape == (115 + 19 * len(SEQUENTIAL_FEATURES),)
    assert len(seq.feature_names) == o2.shape[0] and seq.observation_space.contains(o2)
    for _ in range(5):
        a = plain.action_space.sample()
        o1, *_, i1 = plain.step(a)
        o2, *_, i2 = seq.step(a)
        assert np.array_equal(o1, o2[:115])
        assert "sequential" in i2 and "sequential" not in i1
        assert seq.observation_space.contains(o2)


def test_evaluate_runs_the_sequential_agent_with_its_environment_option():
    from marine_fdi_env.benchmark.agent_api import load_agent
    from marine_fdi_env.benchmark.evaluate import run_episodes
    from marine_fdi_env.benchmark.suites import load_suite

    agent = load_agent("sequential")
    assert agent.env_kwargs == {"observe_sequential": True, "diagnosis_cells": "sized"}
    suite = load_suite("thesis-v1")
    recs = run_episodes(agent, suite.scenarios[:2], dict(suite["env"]), suite="thesis-v1")
    assert len(recs) == 2 and all(r["agent"] == "sequential" for r in recs)
    assert any(ch[2] for r in recs for ch in r["declared_changes"])  # it raised the alarm


def test_reference_and_sequential_share_the_residuals():
    res = Simulator("thesis-12v28", 1, seeds=9, profiles="manoeuvring").run(20.0)
    Y, U = res.measurements.transpose(1, 0, 2), res.truth_of("u").T
    a = ReferenceDiagnoser(n_engines=1, dt=res.dt).observe(Y, U)
    b = SequentialDiagnoser(n_engines=1, dt=res.dt).observe(Y, U)
    assert np.array_equal(a.residuals, b.residuals) and np.array_equal(a.thresholds, b.thresholds)
