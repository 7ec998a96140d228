"""Which faults are active when, for N episode slots at once.

The slots' fault windows are kept as padded arrays (n, width): fault column (-1: none), onset,
end, period and duty, so the active faults of all slots at given times are one vectorised call
of the simulator's own window rule (``faults.window_time``: active from the onset until the end,
on for ``duty`` of every ``period`` for an intermittent fault).
"""

from __future__ import annotations

import math

import numpy as np

from ..engine.faults import FAULT_IDS, window_time

__all__ = ["FaultWindows"]

_FAULT_COL = {f: k for k, f in enumerate(FAULT_IDS)}


class FaultWindows:
    """The fault windows of ``n`` slots (an empty slot has no fault)."""

    def __init__(self, n: int) -> None:
        self.n = int(n)
        self._fcol = np.full((self.n, 0), -1, dtype=np.int64)
        self._fwin = np.zeros((4, self.n, 0))

    def set(self, slot: int, faults) -> None:
        """The faults (:class:`~marine_fdi_env.engine.faults.FaultSpec`) of a new episode in ``slot``."""
        width = self._fcol.shape[1]
        if len(faults) > width:  # grow the padding
            extra = len(faults) - width
            self._fcol = np.concatenate([self._fcol, np.full((self.n, extra), -1, dtype=np.int64)], axis=1)
            self._fwin = np.concatenate([self._fwin, np.zeros((4, self.n, extra))], axis=2)
        inf = math.inf
        self._fcol[slot] = -1
        self._fwin[:, slot] = np.array([[inf], [inf], [inf], [1.0]])  # never active
        for k, f in enumerate(faults):
            self._fcol[slot, k] = _FAULT_COL[f.fault_id]
            self._fwin[:, slot, k] = (
                f.onset_s,
                inf if f.end_s is None else f.end_s,
                inf if f.period_s is None else f.period_s,
                1.0 if f.duty is None else f.duty,
            )

    def active(self, slots, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(active (len(slots), 26) bool, first onset, last onset) of the slots' faults at the times
        ``t`` [s] (one per slot; onsets 0 where no fault is active)."""
        slots = np.asarray(slots, dtype=np.int64)
        col = self._fcol[slots]
        onset, end, period, duty = self._fwin[:, slots]
        on = ~np.isnan(window_time(np.asarray(t)[:, None], onset, end, period, duty))
        act = np.zeros((len(slots), len(FAULT_IDS)), dtype=bool)
        rows, ks = np.nonzero(on)
        act[rows, col[rows, ks]] = True
        some = on.any(axis=1)
        first = np.where(some, np.where(on, onset, math.inf).min(axis=1, initial=math.inf), 0.0)
        last = np.where(some, np.where(on, onset, -math.inf).max(axis=1, initial=-math.inf), 0.0)
        return act, first, last
