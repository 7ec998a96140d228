"""Every agent on one simulation: step several agents in lockstep on a :class:`Trajectory`.

At each decision every agent gets the trajectory's observation (its own columns: an agent that
asks for fewer observation options than the trajectory has gets the features it would get alone)
and infos (``info["sequential"]`` only if it asked for it; ``info["reference"]`` and
``info["sequential"]`` with the diagnosers' cell set it asked for), plus the scoring of its own previous
decision (``declared``, ``alarm``, ``belief_on_truth``, ``reward_terms``, ``decision_time_s``,
``termination_reason``), exactly as ``MarineFDIVectorEnv.step`` returns them.  The decisions of all
agents are scored in one call of :class:`~marine_fdi_env.envs.scoring.DecisionScorer` (one slot per
agent and episode; every operation is per slot), and each agent's episode records are those of
``marine-fdi evaluate`` run on the vector environment, bit for bit except the wall-clock fields
(tested for every shipped agent on every shipped suite).

Agents must treat the rows of a batch independently (the agent API asks for it): past the end of
an episode its row repeats the episode's last observation.
"""

from __future__ import annotations

import hashlib
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..envs.hypotheses import DECLARE_THRESHOLD, N_FAULTS, check_action
from ..envs.observation import feature_names
from ..envs.reward import RewardConfig, RewardConfigV1
from ..envs.scoring import DecisionScorer
from ..envs.trajectory import Trajectory, cell_sets_of, feature_columns
from ..envs.vector import object_array, scatter_infos
from .records import episode_record

__all__ = ["episode_seed", "AgentView", "agent_view", "score_agents"]

_MAX_SEED = 2**63 - 1


def episode_seed(scenario_id: str, seed_offset: int) -> int:
    """The agent's seed for one episode (stable across Python versions and platforms)."""
    h = hashlib.sha256(f"{scenario_id}|{seed_offset}".encode()).digest()
    return int.from_bytes(h[:8], "little") & _MAX_SEED


@dataclass(frozen=True)
class AgentView:
    """What an agent sees of a trajectory: its observation columns (None: all), whether its
    infos hold ``info["sequential"]`` and the diagnosers' cell set of their conclusions."""

    columns: np.ndarray | None
    sequential: bool
    cells: str


def agent_view(env_kwargs: dict, traj: Trajectory) -> AgentView:
    """The view of an agent whose environment would be made with ``env_kwargs`` (its options
    included); ``ValueError`` if the trajectory lacks what it needs."""
    seq = bool(env_kwargs.get("observe_sequential", False))
    want = feature_names(bool(env_kwargs.get("observe_sensors", False)), seq)
    if seq and not traj.observe_sequential:
        raise ValueError("the trajectory has no sequential diagnoser (made without observe_sequential)")
    cells = cell_sets_of(env_kwargs)[0]
    traj.cell_index(cells)
    return AgentView(feature_columns(traj.feature_names, want), seq, cells)


class _Episodes:
    """The episode records of K agents x n episodes being built (slot r = agent * n + episode)."""

    def __init__(self, k: int, traj: Trajectory) -> None:
        m = k * traj.n
        self.traj = traj
        self.ret = np.zeros(m)
        self.terms: dict[str, np.ndarray] = {}
        self.agent_s = np.zeros(m)
        self.trace: list[list] = [[] for _ in range(m)]
        self.prev_decl = np.zeros((m, N_FAULTS), dtype=bool)
        self.prev_alarm = np.zeros(m, dtype=bool)
        self.share = np.full((traj.steps, m), np.nan)

    def add(self, k: int, rows: np.ndarray, t: np.ndarray, beliefs: np.ndarray, out) -> None:
        """Decision ``k`` of the slots ``rows`` (times ``t``) and its scores ``out``."""
        self.ret[rows] += out.reward
        for name, v in out.terms.items():
            self.terms.setdefault(name, np.zeros(len(self.ret)))[rows] += v
        decl = beliefs[:, :N_FAULTS] >= DECLARE_THRESHOLD
        new = (k == 0) | np.any(decl != self.prev_decl[rows], axis=1) | (out.alarm != self.prev_alarm[rows])
        for j in np.flatnonzero(new):
            self.trace[rows[j]].append([float(t[j]), list(out.declared[j]), bool(out.alarm[j])])
        self.prev_decl[rows] = decl
        self.prev_alarm[rows] = out.alarm
        self.share[k, rows] = out.belief_on_truth

    def records(self, agent: int, name: str, suite: str) -> list[dict]:
        tr, out = self.traj, []
        for i, sc in enumerate(tr.scenarios):
            r = agent * tr.n + i
            d = int(tr.n_decisions[i])
            t = tr.t[:d, i]
            share = self.share[:d, r]
            ok = ~np.isnan(share)
            term = bool(tr.terminated[i])
            out.append(
                episode_record(
                    sc,
                    suite,
                    name,
                    duration_s=float(t[-1]) if term else float(sc.duration_s),
                    decision_period_s=tr.decision_period_s,
                    n_samples=int(d * tr.period_samples),
                    declared_changes=self.trace[r],
                    belief_on_truth=np.column_stack((t[ok], share[ok])).tolist(),
                    failure=tr.failures[i],
                    terminated=term,
                    ret=float(self.ret[r]),
                    reward_terms={k: float(v[r]) for k, v in self.terms.items()},
                    split=(float(tr.compute_s[i]), float(self.agent_s[r]), d),
                )
            )
        return out


def score_agents(
    agents: list,
    views: list[AgentView],
    traj: Trajectory,
    reward: RewardConfig | RewardConfigV1,
    *,
    suite: str = "",
    seed_offset: int = 0,
    progress: Callable[[float], None] | None = None,
    on_decision: Callable | None = None,
) -> list[list[dict]]:
    """Step ``agents`` (seen through ``views``) in lockstep on ``traj``; their episode records
    (one list per agent, in the trajectory's episode order).

    ``progress(x)`` after every decision with the episodes' worth of scoring done (over all agents:
    a whole trajectory is ``n`` episodes); ``on_decision(agent, scenario_id, t_s, belief, compute_s)``
    for every decision (``compute_s``: its observation's share of the features plus its share of
    the agent's ``act``).
    """
    n, K = traj.n, len(agents)
    if len({id(a) for a in agents}) != K:
        raise ValueError("each agent once: one agent object stepped twice would mix the state of two runs")
    seeds = [episode_seed(s.scenario_id, seed_offset) for s in traj.scenarios]
    for a in agents:
        a.reset(list(seeds))
    scorer = DecisionScorer(reward, K * n, traj.decision_period_s)
    for j in range(K):
        for i, sc in enumerate(traj.scenarios):
            scorer.start(j * n + i, sc.faults)
    eps = _Episodes(K, traj)
    own: list[dict] = [{} for _ in range(K)]  # each agent's infos from scoring its previous decision
    for k in range(traj.steps):
        live = np.flatnonzero(traj.n_decisions > k)
        active, first, last = traj.active(k)
        shared: dict[tuple[bool, str], dict] = {}  # the infos of each (sequential, cells) asked for
        beliefs, spent = [], []
        for j, (agent, view) in enumerate(zip(agents, views)):
            key = (view.sequential, view.cells)
            if key not in shared:
                info = traj.info_arrays(k, active, view.sequential, view.cells)
                shared[key] = scatter_infos(n, [(np.arange(n), info)])
            infos = dict(shared[key])
            infos.update(own[j])
            obs = traj.observation(k, view.columns)
            t0 = time.perf_counter()
            actions = np.asarray(agent.act(obs, infos), dtype=np.float32)
            act_s = (time.perf_counter() - t0) / len(live)
            beliefs.append(check_action(actions, n_envs=n))
            spent.append(act_s)
            eps.agent_s[j * n + live] += act_s
        rows = np.concatenate([j * n + live for j in range(K)])
        t = traj.t[k, live]
        stacked = np.concatenate([b[live] for b in beliefs])
        out = scorer.score(
            stacked, rows, np.tile(active[live], (K, 1)), np.tile(first[live], K), np.tile(last[live], K), np.tile(t, K)
        )
        ending = traj.n_decisions[live] == k + 1
        scorer.end_terms(out, rows, rows[np.tile(ending, K)])
        eps.add(k, rows, np.tile(t, K), stacked, out)
        stopped = live[ending & traj.terminated[live]]
        reasons = object_array([f"engine failure: {traj.failures[i]['reason']}" for i in stopped])
        m = len(live)
        for j in range(K):
            sl = slice(j * m, (j + 1) * m)
            own[j] = scatter_infos(
                n,
                [
                    (
                        live,
                        {
                            "declared": object_array([list(d) for d in out.declared[sl]]),
                            "alarm": out.alarm[sl],
                            "belief_on_truth": out.belief_on_truth[sl].astype(float),
                            "reward_terms": {name: v[sl].astype(float) for name, v in out.terms.items()},
                            "decision_time_s": t.astype(float),
                        },
                    )
                ],
            )
            own[j].update(scatter_infos(n, [(stopped, {"termination_reason": reasons})]))
            if on_decision is not None:
                cost = traj.feature_s[k, live]
                for i, c in zip(live, cost):
                    on_decision(
                        j, traj.scenarios[i].scenario_id, float(traj.t[k, i]), beliefs[j][i], float(c) + spent[j]
                    )
        if progress is not None:
            progress(len(live) / traj.steps)
    return [eps.records(j, a.name, suite) for j, a in enumerate(agents)]
