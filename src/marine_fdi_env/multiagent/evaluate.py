"""A suite scored through the multi-agent path: a :class:`~.team.Team` on the batched multi-agent
environment, with the episode records and metrics of ``marine-fdi evaluate``.

:func:`evaluate_team` runs the suite's scenarios in batches of :class:`~.batch.MultiAgentBatchEnv`
(one simulation per batch, as ``evaluate``), plays the team on them (:func:`~.team.play`) and builds
each episode's record from the scored declarations: the same fields, and the same numbers except the
wall-clock ones, as ``marine-fdi evaluate --agent`` of the team as one agent (:class:`~.team.TeamAgent`;
tested).  It is what the cost benchmark times (``benchmarks/multiagent.py``).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..benchmark.evaluate import suite_env_kwargs, warm_up
from ..benchmark.lockstep import episode_seed
from ..benchmark.metrics import compute_metrics
from ..benchmark.records import episode_record
from ..benchmark.suites import load_suite
from ..envs.scenario_sampler import ScenarioSpec
from .batch import MultiAgentBatchEnv
from .team import Team, play

__all__ = ["team_records", "evaluate_team"]

_MAX_SEED = 2**63 - 1
_ENV_OPTIONS = ("params", "dt", "decision_period_s", "diagnosis_cells", "diagnosis_thresholds", "observe_sensors")


class _Records:
    """The records of a batch being played (one per slot), built from each step's scored declarations."""

    def __init__(self, n: int) -> None:
        self.ret = np.zeros(n)
        self.terms: dict[str, np.ndarray] = {}
        self.trace: list[list] = [[] for _ in range(n)]
        self.share: list[list] = [[] for _ in range(n)]
        self.prev_decl: list[tuple] = [()] * n
        self.prev_alarm = np.zeros(n, dtype=bool)
        self.decisions = np.zeros(n, dtype=np.int64)
        self.agent_s = np.zeros(n)
        self.last_t = np.zeros(n)

    def add(self, env: MultiAgentBatchEnv, spent: float) -> None:
        rows, out = env.scored, env.outcome
        live = np.flatnonzero(~env.done | np.isin(np.arange(env.num_envs), rows))
        self.agent_s[live] += spent / max(len(live), 1)
        if out is None:
            return
        t = env.scored_t
        self.ret[rows] += out.reward
        for name, v in out.terms.items():
            self.terms.setdefault(name, np.zeros(len(self.ret)))[rows] += v
        for j, r in enumerate(rows.tolist()):
            new = self.decisions[r] == 0 or out.declared[j] != self.prev_decl[r] or out.alarm[j] != self.prev_alarm[r]
            if new:
                self.trace[r].append([float(t[j]), list(out.declared[j]), bool(out.alarm[j])])
            if not np.isnan(out.belief_on_truth[j]):
                self.share[r].append([float(t[j]), float(out.belief_on_truth[j])])
        for j, r in enumerate(rows.tolist()):
            self.prev_decl[r] = out.declared[j]
        self.prev_alarm[rows] = out.alarm
        self.decisions[rows] += 1
        self.last_t[rows] = t


def team_records(
    team: Team, scenarios: list[ScenarioSpec], env_kwargs: dict, *, suite: str = "", seed_offset: int = 0
) -> list[dict]:
    """The episode records of ``team`` on ``scenarios`` (one batch of one sensor-noise scale, seed offset
    already applied) through :class:`~.batch.MultiAgentBatchEnv` made with ``env_kwargs``."""
    scales = {float(s.noise_scale) for s in scenarios}
    if len(scales) != 1:
        raise ValueError(f"a batch must share one sensor-noise scale, got {sorted(scales)}")
    kw = {k: v for k, v in env_kwargs.items() if k in _ENV_OPTIONS}
    if team.observe_sensors:
        kw["observe_sensors"] = True
    n = len(scenarios)
    env = MultiAgentBatchEnv(
        n,
        scenario_config={"noise_scale": scales.pop()},
        message_budget=team.budget,
        reward=env_kwargs.get("reward"),
        **kw,
    )
    obs, _ = env.reset(options={"scenarios": list(scenarios)})
    rec = _Records(n)
    seeds = [episode_seed(s.scenario_id, seed_offset) for s in scenarios]
    play(team, env, obs, seeds, on_step=rec.add)
    b = env.batch
    out = []
    for i, sc in enumerate(scenarios):
        d = int(rec.decisions[i])
        term = bool(env.ended_by_failure[i])
        out.append(
            episode_record(
                sc,
                suite,
                team.name,
                duration_s=float(rec.last_t[i]) if term else float(sc.duration_s),
                decision_period_s=b.decision_period_s,
                n_samples=int(d * b.period_samples),
                declared_changes=rec.trace[i],
                belief_on_truth=rec.share[i],
                failure=b.failure[i],
                terminated=term,
                ret=float(rec.ret[i]),
                reward_terms={k: float(v[i]) for k, v in rec.terms.items()},
                split=(float(b.compute_s[i]), float(rec.agent_s[i]), d),
            )
        )
    return out


def evaluate_team(team: Team, suite_name: str, *, batch_size: int = 32, seed_offset: int = 0, reward=None) -> dict:
    """Score ``team`` on a frozen suite through the multi-agent path; the results object of
    ``marine-fdi evaluate`` (header, ``metrics``, ``episodes``), not written anywhere."""
    suite = load_suite(suite_name)
    env_kwargs, _ = suite_env_kwargs(suite, reward)
    warm_up({k: v for k, v in env_kwargs.items() if k in _ENV_OPTIONS})
    scs = [
        sc if not seed_offset else replace(sc, noise_seed=(int(sc.noise_seed) + int(seed_offset)) % _MAX_SEED)
        for sc in suite.scenarios
    ]
    groups: dict[float, list[int]] = {}
    for i, s in enumerate(scs):
        groups.setdefault(float(s.noise_scale), []).append(i)
    records: list = [None] * len(scs)
    for idx in groups.values():
        for a in range(0, len(idx), batch_size):
            part = idx[a : a + batch_size]
            for i, r in zip(
                part, team_records(team, [scs[i] for i in part], env_kwargs, suite=suite.name, seed_offset=seed_offset)
            ):
                records[i] = r
    return {
        "agent": team.name,
        "suite": suite.name,
        "suite_version": suite["version"],
        "seed_offset": int(seed_offset),
        "n_scenarios": len(records),
        "metrics": compute_metrics(records),
        "episodes": records,
    }
