"""MarineFDI-v1 replayed from recorded episodes: the same observations and rewards, without the simulator.

The engine does not react to the declarations (a monitoring task, docs/environment.md): an
episode's observations and ground truth do not depend on the actions.  So an episode recorded
once (``marine-fdi dataset``: the observation, the active faults and the decision time at every
decision) can be played again under *any* sequence of actions, scoring each action with the
environment's own reward code (:class:`marine_fdi_env.envs.reward.RewardV1`): the transitions and
rewards are exactly those of the live environment on that episode (tested in
``tests/integration/test_rl_agent.py``: observations and rewards bit for bit; one difference: after an engine
failure the live environment returns an observation of the failing period as the last one, which
a dataset does not record, so the replay repeats the last recorded one; SB3 bootstraps values
only on time-limit truncations, never on such terminations).  Reinforcement learning on a
pool of recorded episodes is then about 100x cheaper per decision than simulating it again; what
the agent learns from is still only its reward and the observation features.

:class:`ReplayVecEnv` is an SB3 ``VecEnv`` (same-step autoreset, ``terminal_observation``); each
slot plays episodes drawn at random from the pool (seeded), and the agent's preprocessing
(:class:`marine_fdi_env.training.features.AgentFeatures`) is applied inside, with its per-episode state.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
from stable_baselines3.common.vec_env import VecEnv

from marine_fdi_env.envs.hypotheses import DECLARE_THRESHOLD, N_FAULTS, UNKNOWN
from marine_fdi_env.envs.reward import REWARD_TERMS_V1, RewardConfigV1, RewardV1

from .features import AgentFeatures
from .vec_adapter import action_space, to_belief

__all__ = ["ReplayVecEnv", "load_episodes", "declaration_masks"]


def load_episodes(dirs) -> dict:
    """Episodes of one or more ``marine-fdi dataset`` exports, concatenated: ``obs`` (E, T, D),
    ``active`` (E, T, 26), ``valid`` (E, T), ``t_s`` (E, T), ``first_onset`` (E,) [s] (+inf: no
    fault), ``feature_names``."""
    parts = []
    for d in dirs:
        d = Path(d)
        with np.load(d / "dataset.npz") as z:
            arr = {k: z[k] for k in ("obs", "active", "valid", "t_s", "feature_names")}
        scs = json.loads((d / "scenarios.json").read_text())["scenarios"]
        arr["first_onset"] = np.array([min((f["onset_s"] for f in s["faults"]), default=math.inf) for s in scs])
        if len(scs) != len(arr["obs"]):
            raise ValueError(f"{d}: scenarios.json lists {len(scs)} episodes, dataset.npz holds {len(arr['obs'])}")
        parts.append(arr)
    names = [str(x) for x in parts[0]["feature_names"]]
    for p, d in zip(parts, dirs):
        if [str(x) for x in p["feature_names"]] != names:
            raise ValueError(f"{d}: other observation features than {dirs[0]}")
    T = max(p["obs"].shape[1] for p in parts)
    out = {}
    for k in ("obs", "active", "valid", "t_s"):
        pads = []
        for p in parts:
            a = p[k]
            if a.shape[1] < T:
                a = np.concatenate([a, np.zeros((a.shape[0], T - a.shape[1]) + a.shape[2:], a.dtype)], axis=1)
            pads.append(a)
        out[k] = np.concatenate(pads)
    out["first_onset"] = np.concatenate([p["first_onset"] for p in parts])
    out["feature_names"] = names
    return out


def declaration_masks(beliefs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(declared (n, 26), alarm (n,)) of beliefs, as the environment reads them."""
    declared = beliefs[:, :N_FAULTS] >= DECLARE_THRESHOLD
    return declared, declared.any(axis=1) | (beliefs[:, UNKNOWN] >= DECLARE_THRESHOLD)


class ReplayVecEnv(VecEnv):
    """``num_envs`` slots replaying recorded episodes under MarineFDI-v1's reward (module docstring).

    ``order="random"``: each slot draws its next episode uniformly from the pool (``seed``);
    ``"sequential"``: slot i plays episodes i, i + n, ... (tests).  ``features``: the agent's
    preprocessing (None: the raw observation).
    """

    def __init__(
        self,
        episodes: dict,
        num_envs: int,
        action_mode: str = "pair",
        seed: int = 0,
        reward: RewardConfigV1 | None = None,
        features: AgentFeatures | None = None,
        decision_period_s: float = 1.0,
        order: str = "random",
    ) -> None:
        self.ep = episodes
        self.E, self.T = episodes["obs"].shape[:2]
        self.lengths = episodes["valid"].sum(axis=1).astype(np.int64)
        if np.any(self.lengths < 1):
            raise ValueError("every replayed episode needs at least one decision")
        self.action_mode = action_mode
        self.features = features
        self.period = float(decision_period_s)
        self.reward = RewardV1(reward or RewardConfigV1(), num_envs)
        self.rng = np.random.default_rng(seed)
        self.order = order
        self.render_mode = None
        from gymnasium import spaces

        if features is None:
            obs_space = spaces.Box(-np.inf, np.inf, (episodes["obs"].shape[2],), np.float32)
        else:
            obs_space = spaces.Box(-np.inf, np.inf, (features.size,), np.float32)
        super().__init__(num_envs, obs_space, action_space(action_mode))
        self.episode = np.zeros(num_envs, dtype=np.int64)
        self.k = np.zeros(num_envs, dtype=np.int64)
        self.played = 0
        self.state = features.initial_state(num_envs) if features is not None else None
        self.episode_returns = np.zeros(num_envs)
        self.episode_terms = {t: np.zeros(num_envs) for t in REWARD_TERMS_V1}
        self._actions = None

    # ------------------------------------------------------------------ episodes
    def _draw(self, slots: np.ndarray) -> None:
        for i in slots:
            if self.order == "sequential":
                e = (int(i) + self.num_envs * self.played_by_slot[i]) % self.E
                self.played_by_slot[i] += 1
            else:
                e = int(self.rng.integers(self.E))
            self.episode[i] = e
            self.k[i] = 0
            self.reward.start(int(i), float(self.ep["first_onset"][e]))
        self.played += len(slots)
        self.episode_returns[slots] = 0.0
        for v in self.episode_terms.values():
            v[slots] = 0.0
        if self.state is not None:
            self.features.restart(self.state, slots)

    def _obs(self) -> np.ndarray:
        raw = self.ep["obs"][self.episode, self.k]
        self._last = raw.copy() if self.features is None else self.features(raw, self.state)
        return self._last

    # ------------------------------------------------------------------ VecEnv API
    def reset(self):
        self.played_by_slot = np.zeros(self.num_envs, dtype=np.int64)
        self._draw(np.arange(self.num_envs))
        return self._obs()

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = actions

    def step_wait(self):
        n = self.num_envs
        beliefs = to_belief(self._actions, self.action_mode)
        declared, alarm = declaration_masks(beliefs)
        slots = np.arange(n)
        e, k = self.episode, self.k
        terms = self.reward.score(slots, declared, alarm, self.ep["active"][e, k], self.ep["t_s"][e, k], self.period)
        last = k + 1 >= self.lengths[e]
        ended = np.flatnonzero(last)
        if len(ended):
            for name, v in self.reward.end(ended).items():
                terms[name][ended] += v
        rew = sum(terms[t] for t in REWARD_TERMS_V1)
        self.episode_returns += rew
        for t in REWARD_TERMS_V1:
            self.episode_terms[t] += terms[t]
        if self.state is not None:
            self.features.set_alarm(self.state, alarm)
        infos: list[dict] = [{} for _ in range(n)]
        self.k = np.where(last, k, k + 1)
        if len(ended):
            term_obs = self._last  # the episode's last observation (the live env returns it again)
            for i in ended:
                truncated = bool(self.lengths[e[i]] == self.T)  # time limit, else an engine failure
                infos[i] = {
                    "terminal_observation": term_obs[i].copy(),
                    "TimeLimit.truncated": truncated,
                    "episode": {
                        "r": float(self.episode_returns[i]),
                        "l": int(self.lengths[e[i]]),
                        "terms": {t: float(self.episode_terms[t][i]) for t in REWARD_TERMS_V1},
                    },
                }
            self._draw(ended)
        obs = self._obs()
        return obs, rew.astype(np.float32), last.copy(), infos

    def close(self) -> None:
        pass

    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        idx = list(self._get_indices(indices))
        return [None if attr_name == "render_mode" else getattr(self, attr_name)] * len(idx)

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        setattr(self, attr_name, value)

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list[Any]:
        raise ValueError(f"the replay env has no method {method_name!r}")

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return [False] * len(list(self._get_indices(indices)))
