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

The period statistics of the module ratios (the environment observation's features and the
reference diagnoser's ``BlockOutput.stats``) are computed here too, by compiled helpers both use:
the signed ratio ``r / threshold`` clipped to ``±RATIO_CAP`` (NaN: ``+RATIO_CAP``), and per engine and
module over the B samples of a period (max |ratio|, mean |ratio|, mean signed ratio, share of
|ratio| > 1), summed in sample order.
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import jit, jit_inline

__all__ = [
    "PEAK_CAP",
    "RATIO_CAP",
    "STEP",
    "FLOOR",
    "ratios",
    "running_peaks",
    "PeakRecorder",
    "peak_at",
    "clipped_signed_ratio",
    "reset_period_stats",
    "add_period_ratio",
    "finish_period_stats",
    "period_stats",
]

PEAK_CAP = 1e3
RATIO_CAP = PEAK_CAP  # the cap of the signed ratio in the period statistics
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


@jit_inline
def clipped_signed_ratio(r, thr):
    """The signed ratio ``r / thr`` clipped to ±RATIO_CAP; NaN gives +RATIO_CAP."""
    s = r / thr
    if s != s:
        s = RATIO_CAP
    elif s > RATIO_CAP:
        s = RATIO_CAP
    elif s < -RATIO_CAP:
        s = -RATIO_CAP
    return s


@jit_inline
def reset_period_stats(stats, i):
    """Zero the period statistics ``stats[i]`` (19, 4) of engine i."""
    for m in range(stats.shape[1]):
        stats[i, m, 0] = 0.0
        stats[i, m, 1] = 0.0
        stats[i, m, 2] = 0.0
        stats[i, m, 3] = 0.0


@jit_inline
def add_period_ratio(stats, i, m, s):
    """Add the clipped signed ratio ``s`` of one sample to ``stats[i, m]`` (max, sum |s|, sum s, count |s| > 1)."""
    a = abs(s)
    if a > stats[i, m, 0]:
        stats[i, m, 0] = a
    stats[i, m, 1] += a
    stats[i, m, 2] += s
    if a > 1.0:
        stats[i, m, 3] += 1.0


@jit_inline
def finish_period_stats(stats, i, B):
    """Turn the sums of ``stats[i]`` over a period of B samples into means and a share."""
    for m in range(stats.shape[1]):
        stats[i, m, 1] /= B
        stats[i, m, 2] /= B
        stats[i, m, 3] /= B


@jit
def period_stats(R, THR, stats):
    """Per engine and module over the B samples of a period (one pass, compiled): stats[:, :, 0] =
    max ratio, 1 = mean ratio, 2 = mean signed ratio, 3 = share of ratios > 1, with the signed
    ratio r/thr clipped to ±RATIO_CAP (NaN: +RATIO_CAP) and ratio = |signed ratio|.  The sums run in
    sample order, as numpy's reduction over axis 1 of a C-contiguous (N, B, 19) array, so the
    values equal the numpy expressions bit for bit (tested)."""
    N, B, M = R.shape
    for i in range(N):
        reset_period_stats(stats, i)
        for k in range(B):
            for m in range(M):
                add_period_ratio(stats, i, m, clipped_signed_ratio(R[i, k, m], THR[i, k, m]))
        finish_period_stats(stats, i, B)
