"""The reference diagnoser as an agent: the thesis's distributed observer / adaptive-threshold /
fault-signature scheme (chapters 5-6), reproduced in :mod:`marine_fdi_env.diagnosis`.

It consumes the measurement stream of N engines (blocks of samples) and gives, at every sample:
whether a fault is detected, the first detection time of every module, the minimal diagnoses
(sets of fault ids, consistency-based: minimal hitting sets of the fired ARRs' fault supports),
the class (sensor or process) of each candidate, and the residual/threshold features the
environment observes.

>>> agent = ReferenceDiagnoser("thesis-12v28", n_engines=1)
>>> out = agent.observe(measurements_block, u_block)      # doctest: +SKIP
>>> agent.diagnoses(0)                                    # doctest: +SKIP
[frozenset({'S4.2'})]
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from marine_fdi_env._jit import jit
from marine_fdi_env.diagnosis.cell_sets import DEFAULT_CELLS, CellDecisions, DecidesWithCellSets, check_cells
from marine_fdi_env.diagnosis.decision import candidate_classes, sorted_diagnoses
from marine_fdi_env.diagnosis.modules import MODULE_IDS
from marine_fdi_env.diagnosis.peak_ratio import (
    PEAK_CAP,
    add_period_ratio,
    clipped_signed_ratio,
    finish_period_stats,
    ratios,
    reset_period_stats,
    running_peaks,
)
from marine_fdi_env.diagnosis.residuals import (
    INCLUSIONS,
    SIDE_COLS,
    T_OUT_COL,
    compute_residuals_batch,
    inclusion_arrays,
    new_state,
)
from marine_fdi_env.diagnosis.sized_decision import SizedDiagnosisState, drive_block
from marine_fdi_env.diagnosis.thresholds import DEFAULT_THRESHOLDS, check_thresholds, threshold_array
from marine_fdi_env.engine.constants import model_constants
from marine_fdi_env.engine.integrators import THREADED_MIN_ENGINES, thread_pool
from marine_fdi_env.engine.params import EngineParams, engine_batch
from marine_fdi_env.engine.sensors import N_SENSORS, NOISE_BOUNDS

__all__ = ["ReferenceDiagnoser", "ReferenceDecisions", "BlockOutput", "N_FEATURES_PER_MODULE"]

N_MODULES = len(MODULE_IDS)
# per module: max |r|/threshold over the block, latched decision, time since first violation [s]
N_FEATURES_PER_MODULE = 3
TIME_SINCE_CAP_S = 300.0


@dataclass
class BlockOutput:
    """What the agent concluded over one block of samples (arrays over engines and samples)."""

    residuals: np.ndarray  # (N, B, 19)
    thresholds: np.ndarray  # (N, B, 19)
    violations: np.ndarray  # (N, B, 19) bool
    detected: np.ndarray  # (N,) bool, at the end of the block
    features: np.ndarray  # (N, 19 * N_FEATURES_PER_MODULE) float32
    stats: np.ndarray | None = None  # (N, 19, 4) the environment observation's period statistics
    peaks: np.ndarray | None = None  # (N, 19) max |r|/threshold over the block (capped at PEAK_CAP)


@jit
def _violations_and_peaks(R, THR, viol, peak, stats, i0, i1):
    """For engines i0..i1-1: viol = not |R| <= THR (inf/nan residuals violate); peak[i, m] = max over
    the block of |R|/THR, where a ratio that is not finite or THR <= 0 counts as the cap 1e3,
    capped at 1e3; and the observation's period statistics of the block in the same pass
    (:func:`~marine_fdi_env.diagnosis.peak_ratio.period_stats`)."""
    N, B, M = R.shape
    for i in range(i0, i1):
        for m in range(M):
            peak[i, m] = 0.0
        reset_period_stats(stats, i)
        for k in range(B):
            for m in range(M):
                r = abs(R[i, k, m])
                thr = THR[i, k, m]
                viol[i, k, m] = not (r <= thr)
                q = r / thr if thr > 0.0 else math.inf
                if not (q <= PEAK_CAP):  # nan, inf or above the cap
                    q = PEAK_CAP
                if q > peak[i, m]:
                    peak[i, m] = q
                add_period_ratio(stats, i, m, clipped_signed_ratio(R[i, k, m], thr))
        finish_period_stats(stats, i, B)


def _post_process(R, THR, viol, peak, stats) -> None:
    """:func:`_violations_and_peaks` for all engines, on the two worker threads for large batches."""
    n = R.shape[0]
    if n < THREADED_MIN_ENGINES:
        _violations_and_peaks(R, THR, viol, peak, stats, 0, n)
        return
    edges = np.linspace(0, n, 9).astype(np.int64)
    list(
        thread_pool().map(
            lambda r: _violations_and_peaks(R, THR, viol, peak, stats, r[0], r[1]), list(zip(edges[:-1], edges[1:]))
        )
    )


class ReferenceDecisions(CellDecisions):
    """The reference diagnoser's decision logic of N engines with one cell set, fed the module
    violations of each block (:class:`~marine_fdi_env.diagnosis.cell_sets.CellDecisions`)."""

    def __init__(
        self,
        n: int,
        cells: str,
        exoneration: str = "sure",
        max_cardinality: int | None = 2,
        thresholds: str = DEFAULT_THRESHOLDS,
    ) -> None:
        super().__init__("reference", n, cells, exoneration, max_cardinality, thresholds)

    def update(self, R, THR, viol, peak, tt, new_mod, fresh, peak_run) -> None:
        """One block: residuals R and thresholds THR (N, B, 19), violations viol (N, B, 19), block
        peak ratios peak (N, 19), engine clocks tt (N, B) [s], the modules firing for the first time
        new_mod (N, 19) and ``fresh`` = new_mod.any(axis=1); peak_run (N, 19) the running peak
        ratios before the block (sized cells).

        Only engines where a module fires for the first time, a grace period ends within the block
        or (sized) a size band moves up need the (Python) decision update; for all others
        DiagnosisState.update/advance would change nothing."""
        t_end_all = tt[:, -1]
        busy = fresh | (t_end_all > self.next_expiry)
        if self.sized:
            busy |= (peak > self.next_peak).any(axis=1)
            self._update_sized(np.flatnonzero(busy), R, THR, viol, tt, peak_run)
            return
        if not busy.any():
            return
        any_row = viol.any(axis=2)  # (N, B)
        for i in np.flatnonzero(busy):
            t = tt[i]
            st = self.decisions[i]
            v = viol[i]
            rows = np.flatnonzero(any_row[i])
            if len(rows):
                # a row that fires no new module only advances the clock: feed it only where a
                # grace period may have ended (the same recomputations as feeding every row)
                fired = np.logical_or.accumulate(v[rows], axis=0) | st.fired
                adds = np.empty(len(rows), dtype=bool)
                adds[0] = (fired[0] != st.fired).any()
                adds[1:] = (fired[1:] != fired[:-1]).any(axis=1)
                for r, a in zip(rows, adds):
                    if a or t[r] > st._next_expiry:
                        st.update(v[r], float(t[r]))
            st.advance(float(t_end_all[i]))
            self.next_expiry[i] = st._next_expiry

    def _update_sized(self, engines, R, THR, viol, tt, peak_run) -> None:
        """The decision update of the sized cells for the engines that need one: every sample where
        a module fires first, a grace period ends or a size band moves up, in time order."""
        for i in engines:
            st: SizedDiagnosisState = self.decisions[i]
            v = viol[i]
            q = running_peaks(ratios(R[i : i + 1], THR[i : i + 1]), peak_run[i : i + 1])[0]
            fired = np.logical_or.accumulate(v, axis=0) | st.fired
            changed = np.empty(len(v), dtype=bool)
            changed[0] = (fired[0] != st.fired).any()
            changed[1:] = (fired[1:] != fired[:-1]).any(axis=1)
            drive_block(st, tt[i], q, [(r, v[r]) for r in np.flatnonzero(changed)], float(tt[i, -1]))
            self.next_expiry[i] = st._next_expiry
            self.next_peak[i] = st.next_peak


class ReferenceDiagnoser(DecidesWithCellSets):
    """Streaming reference diagnoser for N engines.

    Parameters
    ----------
    params : parameter-set name or :class:`EngineParams` (the diagnoser's model of the engine).
    n_engines : number of engines monitored in parallel.
    dt : sample time [s].
    noise_bounds : (19,) sensor noise bounds (default: table 6.3).
    max_cardinality : largest diagnosis considered by the hitting-set search.
    exoneration : ``"sure"`` (default): a module that has not fired clears the faults it surely
        detects (measured cells, the certainty study of docs/diagnosis.md; the thesis's '1'
        cells), with the temporal check that a fault explains a module only if its sure modules
        fired no later than shortly after it; ``"none"``: plain consistency-based diagnosis;
        ``"all"``: every structural sensitivity counts as sure.
    cells : which measured sure cells (:mod:`marine_fdi_env.diagnosis.cell_sets`): ``"sized"``
        (default; the cells of the size the evidence bounds each candidate to), ``"grid"``
        (sure at every size of the grid) or ``"thesis"`` (the table sizes only).  :meth:`add_cells`
        adds other cell sets decided on the same residuals (:meth:`decider`).
    inclusion : ``"tabulated"`` (default): the Σ2 inclusion terms of the adaptive thresholds
        interpolated from a table with a certified margin (never below ``"exact"``'s, at most 1 %
        above; :mod:`marine_fdi_env.diagnosis.inclusion_table`); ``"exact"``: computed at every
        sample.
    thresholds : the reading of the observer modules' adaptive thresholds
        (:mod:`marine_fdi_env.diagnosis.thresholds`): ``"local"`` (default; the local inclusion of
        the forcing over every input's noise box), ``"thesis-lipschitz"``,
        ``"thesis-no-interconnection"`` or ``"thesis-table-6.1"``.  The residuals are the same in
        every reading.
    """

    name = "reference"

    def __init__(
        self,
        params: "str | EngineParams" = "thesis-12v28",
        n_engines: int = 1,
        dt: float = 0.01,
        noise_bounds=None,
        max_cardinality: int = 2,
        exoneration: str = "sure",
        inclusion: str = "tabulated",
        cells: str = DEFAULT_CELLS,
        thresholds: str = DEFAULT_THRESHOLDS,
    ) -> None:
        self.params, self.n, self.dt = engine_batch(params, n_engines, dt)
        self.c = model_constants(self.params)
        nb = NOISE_BOUNDS if noise_bounds is None else np.asarray(noise_bounds, dtype=float)
        if nb.shape != (N_SENSORS,) or not np.all(np.isfinite(nb)) or np.any(nb < 0):
            raise ValueError(f"noise_bounds must be 19 finite numbers >= 0, got {noise_bounds!r}")
        self.noise_bounds = np.array(nb, dtype=np.float64)
        self.max_cardinality = max_cardinality
        if exoneration not in ("sure", "none", "all", None):
            raise ValueError(f"exoneration must be 'sure', 'none' or 'all', got {exoneration!r}")
        self.exoneration = "none" if exoneration is None else exoneration
        self.cells = check_cells(cells)
        self.cell_sets: tuple[str, ...] = (self.cells,)
        if inclusion not in INCLUSIONS:
            raise ValueError(f"inclusion must be one of {', '.join(INCLUSIONS)}, got {inclusion!r}")
        self.inclusion = inclusion
        self._table = inclusion_arrays(self.c, self.noise_bounds, inclusion)
        self.thresholds = check_thresholds(thresholds)
        self._thr = threshold_array(thresholds, self.params.name)
        self.reset()

    def reset(self) -> None:
        """Forget everything: observers restart on the next sample."""
        self.state = new_state(self.n, self.params.n_nom_rev_s)
        self.samples = 0
        self._deciders = [self._decider(c) for c in self.cell_sets]
        self.first_violation = np.full((self.n, N_MODULES), np.nan)
        # per engine, the stream sample whose time is 0 (engines restarted mid-stream differ)
        self._offset = np.zeros(self.n, dtype=np.int64)
        # per engine and module the running peak of |r|/threshold (the sized cells' size bands)
        self.peak_run = np.zeros((self.n, N_MODULES))

    def _decider(self, cells: str) -> ReferenceDecisions:
        return ReferenceDecisions(self.n, cells, self.exoneration, self.max_cardinality, self.thresholds)

    @property
    def _started(self) -> bool:
        return self.samples > 0

    def reset_engines(self, engines, first_sample_index: int = 0) -> None:
        """Forget everything about some engines (new runs on them); the others carry on.

        The next sample of each engine given is its sample number ``first_sample_index`` (time
        ``first_sample_index * dt``): 1 when its run's t = 0 reading is not passed on.
        """
        idx = np.asarray(engines, dtype=np.int64).reshape(-1)
        if np.any((idx < 0) | (idx >= self.n)):
            raise ValueError(f"engines must be indices in [0, {self.n}), got {engines!r}")
        for i in idx:
            self.state[i] = new_state(1, self.params.n_nom_rev_s)[0]
            self.first_violation[i] = np.nan
            self._offset[i] = self.samples - int(first_sample_index)
            self.peak_run[i] = 0.0
        for d in self._deciders:
            d.reset_engines(idx)

    # ------------------------------------------------------------------------------ streaming
    def observe(self, measurements, u) -> BlockOutput:
        """Process a block of samples: measurements (N, B, 19) or (B, 19); u (N, B) or (B,)."""
        Y = np.asarray(measurements, dtype=np.float64)
        U = np.asarray(u, dtype=np.float64)
        if Y.ndim == 2:
            Y = Y[None]
        if U.ndim == 1:
            U = U[None]
        if Y.ndim != 3 or Y.shape[0] != self.n or Y.shape[2] != N_SENSORS:
            raise ValueError(f"measurements must have shape ({self.n}, B, {N_SENSORS}), got {np.shape(measurements)}")
        if U.shape != Y.shape[:2]:
            raise ValueError(f"u must have shape {Y.shape[:2]} (engines, samples), got {np.shape(u)}")
        if not np.all(np.isfinite(U)):
            raise ValueError("u (the applied fuel setting) must be finite")
        N, B, _ = Y.shape
        Y = np.ascontiguousarray(Y)
        U = np.ascontiguousarray(U)
        R = np.empty((N, B, N_MODULES))
        THR = np.empty((N, B, N_MODULES))
        compute_residuals_batch(
            self.c, Y, U, self.dt, self.noise_bounds, SIDE_COLS, T_OUT_COL, R, THR, self.state, self._table, self._thr
        )
        viol = np.empty((N, B, N_MODULES), dtype=np.bool_)
        peak = np.empty((N, N_MODULES))
        stats = np.empty((N, N_MODULES, 4))
        _post_process(R, THR, viol, peak, stats)
        tt = (self.samples - self._offset[:, None] + np.arange(B)[None, :]) * self.dt  # (N, B) engine clocks
        new_mod = viol.any(axis=1) & np.isnan(self.first_violation)  # (N, 19)
        fresh = new_mod.any(axis=1)
        for d in self._deciders:
            d.update(R, THR, viol, peak, tt, new_mod, fresh, self.peak_run)
        for i in np.flatnonzero(fresh):
            first = np.argmax(viol[i], axis=0)
            self.first_violation[i, new_mod[i]] = tt[i][first[new_mod[i]]]
        if self.needs_peaks:
            np.maximum(self.peak_run, peak, out=self.peak_run)
        self.samples += B
        feats = self._features(peak)
        return BlockOutput(
            residuals=R,
            thresholds=THR,
            violations=viol,
            detected=self.detected.copy(),
            features=feats,
            stats=stats,
            peaks=peak,
        )

    def _features(self, peak: np.ndarray) -> np.ndarray:
        """peak: (N, 19) max |r|/threshold over the block, capped at 1e3 (see _violations_and_peaks)."""
        now = ((self.samples - self._offset) * self.dt)[:, None]
        latched = ~np.isnan(self.first_violation)
        f = np.empty((self.n, N_MODULES, N_FEATURES_PER_MODULE), dtype=np.float32)
        f[:, :, 0] = peak
        f[:, :, 1] = latched
        f[:, :, 2] = np.where(latched, np.minimum(now - self.first_violation, TIME_SINCE_CAP_S), 0.0)
        return f.reshape(self.n, -1)

    # ------------------------------------------------------------------------------ results
    @property
    def detected(self) -> np.ndarray:
        # a module fired (latched) exactly when it has a first violation time
        return ~np.isnan(self.first_violation).all(axis=1)

    def first_detection_time(self, engine: int = 0) -> float:
        return self.decisions[engine].first_detection_time

    def module_detection_times(self, engine: int = 0) -> dict[str, float | None]:
        t = self.decisions[engine].detection_times
        return {m: (None if math.isnan(v) else float(v)) for m, v in zip(MODULE_IDS, t)}

    def diagnoses(self, engine: int = 0) -> list[frozenset[str]]:
        return list(self.decisions[engine].diagnoses)

    def report(self, engine: int = 0) -> dict:
        """JSON-ready summary of one engine (keys of ``marine-fdi diagnose``)."""
        d = self.decisions[engine]
        return {
            "detected": bool(d.detected),
            "first_detection_time_s": None if math.isnan(d.first_detection_time) else d.first_detection_time,
            "module_detection_times_s": self.module_detection_times(engine),
            "final_minimal_diagnoses": sorted_diagnoses(d.diagnoses) if d.detected else [],
            "candidate_classes": candidate_classes(d.diagnoses) if d.detected else {},
        }
