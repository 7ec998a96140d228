"""The learned agents' noise-invariant inputs (training/features.py) and the classifier's conformal
isolation rule (training/classifier.py)."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("torch")

from marine_fdi_env.envs.observation import MODULE_FEATURES, feature_names  # noqa: E402
from marine_fdi_env.training.classifier import (
    calibrate_isolation,
    conformal_declaration,  # noqa: E402
    set_score,
)
from marine_fdi_env.training.features import AgentFeatures, transform_episodes  # noqa: E402

NAMES = feature_names(False)
N_MOD = len(NAMES) // len(MODULE_FEATURES)


def _obs(signed: np.ndarray, mean_abs: np.ndarray, peak: np.ndarray) -> np.ndarray:
    """Observations (E, T, 115) from per-module period statistics of r / thr (E, T, 19): the
    observation's log-compressed features; the threshold-bound ones set as a noisier sensor would
    (violations, fired)."""
    E, T, _ = signed.shape
    o = np.zeros((E, T, len(NAMES)), np.float32)
    f = o[..., :-1].reshape(E, T, N_MOD, len(MODULE_FEATURES))
    f[..., 0] = np.log1p(peak)
    f[..., 1] = np.log1p(mean_abs)
    f[..., 2] = np.sign(signed) * np.log1p(np.abs(signed))
    f[..., 3] = peak > 1.0
    f[..., 4] = np.maximum.accumulate(peak > 1.0, axis=1)
    return o


def _noise(rng, E=4, T=60):
    n = rng.uniform(-1.0, 1.0, size=(E, T, N_MOD))
    return 0.05 * n, 0.3 + 0.02 * np.abs(n), 0.8 + 0.1 * np.abs(n)


def test_a_noise_dominated_residual_gives_the_same_inputs_at_any_noise_level():
    f = AgentFeatures(NAMES, noise_window=4, drop=(), previous_alarm=False)
    s, m, p = _noise(np.random.default_rng(0))
    base = transform_episodes(f, _obs(s, m, p))
    for c in (0.5, 1.3, 3.0):  # every residual statistic scales with the sensors' noise
        scaled = transform_episodes(f, _obs(c * s, c * m, c * p))
        np.testing.assert_allclose(scaled, base, atol=2e-5)  # float32 observations
    raw = AgentFeatures(NAMES, previous_alarm=False)  # the v1 inputs: they see the noise level
    assert (
        np.abs(transform_episodes(raw, _obs(3 * s, 3 * m, 3 * p)) - transform_episodes(raw, _obs(s, m, p))).max() > 0.5
    )
    assert len(f.input_names()) == f.size == 6 * N_MOD and f.input_names()[0] == "M1.1.signed_mean_over_noise"


def test_the_noise_level_is_learned_from_the_first_decisions_only():
    f = AgentFeatures(NAMES, noise_window=4, drop=(), previous_alarm=False, taus=())
    s, m, p = _noise(np.random.default_rng(1), E=1, T=20)
    s[:, 10:, 3] += 0.5  # a fault after the window: a bias on module 3
    m[:, 10:, 3] += 0.5
    state = f.initial_state(1)
    obs = _obs(s, m, p)
    for k in range(20):
        f.raw(obs[:, k], state)
        if k == 3:
            sigma = state["noise_sum"] / state["noise_n"][:, None]
    assert state["noise_n"][0] == 4
    np.testing.assert_array_equal(state["noise_sum"] / 4, sigma)  # frozen after the window
    np.testing.assert_allclose(sigma[0], m[0, :4].mean(axis=0), rtol=1e-5)
    f.restart(state, [0])
    assert state["noise_n"][0] == 0 and not state["noise_sum"].any()


def test_the_set_score_and_the_conformal_rule():
    p = np.full(26, 0.02)
    p[3] = 0.97
    one = np.zeros(26, bool)
    one[3] = True
    assert set_score(p, one) == pytest.approx(0.03)
    assert set_score(p, np.zeros(26, bool)) == 1.0
    np.testing.assert_array_equal(conformal_declaration(p, 0.5, 0.1), one)
    assert conformal_declaration(p, 0.5, 0.02) is None  # not sure enough: abstain
    q = p.copy()
    q[7] = 0.4  # a second fault is plausible: the best set {3} scores 0.4
    assert conformal_declaration(q, 0.5, 0.35) is None  # {3} is not in the prediction set: abstain
    # at quantile 0.7 the sets {3} and {3, 7} (score 0.6) are both in the prediction set: the most
    # probable one is declared, not an abstention
    np.testing.assert_array_equal(conformal_declaration(q, 0.5, 0.7), one)
    assert set_score(q, one | (np.arange(26) == 7)) == pytest.approx(0.6)
    assert conformal_declaration(np.full(26, 0.3), 0.5, 0.99) is None  # no fault at the threshold: unknown


def test_the_conformal_quantile_declares_on_the_asked_share_of_exchangeable_episodes():
    rng = np.random.default_rng(3)
    E, T = 400, 5
    active = np.zeros((E, T, 26), bool)
    active[np.arange(E), :, rng.integers(26, size=E)] = True
    probs = np.concatenate(
        [np.where(active, rng.uniform(0.3, 1.0, (E, T, 26)), rng.uniform(0, 0.6, (E, T, 26))), np.ones((E, T, 1))],
        axis=-1,
    )
    valid = np.ones((E, T), bool)
    cal = calibrate_isolation(probs[:200], active[:200], valid[:200], alpha=0.2)
    assert cal["episodes"] == 200 and cal["declared_in_calibration"] >= 0.8
    assert 0.0 < cal["quantile"] <= 0.5  # the most probable set never scores above 0.5
    declared = [conformal_declaration(p, 0.5, cal["quantile"]) is not None for p in probs[200:, -1, :26]]
    assert np.mean(declared) == pytest.approx(0.8, abs=0.08)  # exchangeable: 1 - alpha (binomial SD 0.028)
    with pytest.raises(ValueError, match="isolation_alpha"):
        calibrate_isolation(probs, active, valid, alpha=1.5)
