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

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from .core import EpisodeBatch
from .hypotheses import HYPOTHESES, N_HYPOTHESES, check_action
from .observation import feature_names, observation_bounds
from .rendering import supported_render_mode
from .reward import RewardConfig, RewardConfigV1, make_reward_config
from .scenario_sampler import ScenarioConfig, ScenarioSpec, get_preset

__all__ = ["MarineFDIVectorEnv", "scatter_infos", "object_array", "reseed_slots"]


class MarineFDIVectorEnv(VectorEnv):
    """``num_envs`` episodes of ``MarineFDI-v0`` on one batched simulator (see module docstring).

    Arguments are those of :class:`~marine_fdi_env.envs.fdi_env.MarineFDIEnv` plus ``num_envs``.
    ``reset(options={"scenarios": [ScenarioSpec | dict, ...]})`` runs given scenarios (one per
    sub-environment) instead of drawn ones.
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(
        self,
        num_envs: int = 1,
        scenario_config: "str | ScenarioConfig | dict" = "default",
        decision_period_s: float = 1.0,
        observe_sensors: bool = False,
        reward: "RewardConfig | RewardConfigV1 | dict | str | None" = None,
        params: str = "thesis-12v28",
        dt: float = 0.01,
        render_mode: str | None = None,
        observe_sequential: bool = False,
        diagnosis_cells: str = "sized",
        diagnosis_thresholds: str = "local",
    ) -> None:
        if not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs must be a positive integer, got {num_envs!r}")
        self.render_mode = supported_render_mode(render_mode, self.metadata["render_modes"])
        self.num_envs = int(num_envs)
        self.scenario_config = get_preset(scenario_config)
        reward = make_reward_config(reward)
        self.batch = EpisodeBatch(
            self.num_envs,
            params,
            decision_period_s,
            dt,
            observe_sensors,
            reward,
            noise_scale=self.scenario_config.noise_scale,
            observe_sequential=observe_sequential,
            diagnosis_cells=diagnosis_cells,
            diagnosis_thresholds=diagnosis_thresholds,
        )
        low, high = observation_bounds(observe_sensors, observe_sequential)
        self.single_observation_space = spaces.Box(low, high, dtype=np.float32)
        self.single_action_space = spaces.Box(0.0, 1.0, (N_HYPOTHESES,), dtype=np.float32)
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.feature_names = feature_names(observe_sensors, observe_sequential)
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
        seeds = reseed_slots(self._rngs, seed)
        if seed is not None:
            self._np_random, self._np_random_seed = seeding.np_random(seeds[0])
        scenarios = self._scenarios_from_options(options)
        if scenarios is None:
            scenarios = [self._draw(i) for i in range(n)]
        self.batch.start(range(n), scenarios)
        self.batch.advance()
        self._autoreset[:] = False
        self._started = True
        infos = scatter_infos(n, [(np.arange(n), self.batch.info_arrays(np.arange(n)))])
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
        b.steps[live] += 1
        rewards[live] = out.reward
        decision_t = b.t[live].astype(float)
        terminated[live] = b.failed[live]
        truncated[live] = ~terminated[live] & (decision_t >= b.durations[live] - 1e-9)
        ended = np.flatnonzero(terminated | truncated)
        final = b.info_arrays(ended)  # before their engines move on
        if len(resetting):
            b.start(resetting, [self._draw(int(i)) for i in resetting])
        advancing = np.flatnonzero(~(terminated | truncated))  # live slots going on, and the new episodes
        failed = b.advance(advancing)
        live_mask = ~self._autoreset
        for i in failed:
            if live_mask[i] and not (terminated[i] or truncated[i]):
                terminated[i] = True
        b.end_terms(out, live, live[(terminated | truncated)[live]])  # v1: missed detections
        rewards[live] = out.reward
        infos = scatter_infos(n, [(ended, final), (advancing, b.info_arrays(advancing))])
        declared = object_array([list(d) for d in out.declared])
        infos.update(
            scatter_infos(
                n,
                [
                    (
                        live,
                        {
                            "declared": declared,
                            "alarm": out.alarm,
                            "belief_on_truth": out.belief_on_truth.astype(float),
                            "reward_terms": {k: v.astype(float) for k, v in out.terms.items()},
                            "decision_time_s": decision_t,
                        },
                    )
                ],
            )
        )
        stopped = np.flatnonzero(terminated)
        reasons = object_array([f"engine failure: {b.failure[i]['reason']}" for i in stopped])
        infos.update(scatter_infos(n, [(stopped, {"termination_reason": reasons})]))
        self._autoreset = terminated | truncated
        return b.obs.copy(), rewards, terminated, truncated, infos


def object_array(values: list) -> np.ndarray:
    """A 1-d object array holding the given Python objects (lists stay lists)."""
    arr = np.empty(len(values), dtype=object)
    for j, v in enumerate(values):
        arr[j] = v
    return arr


def scatter_infos(n: int, pieces: list[tuple[np.ndarray, dict]]) -> dict:
    """Gymnasium's vector info layout (``infos[key][i]`` with a mask ``infos["_" + key]``) from info
    arrays over disjoint sets of slots (:meth:`EpisodeBatch.info_arrays`), built with array
    assignments instead of one ``_add_info`` merge per sub-env (measured 0.13 s per step at N = 1024)."""
    pieces = [(np.asarray(sl, dtype=np.int64), p) for sl, p in pieces if len(sl)]
    if not pieces:
        return {}
    if len(pieces) == 1 and len(pieces[0][0]) == n and np.array_equal(pieces[0][0], np.arange(n)):
        return _every_slot(n, pieces[0][1])  # the same arrays, without the assignments
    out: dict = {}
    mask = np.zeros(n, dtype=bool)
    for sl, _ in pieces:
        mask[sl] = True
    for key, v in pieces[0][1].items():
        if isinstance(v, dict):
            out[key] = scatter_infos(n, [(sl, p[key]) for sl, p in pieces])
        else:
            arr = np.full(n, None, dtype=object) if v.dtype == object else np.zeros(n, dtype=v.dtype)
            for sl, p in pieces:
                arr[sl] = p[key]
            out[key] = arr
        out["_" + key] = mask.copy()
    return out


def _every_slot(n: int, piece: dict) -> dict:
    """:func:`scatter_infos` of one piece whose slots are 0..n-1 in order: copies of its arrays."""
    out: dict = {}
    for key, v in piece.items():
        out[key] = _every_slot(n, v) if isinstance(v, dict) else v.copy()
        out["_" + key] = np.ones(n, dtype=bool)
    return out


def reseed_slots(rngs: list, seed: "int | list[int | None] | None") -> list:
    """Gymnasium's vector seeding: ``seed`` an int seeds slot ``i`` with ``seed + i``, a list one seed per slot
    (None keeps a slot's generator), None none; reseeds ``rngs`` in place and returns the per-slot seeds."""
    n = len(rngs)
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
            rngs[i], _ = seeding.np_random(s)
    return seeds
