"""Vector ``MarineFDI-v0``: N engines advanced in one batched call per decision period.

``gymnasium.make_vec("marine_fdi_env:MarineFDI-v0", num_envs=N, vectorization_mode="vector_entry_point")``.
Sub-environment i behaves exactly, bit for bit, like a single ``MarineFDI-v0`` reset with seed
``seed + i`` (and then reset without a seed at every episode end): each slot has its own
``np_random`` for its scenarios and its own engine, noise and observers; the batch only shares
the compiled calls.  Autoreset is Gymnasium's default next-step mode: after a slot's episode ends,
the next ``step`` ignores its action and returns the first observation of a new episode with
reward 0 and ``terminated = truncated = False``.
"""

from __future__ import annotations

import math

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from .core import EpisodeBatch
from .hypotheses import HYPOTHESES, N_HYPOTHESES, check_action
from .observation import feature_names, observation_bounds
from .reward import RewardConfig
from .scenario_sampler import ScenarioConfig, ScenarioSpec, get_preset

__all__ = ["MarineFDIVectorEnv"]


class MarineFDIVectorEnv(VectorEnv):
    """``num_envs`` episodes of ``MarineFDI-v0`` on one batched simulator (see module docstring).

    Arguments are those of :class:`~marine_fdi_env.envs.fdi_env.MarineFDIEnv` plus ``num_envs``.
    ``reset(options={"scenarios": [ScenarioSpec | dict, ...]})`` runs given scenarios (one per
    sub-environment) instead of drawn ones.
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int = 1, scenario_config: "str | ScenarioConfig | dict" = "default",
                 decision_period_s: float = 1.0, observe_sensors: bool = False,
                 reward: RewardConfig | dict | None = None, params: str = "thesis-12v28", dt: float = 0.01,
                 render_mode: str | None = None) -> None:
        if not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs must be a positive integer, got {num_envs!r}")
        if render_mode is not None:
            raise ValueError("the vector environment does not render; use render_mode=None")
        self.num_envs = int(num_envs)
        self.scenario_config = get_preset(scenario_config)
        if isinstance(reward, dict):
            reward = RewardConfig(**reward)
        self.batch = EpisodeBatch(self.num_envs, params, decision_period_s, dt, observe_sensors, reward,
                                  noise_scale=self.scenario_config.noise_scale)
        low, high = observation_bounds(observe_sensors)
        self.single_observation_space = spaces.Box(low, high, dtype=np.float32)
        self.single_action_space = spaces.Box(0.0, 1.0, (N_HYPOTHESES,), dtype=np.float32)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.feature_names = feature_names(observe_sensors)
        self.hypotheses = HYPOTHESES
        self._rngs: list[np.random.Generator | None] = [None] * self.num_envs
        self._autoreset = np.zeros(self.num_envs, dtype=bool)
        self._started = False

    def _slot_rng(self, i: int) -> np.random.Generator:
        if self._rngs[i] is None:
            self._rngs[i], _ = seeding.np_random()
        return self._rngs[i]

    def reset(self, *, seed: "int | list[int | None] | None" = None, options: dict | None = None):
        n = self.num_envs
        if seed is None:
            seeds = [None] * n
        elif isinstance(seed, (int, np.integer)):
            seeds = [int(seed) + i for i in range(n)]
        else:
            seeds = list(seed)
            if len(seeds) != n:
                raise ValueError(f"seed must be an int or a list of {n} seeds, got {len(seeds)}")
        for i, s in enumerate(seeds):
            if s is not None:
                self._rngs[i], _ = seeding.np_random(s)
        if seed is not None:
            self._np_random, self._np_random_seed = seeding.np_random(seeds[0])
        scenarios = self._scenarios_from_options(options)
        if scenarios is None:
            scenarios = [self._draw(i) for i in range(n)]
        self.batch.start(range(n), scenarios)
        self.batch.advance()
        self._autoreset[:] = False
        self._started = True
        infos = _stack_infos([_uniform(self.batch.info(i)) for i in range(n)])
        return self.batch.obs.copy(), infos

    def _draw(self, i: int) -> ScenarioSpec:
        return self.scenario_config.sample(int(self._slot_rng(i).integers(0, 2**63 - 1)))

    def _scenarios_from_options(self, options) -> list[ScenarioSpec] | None:
        if not options:
            return None
        if not isinstance(options, dict) or set(options) - {"scenarios"}:
            raise ValueError("options must be a dict with the single key 'scenarios' (one scenario per sub-env)")
        sc = options["scenarios"]
        if len(sc) != self.num_envs:
            raise ValueError(f"options['scenarios'] must hold {self.num_envs} scenarios, got {len(sc)}")
        return [s if isinstance(s, ScenarioSpec) else ScenarioSpec.from_dict(s) for s in sc]

    def step(self, actions):
        if not self._started:
            raise RuntimeError("step() called before reset()")
        b = self.batch
        n = self.num_envs
        beliefs = check_action(actions, n_envs=n)
        resetting = np.flatnonzero(self._autoreset)
        live = np.flatnonzero(~self._autoreset)
        rewards = np.zeros(n)
        terminated = np.zeros(n, dtype=bool)
        truncated = np.zeros(n, dtype=bool)
        out = b.score(beliefs[live], live)
        decision_t = {}
        for j, i in enumerate(live):
            b.steps[i] += 1
            rewards[i] = out.reward[j]
            decision_t[i] = b.time(i)
            if b.failure[i] is not None:
                terminated[i] = True
            elif decision_t[i] >= b.scenarios[i].duration_s - 1e-9:
                truncated[i] = True
        ended = terminated | truncated
        final_infos = {int(i): b.info(int(i)) for i in np.flatnonzero(ended)}  # before their engines move on
        if len(resetting):
            b.start(resetting, [self._draw(int(i)) for i in resetting])
        advancing = np.flatnonzero(~ended)  # live slots going on, and the new episodes
        failed = b.advance(advancing)
        for i in failed:
            if i in live and not (terminated[i] or truncated[i]):
                terminated[i] = True
        per_slot: list[dict | None] = [None] * n
        for j, i in enumerate(live):
            info = final_infos[int(i)] if ended[i] else b.info(i)
            info.update(declared=list(out.declared[j]), alarm=bool(out.alarm[j]),
                        belief_on_truth=float(out.belief_on_truth[j]),
                        reward_terms={k: float(v[j]) for k, v in out.terms.items()}, decision_time_s=decision_t[i])
            if terminated[i]:
                info["termination_reason"] = f"engine failure: {b.failure[i]['reason']}"
            per_slot[i] = info
        for i in resetting:
            per_slot[i] = b.info(int(i))
        infos = _stack_infos([_uniform(x) if x is not None else None for x in per_slot])
        self._autoreset = terminated | truncated
        return b.obs.copy(), rewards, terminated, truncated, infos


_NO_FAILURE = {"engine": -1, "time_s": math.nan, "reason": ""}


def _uniform(info: dict) -> dict:
    """One type per info key across sub-envs (Gymnasium stacks them into arrays): None -> NaN."""
    info = dict(info)
    if info.get("engine_failure") is None:
        info["engine_failure"] = dict(_NO_FAILURE)
    if "belief_on_truth" in info and info["belief_on_truth"] is None:
        info["belief_on_truth"] = math.nan
    return info


def _stack_infos(per_slot: list[dict | None]) -> dict:
    """Gymnasium's vector info layout (``infos[key][i]`` with a mask ``infos["_" + key]``), built in
    one pass instead of one ``_add_info`` merge per sub-env (measured 0.13 s per step at N = 1024)."""
    n = len(per_slot)
    keys: list[str] = []
    for d in per_slot:
        if d is not None:
            keys.extend(k for k in d if k not in keys)
    out: dict = {}
    for k in keys:
        vals = [None if d is None or k not in d else d[k] for d in per_slot]
        mask = np.array([d is not None and k in d for d in per_slot], dtype=bool)
        first = next(v for v, m in zip(vals, mask) if m)
        if isinstance(first, dict):
            out[k] = _stack_infos([v if m else None for v, m in zip(vals, mask)])
        elif type(first) in (int, float, bool) or isinstance(first, np.number):
            arr = np.zeros(n, dtype=type(first))
            for i in np.flatnonzero(mask):
                arr[i] = vals[i]
            out[k] = arr
        else:
            arr = np.full(n, None, dtype=object)
            for i in np.flatnonzero(mask):
                arr[i] = vals[i]
            out[k] = arr
        out["_" + k] = mask
    return out
