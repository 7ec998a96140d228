"""The detection bounds of issue 13's seal-leak must-show (studies.diagnosis.detection_bound)."""

import math

import numpy as np
import pytest

from marine_fdi_env.diagnosis.incipient_glr import glr_polynomial
from studies.diagnosis.detection_bound import matched_filter, white_noise_threshold


def _brute_glr(p, order, window, paused=None):
    R, N = p.shape
    out = np.zeros((R, N))
    for r in range(R):
        for T in range(1, N + 1):
            best = 0.0
            for tau in range(max(0, T - window), T):
                if paused is not None and paused[r, :T][tau:].any():
                    continue  # a paused block at or after the onset: the test restarted after it
                g = np.arange(1, T - tau + 1, dtype=float) ** order
                best = max(best, abs(float(p[r, tau:T] @ g)) / math.sqrt(float(g @ g)))
            out[r, T - 1] = best
    return out


@pytest.mark.parametrize("order", [0, 1, 2])
def test_glr_equals_the_direct_maximum_over_onsets(order):
    rng = np.random.default_rng(3)
    p = rng.standard_normal((3, 40))
    paused = np.zeros_like(p, dtype=bool)
    paused[1, 10] = True
    paused[2, :5] = True
    got = glr_polynomial(p, order, 25, paused)
    want = _brute_glr(p, order, 25, paused)
    # prefix sums of t^j p with t <= 40: cancellation error ~ 1e-16 x 40^2q x N, far below 1e-9
    np.testing.assert_allclose(got, want, rtol=1e-9, atol=1e-9)


def test_glr_is_at_least_the_matched_filter_at_the_true_onset():
    """The GLR maximises over onsets (and the sign), so it can never be below the oracle that knows
    the onset: the bound's rows are ordered by construction."""
    rng = np.random.default_rng(4)
    t = np.arange(1, 201, dtype=float)
    onset = 50
    p = rng.standard_normal((20, 200)) - 1e-4 * np.clip(t - onset, 0, None) ** 2
    glr = glr_polynomial(p, 2, 200)
    for end in (120, 200):
        mf = matched_filter(p, onset, 2, end)
        assert np.all(glr[:, end - 1] >= np.abs(mf) - 1e-9)


def test_matched_filter_is_standard_normal_without_a_fault_and_sees_a_planted_shift():
    rng = np.random.default_rng(5)
    n = 4000
    p = rng.standard_normal((n, 300))
    z = matched_filter(p, 15.0, 2, 300)
    # mean within 4 standard errors of 0, sd within 4 of 1 (se of the sd ~ 1/sqrt(2n))
    assert abs(z.mean()) < 4 / math.sqrt(n)
    assert abs(z.std() - 1.0) < 4 / math.sqrt(2 * n)
    c = 1e-5
    t = np.arange(1, 301, dtype=float)
    g = np.clip(t - 15.0, 0, None) ** 2
    shifted = matched_filter(p + c * g, 15.0, 2, 300)
    np.testing.assert_allclose(shifted - z, c * math.sqrt(float(g @ g)), rtol=1e-12)


def test_white_noise_threshold_is_seeded_and_grows_as_the_budget_shrinks():
    a = white_noise_threshold(2, 60, 60, 1e-3, n_runs=2000, seed=1)
    b = white_noise_threshold(2, 60, 60, 1e-3, n_runs=2000, seed=1)
    assert a == b
    strict = white_noise_threshold(2, 60, 60, 1e-5, n_runs=2000, seed=1)
    assert strict["h"] > a["h"]
    # a single known-onset look needs |N(0,1)| > 3.29 at p = 1e-3; scanning onsets and times costs more
    assert a["h"] > 3.29


def test_recorded_threshold_keeps_the_margin_over_the_largest_peak():
    from studies.diagnosis.detection_bound import recorded_threshold

    rng = np.random.default_rng(6)
    p = rng.standard_normal((200, 120))
    paused = np.zeros_like(p, dtype=bool)
    h, h_tail, peak = recorded_threshold(p, paused)
    assert peak == pytest.approx(glr_polynomial(p, 2, 300, paused).max())
    assert h == max(h_tail, 1.2 * peak)
