"""A team of policies for the multi-agent track, and the team as one benchmark agent.

A :class:`Team` holds one :class:`LocalPolicy` per local agent and a :class:`GlobalPolicy`, under
one message budget.  The same team runs

* in the multi-agent environments (:func:`play` on :class:`~.batch.MultiAgentBatchEnv`, or the
  ParallelEnv one engine at a time), each policy seeing only its own agent's observation;
* as a single benchmark agent (:class:`TeamAgent`, ``marine-fdi evaluate --agent``): each local
  policy is handed only its own columns of the single-agent observation, and the global policy only
  the messages, checked against the budget, of the same decision.

Both give the same declarations at every decision, bit for bit (tested), because the global
declares for decision k from the messages about decision k in both (:mod:`.batch`, Timing).
Policies must treat the rows of a batch independently, as agents do (docs/agent_api.md).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from ..envs.hypotheses import N_HYPOTHESES, check_action
from ..envs.observation import feature_names
from .budgets import MessageBudget
from .roles import GLOBAL_AGENT, LOCAL_AGENTS, local_columns

__all__ = ["LocalPolicy", "GlobalPolicy", "Team", "TeamAgent", "play"]


class LocalPolicy(Protocol):
    """A local agent's policy: its observation (n, d) -> its message (n, size) under the budget."""

    def reset(self, seeds: list[int]) -> None: ...

    def message(self, obs: np.ndarray) -> np.ndarray: ...


class GlobalPolicy(Protocol):
    """The global agent's policy: the locals' messages (n, total) -> beliefs (n, 28)."""

    def reset(self, seeds: list[int]) -> None: ...

    def declare(self, messages: np.ndarray) -> np.ndarray: ...


@dataclass
class Team:
    """The policies of the five agents under one budget; ``observe_sensors``: the locals also see
    their sensors (:mod:`.roles`); ``training_seed``: a learned team's training seed (results record it)."""

    name: str
    budget: MessageBudget
    locals: dict[str, LocalPolicy]
    global_policy: GlobalPolicy
    observe_sensors: bool = False
    training_seed: int | None = None
    env_kwargs: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        missing = [a for a in LOCAL_AGENTS if a not in self.locals]
        if missing:
            raise ValueError(f"team {self.name!r} has no policy for {', '.join(missing)}")

    def reset(self, seeds: list[int]) -> None:
        for a in LOCAL_AGENTS:
            self.locals[a].reset(list(seeds))
        self.global_policy.reset(list(seeds))

    def messages(self, local_obs: dict, n: int) -> dict[str, np.ndarray]:
        """Every local's message (checked against the budget) from its own observation."""
        return {a: self.budget.check(a, self.locals[a].message(local_obs[a]), n) for a in LOCAL_AGENTS}


class TeamAgent:
    """A :class:`Team` as a benchmark agent of the single-agent environment (module docstring)."""

    def __init__(self, team: Team) -> None:
        self.team = team
        self.name = team.name
        self.env_kwargs = dict(team.env_kwargs)
        if team.observe_sensors:
            self.env_kwargs["observe_sensors"] = True
        if team.training_seed is not None:
            self.training_seed = team.training_seed
        names = feature_names(team.observe_sensors)
        self._width = len(names)
        self._columns = {a: local_columns(a, names, team.observe_sensors) for a in LOCAL_AGENTS}

    def reset(self, seeds: list[int]) -> None:
        self.team.reset(seeds)

    def act(self, obs: np.ndarray, infos: dict) -> np.ndarray:
        obs = np.asarray(obs, dtype=np.float32)
        if obs.ndim != 2 or obs.shape[1] != self._width:
            raise ValueError(f"{self.name}: expects observations of {self._width} features, got shape {obs.shape}")
        n = len(obs)
        msgs = self.team.messages({a: obs[:, c] for a, c in self._columns.items()}, n)
        return self.team.global_policy.declare(np.concatenate([msgs[a] for a in LOCAL_AGENTS], axis=1))


def play(team: Team, env, obs: dict, seeds: list[int], on_step=None) -> None:
    """Run ``team`` on a :class:`~.batch.MultiAgentBatchEnv` just reset (``obs``: its first observations)
    until every episode has ended; ``on_step(env, seconds)`` after every step (``seconds``: the wall
    time the team's policies took)."""
    import time

    n = env.num_envs
    team.reset(seeds)
    first = True
    idle = np.zeros((n, N_HYPOTHESES), dtype=np.float32)
    while not env.done.all():
        t0 = time.perf_counter()
        acts: dict = team.messages({a: obs[a] for a in LOCAL_AGENTS}, n)
        # the global's first call would answer no message: it is not made (its action is not scored)
        acts[GLOBAL_AGENT] = idle if first else check_action(team.global_policy.declare(obs[GLOBAL_AGENT]), n_envs=n)
        spent = time.perf_counter() - t0
        obs, *_ = env.step(acts)
        first = False
        if on_step is not None:
            on_step(env, spent)
