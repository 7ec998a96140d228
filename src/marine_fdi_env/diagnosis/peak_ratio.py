"""The running peak of each module's |r|/threshold: the evidence from which the size-aware
exoneration bounds a fault's size (:mod:`marine_fdi_env.diagnosis.sized_cells`).

The ratio of a sample is ``|r| / threshold`` with the rule of the reference diagnoser's features
(:func:`marine_fdi_env.diagnosis.agent._violations_and_peaks`): a ratio that is not finite, or a
threshold <= 0, counts as the cap ``PEAK_CAP``; ratios are capped there.  The running peak is the
largest ratio since the engine's run started; it only grows.

:class:`PeakRecorder` keeps, per engine and module, the times at which the running peak first
reaches each step of a logarithmic scale (``STEP`` = 2 %, from ``FLOOR`` on): the compact record
the certainty grid stores so that the decision logic can be replayed on it (a replay reads the
peak at most 2 % low, which can only lower a size bound).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["PEAK_CAP", "STEP", "FLOOR", "ratios", "running_peaks", "PeakRecorder", "peak_at"]

PEAK_CAP = 1e3
STEP = 1.02
FLOOR = 0.25
_LOG_STEP = math.log(STEP)


def ratios(residuals: np.ndarray, thresholds: np.ndarray) -> np.ndarray:
    """|r| / threshold (..., 19), non-finite or threshold <= 0 -> ``PEAK_CAP``, capped there."""
    r = np.abs(np.asarray(residuals, dtype=np.float64))
    thr = np.asarray(thresholds, dtype=np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        q = np.where(thr > 0.0, r / thr, np.inf)
    q[~(q <= PEAK_CAP)] = PEAK_CAP
    return q


def running_peaks(ratio: np.ndarray, carry: np.ndarray) -> np.ndarray:
    """(N, B, 19) running maximum along the samples of ``ratio`` (N, B, 19), starting from
    ``carry`` (N, 19), the running peak before the block."""
    out = np.maximum(ratio, np.asarray(carry)[:, None, :])
    np.maximum.accumulate(out, axis=1, out=out)
    return out


def _level(q: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore"):
        return np.where(q >= FLOOR, np.floor(np.log(np.maximum(q, FLOOR)) / _LOG_STEP), -np.inf)


class PeakRecorder:
    """Running peaks of N engines and their step crossings: ``events[i][m]`` is a list of
    ``[t, q]`` (time [s], running peak) where the running peak of module m reached a new 2 % step."""

    def __init__(self, n_engines: int, n_modules: int = 19) -> None:
        self.peak = np.zeros((n_engines, n_modules))
        self._level = np.full((n_engines, n_modules), -np.inf)
        self.events: list[list[list[list[float]]]] = [[[] for _ in range(n_modules)] for _ in range(n_engines)]

    def update(self, residuals: np.ndarray, thresholds: np.ndarray, t0: np.ndarray, dt: float) -> None:
        """One block (N, B, 19) whose first sample of engine i is at time ``t0[i]``."""
        rp = running_peaks(ratios(residuals, thresholds), self.peak)
        lv = _level(rp)
        prev = np.concatenate([self._level[:, None, :], lv[:, :-1, :]], axis=1)
        for i, k, m in zip(*np.nonzero(lv > prev)):
            self.events[i][m].append([round(float(t0[i] + k * dt), 3), float(f"{rp[i, k, m]:.5g}")])
        self.peak = rp[:, -1, :].copy()
        self._level = lv[:, -1, :].copy()


def peak_at(events: list[list[float]], t: float) -> float:
    """The recorded running peak of one module at time t (0 before its first event)."""
    q = 0.0
    for te, qe in events:
        if te > t:
            break
        q = qe
    return q
