"""The data's own scatter, the scale at which residual structure is judged where a stated tolerance is loose.

A tolerance is both the residual scale of the fit and the smallest discrepancy worth naming.  When a sensor is
stated looser than it reads (a tolerance of 5 K on a thermocouple that scatters by 2.5 K), a local effect of
several times the real noise stays inside a scan whose noise is floored at the tolerance (a 25 K bump on the
turbine outlet temperature, 5 tolerances at its peak and about 9 standard deviations of the file's noise).  So
each channel's local-window scan (:func:`~.unexplained.local_excess`) is judged at the scale the data show where it
is below the tolerance, and at the tolerance elsewhere; what is reported must still depart by a tolerance.

The data's scale of a channel (:func:`channel_scales`, in its units) is its tolerance times the larger of

* the noise of the whole dataset in tolerances, :func:`~.window_scan.noise_ratio` without its floor (the median
  over channels of the scatter of successive residual differences in load order: blind to smooth biases and
  trends, and to one channel's effect), and
* the channel's own, robustly: ``median |Δr| / (0.6745 sqrt 2)`` of its successive differences (a bump or a step
  touches a few of them and barely moves the median; a channel noisier than the rest keeps its own level).

Each finding says which scale it was judged at (``scale``: ``"data"`` or ``"tolerance"``, and ``noise``).
"""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np

from .window_scan import noise_ratio

__all__ = ["channel_noise", "channel_scales"]


def channel_noise(r: np.ndarray, load: np.ndarray) -> float:
    """Robust scatter of one channel's residuals (its units): ``median |Δr| / (0.6745 sqrt 2)`` of the successive
    differences in load order; NaN with fewer than four readings."""
    ok = np.isfinite(r) & np.isfinite(load)
    if ok.sum() < 4:
        return math.nan
    d = np.diff(np.asarray(r, float)[ok][np.argsort(np.asarray(load, float)[ok], kind="stable")])
    return float(np.median(np.abs(d)) / (0.6745 * math.sqrt(2.0)))


def channel_scales(
    residuals: Mapping[str, np.ndarray],
    tolerances: Mapping[str, float],
    load: np.ndarray,
    channels: Sequence[str] | None = None,
) -> dict[str, float | None]:
    """Per channel, the data's scale (its units) where it is below the channel's tolerance, else None (the
    tolerance is the scale): the module docstring's larger of the dataset's and the channel's own noise."""
    channels = list(channels or residuals)
    R = np.column_stack([np.asarray(residuals[c], float) / float(tolerances[c]) for c in residuals])
    pooled = noise_ratio(R, load, floor=0.0)
    out: dict[str, float | None] = {}
    for c in channels:
        tol = float(tolerances[c])
        own = channel_noise(np.asarray(residuals[c], float), load) / tol
        ratio = max(pooled, own if math.isfinite(own) else 0.0)
        out[c] = ratio * tol if 0.0 < ratio < 1.0 else None
    return out
