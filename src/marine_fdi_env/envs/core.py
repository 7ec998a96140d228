"""N episodes of ``MarineFDI-v0`` advanced together: one batched :class:`Simulator` and one
streaming :class:`ReferenceDiagnoser` (the feature generator), one slot per episode.

The single environment is this with N = 1 and the vector environment with N = num_envs; since
the simulator and the diagnoser treat every engine independently (bit for bit), a slot's episode
does not depend on what the other slots do, nor on when they restart.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from ..diagnosis.agent import ReferenceDiagnoser
from ..faults import FAULT_IDS, _window_time
from ..params import EngineParams, load_params
from ..simulator import Simulator
from .hypotheses import DECLARE_THRESHOLD, N_FAULTS, UNKNOWN
from .observation import module_features, observation_size, sensor_features
from .reward import REWARD_TERMS, RewardConfig, score
from .scenario_sampler import ScenarioSpec, nominal_reading

__all__ = ["EpisodeBatch", "StepOutcome"]

_FAULT_COL = {f: k for k, f in enumerate(FAULT_IDS)}


@dataclass
class StepOutcome:
    """Scores of one decision for every slot."""

    reward: np.ndarray  # (N,)
    terms: dict[str, np.ndarray]  # term -> (N,)
    declared: list[tuple[str, ...]]
    alarm: np.ndarray  # (N,) bool
    belief_on_truth: np.ndarray  # (N,) (NaN when no fault is active)


class EpisodeBatch:
    """Episodes of N engines, advanced one decision period at a time."""

    def __init__(self, n: int, params: "str | EngineParams" = "thesis-12v28", decision_period_s: float = 1.0,
                 dt: float = 0.01, observe_sensors: bool = False, reward: RewardConfig | None = None,
                 noise_scale: float = 1.0) -> None:
        self.n = int(n)
        self.params = load_params(params) if isinstance(params, str) else params
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a positive number of seconds, got {dt!r}")
        if not (isinstance(decision_period_s, (int, float)) and math.isfinite(decision_period_s)
                and decision_period_s > 0):
            raise ValueError(f"decision_period_s must be a positive number of seconds, got {decision_period_s!r}")
        k = decision_period_s / dt
        if abs(k - round(k)) > 1e-9 * max(1.0, k) or round(k) < 1:
            raise ValueError(f"decision_period_s ({decision_period_s}) must be a whole number of samples of dt ({dt})")
        self.dt = float(dt)
        self.period_samples = int(round(k))
        self.decision_period_s = self.period_samples * self.dt
        self.observe_sensors = bool(observe_sensors)
        self.reward_cfg = reward or RewardConfig()
        self.noise_scale = float(noise_scale)
        self.obs_size = observation_size(self.observe_sensors)
        self.sim: Simulator | None = None
        self.diag = ReferenceDiagnoser(self.params, n_engines=self.n, dt=self.dt)
        self.scenarios: list[ScenarioSpec | None] = [None] * self.n
        self._truth: list[list[dict]] = [[] for _ in range(self.n)]  # per slot, computed once per episode
        self._durations = np.ones(self.n)  # episode lengths [s]
        self.steps = np.zeros(self.n, dtype=np.int64)  # decisions taken this episode
        self.obs = np.zeros((self.n, self.obs_size), dtype=np.float32)
        self.failure: list[dict | None] = [None] * self.n
        self.compute_s = np.zeros(self.n)
        self._nominal = None
        if self.observe_sensors:
            from ..sensors import SENSOR_IDS

            self._nominal = np.array([nominal_reading(s) for s in SENSOR_IDS])

    # ------------------------------------------------------------------------------ episodes
    def start(self, slots, scenarios: list[ScenarioSpec]) -> None:
        """Start new episodes in ``slots`` and advance them by their first decision period.

        The other slots must be at a decision boundary too (they are, in the environments): all
        engines then advance together by one period, and the other slots' observations are kept.
        """
        slots = [int(s) for s in slots]
        for sc in scenarios:
            if sc.noise_scale != self.noise_scale:
                raise ValueError(f"scenario field 'noise_scale' ({sc.noise_scale}) must equal the environment's "
                                 f"({self.noise_scale})")
        seeds = [sc.noise_seed for sc in scenarios]
        faults = [list(sc.faults) for sc in scenarios]
        profiles = [sc.profile for sc in scenarios]
        n_before = 0 if self.sim is None else len(self.sim.failures)
        if self.sim is None:
            if len(slots) != self.n:
                raise RuntimeError("the first start must start every slot")
            order = np.argsort(slots)
            self.sim = Simulator(self.params, n_engines=self.n, seeds=[seeds[i] for i in order],
                                 faults=[faults[i] for i in order], profiles=[profiles[i] for i in order],
                                 dt=self.dt, noise_scale=self.noise_scale)
        else:
            self.sim.restart_engines(slots, seeds, faults, profiles)
        self.diag.reset_engines(slots, first_sample_index=1)
        self.t = self.sim.local_time
        for s, sc in zip(slots, scenarios):
            self.scenarios[s] = sc
            self._truth[s] = sc.truth()
            self._durations[s] = sc.duration_s
            self.steps[s] = 0
            self.failure[s] = None
            self.compute_s[s] = 0.0
        for f in self.sim.failures[n_before:]:  # engines outside their physical range at t = 0
            self.failure[f.engine] = f.to_dict()
        self._failures_seen = len(self.sim.failures)

    def advance(self, slots=None) -> np.ndarray:
        """Advance all engines one decision period; update the observations of ``slots`` (default all).

        Returns the slots whose engine failed during the period.
        """
        blk = self.sim.advance(self.period_samples)
        t0 = time.perf_counter()
        out = self.diag.observe(blk.measurements, blk.u)
        t_now = self.t = self.sim.local_time
        durations = self._durations
        feats = module_features(out.residuals, out.thresholds, self.diag.first_violation, t_now, durations)
        if self.observe_sensors:
            feats = np.concatenate([feats, sensor_features(blk.measurements, blk.u, self._nominal)], axis=1)
        elapsed = time.perf_counter() - t0
        sel = np.arange(self.n) if slots is None else np.asarray(slots, dtype=np.int64)
        self.obs[sel] = feats[sel]
        self.compute_s += elapsed / self.n
        failed = []
        for f in self.sim.failures[self._failures_seen:]:
            self.failure[f.engine] = f.to_dict()
            failed.append(f.engine)
        self._failures_seen = len(self.sim.failures)
        return np.asarray(failed, dtype=np.int64)

    # ------------------------------------------------------------------------------ truth
    def time(self, slot: int) -> float:
        return float(self.t[slot])

    def active_faults(self, slot: int, t: float | None = None) -> dict[str, float]:
        """Faults active in the slot's episode at time t (default now): id -> onset [s].

        The same activity windows as the simulator's ground truth (``faults._window_time``)."""
        t = self.time(slot) if t is None else t
        out = {}
        for f in self.scenarios[slot].faults:
            inf = math.inf
            s = _window_time(t, f.onset_s, inf if f.end_s is None else f.end_s,
                             inf if f.period_s is None else f.period_s, 1.0 if f.duty is None else f.duty)
            if not np.isnan(s):
                out[f.fault_id] = float(f.onset_s)
        return out

    def active_matrix(self, slots) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(active (n, 26) bool, first onset (n,), last onset (n,)) of the slots' faults now."""
        n = len(slots)
        act = np.zeros((n, N_FAULTS), dtype=bool)
        first = np.zeros(n)
        last = np.zeros(n)
        for j, s in enumerate(slots):
            on = self.active_faults(s)
            if on:
                act[j, [_FAULT_COL[f] for f in on]] = True
                first[j] = min(on.values())
                last[j] = max(on.values())
        return act, first, last

    def score(self, beliefs: np.ndarray, slots) -> StepOutcome:
        """Score the declarations ``beliefs`` (len(slots), 28) made now."""
        slots = np.asarray(slots, dtype=np.int64)
        decl = beliefs[:, :N_FAULTS] >= DECLARE_THRESHOLD
        alarm = decl.any(axis=1) | (beliefs[:, UNKNOWN] >= DECLARE_THRESHOLD)
        act, first, last = self.active_matrix(slots)
        terms = score(self.reward_cfg, decl, alarm, act, first, last, self.t[slots])
        reward = sum(terms[k] for k in REWARD_TERMS)
        total = beliefs.sum(axis=1, dtype=np.float64)
        on_truth = np.where(act, beliefs[:, :N_FAULTS], 0.0).sum(axis=1, dtype=np.float64)
        with np.errstate(invalid="ignore", divide="ignore"):
            share = np.where(total > 0, on_truth / total, 0.0)
        share = np.where(act.any(axis=1), share, np.nan)
        declared = [tuple(FAULT_IDS[k] for k in np.flatnonzero(row)) for row in decl]
        return StepOutcome(reward, terms, declared, alarm, share)

    def reference_declaration(self, slot: int) -> dict:
        """The reference diagnoser's current conclusion for a slot (the ``reference`` agent's input)."""
        st = self.diag.decisions[slot]
        return {"detected": bool(st.detected),
                "diagnoses": [sorted(d) for d in st.diagnoses] if st.detected else []}

    def info(self, slot: int) -> dict:
        sc = self.scenarios[slot]
        t = self.time(slot)
        act = self.active_faults(slot, t)
        return {
            "t_s": t,
            "scenario_id": sc.scenario_id,
            "profile": sc.profile,
            "true_faults": [dict(f) for f in self._truth[slot]],
            "active_faults": sorted(act, key=FAULT_IDS.index),
            "engine_failure": self.failure[slot],
            "reference": self.reference_declaration(slot),
        }
