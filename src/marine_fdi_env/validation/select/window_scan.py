"""Scan for a local departure: the window of consecutive points (in load order) whose mean residual departs most
from the rest, with a p-value calibrated by simulation.

The statistic of one window of ``w`` of the ``n`` points is ``z = |d| / (σ sqrt(1/w + 1/(n - w)))``, ``d`` the
window's mean residual minus the rest's, ``σ = max(tol, s_rest)`` (``s_rest`` the scatter outside the window: a
bump's own spread is not noise; the tolerance is the floor).  The scan takes the largest ``z`` over every window of
2 .. ``n/2`` points.

Its p-value is the probability that noise alone gives a scan statistic as large: simulated once per (number of
points, widest window, noise level) with :data:`NULL_SAMPLES` draws from a fixed seed (the same numbers on every
run) and cached.  Not the best window's normal p-value times the number of windows (Bonferroni), which errs both
ways:

* the windows overlap, so with noise at the tolerance Bonferroni is about 2x conservative (8 points: false alarm
  rate 0.045 % at a nominal 0.077 %);
* ``s_rest`` from four to six points is a poor estimate of a noise larger than the tolerance, and a normal p-value
  ignores that: with noise 1.5x the tolerance that scan flags 9 % of pure-noise channels at a nominal 1 %.

The null's noise level is the dataset's (:func:`noise_ratio`, at least the tolerance), so the test holds its level when
the data as a whole are noisier than the tolerance says (tested).  It does not when only some channels are: the level is
a median over channels.  With noise 1.5 % of each reading against a 1 % tolerance of the mean reading (the open-world
study, docs/validation.md) the engine and turbocharger speeds and the cylinder-outlet temperature carry noise of 1.3-2
tolerances while most other channels carry less, and 5-6 of 20 negative controls still show a local finding on one of
them (with the Bonferroni p-value: 6 of 20).  A per-channel noise level robust to the channel's own effect is the next
step (not done).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy import stats

__all__ = ["window_excess", "noise_ratio", "scan_null", "NULL_SAMPLES", "NOISE_GRID"]

#: simulated pure-noise channels per null distribution (p-values resolve down to 1/NULL_SAMPLES)
NULL_SAMPLES = 40_000
#: the null's noise level (in tolerances) is rounded *up* to this grid, so that few distributions are simulated and
#: the rounding errs on the conservative side
NOISE_GRID = 0.05

_NULL_CACHE: dict[tuple[int, int, int], np.ndarray] = {}


def _windows(n: int, wmax: int) -> list[tuple[int, int]]:
    return [(a, w) for w in range(2, wmax + 1) for a in range(0, n - w + 1)]


def _scan(R: np.ndarray, tol: float, wmax: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Scan statistic of each row of ``R`` (samples x n, in load order): (max z, window start, width, d, σ) of the
    best window per row (vectorised over rows; the observed data are a one-row call)."""
    N, n = R.shape
    c1 = np.concatenate([np.zeros((N, 1)), np.cumsum(R, axis=1)], axis=1)
    c2 = np.concatenate([np.zeros((N, 1)), np.cumsum(R * R, axis=1)], axis=1)
    tot, tot2 = c1[:, -1], c2[:, -1]
    best = np.full(N, -np.inf)
    arg_a, arg_w = np.zeros(N, int), np.zeros(N, int)
    best_d, best_s = np.zeros(N), np.zeros(N)
    for a, w in _windows(n, wmax):
        s_in = c1[:, a + w] - c1[:, a]
        m = n - w
        s_out = tot - s_in
        d = s_in / w - s_out / m
        if m >= 3:
            q_out = tot2 - (c2[:, a + w] - c2[:, a])
            s_rest = np.sqrt(np.maximum(q_out - s_out * s_out / m, 0.0) / (m - 1))
            sigma = np.maximum(tol, s_rest)
        else:
            sigma = np.full(N, tol)
        z = np.abs(d) / (sigma * math.sqrt(1.0 / w + 1.0 / m))
        better = z > best
        best = np.where(better, z, best)
        arg_a, arg_w = np.where(better, a, arg_a), np.where(better, w, arg_w)
        best_d, best_s = np.where(better, d, best_d), np.where(better, sigma, best_s)
    return best, arg_a, arg_w, np.stack([best_d, best_s])


def scan_null(n: int, wmax: int, noise: float = 1.0) -> np.ndarray:
    """Sorted scan statistics of :data:`NULL_SAMPLES` channels of independent Gaussian noise of ``noise`` tolerances
    (tolerance 1), ``n`` points, windows up to ``wmax``; cached, from a seed fixed by the arguments."""
    step = max(1, math.ceil(round(max(noise, 1.0) / NOISE_GRID, 9)))
    key = (int(n), int(wmax), step)
    if key not in _NULL_CACHE:
        rng = np.random.default_rng([int(n), int(wmax), step, 20261125])
        out = np.empty(NULL_SAMPLES)
        chunk = max(1, 4_000_000 // max(n * len(_windows(n, wmax)), 1))
        for s in range(0, NULL_SAMPLES, chunk):
            k = min(chunk, NULL_SAMPLES - s)
            out[s : s + k] = _scan(rng.normal(0.0, step * NOISE_GRID, (k, n)), 1.0, wmax)[0]
        _NULL_CACHE[key] = np.sort(out)
    return _NULL_CACHE[key]


def noise_ratio(R: np.ndarray, load: np.ndarray, floor: float = 1.0) -> float:
    """The data's noise in tolerances (at least ``floor``): per channel (columns of ``R``, residuals already divided
    by their tolerance) the scatter of successive differences in load order (``sqrt(mean(Δr²)/2)``, blind to smooth
    biases and trends), the median over channels (blind to one channel's effect)."""
    R = np.asarray(R, dtype=float)
    if R.ndim == 1:
        R = R[:, None]
    order = np.argsort(np.asarray(load, dtype=float), kind="stable")
    per = []
    for j in range(R.shape[1]):
        r = R[order, j]
        r = r[np.isfinite(r)]
        if r.size >= 4:
            per.append(math.sqrt(float(np.mean(np.diff(r) ** 2)) / 2.0))
    return max(floor, float(np.median(per))) if per else max(floor, 1.0)


def window_excess(
    r: np.ndarray, load: np.ndarray, tol: float, max_width: int | None = None, noise: float = 1.0
) -> dict[str, Any] | None:
    """The most significant window of 2 .. n/2 consecutive points (in load order) whose mean residual departs from
    the rest (see the module docstring).  ``noise``: the data's noise in tolerances (:func:`noise_ratio`).

    Returns ``{p, p_at_floor, p_raw, z, d, sigma, noise, load_range, positions}`` or None (fewer than 4 points):
    ``p`` the simulated probability that noise gives a scan statistic as large (``p_at_floor``: larger than every
    simulated one, then ``p`` is the resolution 1/(NULL_SAMPLES + 1), an upper bound), ``p_raw`` the best window's
    own normal p-value."""
    ok = np.isfinite(r) & np.isfinite(load)
    idx = np.flatnonzero(ok)
    n = idx.size
    if n < 4:
        return None
    order = idx[np.argsort(load[idx], kind="stable")]
    rr, x = np.asarray(r, dtype=float)[order], np.asarray(load, dtype=float)[order]
    wmax = min(max_width or n // 2, n - 2)
    if wmax < 2:
        return None
    z, a, w, (d, sigma) = _scan(rr[None, :] / tol, 1.0, wmax)
    z, a, w = float(z[0]), int(a[0]), int(w[0])
    null = scan_null(n, wmax, noise)
    p = (1 + null.size - int(np.searchsorted(null, z, side="left"))) / (null.size + 1)
    return {
        "p": float(p),
        "p_at_floor": bool(z > null[-1]),
        "p_raw": float(2 * stats.norm.sf(z)),
        "z": z,
        "d": float(d[0]) * tol,
        "sigma": float(sigma[0]) * tol,
        "noise": float(noise),
        "load_range": [float(x[a]), float(x[a + w - 1])],
        "positions": order[a : a + w],
    }
