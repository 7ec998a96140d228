"""The PPO policy's supervised start (training/pretrain.py): targets from the ground truth, a
fit that lowers the cross entropy, and an alarm that stays off before every onset."""

from __future__ import annotations

import numpy as np
import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("stable_baselines3")

from marine_fdi_env.training.pretrain import (  # noqa: E402
    alarm_margins,
    fit_policy,
    gated_targets,
    quiet_alarm,
)
from marine_fdi_env.training.vec_adapter import to_belief  # noqa: E402


def _policy(n_inputs: int, seed: int = 0):
    from gymnasium import spaces
    from stable_baselines3.common.policies import ActorCriticPolicy

    from marine_fdi_env.envs.actions import action_space

    torch.manual_seed(seed)
    obs = spaces.Box(-np.inf, np.inf, (n_inputs,), np.float32)
    return ActorCriticPolicy(obs, action_space("gated"), lambda _: 1e-3, net_arch=dict(pi=[32], vf=[8]))


def test_targets_are_the_alarm_and_the_active_faults_in_ascending_order():
    active = np.zeros((1, 4, 26), dtype=bool)
    active[0, 1, 7] = True
    active[0, 2, [3, 20]] = True
    active[0, 3, [25, 0]] = True
    y = gated_targets(active)
    assert y[0].tolist() == [[0, 0, 0], [1, 8, 0], [1, 4, 21], [1, 1, 26]]
    # the target action declares exactly the active set (the environment's own decoding)
    beliefs = to_belief(y[0], "gated")
    np.testing.assert_array_equal(beliefs[:, :26] >= 0.5, active[0])


def test_fit_learns_a_separable_rule_and_is_seeded():
    rng = np.random.default_rng(0)
    x = rng.normal(size=(2000, 4)).astype(np.float32)
    fault = np.where(x[:, 0] > 0.5, 1 + (x[:, 1] > 0).astype(np.int64), 0)  # fault id 0 or 1 when x0 > 0.5
    y = np.stack([(fault > 0).astype(np.int64), fault, np.zeros_like(fault)], axis=1)
    runs = []
    for _ in range(2):
        policy = _policy(4)
        losses = fit_policy(policy, x, y, epochs=8, batch_size=128, learning_rate=3e-3, seed=5)
        runs.append((losses, [p.detach().clone() for p in policy.parameters()]))
    losses = runs[0][0]
    assert losses[-1] < 0.3 * losses[0]  # from ~ln 2 + 2 ln 27 = 7.3 nats at the start
    assert runs[0][0] == runs[1][0] and all(torch.equal(a, b) for a, b in zip(runs[0][1], runs[1][1]))
    with torch.no_grad():
        act, _, _ = policy(torch.as_tensor(x), deterministic=True)
    assert np.mean(act.numpy()[:, 1] == fault) > 0.95


def test_quiet_alarm_keeps_the_deterministic_alarm_off_with_the_margin():
    policy = _policy(3, seed=1)
    rng = np.random.default_rng(1)
    with torch.no_grad():
        policy.action_net.bias[1] += 5.0  # an alarm-happy start
    before = rng.normal(size=(500, 3)).astype(np.float32)
    assert (alarm_margins(policy, before) > 0).any()
    info = quiet_alarm(policy, before, margin=0.5)
    m = alarm_margins(policy, before)
    assert m.max() == pytest.approx(-0.5, abs=1e-5)  # the peak sits exactly margin below the switch
    assert info["alarm_logit_shift"] == pytest.approx(info["peak_margin_before_onset"] + 0.5)
    with torch.no_grad():
        act, _, _ = policy(torch.as_tensor(before), deterministic=True)
    assert not act.numpy()[:, 0].any()
