"""The part of a batch of episodes that no agent can change, computed once.

An agent's declarations change only its reward and its declaration trace: the engines, the sensors,
the observation features and the diagnosers' conclusions (``info["reference"]``,
``info["sequential"]``) do not depend on them, nor does when an episode ends (its duration, or an
engine failure).  :func:`simulate` runs that part of N episodes once on the vector environment's
:class:`~.core.EpisodeBatch` and keeps it as a :class:`Trajectory`; any number of agents can then
be stepped on it (:mod:`marine_fdi_env.benchmark.lockstep`) and each sees exactly the observations
and infos ``MarineFDIVectorEnv`` gives it alone, bit for bit (tested on every shipped suite).

The diagnosers' cell sets (``diagnosis_cells``) change only their conclusions, never the engines
or the observation: one simulation decides with every cell set asked for (``diagnosis_cells`` a
list of them) and keeps each one's conclusions (the trajectory's ``cell_sets`` axis); an agent sees
those of its own cell set.

Decision ``k`` of episode ``i`` is made on ``obs[k, i]`` at time ``t[k, i]``; the episode has
``n_decisions[i]`` of them.  Past its end a slot's row repeats its last decision's (the vector
environment would show an unrelated new episode there: a slot's numbers never depend on that row).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..diagnosis.cell_sets import DEFAULT_CELLS, check_cells
from ..engine.faults import FAULT_IDS
from .fault_windows import FaultWindows
from .scenario_sampler import ScenarioSpec, with_noise_scale
from .scoring import row_members
from .vector import MarineFDIVectorEnv, object_array

__all__ = ["Trajectory", "simulate", "assemble", "feature_columns", "cell_sets_of", "one_cell_set"]


def cell_sets_of(env_kwargs: dict) -> tuple[str, ...]:
    """The cell sets of ``env_kwargs["diagnosis_cells"]`` (default ``sized``): one cell set, or a
    list of them (a simulation pass's; the first is the one the environment's infos show)."""
    cells = env_kwargs.get("diagnosis_cells", DEFAULT_CELLS)
    out = (cells,) if isinstance(cells, str) else tuple(cells)
    if not out:
        raise ValueError("diagnosis_cells must name at least one cell set")
    for c in out:
        check_cells(c)
    return tuple(dict.fromkeys(out))


def one_cell_set(env_kwargs: dict) -> dict:
    """``env_kwargs`` as the environment takes them: ``diagnosis_cells`` its first cell set (when given)."""
    if "diagnosis_cells" not in env_kwargs:
        return dict(env_kwargs)
    return {**env_kwargs, "diagnosis_cells": cell_sets_of(env_kwargs)[0]}


@dataclass
class Trajectory:
    """What every agent sees in a batch of ``n`` episodes over ``S`` decisions (arrays (S, n, ...)),
    the diagnosers' conclusions with each of ``C`` cell sets."""

    scenarios: list[ScenarioSpec]  # as simulated (a seed offset already applied)
    feature_names: tuple[str, ...]  # the observation's columns
    cell_sets: tuple[str, ...]  # (C,) the diagnosers' cell sets of the conclusions (diagnosis.cell_sets)
    decision_period_s: float  # [s]
    period_samples: int  # sensor samples per decision
    obs: np.ndarray  # (S, n, D) float32: the observation of each decision
    t: np.ndarray  # (S, n) float64: decision times [s]
    feature_s: np.ndarray  # (S, n) float64: wall time spent making each observation [s]
    reference_detected: np.ndarray  # (S, n, C) bool: info["reference"]["detected"] with each cell set
    reference_diagnoses: np.ndarray  # (S, n, C) object: info["reference"]["diagnoses"] (lists of fault ids)
    sequential_detected: np.ndarray | None  # the same for info["sequential"] (observe_sequential only)
    sequential_diagnoses: np.ndarray | None
    n_decisions: np.ndarray  # (n,) int64: decisions of each episode
    terminated: np.ndarray  # (n,) bool: ended by an engine failure
    failures: list[dict | None]  # {"time_s": [s], "reason": str} of the failed engines, else None
    failure_step: np.ndarray  # (n,) int64: the first decision whose info shows the failure (-1: none)
    compute_s: np.ndarray  # (n,) float64: wall time spent on each episode's observations [s]
    _windows: FaultWindows | None = field(default=None, repr=False, compare=False)
    _constant: dict | None = field(default=None, repr=False, compare=False)

    @property
    def n(self) -> int:
        return len(self.scenarios)

    @property
    def steps(self) -> int:
        return int(self.obs.shape[0])

    @property
    def observe_sequential(self) -> bool:
        return self.sequential_detected is not None

    def take(self, idx) -> "Trajectory":
        """The episodes ``idx`` (in that order) as a trajectory of their own, ``S`` cut to theirs."""
        idx = np.asarray(idx, dtype=np.int64)
        S = int(self.n_decisions[idx].max(initial=1))
        cut = lambda a: None if a is None else a[:S, idx]  # noqa: E731
        return replace(
            self,
            scenarios=[self.scenarios[i] for i in idx],
            obs=self.obs[:S, idx],
            t=self.t[:S, idx],
            feature_s=self.feature_s[:S, idx],
            reference_detected=cut(self.reference_detected),
            reference_diagnoses=cut(self.reference_diagnoses),
            sequential_detected=cut(self.sequential_detected),
            sequential_diagnoses=cut(self.sequential_diagnoses),
            n_decisions=self.n_decisions[idx],
            terminated=self.terminated[idx],
            failures=[self.failures[i] for i in idx],
            failure_step=self.failure_step[idx],
            compute_s=self.compute_s[idx],
            _windows=None,
            _constant=None,
        )

    # ------------------------------------------------------------------------------ per decision
    def last(self, k: int) -> np.ndarray:
        """The row of each slot at decision ``k``: ``k``, or its last decision after its end."""
        return np.minimum(k, self.n_decisions - 1)

    def observation(self, k: int, columns: np.ndarray | None = None) -> np.ndarray:
        """The observation batch (n, D) of decision ``k`` (a new array; ``columns``: a selection)."""
        o = self.obs[self.last(k), np.arange(self.n)]
        return o if columns is None else o[:, columns]

    def active(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(active (n, 26) bool, first onset, last onset) of the faults at decision ``k``."""
        if self._windows is None:
            self._windows = FaultWindows(self.n)
            for i, sc in enumerate(self.scenarios):
                self._windows.set(i, sc.faults)
        return self._windows.active(np.arange(self.n), self.t[self.last(k), np.arange(self.n)])

    def cell_index(self, cells: str) -> int:
        """The column of the cell set ``cells`` in the conclusions; ``ValueError`` if it has none."""
        if cells not in self.cell_sets:
            raise ValueError(
                f"the trajectory has no conclusions with the cell set {cells!r} (it has {', '.join(self.cell_sets)})"
            )
        return self.cell_sets.index(cells)

    def info_arrays(self, k: int, active: np.ndarray, sequential: bool, cells: str | None = None) -> dict:
        """The infos of decision ``k`` as :meth:`.core.EpisodeBatch.info_arrays` gives them for every
        slot (``active``: :meth:`active` of ``k``; ``sequential``: include ``info["sequential"]``;
        ``cells``: the diagnosers' cell set, default the first of :attr:`cell_sets`)."""
        n, ar, kk = self.n, np.arange(self.n), self.last(k)
        c = self.cell_index(self.cell_sets[0] if cells is None else cells)
        shows = (self.failure_step >= 0) & (self.failure_step <= k)
        engine = np.where(shows, ar, -1).astype(np.int64)
        fail_t = np.full(n, math.nan)
        reason = np.full(n, "", dtype=object)
        for i in np.flatnonzero(shows):
            fail_t[i], reason[i] = self.failures[i]["time_s"], self.failures[i]["reason"]
        if self._constant is None:
            self._constant = {
                "scenario_id": object_array([s.scenario_id for s in self.scenarios]),
                "profile": object_array([s.profile for s in self.scenarios]),
                "true_faults": object_array([s.truth() for s in self.scenarios]),
            }
        out = {
            "t_s": self.t[kk, ar].astype(float),
            **self._constant,
            "active_faults": object_array([[FAULT_IDS[c] for c in cols] for cols in row_members(active)]),
            "engine_failure": {"engine": engine, "time_s": fail_t, "reason": reason},
            "reference": {
                "detected": self.reference_detected[kk, ar, c],
                "diagnoses": self.reference_diagnoses[kk, ar, c],
            },
        }
        if sequential:
            if self.sequential_detected is None:
                raise ValueError("this trajectory has no sequential diagnoser (made without observe_sequential)")
            out["sequential"] = {
                "detected": self.sequential_detected[kk, ar, c],
                "diagnoses": self.sequential_diagnoses[kk, ar, c],
            }
        return out


def assemble(parts: list[tuple[np.ndarray, Trajectory]]) -> Trajectory:
    """One trajectory of the episodes of ``parts`` ((indices, trajectory) whose indices together
    are 0..N-1 once each), episode ``idx[j]`` of the result being episode ``j`` of its part."""
    idx_all = np.concatenate([np.asarray(i, dtype=np.int64) for i, _ in parts])
    N = len(idx_all)
    if sorted(idx_all.tolist()) != list(range(N)):
        raise ValueError("the parts' episode indices must be 0..N-1, each once")
    first = parts[0][1]
    for _, p in parts[1:]:
        if (p.feature_names, p.cell_sets, p.decision_period_s, p.period_samples, p.observe_sequential) != (
            first.feature_names,
            first.cell_sets,
            first.decision_period_s,
            first.period_samples,
            first.observe_sequential,
        ):
            raise ValueError("the parts were made with other observation options, cell sets or decision periods")
    S = max(p.steps for _, p in parts)

    def put(name: str, dtype, fill):
        arrays = [getattr(p, name) for _, p in parts]
        if arrays[0] is None:
            return None
        out = np.full((S, N) + arrays[0].shape[2:], fill, dtype=dtype)
        for (i, _), a in zip(parts, arrays):
            out[: a.shape[0], np.asarray(i, dtype=np.int64)] = a
        return out

    def per_episode(name: str):
        out = np.empty(N, dtype=getattr(first, name).dtype)
        for i, p in parts:
            out[np.asarray(i, dtype=np.int64)] = getattr(p, name)
        return out

    scenarios: list = [None] * N
    failures: list = [None] * N
    for i, p in parts:
        for j, e in enumerate(np.asarray(i, dtype=np.int64).tolist()):
            scenarios[e], failures[e] = p.scenarios[j], p.failures[j]
    return Trajectory(
        scenarios=scenarios,
        feature_names=first.feature_names,
        cell_sets=first.cell_sets,
        decision_period_s=first.decision_period_s,
        period_samples=first.period_samples,
        obs=put("obs", np.float32, 0.0),
        t=put("t", float, 0.0),
        feature_s=put("feature_s", float, 0.0),
        reference_detected=put("reference_detected", bool, False),
        reference_diagnoses=put("reference_diagnoses", object, None),
        sequential_detected=put("sequential_detected", bool, False),
        sequential_diagnoses=put("sequential_diagnoses", object, None),
        n_decisions=per_episode("n_decisions"),
        terminated=per_episode("terminated"),
        failures=failures,
        failure_step=per_episode("failure_step"),
        compute_s=per_episode("compute_s"),
    )


def feature_columns(have: tuple[str, ...], want: list[str]) -> np.ndarray | None:
    """The columns of ``have`` that make the observation ``want`` (None: all of them, in order);
    ``ValueError`` naming a missing feature."""
    if tuple(want) == tuple(have):
        return None
    pos = {name: j for j, name in enumerate(have)}
    missing = [name for name in want if name not in pos]
    if missing:
        raise ValueError(
            f"the trajectory has no feature {missing[0]!r} ({len(missing)} missing); it was made "
            "with other observation options"
        )
    return np.array([pos[name] for name in want], dtype=np.int64)


def simulate(scenarios: list[ScenarioSpec], env_kwargs: dict | None = None, progress=None) -> Trajectory:
    """Run ``scenarios`` (one sensor-noise scale) to their ends on one batch of the vector
    environment made with ``env_kwargs``; the :class:`Trajectory` any agent would see.
    ``env_kwargs["diagnosis_cells"]`` may list several cell sets: the diagnosers decide with each
    on the same residuals (:func:`cell_sets_of`).

    The decisions, their ends and the infos follow ``MarineFDIVectorEnv.step``: a decision whose
    engine has failed, or at or after the episode's duration, is the episode's last; an engine that
    fails while advancing past decision ``k`` makes ``k`` the last.  ``progress(x)`` after every
    decision with the episodes' worth of work done since the last call.
    """
    scales = {float(s.noise_scale) for s in scenarios}
    if len(scales) != 1:
        raise ValueError(f"a simulated batch must share one sensor-noise scale, got {sorted(scales)}")
    n = len(scenarios)
    env_kwargs = dict(env_kwargs or {})
    cells = cell_sets_of(env_kwargs)
    venv = MarineFDIVectorEnv(num_envs=n, **with_noise_scale(one_cell_set(env_kwargs), scales.pop()))
    b = venv.batch
    b.decide_cells(cells[1:])
    b.start(range(n), list(scenarios))
    b.advance()
    expected = max(1, max(math.ceil(s.duration_s / b.decision_period_s - 1e-9) for s in scenarios))
    live = np.ones(n, dtype=bool)
    n_dec = np.zeros(n, dtype=np.int64)
    term = np.zeros(n, dtype=bool)
    fstep = np.where(b.failed, 0, -1).astype(np.int64)
    compute_s = np.zeros(n)
    rows: dict[str, list] = {k: [] for k in ("obs", "t", "feature_s", "rdet", "rdiag", "sdet", "sdiag")}
    spent = b.compute_s.copy()

    def record(slots) -> None:
        rows["obs"].append(b.obs.copy())
        rows["t"].append(b.t.astype(float))
        rows["feature_s"].append(spent.copy())
        for key, diagnoser in (("r", "reference"), ("s", None if b.seq is None else "sequential")):
            if diagnoser is None:
                continue
            det, diag = np.zeros((n, len(cells)), dtype=bool), np.empty((n, len(cells)), dtype=object)
            for c, name in enumerate(cells):
                det[slots, c], diag[slots, c] = b.declarations(diagnoser, name, slots)
            rows[key + "det"].append(det)
            rows[key + "diag"].append(diag)

    record(np.arange(n))
    k, reported = 0, 0.0
    while True:
        lv = np.flatnonzero(live)
        failed_now = b.failed[lv]
        at_end = ~failed_now & (b.t[lv] >= b.durations[lv] - 1e-9)
        ended = lv[failed_now | at_end]
        term[lv[failed_now]] = True
        n_dec[ended] = k + 1
        live[ended] = False
        going = np.flatnonzero(live)
        if len(going):
            before = b.compute_s.copy()
            for f in b.advance(going):
                if live[f]:
                    term[f], n_dec[f], live[f], fstep[f] = True, k + 1, False, k + 1
                    ended = np.append(ended, f)
            spent = b.compute_s - before
        compute_s[ended] = b.compute_s[ended]
        if progress is not None:  # a decision of each live episode; at the end what early ends left
            x = len(lv) / expected if live.any() else n - reported
            progress(x)
            reported += x
        if not live.any():
            break
        k += 1
        record(np.flatnonzero(live))
    seq = b.seq is not None
    return Trajectory(
        scenarios=list(scenarios),
        feature_names=tuple(venv.feature_names),
        cell_sets=cells,
        decision_period_s=b.decision_period_s,
        period_samples=b.period_samples,
        obs=np.stack(rows["obs"]),
        t=np.stack(rows["t"]),
        feature_s=np.stack(rows["feature_s"]),
        reference_detected=np.stack(rows["rdet"]),
        reference_diagnoses=np.stack(rows["rdiag"]),
        sequential_detected=np.stack(rows["sdet"]) if seq else None,
        sequential_diagnoses=np.stack(rows["sdiag"]) if seq else None,
        n_decisions=n_dec,
        terminated=term,
        failures=[
            {"time_s": f["time_s"], "reason": f["reason"]} if ended else None for f, ended in zip(b.failure, term)
        ],
        failure_step=fstep,
        compute_s=compute_s,
    )
