"""Exact binomial confidence intervals for the rates the validation reports (replicas, pooled study files)."""

from __future__ import annotations

import math

from scipy import stats

__all__ = ["proportion_ci95"]


def proportion_ci95(k: int, n: int) -> list[float]:
    """Two-sided 95 % Clopper-Pearson interval ``[low, high]`` of ``k`` successes in ``n`` trials (NaN when n = 0)."""
    if n == 0:
        return [math.nan, math.nan]
    ci = stats.binomtest(k, n).proportion_ci(0.95, method="exact")
    return [float(ci.low), float(ci.high)]
