"""N episodes of ``MarineFDI-v0`` advanced together: one batched :class:`Simulator` and one
streaming :class:`ReferenceDiagnoser` (the feature generator), one slot per episode.

The single environment is this with N = 1 and the vector environment with N = num_envs; since
the simulator and the diagnoser treat every engine independently (bit for bit), a slot's episode
does not depend on what the other slots do, nor on when they restart.
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..diagnosis.agent import ReferenceDiagnoser
from ..diagnosis.sequential import SequentialStage, pressure_ratio
from ..engine.faults import FAULT_IDS
from ..engine.params import EngineParams, load_params
from ..engine.simulator import Simulator
from .fault_windows import FaultWindows
from .observation import module_features, observation_size, sensor_features
from .reward import RewardConfig, RewardConfigV1
from .scenario_sampler import ScenarioSpec, nominal_reading
from .scoring import DecisionScorer, StepOutcome, row_members

__all__ = ["EpisodeBatch", "StepOutcome"]


class EpisodeBatch:
    """Episodes of N engines, advanced one decision period at a time."""

    def __init__(
        self,
        n: int,
        params: "str | EngineParams" = "thesis-12v28",
        decision_period_s: float = 1.0,
        dt: float = 0.01,
        observe_sensors: bool = False,
        reward: RewardConfig | RewardConfigV1 | None = None,
        noise_scale: float = 1.0,
        observe_sequential: bool = False,
        diagnosis_cells: str = "sized",
        diagnosis_thresholds: str = "local",
    ) -> None:
        self.n = int(n)
        self.params = load_params(params) if isinstance(params, str) else params
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a positive number of seconds, got {dt!r}")
        if not (
            isinstance(decision_period_s, (int, float)) and math.isfinite(decision_period_s) and decision_period_s > 0
        ):
            raise ValueError(f"decision_period_s must be a positive number of seconds, got {decision_period_s!r}")
        k = decision_period_s / dt
        if abs(k - round(k)) > 1e-9 * max(1.0, k) or round(k) < 1:
            raise ValueError(f"decision_period_s ({decision_period_s}) must be a whole number of samples of dt ({dt})")
        self.dt = float(dt)
        self.period_samples = int(round(k))
        self.decision_period_s = self.period_samples * self.dt
        self.observe_sensors = bool(observe_sensors)
        # MarineFDI-v1: the reward keeps per-slot state (previous alarm, detected); v0 is stateless
        self.scorer = DecisionScorer(reward, self.n, self.decision_period_s)
        self.reward_cfg = self.scorer.cfg
        self.noise_scale = float(noise_scale)
        self.observe_sequential = bool(observe_sequential)
        self.obs_size = observation_size(self.observe_sensors, self.observe_sequential)
        self.sim: Simulator | None = None
        # diagnosis_cells: the diagnosers' sure cells (thesis | grid | sized, diagnosis.cell_sets); only
        # info["reference"] / info["sequential"] depend on it, not the observation (decide_cells adds others)
        # diagnosis_thresholds: the reading of the observer modules' thresholds (diagnosis.thresholds); it
        # changes the reference's thresholds, so the observation too (the sequential tests: local only)
        if diagnosis_thresholds != "local" and self.observe_sequential:
            raise ValueError(
                f"observe_sequential needs diagnosis_thresholds='local' (the sequential diagnoser's tests are "
                f"calibrated on the local thresholds), got {diagnosis_thresholds!r}"
            )
        self.diag = ReferenceDiagnoser(
            self.params, n_engines=self.n, dt=self.dt, cells=diagnosis_cells, thresholds=diagnosis_thresholds
        )
        # the sequential diagnoser's tests on the same residuals (observe_sequential only)
        self.seq = SequentialStage(self.n, dt=self.dt, cells=diagnosis_cells) if self.observe_sequential else None
        self.scenarios: list[ScenarioSpec | None] = [None] * self.n
        self._truth: list[list[dict]] = [[] for _ in range(self.n)]  # per slot, computed once per episode
        self.durations = np.ones(self.n)  # episode lengths [s]
        self.steps = np.zeros(self.n, dtype=np.int64)  # decisions taken this episode
        self.obs = np.zeros((self.n, self.obs_size), dtype=np.float32)
        self.failure: list[dict | None] = [None] * self.n
        self.failed = np.zeros(self.n, dtype=bool)  # failure[i] is not None
        self.windows = FaultWindows(self.n)  # the slots' faults: which are active when
        self.compute_s = np.zeros(self.n)
        self._nominal = None
        if self.observe_sensors:
            from ..engine.sensors import SENSOR_IDS

            self._nominal = np.array([nominal_reading(s) for s in SENSOR_IDS])

    @property
    def cell_sets(self) -> tuple[str, ...]:
        """The cell sets the diagnosers decide with, ``diagnosis_cells`` first (the infos' one)."""
        return self.diag.cell_sets

    def decide_cells(self, cells) -> None:
        """Let the diagnosers decide with the cell sets ``cells`` too, on the same residuals and
        tests (:meth:`declarations`; the simulation, observation and infos do not change); before
        the first :meth:`start`."""
        if self.sim is not None:
            raise RuntimeError("decide_cells before the first start: a cell set decides from an episode's start")
        for c in cells:
            self.diag.add_cells(c)
            if self.seq is not None:
                self.seq.add_cells(c)

    def declarations(self, diagnoser: str, cells: str, slots) -> tuple[np.ndarray, np.ndarray]:
        """(detected, diagnoses) of ``slots`` now, as ``info[diagnoser]`` gives them (``reference``, or
        ``sequential`` with ``observe_sequential``), with the cell set ``cells`` (:attr:`cell_sets`)."""
        if diagnoser == "sequential" and self.seq is None:
            raise ValueError("no sequential diagnoser: the environment was made without observe_sequential")
        return (self.diag if diagnoser == "reference" else self.seq).decider(cells).declarations(slots)

    def reference_declaration(self, slot: int) -> dict:
        """The reference diagnoser's current conclusion for a slot (the ``reference`` agent's input)."""
        det, diag = self.declarations("reference", self.diag.cells, [slot])
        return {"detected": bool(det[0]), "diagnoses": diag[0]}

    def sequential_declaration(self, slot: int) -> dict:
        """The sequential diagnoser's current conclusion for a slot (``observe_sequential`` only)."""
        det, diag = self.declarations("sequential", self.seq.cells if self.seq else "", [slot])
        return {"detected": bool(det[0]), "diagnoses": diag[0]}

    # ------------------------------------------------------------------------------ episodes
    def start(self, slots, scenarios: list[ScenarioSpec]) -> None:
        """Start new episodes in ``slots`` and advance them by their first decision period.

        The other slots must be at a decision boundary too (they are, in the environments): all
        engines then advance together by one period, and the other slots' observations are kept.
        """
        slots = [int(s) for s in slots]
        for sc in scenarios:
            if sc.noise_scale != self.noise_scale:
                raise ValueError(
                    f"scenario field 'noise_scale' ({sc.noise_scale}) must equal the environment's ({self.noise_scale})"
                )
        seeds = [sc.noise_seed for sc in scenarios]
        faults = [list(sc.faults) for sc in scenarios]
        profiles = [sc.profile for sc in scenarios]
        n_before = 0 if self.sim is None else len(self.sim.failures)
        if self.sim is None:
            if len(slots) != self.n:
                raise RuntimeError("the first start must start every slot")
            order = np.argsort(slots)
            self.sim = Simulator(
                self.params,
                n_engines=self.n,
                seeds=[seeds[i] for i in order],
                faults=[faults[i] for i in order],
                profiles=[profiles[i] for i in order],
                dt=self.dt,
                noise_scale=self.noise_scale,
            )
        else:
            self.sim.restart_engines(slots, seeds, faults, profiles)
        self.diag.reset_engines(slots, first_sample_index=1)
        if self.seq is not None:
            self.seq.reset_engines(slots)
        self.t = self.sim.local_time
        for s, sc in zip(slots, scenarios):
            self.scenarios[s] = sc
            self._truth[s] = sc.truth()
            self.durations[s] = sc.duration_s
            self.steps[s] = 0
            self.failure[s] = None
            self.failed[s] = False
            self.compute_s[s] = 0.0
            self.windows.set(s, sc.faults)
            self.scorer.start(s, sc.faults)
        for f in self.sim.failures[n_before:]:  # engines outside their physical range at t = 0
            self._fail(f)
        self._failures_seen = len(self.sim.failures)

    def _fail(self, f) -> None:
        self.failure[f.engine] = f.to_dict()
        self.failed[f.engine] = True

    def advance(self, slots=None) -> np.ndarray:
        """Advance all engines one decision period; update the observations of ``slots`` (default all).

        Returns the slots whose engine failed during the period.
        """
        blk = self.sim.advance(self.period_samples)
        t0 = time.perf_counter()
        t_first = (self.diag.samples - self.diag._offset) * self.dt  # each engine's time of the period's first sample
        out = self.diag.observe(blk.measurements, blk.u)
        t_now = self.t = self.sim.local_time
        feats = module_features(
            out.residuals, out.thresholds, self.diag.first_violation, t_now, self.durations, out.stats
        )
        if self.observe_sensors:
            feats = np.concatenate([feats, sensor_features(blk.measurements, blk.u, self._nominal)], axis=1)
        if self.seq is not None:
            self.seq.update(
                out.residuals,
                blk.u,
                pressure_ratio(blk.measurements),
                out.violations,
                t_first,
                out.thresholds,
                out.peaks,
            )
            feats = np.concatenate([feats, self.seq.features()], axis=1)
        elapsed = time.perf_counter() - t0
        sel = np.arange(self.n) if slots is None else np.asarray(slots, dtype=np.int64)
        self.obs[sel] = feats[sel]
        self.compute_s += elapsed / self.n
        failed = []
        for f in self.sim.failures[self._failures_seen :]:
            self._fail(f)
            failed.append(f.engine)
        self._failures_seen = len(self.sim.failures)
        return np.asarray(failed, dtype=np.int64)

    # ------------------------------------------------------------------------------ truth
    def time(self, slot: int) -> float:
        return float(self.t[slot])

    def active_matrix(self, slots) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(active (n, 26) bool, first onset (n,), last onset (n,)) of the slots' faults now (onsets 0
        where none is active): the simulator's activity windows (:class:`.fault_windows.FaultWindows`)."""
        slots = np.asarray(slots, dtype=np.int64)
        return self.windows.active(slots, self.t[slots])

    def score(self, beliefs: np.ndarray, slots) -> StepOutcome:
        """Score the declarations ``beliefs`` (len(slots), 28) made now."""
        slots = np.asarray(slots, dtype=np.int64)
        return self.scorer.score(beliefs, slots, *self.active_matrix(slots), self.t[slots])

    def end_terms(self, outcome: StepOutcome, slots, ended) -> None:
        """Add the one-off end-of-episode terms (v1: ``missed_detection``, ``final_isolation``) of the
        ``ended`` slots to ``outcome`` (scored over ``slots``); nothing for v0."""
        self.scorer.end_terms(outcome, slots, ended)

    def info(self, slot: int) -> dict:
        """The info of one slot now (the single environment's ``info``)."""
        parts = self.info_arrays([slot])
        fail = self.failure[slot]
        extra = {}
        if self.seq is not None:
            extra["sequential"] = {
                "detected": bool(parts["sequential"]["detected"][0]),
                "diagnoses": parts["sequential"]["diagnoses"][0],
            }
        return {
            "t_s": float(parts["t_s"][0]),
            "scenario_id": parts["scenario_id"][0],
            "profile": parts["profile"][0],
            "true_faults": parts["true_faults"][0],
            "active_faults": parts["active_faults"][0],
            "engine_failure": None if fail is None else dict(fail),
            "reference": {
                "detected": bool(parts["reference"]["detected"][0]),
                "diagnoses": parts["reference"]["diagnoses"][0],
            },
            **extra,
        }

    def info_arrays(self, slots) -> dict:
        """The infos of ``slots`` now as arrays over the slots (Gymnasium's vector info layout,
        without the masks): ``engine_failure`` of a slot without failure is engine -1, time NaN,
        reason ""."""
        slots = np.asarray(slots, dtype=np.int64)
        k = len(slots)
        act, _, _ = self.active_matrix(slots)
        active = row_members(act)
        sid, prof, truth, act_ids = (np.empty(k, dtype=object) for _ in range(4))
        engine = np.full(k, -1, dtype=np.int64)
        fail_t = np.full(k, math.nan)
        reason = np.full(k, "", dtype=object)
        for j, s in enumerate(slots):
            sc = self.scenarios[s]
            sid[j] = sc.scenario_id
            prof[j] = sc.profile
            truth[j] = [dict(f) for f in self._truth[s]]
            act_ids[j] = [FAULT_IDS[c] for c in active[j]]
            fail = self.failure[s]
            if fail is not None:
                engine[j], fail_t[j], reason[j] = fail["engine"], fail["time_s"], fail["reason"]
        detected, diagnoses = self.declarations("reference", self.diag.cells, slots)
        out = {
            "t_s": self.t[slots].astype(float),
            "scenario_id": sid,
            "profile": prof,
            "true_faults": truth,
            "active_faults": act_ids,
            "engine_failure": {"engine": engine, "time_s": fail_t, "reason": reason},
            "reference": {"detected": detected, "diagnoses": diagnoses},
        }
        if self.seq is not None:
            sdet, sdiag = self.declarations("sequential", self.seq.cells, slots)
            out["sequential"] = {"detected": sdet, "diagnoses": sdiag}
        return out
