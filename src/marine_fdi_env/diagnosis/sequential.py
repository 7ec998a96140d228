"""The ``sequential`` diagnoser: two-sided CUSUM tests on the reference diagnoser's residuals, with
the same structural isolation logic (minimal diagnoses, exoneration by measured sure cells, time
order) on its module decisions.

The reference scheme compares every sample with a worst-case bound over the sensor noise; it can
never raise a false alarm, and it can never see a fault whose effect stays below that bound.  A
sequential test accumulates the evidence instead (Page's CUSUM; Basseville & Nikiforov 1993, ch. 2):

* **normalised residual.**  Per module m, the mean r̄ of its residual over blocks of
  ``block_s`` = 1 s is normalised by its fault-free mean and spread at the current load,
  ``z = (r̄ - μ_m(u)) / s_m(u)``, with μ_m and s_m measured on fault-free runs over all profile
  families and interpolated linearly in the block's mean fuel setting u (the known input; so a
  fault never changes its own normaliser).  Block means make the increments nearly Gaussian
  (central limit) and keep the cost per sample at one addition.
* **two-sided CUSUM.**  ``S+ = max(0, S+ + z - k)``, ``S- = max(0, S- - z - k)`` with the reference
  value k (half the shift, in spreads, detected fastest); module m fires when S+ or S- exceeds
  its threshold h_m.  The thresholds are set for at most one false alarm in 200 fault-free
  engine-hours over all modules (measured on calibration runs, checked on other runs:
  docs/diagnosis.md).
* **warm-up.**  The tests start after ``warmup_s`` (the observers' start-up transient: about 15 s
  for the charge-air observer, a few seconds for the others).
* **inactive region.**  Where the block's mean measured pressure ratio x3/x4 (both chains) exceeds
  ``r_max`` a module's test pauses (S+ = S- = 0): M3.1-M3.4 near x3/x4 = 1, where the receiver and
  turbine-inlet residuals are biased by the scavenge flow function clipped at 1 (the measured
  ratio crosses 1 with the noise, the true one does not), by an amount that depends on how close
  the ratio is, in steady state at fuel settings below about 0.45 and on slow load increases
  from there, when the charge pressure lags (calibration runs: CUSUM peaks up to 320 spreads
  with the fuel setting alone as region, below 12 above u = 0.5).  The worst-case test of these
  modules stays active everywhere.
* **receiver test** (:mod:`~marine_fdi_env.diagnosis.incipient_glr`): a GLR for a shift growing as
  (t - τ)² on the pooled z of the two receiver chains M3.1 and M3.2, paused while the load changes;
  when it crosses its threshold and a common shift explains the two chains better than a shift of
  either alone, it fires M3.1 and M3.2 together; it runs only while neither of them has fired on
  its own evidence (the turbine seal leak moves both by less than half a spread within 300 s,
  below any k).
* **module decision** = the reference's worst-case violation OR the CUSUM alarm (OR, for M3.1 and
  M3.2, the receiver test), latched: large faults are still seen at the first sample, small ones
  once their evidence accumulates.

The decision logic is :class:`~marine_fdi_env.diagnosis.decision.DiagnosisState` with sure cells,
settle and grace times measured for *these* decisions over the same magnitude grid as the
reference's (``data/diagnosis/sequential_sure_cells.json``).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources

import numpy as np

from .._jit import jit
from .agent import ReferenceDiagnoser
from .cell_sets import DEFAULT_CELLS, CellDecisions, DecidesWithCellSets, check_cells
from .decision import candidate_classes, sorted_diagnoses
from .incipient_glr import GATE_DELTA, GATE_TAU_S, ORDER, WINDOW_BLOCKS, common_shift, glr_norms, glr_pair_update
from .modules import MODULE_IDS
from .peak_ratio import ratios, running_peaks
from .sized_decision import drive_block

__all__ = [
    "SequentialCalibration",
    "ReceiverTest",
    "SequentialStage",
    "SequentialDecisions",
    "SequentialDiagnoser",
    "SEQUENTIAL_FEATURES",
    "CALIBRATION_FILE",
    "SURE_CELLS_FILE",
    "cusum_blocks",
    "pressure_ratio",
]

N_MODULES = len(MODULE_IDS)
CALIBRATION_FILE = "sequential.json"
SURE_CELLS_FILE = "sequential_sure_cells.json"
# observation features per module (MarineFDI-v0 with observe_sequential=True)
SEQUENTIAL_FEATURES = ("cusum_up", "cusum_down", "block_z", "seq_fired")
Z_CAP = 10.0


@dataclass(frozen=True)
class ReceiverTest:
    """Settings of the receiver test (:mod:`~marine_fdi_env.diagnosis.incipient_glr`).

    modules : the two pooled chains; h : GLR threshold [spreads] (inf: the test is off, as in a
    calibration file without it); order : shape (t - τ)^order; window_blocks : onsets kept;
    gate_tau_s [s], gate_delta [-] : the transient gate on the fuel setting.
    """

    modules: tuple[str, str] = ("M3.1", "M3.2")
    h: float = math.inf
    order: int = ORDER
    window_blocks: int = WINDOW_BLOCKS
    gate_tau_s: float = GATE_TAU_S
    gate_delta: float = GATE_DELTA

    @classmethod
    def from_dict(cls, d: dict | None) -> "ReceiverTest":
        if d is None:
            return cls()
        out = cls(
            tuple(d["modules"]),
            float(d["h"]),
            int(d["order"]),
            int(d["window_blocks"]),
            float(d["gate_tau_s"]),
            float(d["gate_delta"]),
        )
        if len(out.modules) != 2 or any(m not in MODULE_IDS for m in out.modules):
            raise ValueError(f"sequential calibration: receiver modules must be two of {MODULE_IDS}, got {out.modules}")
        if not (out.h > 0 and out.order >= 0 and out.window_blocks >= 1 and out.gate_tau_s > 0 and out.gate_delta > 0):
            raise ValueError("sequential calibration: receiver h, window and gate must be positive")
        return out


@dataclass(frozen=True)
class SequentialCalibration:
    """Normalisation and CUSUM settings (see module docstring).

    block_s : block length [s]; u_nodes : (nu,) fuel settings of the normalisation nodes;
    mean, scale : (19, nu) fault-free block-mean residual mean and spread at the nodes;
    k, h : (19,) reference values and thresholds [spreads]; warmup_s : (19,); r_max : (19,)
    pressure ratio above which the test pauses; receiver : the receiver test.
    """

    block_s: float
    u_nodes: np.ndarray
    mean: np.ndarray
    scale: np.ndarray
    k: np.ndarray
    h: np.ndarray
    warmup_s: np.ndarray
    r_max: np.ndarray
    data: dict
    receiver: ReceiverTest = ReceiverTest()

    @classmethod
    def from_dict(cls, d: dict) -> "SequentialCalibration":
        if d.get("module_ids") != list(MODULE_IDS):
            raise ValueError("sequential calibration: module ids do not match; regenerate it")
        arr = {k: np.asarray(d[k], dtype=float) for k in ("u_nodes", "mean", "scale", "k", "h", "warmup_s", "r_max")}
        nu = len(arr["u_nodes"])
        for k in ("mean", "scale"):
            if arr[k].shape != (N_MODULES, nu):
                raise ValueError(f"sequential calibration: {k!r} must have shape ({N_MODULES}, {nu})")
        for k in ("k", "h", "warmup_s", "r_max"):
            if arr[k].shape != (N_MODULES,):
                raise ValueError(f"sequential calibration: {k!r} must have {N_MODULES} values")
        if not np.all(np.diff(arr["u_nodes"]) > 0) or not np.all(arr["scale"] > 0):
            raise ValueError("sequential calibration: u_nodes must increase and every scale be > 0")
        return cls(
            float(d["block_s"]),
            arr["u_nodes"],
            arr["mean"],
            arr["scale"],
            arr["k"],
            arr["h"],
            arr["warmup_s"],
            arr["r_max"],
            d,
            ReceiverTest.from_dict(d.get("receiver")),
        )


@lru_cache(maxsize=None)
def load_calibration(name: str = CALIBRATION_FILE) -> SequentialCalibration:
    path = resources.files("marine_fdi_env") / "data" / "diagnosis" / name
    try:
        return SequentialCalibration.from_dict(json.loads(path.read_text()))
    except FileNotFoundError:
        raise ValueError(
            f"no sequential calibration {name!r} in marine_fdi_env/data/diagnosis; build it with "
            "python -m studies.diagnosis.sequential_calibration"
        ) from None


def pressure_ratio(measurements) -> np.ndarray:
    """(N, B) the mean of the two chains' measured receiver/charge pressure ratios x3/x4 (sensors
    S3.1/S4.1 and S3.2/S4.2): the operating-region indicator of the tests' pause region."""
    from ..engine.sensors import sensor_index

    Y = np.asarray(measurements, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        r = 0.5 * (
            Y[..., sensor_index("S3.1")] / Y[..., sensor_index("S4.1")]
            + Y[..., sensor_index("S3.2")] / Y[..., sensor_index("S4.2")]
        )
    return r


@jit
def _interp(u, nodes, values, m):
    """values[m] interpolated linearly at u over the nodes (held constant outside)."""
    n = len(nodes)
    if u <= nodes[0]:
        return values[m, 0]
    if u >= nodes[n - 1]:
        return values[m, n - 1]
    j = 0
    while nodes[j + 1] < u:
        j += 1
    w = (u - nodes[j]) / (nodes[j + 1] - nodes[j])
    return values[m, j] * (1.0 - w) + values[m, j + 1] * w


@jit
def cusum_blocks(
    R,
    U,
    RATIO,
    VIOL,
    dt,
    t0,
    block,
    nodes,
    mean,
    scale,
    k,
    h,
    warm,
    r_max,
    acc,
    st,
    first,
    feats,
    pair,
    gpar,
    gnorms,
    gnum,
    gcount,
    gpos,
    gavg,
    gstate,
):
    """Advance the tests of N engines over a block of samples (compiled).

    R (N, B, 19) residuals, U (N, B) fuel setting, RATIO (N, B) measured pressure ratio x3/x4,
    VIOL (N, B, 19) worst-case violations (or an empty (N, 0, 19) array to ignore them); t0 (N,)
    each engine's time of the block's first sample; block : samples per CUSUM block.  State: acc
    (N, 22) partial block sums (columns 0-18 residuals, 19 u, 20 samples in the block, 21 ratio);
    st (N, 19, 2) CUSUM S+ / S-; first (N, 19): first firing time (NaN: not yet), set at the sample
    of a worst-case violation or at the end of the block whose CUSUM crosses h.  feats (N, 19, 3):
    S+/h, S-/h and the last block's z.
    Receiver test (:func:`~marine_fdi_env.diagnosis.incipient_glr.glr_pair_update`): pair (2,) the
    chains' module indices; gpar (4,) h, order, gate coefficient block/τ, gate δ; gnorms (W,);
    state gnum (N, W, 2), gcount (N,), gpos (N,), gavg (N,), gstate (N, 4): the last block's
    statistic, the alarm time (NaN: none; it also fires both chains' modules), and the last block's
    chain statistics c1, c2 at the maximising onset.
    """
    N, B, M = R.shape
    use_viol = VIOL.shape[1] == B
    for i in range(N):
        for kk in range(B):
            t = t0[i] + kk * dt
            if use_viol:
                for m in range(M):
                    if VIOL[i, kk, m] and first[i, m] != first[i, m]:
                        first[i, m] = t
            for m in range(M):
                acc[i, m] += R[i, kk, m]
            acc[i, 19] += U[i, kk]
            acc[i, 20] += 1.0
            acc[i, 21] += RATIO[i, kk]
            if acc[i, 20] >= block:
                nb = acc[i, 20]
                u = acc[i, 19] / nb
                ratio = acc[i, 21] / nb
                for m in range(M):
                    z = (acc[i, m] / nb - _interp(u, nodes, mean, m)) / _interp(u, nodes, scale, m)
                    if not (z == z):  # a residual that is not finite (a sensor dropped out): no evidence
                        z = 0.0
                    z = min(max(z, -Z_CAP), Z_CAP)
                    feats[i, m, 2] = z
                    if t + 0.5 * dt >= warm[m] and ratio <= r_max[m]:  # (a NaN ratio pauses)
                        st[i, m, 0] = max(0.0, st[i, m, 0] + z - k[m])
                        st[i, m, 1] = max(0.0, st[i, m, 1] - z - k[m])
                        if (st[i, m, 0] > h[m] or st[i, m, 1] > h[m]) and first[i, m] != first[i, m]:
                            first[i, m] = t
                    else:
                        st[i, m, 0] = 0.0
                        st[i, m, 1] = 0.0
                    acc[i, m] = 0.0
                a, b = pair[0], pair[1]
                # only while neither chain has fired on its own evidence: a chain already known to be
                # faulty would lend its fault to the other through the pooled sum
                active = (
                    t + 0.5 * dt >= warm[a]
                    and t + 0.5 * dt >= warm[b]
                    and ratio <= r_max[a]
                    and ratio <= r_max[b]
                    and first[i, a] != first[i, a]
                    and first[i, b] != first[i, b]
                )
                g, c1, c2 = glr_pair_update(
                    i,
                    feats[i, a, 2],
                    feats[i, b, 2],
                    u,
                    active,
                    gnum,
                    gcount,
                    gpos,
                    gavg,
                    gnorms,
                    gpar[1],
                    gpar[2],
                    gpar[3],
                )
                gstate[i, 0] = g
                gstate[i, 2] = c1
                gstate[i, 3] = c2
                if g > gpar[0] and common_shift(c1, c2) and gstate[i, 1] != gstate[i, 1]:
                    gstate[i, 1] = t
                    if first[i, a] != first[i, a]:
                        first[i, a] = t
                    if first[i, b] != first[i, b]:
                        first[i, b] = t
                acc[i, 19] = 0.0
                acc[i, 20] = 0.0
                acc[i, 21] = 0.0
        for m in range(M):
            feats[i, m, 0] = st[i, m, 0] / h[m]
            feats[i, m, 1] = st[i, m, 1] / h[m]


class SequentialDecisions(CellDecisions):
    """The sequential diagnoser's decision logic of N engines with one cell set, fed its modules'
    first firing times (:class:`~marine_fdi_env.diagnosis.cell_sets.CellDecisions`)."""

    def __init__(self, n: int, cells: str, exoneration: str = "sure", max_cardinality: int | None = 2) -> None:
        super().__init__("sequential", n, cells, exoneration, max_cardinality)

    def update(self, first, new, t0, dt, R, THR, peaks, peak_run) -> None:
        """One block of B samples: first (N, 19) the modules' first firing times [s] (NaN: not
        yet), new (N, 19) those that fired in this block, t0 (N,) each engine's time of its first
        sample, dt [s]; sized cells only: residuals R and thresholds THR (N, B, 19), the block's
        peak ratios peaks (N, 19) and peak_run (N, 19) the running peak ratios before it."""
        B = R.shape[1]
        t_end = t0 + (B - 1) * dt
        busy = new.any(axis=1) | (t_end > self.next_expiry)
        if self.sized:
            busy |= (peaks > self.next_peak).any(axis=1)
            for i in np.flatnonzero(busy):
                st = self.decisions[i]
                times = first[i]
                tt = t0[i] + np.arange(B) * dt
                q = running_peaks(ratios(R[i : i + 1], THR[i : i + 1]), peak_run[i : i + 1])[0]
                firings = [
                    (min(B - 1, max(0, int(round((t - t0[i]) / dt)))), ~np.isnan(times) & (times <= t))
                    for t in np.unique(times[new[i]])
                ]
                drive_block(st, tt, q, firings, float(tt[-1]))
                self.next_expiry[i] = st._next_expiry
                self.next_peak[i] = st.next_peak
            return
        for i in np.flatnonzero(busy):
            st = self.decisions[i]
            if new[i].any():
                times = first[i]
                for t in np.unique(times[new[i]]):
                    st.update(~np.isnan(times) & (times <= t), float(t))
            st.advance(float(t_end[i]))
            self.next_expiry[i] = st._next_expiry


class SequentialStage(DecidesWithCellSets):
    """The CUSUM tests and the decision logic of N engines, fed with the reference diagnoser's
    residuals and violations (the environment's feature generator already computes them).

    exoneration, cells : as :class:`ReferenceDiagnoser` (``"sure"``: this stage's own measured sure
    cells, of the cell set ``cells``; ``"sized"`` bounds a fault's size by the reference's running
    peak ratios, so :meth:`update` then needs the thresholds).
    """

    def __init__(
        self,
        n_engines: int,
        dt: float = 0.01,
        calibration: "SequentialCalibration | str | None" = None,
        max_cardinality: int = 2,
        exoneration: str = "sure",
        cells: str = DEFAULT_CELLS,
    ) -> None:
        self.n = int(n_engines)
        self.dt = float(dt)
        if calibration is None or isinstance(calibration, str):
            calibration = load_calibration(calibration or CALIBRATION_FILE)
        self.cal = calibration
        self.block = int(round(self.cal.block_s / self.dt))
        if self.block < 1:
            raise ValueError(f"the CUSUM block ({self.cal.block_s} s) is shorter than a sample ({self.dt} s)")
        if exoneration not in ("sure", "none", "all", None):
            raise ValueError(f"exoneration must be 'sure', 'none' or 'all', got {exoneration!r}")
        self.exoneration = "none" if exoneration is None else exoneration
        self.max_cardinality = max_cardinality
        self.cells = check_cells(cells)
        self.cell_sets: tuple[str, ...] = (self.cells,)
        self.reset()

    def _decider(self, cells: str) -> SequentialDecisions:
        return SequentialDecisions(self.n, cells, self.exoneration, self.max_cardinality)

    def _receiver_arrays(self) -> None:
        r = self.cal.receiver
        self._pair = np.array([MODULE_IDS.index(m) for m in r.modules], dtype=np.int64)
        self._gpar = np.array([r.h, r.order, self.cal.block_s / r.gate_tau_s, r.gate_delta])
        self._gnorms = glr_norms(r.order, r.window_blocks)

    def reset(self) -> None:
        self.acc = np.zeros((self.n, 22))
        self.st = np.zeros((self.n, N_MODULES, 2))
        self.first = np.full((self.n, N_MODULES), np.nan)
        self.feats = np.zeros((self.n, N_MODULES, 3))
        self._receiver_arrays()
        self.gnum = np.zeros((self.n, len(self._gnorms), 2))
        self.gcount = np.zeros(self.n, dtype=np.int64)
        self.gpos = np.zeros(self.n, dtype=np.int64)
        self.gavg = np.full(self.n, np.nan)
        self.gstate = np.zeros((self.n, 4))
        self.gstate[:, 1] = np.nan
        self._deciders = [self._decider(c) for c in self.cell_sets]
        self.peak_run = np.zeros((self.n, N_MODULES))
        self._started = False

    def reset_engines(self, engines) -> None:
        idx = np.asarray(engines, dtype=np.int64).reshape(-1)
        for d in self._deciders:
            d.reset_engines(idx)
        for i in idx:
            self.acc[i] = 0.0
            self.st[i] = 0.0
            self.first[i] = np.nan
            self.feats[i] = 0.0
            self.gnum[i] = 0.0
            self.gcount[i] = 0
            self.gpos[i] = 0
            self.gavg[i] = np.nan
            self.gstate[i] = (0.0, np.nan, 0.0, 0.0)
            self.peak_run[i] = 0.0

    def update(self, residuals, u, ratio, violations, t0, thresholds=None, peaks=None) -> None:
        """One block: residuals (N, B, 19), u (N, B), ratio (N, B) the measured pressure ratio
        (:func:`pressure_ratio`), violations (N, B, 19) bool or None, t0 (N,) each engine's time
        of the block's first sample.  Sized cells only: the reference's thresholds (N, B, 19) and
        its block peaks of |r|/threshold (N, 19) (:attr:`BlockOutput.peaks`; computed if None)."""
        R = np.ascontiguousarray(residuals, dtype=np.float64)
        U = np.ascontiguousarray(u, dtype=np.float64)
        Q = np.ascontiguousarray(ratio, dtype=np.float64)
        N, B, _ = R.shape
        V = np.zeros((N, 0, N_MODULES), dtype=np.bool_) if violations is None else np.ascontiguousarray(violations)
        t0 = np.ascontiguousarray(t0, dtype=np.float64)
        before = np.isnan(self.first)
        c = self.cal
        cusum_blocks(
            R,
            U,
            Q,
            V,
            self.dt,
            t0,
            self.block,
            c.u_nodes,
            c.mean,
            c.scale,
            c.k,
            c.h,
            c.warmup_s,
            c.r_max,
            self.acc,
            self.st,
            self.first,
            self.feats,
            self._pair,
            self._gpar,
            self._gnorms,
            self.gnum,
            self.gcount,
            self.gpos,
            self.gavg,
            self.gstate,
        )
        new = before & ~np.isnan(self.first)
        THR = pk = None
        if self.needs_peaks:
            if thresholds is None:
                raise ValueError("the sized cells need the reference's thresholds: pass thresholds=")
            THR = np.asarray(thresholds, dtype=np.float64)
            pk = ratios(R, THR).max(axis=1) if peaks is None else np.asarray(peaks, dtype=np.float64)
        self._started = True
        for d in self._deciders:
            d.update(self.first, new, t0, self.dt, R, THR, pk, self.peak_run)
        if pk is not None:
            np.maximum(self.peak_run, pk, out=self.peak_run)

    def features(self) -> np.ndarray:
        """(N, 19 * 4) float32: per module S+/h and S-/h (capped at 10), the last block's z, fired."""
        f = np.empty((self.n, N_MODULES, len(SEQUENTIAL_FEATURES)), dtype=np.float32)
        f[:, :, 0] = np.minimum(self.feats[:, :, 0], Z_CAP)
        f[:, :, 1] = np.minimum(self.feats[:, :, 1], Z_CAP)
        f[:, :, 2] = self.feats[:, :, 2]
        f[:, :, 3] = ~np.isnan(self.first)
        return f.reshape(self.n, -1)

    @property
    def detected(self) -> np.ndarray:
        return ~np.isnan(self.first).all(axis=1)

    def report(self, engine: int = 0) -> dict:
        d = self.decisions[engine]
        times = {m: (None if math.isnan(v) else float(v)) for m, v in zip(MODULE_IDS, self.first[engine])}
        det = bool(d.detected)
        return {
            "detected": det,
            "first_detection_time_s": None if math.isnan(d.first_detection_time) else d.first_detection_time,
            "module_detection_times_s": times,
            "receiver_test_time_s": None if math.isnan(self.gstate[engine, 1]) else float(self.gstate[engine, 1]),
            "final_minimal_diagnoses": sorted_diagnoses(d.diagnoses) if det else [],
            "candidate_classes": candidate_classes(d.diagnoses) if det else {},
        }


class SequentialDiagnoser:
    """Streaming ``sequential`` diagnoser for N engines: the reference diagnoser's residual
    generators (its worst-case thresholds too) followed by :class:`SequentialStage`.

    Parameters as :class:`ReferenceDiagnoser` (``inclusion`` for its thresholds) plus
    ``calibration`` (a :class:`SequentialCalibration` or file name in data/diagnosis).
    """

    name = "sequential"

    def __init__(
        self,
        params="thesis-12v28",
        n_engines: int = 1,
        dt: float = 0.01,
        noise_bounds=None,
        max_cardinality: int = 2,
        exoneration: str = "sure",
        inclusion: str = "tabulated",
        calibration=None,
        cells: str = DEFAULT_CELLS,
    ) -> None:
        self.ref = ReferenceDiagnoser(
            params,
            n_engines=n_engines,
            dt=dt,
            noise_bounds=noise_bounds,
            max_cardinality=max_cardinality,
            exoneration="none",
            inclusion=inclusion,
        )
        self.stage = SequentialStage(n_engines, dt, calibration, max_cardinality, exoneration, cells)
        self.n, self.dt = self.ref.n, self.ref.dt

    def reset(self) -> None:
        self.ref.reset()
        self.stage.reset()

    def observe(self, measurements, u):
        t0 = (self.ref.samples - self.ref._offset) * self.dt
        out = self.ref.observe(measurements, u)
        U = np.asarray(u, dtype=np.float64)
        Y = np.asarray(measurements, dtype=np.float64)
        self.stage.update(
            out.residuals,
            U[None] if U.ndim == 1 else U,
            pressure_ratio(Y[None] if Y.ndim == 2 else Y),
            out.violations,
            t0,
            out.thresholds,
            out.peaks,
        )
        return out

    @property
    def detected(self) -> np.ndarray:
        return self.stage.detected

    def diagnoses(self, engine: int = 0):
        return list(self.stage.decisions[engine].diagnoses)

    def module_detection_times(self, engine: int = 0) -> dict:
        return self.stage.report(engine)["module_detection_times_s"]

    def report(self, engine: int = 0) -> dict:
        return self.stage.report(engine)
