"""The data's own scatter, the scale at which residual structure is judged where a stated tolerance is loose.

A tolerance is both the residual scale of the fit and the smallest discrepancy worth naming.  When a sensor is
stated looser than it reads (a tolerance of 5 K on a thermocouple that scatters by 2.5 K), a local effect of
several times the real noise stays inside a scan whose noise is floored at the tolerance (a 25 K bump on the
turbine outlet temperature, 5 tolerances at its peak and about 9 standard deviations of the file's noise).  So
each channel's local-window scan (:func:`~.unexplained.local_excess`) is judged at the scale the data show where it
is below the tolerance, and at the tolerance elsewhere; what is reported must still depart by a tolerance.

The data's scale is one number for the whole dataset, in tolerances: the largest over the channels of each
channel's robust scatter, ``median |Δr| / (0.6745 sqrt 2)`` of its successive residual differences in load order
(blind to smooth biases and trends; a bump or a step touches a few of the differences and barely moves the median).
It applies only when it is below 1, i.e. when every channel reads tighter than its stated tolerance; each channel is
then judged at its tolerance times that number.  A channel that reads at or above its tolerance turns the
data-scale judgement off for the dataset (every channel is judged at its tolerance).

Why the largest channel and not each channel's own scatter or their median (pure-noise datasets and one effect on
one channel, 8 points, 13 channels, family-wise 5 %, 2000 draws each; docs/figures/validation/data_scale_bound.json,
made as docs/validation.md says):

* each channel's own scatter from 7 differences is too uncertain to be used as if known; a null that simulates the
  estimate (a studentised scan) needs a scan statistic of 6.8 instead of 3.5, and finds a 5-noise-level bump in
  3 % of draws against 79 % with the noise known: one channel alone cannot carry the judgement;
* the median over channels treats every channel as equally loose.  Where they are not (1 % noise against
  1 % / 5 K tolerances: pressures and speeds at their tolerance, cool temperatures far below it) the channels at
  their tolerance are judged below their noise, and 15 % of pure-noise datasets show a local finding (3 % with the
  largest);
* the price of the largest: the largest of 13 estimates lies above their common level, so with every channel at
  half its tolerance a bump of 5 noise levels is found in 4 % of draws (median 27 %, known noise 79 %), of 8
  levels in 54 %, a step of 5 levels in 65 %; with 14 points 39 %, 99 % and 99 %.

Each finding says which scale it was judged at (``scale``: ``"data"`` or ``"tolerance"``, and ``noise``).
"""

from __future__ import annotations

import math
from typing import Mapping, Sequence

import numpy as np

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
    """Per channel (``channels``, default every channel of ``residuals``), the data's scale in its units, or None
    for all when the largest channel scatter (in tolerances) is not below 1 (see the module docstring)."""
    channels = list(channels or residuals)
    own = [channel_noise(np.asarray(residuals[c], float), load) / float(tolerances[c]) for c in residuals]
    own = [x for x in own if math.isfinite(x)]
    ratio = max(own) if own else math.inf
    if not 0.0 < ratio < 1.0:
        return {c: None for c in channels}
    return {c: ratio * float(tolerances[c]) for c in channels}
