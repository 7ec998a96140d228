"""The episode records of one agent as the vector environment gives them: the agent stepped on
``MarineFDIVectorEnv`` alone, one batch at a time (``marine-fdi evaluate``'s loop before it
simulated each batch once for every agent, commit ca28256, kept verbatim but for the imports).

The anchor of the shared-trajectory evaluation (tests/integration/test_lockstep.py): every
agent scored in lockstep on one simulation must give these records bit for bit, except the
wall-clock fields.
"""

from __future__ import annotations

import time

import numpy as np

from marine_fdi_env.benchmark.evaluate import offset_scenario, warm_up
from marine_fdi_env.benchmark.lockstep import episode_seed
from marine_fdi_env.envs.scenario_sampler import ScenarioSpec, with_noise_scale
from marine_fdi_env.envs.vector import MarineFDIVectorEnv

__all__ = ["run_episodes"]


def run_episodes(
    agent,
    scenarios: list[ScenarioSpec],
    env_kwargs: dict | None = None,
    *,
    suite: str = "",
    seed_offset: int = 0,
    batch_size: int = 32,
    on_episode=None,
    progress=None,
    on_decision=None,
) -> list[dict]:
    """Run ``agent`` on every scenario; returns the episode records (scenario order).

    ``on_episode(record)`` is called as soon as an episode's record is complete; ``progress(x)``
    after every decision with the episodes' worth of work done since the last call (fractions);
    ``on_decision(scenario_id, t_s, belief, compute_s)`` for every decision of every episode (the
    belief vector the agent declared at decision time ``t_s`` and the time spent on this decision:
    its observation and its share of the agent's ``act``).
    """
    env_kwargs = dict(env_kwargs or {})
    env_kwargs.update(getattr(agent, "env_kwargs", {}))  # options the agent needs (e.g. observe_sequential)
    warm_up(env_kwargs)  # compile time stays out of compute_s
    records: dict[int, dict] = {}
    groups: dict[float, list[int]] = {}  # one batched engine set per sensor-noise scale
    for i, s in enumerate(scenarios):
        groups.setdefault(float(s.noise_scale), []).append(i)
    for noise_scale, idx in groups.items():
        kw = with_noise_scale(env_kwargs, noise_scale)
        for start in range(0, len(idx), batch_size):
            part = idx[start : start + batch_size]
            chunk = [offset_scenario(scenarios[i], seed_offset) for i in part]
            for i, rec in zip(part, _run_batch(agent, chunk, kw, suite, seed_offset, progress, on_decision)):
                records[i] = rec
                if on_episode is not None:
                    on_episode(rec)
    return [records[i] for i in range(len(scenarios))]


def _run_batch(agent, scenarios, env_kwargs, suite, seed_offset, progress=None, on_decision=None):
    n = len(scenarios)
    venv = MarineFDIVectorEnv(num_envs=n, **env_kwargs)
    obs, infos = venv.reset(options={"scenarios": scenarios})
    agent.reset([episode_seed(s.scenario_id, seed_offset) for s in scenarios])
    period = venv.batch.decision_period_s
    live = np.ones(n, dtype=bool)
    trace = [[] for _ in range(n)]
    share = [[] for _ in range(n)]
    ret = np.zeros(n)
    terms = [dict() for _ in range(n)]
    agent_s = np.zeros(n)
    feature_s = np.zeros(n)
    steps = np.zeros(n, dtype=np.int64)
    out: list[dict | None] = [None] * n
    n_decisions = np.maximum(1.0, np.round([s.duration_s / period for s in scenarios]))
    obs_cost = venv.batch.compute_s.copy()  # time spent on the observation each slot decides on
    reported = 0.0
    while live.any():
        t0 = time.perf_counter()
        actions = np.asarray(agent.act(obs, infos), dtype=np.float32)
        act_s = (time.perf_counter() - t0) / live.sum()
        agent_s[live] += act_s
        feats_before = venv.batch.compute_s.copy() if on_decision is not None else None
        obs, rew, term, trunc, infos = venv.step(actions)
        if on_decision is not None:
            for i in np.flatnonzero(live):
                on_decision(
                    scenarios[i].scenario_id, float(infos["decision_time_s"][i]), actions[i], float(obs_cost[i]) + act_s
                )
            obs_cost = venv.batch.compute_s - feats_before  # the next observation's cost
        for i in np.flatnonzero(live):
            t = float(infos["decision_time_s"][i])
            declared = list(infos["declared"][i])
            alarm = bool(infos["alarm"][i])
            if not trace[i] or trace[i][-1][1] != declared or trace[i][-1][2] != alarm:
                trace[i].append([t, declared, alarm])
            b = float(infos["belief_on_truth"][i])
            if b == b:  # not NaN: a fault is active
                share[i].append([t, b])
            ret[i] += rew[i]
            for k, v in infos["reward_terms"].items():
                if k.startswith("_"):
                    continue
                terms[i][k] = terms[i].get(k, 0.0) + float(v[i])
            steps[i] += 1
            if term[i] or trunc[i]:
                live[i] = False
                feature_s[i] = venv.batch.compute_s[i]
                sc = scenarios[i]
                fail = infos["engine_failure"]
                reason = str(fail["reason"][i]) if term[i] else None
                out[i] = {
                    "scenario_id": sc.scenario_id,
                    "suite": suite,
                    "seed": int(sc.noise_seed),
                    "agent": agent.name,
                    "profile": sc.profile,
                    "duration_s": t if term[i] else float(sc.duration_s),
                    "decision_period_s": period,
                    "n_samples": int(steps[i] * venv.batch.period_samples),
                    "faults": sc.truth(),
                    "declared_changes": trace[i],
                    "belief_on_truth": share[i],
                    "terminated": bool(term[i]),
                    "failure_reason": reason or None,
                    "compute_s": float(feature_s[i] + agent_s[i]),
                    "return": float(ret[i]),
                    "reward_terms": terms[i],
                    "feature_compute_s": float(feature_s[i]),
                    "agent_compute_s": float(agent_s[i]),
                    "n_decisions": int(steps[i]),
                }
        if progress is not None:
            done = float(np.where(live, steps / n_decisions, 1.0).clip(0.0, 1.0).sum())
            progress(done - reported)
            reported = done
    return out
