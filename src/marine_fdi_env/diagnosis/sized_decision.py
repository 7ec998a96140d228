"""Minimal diagnoses with size-aware exoneration and time order (the ``sized`` cell set).

The logic of :func:`marine_fdi_env.diagnosis.decision.diagnosis_conflicts` with the temporal
check, with one change: a fault f is judged as the explanation of each fired module m with the
cells of its size band for m (:meth:`SizedCells.bands`, from m's running peak ratio).  Fault f can
explain fired module m when

* **exoneration**: no module m' that is sure for f in that band is silent after its grace period
  T_D(m) + 1.5 x lag + 2 s, lag being m''s largest delay behind f's first fired module over the
  band's runs (had f fired m, its first module fired no later than T_D(m)); where f fired m in none
  of its runs at any size, f is judged at its largest size and the grace is 2 s: in every run
  its sure modules fired before the run ended and m not at all, and
* **time order** (sensor faults): every sure module m' of f in that band that has fired did so by
  the same time: had f fired m, m' followed within its measured lag.  A module fired long before
  the modules a fault of that size fires with it is not explained by it.

The minimal diagnoses are the minimal hitting sets of these conflicts (Berge's algorithm, as
:func:`~marine_fdi_env.diagnosis.decision.minimal_diagnoses`).  :class:`SizedDiagnosisState`
recomputes them when the fired set changes, a grace period ends or a band moves up (the running
peak of a fired module passes :meth:`SizedCells.next_peak`); :func:`drive_block` feeds it the
samples of a block in time order.
"""

from __future__ import annotations

import math

import numpy as np

from ..engine.faults import FAULT_IDS
from .decision import N_FAULTS, N_MODULES, DiagnosisState, diagnosis_sort_key, mhs_masks, set_from_mask
from .sized_cells import SizedCells

__all__ = ["sized_conflicts", "SizedDiagnosisState", "drive_block"]


def sized_conflicts(
    fired: np.ndarray,
    detection_times: np.ndarray,
    peaks: np.ndarray,
    now: float,
    cells: SizedCells,
    support: np.ndarray,
    margin_s: float = 2.0,
    factor: float = 1.5,
) -> tuple[list[int], float]:
    """Bitmasks (over ``FAULT_IDS``) of the faults that can explain each fired module (module
    docstring), and the next time a grace period that matters ends (inf: none).

    fired (19,) bool; detection_times (19,) [s]; peaks (19,) running peak ratios; margin_s [s],
    factor: of the grace and settle times (:meth:`SizedCells.timings`).
    """
    rows = np.flatnonzero(fired)
    if not len(rows):
        return [], math.inf
    td = np.where(fired, detection_times, np.inf)
    band = cells.bands(peaks)[rows]  # (r, 26)
    cols = np.arange(N_FAULTS)[None, :]
    sure = cells.sure.transpose(0, 2, 1)[band, cols]  # (r, 26, 19)
    g, s = cells.timings(band, rows, margin_s, factor)  # (r, 26, 19): per sure module, given the module explained
    # had f fired module m (row r), f's first module fired no later than T_D(m): its silent sure
    # modules are awaited until T_D(m) + grace (counting from f's earliest support module instead
    # would let a module another fault fired earlier end the grace too soon)
    ends = td[rows][:, None, None] + g
    silent_sure = sure & ~fired[None, None, :]
    exonerated = (silent_sure & (now > ends)).any(axis=2)
    late = (sure & fired[None, None, :] & (td[None, None, :] > td[rows][:, None, None] + s)).any(axis=2)
    ok = support[rows] & ~exonerated & ~late
    pending = ends[silent_sure & (ends >= now) & ok[:, :, None]]
    conflicts = []
    for r in range(len(rows)):
        m = 0
        for j in np.flatnonzero(ok[r]):
            m |= 1 << int(j)
        conflicts.append(m)
    return conflicts, float(pending.min()) if len(pending) else math.inf


class SizedDiagnosisState(DiagnosisState):
    """:class:`~marine_fdi_env.diagnosis.decision.DiagnosisState` with the sized cells: ``update``
    and ``advance`` also take the modules' running peak ratios (19,) at that time."""

    def __init__(
        self,
        cells: SizedCells,
        *,
        support=None,
        max_cardinality: int | None = 2,
        settle_margin_s: float = 2.0,
        factor: float = 1.5,
    ) -> None:
        self.cells = cells
        self._margin_s, self._factor = float(settle_margin_s), float(factor)
        super().__init__(support=support, exoneration=cells.sure[0], max_cardinality=max_cardinality, temporal=True)

    def reset(self) -> None:
        super().reset()
        self.peaks = np.zeros(N_MODULES)
        self.next_peak = np.full(N_MODULES, np.inf)

    def update(self, decisions, t: float | None = None, peaks=None) -> bool:
        if peaks is not None:
            self.peaks = np.maximum(self.peaks, peaks)
        return super().update(decisions, t)

    def advance(self, t: float, peaks=None) -> bool:
        """Move the clock to t (and the running peaks to ``peaks``); recompute when a grace period
        has ended or a band has moved up."""
        if peaks is not None:
            self.peaks = np.maximum(self.peaks, peaks)
        if self.fired.any() and (t > self._next_expiry or bool((self.peaks > self.next_peak).any())):
            self._recompute(float(t))
            return True
        return False

    def _recompute(self, now: float) -> None:
        conflicts, self._next_expiry = sized_conflicts(
            self.fired, self.detection_times, self.peaks, now, self.cells, self.support, self._margin_s, self._factor
        )
        k = N_FAULTS if self.max_cardinality is None else int(self.max_cardinality)
        self.diagnoses = sorted((set_from_mask(m, FAULT_IDS) for m in mhs_masks(conflicts, k)), key=diagnosis_sort_key)
        self.next_peak = self.cells.next_peak(self.peaks, self.fired)
        self.n_recomputations += 1


def drive_block(st: SizedDiagnosisState, times: np.ndarray, peaks: np.ndarray, firings, t_end: float) -> None:
    """Feed one engine's block to ``st`` in time order.

    times (B,) [s]; peaks (B, 19) running peak ratios at each sample; firings: (row, decision
    vector (19,)) for the samples where a module fires for the first time, ascending.  Between
    firings, the state is advanced at the first sample where a grace period has ended or a band
    moves up, repeatedly; at the end to ``t_end`` with the last running peaks.
    """
    row = 0
    for r_fire, dec in list(firings) + [(len(times), None)]:
        while row < r_fire:
            seg_t = times[row:r_fire]
            hit = (seg_t > st._next_expiry) | (peaks[row:r_fire] > st.next_peak).any(axis=1)
            if not st.fired.any() or not hit.any():
                break
            r = row + int(np.argmax(hit))
            st.advance(float(times[r]), peaks[r])
            row = r + 1
        if dec is None:
            break
        st.update(dec, float(times[r_fire]), peaks[r_fire])
        row = r_fire + 1
    st.advance(float(t_end), peaks[-1] if len(peaks) else None)
