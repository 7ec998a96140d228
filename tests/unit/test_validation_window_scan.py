"""The local-departure scan (:mod:`marine_fdi_env.validation.select.window_scan`): its p-value holds its level on pure
noise, also when the noise is larger than the tolerance, it finds a bump of a few tolerances, and the noise level of
a dataset is estimated blind to biases, trends and one channel's effect."""

from __future__ import annotations

import math

import numpy as np
import pytest

from marine_fdi_env.validation.select import window_scan as ws


def _p_values(R: np.ndarray, noise: float) -> np.ndarray:
    """Scan p-values of every row of R (pure noise rows, tolerance 1, already in load order)."""
    n = R.shape[1]
    z = ws._scan(R, 1.0, n // 2)[0]
    null = ws.scan_null(n, n // 2, noise)
    return (1 + null.size - np.searchsorted(null, z, side="left")) / (null.size + 1)


@pytest.mark.parametrize("n, noise", [(8, 1.0), (8, 1.5), (12, 1.5)])
def test_the_scan_holds_its_level_on_pure_noise(n, noise):
    """4000 channels of Gaussian noise (drawn apart from the null's seed): the share with p < 5 % is 5 % within
    four binomial standard deviations (0.014).  The Bonferroni p-value (best window's normal p-value x number of
    windows) flags about 9 % of channels with noise 1.5x the tolerance at a nominal 1 %."""
    rng = np.random.default_rng(1234)
    R = rng.normal(0.0, noise, (4000, n))
    p = _p_values(R, noise)
    a = 0.05
    assert abs(np.mean(p < a) - a) <= 4 * math.sqrt(a * (1 - a) / R.shape[0])
    if noise > 1.0:
        z = ws._scan(R, 1.0, n // 2)[0]
        n_win = len(ws._windows(n, n // 2))
        bonferroni = np.minimum(1.0, 2 * __import__("scipy").stats.norm.sf(z) * n_win)
        assert np.mean(bonferroni < 0.01) > 0.04  # Bonferroni's level is broken here


def test_the_null_is_the_same_numbers_on_every_call():
    a = ws.scan_null(8, 4, 1.02).copy()
    ws._NULL_CACHE.clear()
    b = ws.scan_null(8, 4, 1.02)
    assert np.array_equal(a, b)
    assert np.array_equal(b, ws.scan_null(8, 4, 1.05))  # rounded up to the same grid point


def test_a_bump_of_five_tolerances_is_found_where_it_is():
    load = np.linspace(0.25, 1.1, 8)
    rng = np.random.default_rng(7)
    r = rng.normal(0.0, 1.0, 8) * 2.0
    r[4:6] += 5 * 2.0  # two points, 5 tolerances of 2.0
    best = ws.window_excess(r, load, tol=2.0)
    assert best["p"] < 0.05 / 13
    assert best["load_range"] == [pytest.approx(load[4]), pytest.approx(load[5])]
    assert best["d"] == pytest.approx(r[4:6].mean() - np.delete(r, [4, 5]).mean())
    assert ws.window_excess(r[:3], load[:3], tol=2.0) is None


def test_noise_ratio_ignores_biases_trends_and_one_channels_effect():
    """13 channels with noise 1.5 tolerances, each with its own bias and linear trend, one with a bump of 10
    tolerances: the estimate is 1.5 within 15 % (the spread of a median of 13 successive-difference estimates from 8
    points); noise below the tolerance reads as the tolerance."""
    rng = np.random.default_rng(3)
    load = rng.uniform(0.25, 1.1, 8)
    R = rng.normal(0.0, 1.5, (8, 13)) + rng.normal(0, 3, 13) + np.outer(load, rng.normal(0, 4, 13))
    R[np.argsort(load)[3:5], 0] += 10.0
    assert ws.noise_ratio(R, load) == pytest.approx(1.5, rel=0.15)
    assert ws.noise_ratio(0.3 * rng.normal(size=(8, 13)), load) == 1.0
