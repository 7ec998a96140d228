"""Supervised start of the PPO policy: behaviour cloning of the ground truth, then a quiet alarm.

With ``pretrain`` in a ``ppo.yml`` entry, :func:`marine_fdi_env.training.rl.train_ppo_replay`
starts PPO from a policy network fitted to the training episodes' ground truth (never a suite,
never another agent's outputs):

1. per decision the ``gated`` action targets (:func:`gated_targets`): alarm = some fault active,
   first fault = the lowest active fault id, second = the next one (``1 + k`` for fault id k,
   0 = none);
2. :func:`fit_policy`: a few epochs of cross entropy of the three heads of the SB3 policy's
   action distribution (``-log_prob`` of the target triple) on the agent's own inputs
   (:class:`~marine_fdi_env.training.features.AgentFeatures`, the ones PPO sees).  The
   previous-alarm input is held at its standardisation mean (input 0) and its first-layer weights
   start at 0, so the fitted policy ignores its previous alarm (teacher-forcing it with the
   target alarm would teach "keep the alarm as it was", which the agent cannot rely on when its
   own alarm is wrong); PPO then learns what the input is worth;
3. :func:`quiet_alarm`: the alarm logit is shifted so that the largest alarm margin
   ``logit(on) - logit(off)`` over every decision before the first onset of the training
   episodes is ``-alarm_margin``: the deterministic policy raises no false alarm on them, and no
   alarm is held back beyond that (the zero-false-alarm calibration of the classifier,
   ``classifier.calibrate_threshold``);
4. PPO fine-tunes the whole policy on the reward (the value head starts untrained);
5. with ``final_alarm_margin`` (:func:`final_quiet_alarm`), step 3 once more after PPO, on the
   same decisions with the previous alarm off: PPO's exploration leaves the deterministic policy
   with a few alarms before an onset, and this moves them below the switch again.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "gated_targets",
    "policy_inputs",
    "fit_policy",
    "alarm_margins",
    "quiet_alarm",
    "before_onset",
    "pretrain_policy",
    "final_quiet_alarm",
]


def gated_targets(active: np.ndarray) -> np.ndarray:
    """Targets (E, T, 3) int64 of the ``gated`` action from the active faults (E, T, 26) bool:
    alarm (0/1), first fault and second fault (``1 + k`` for fault id k in ascending order, 0 = none)."""
    active = np.asarray(active, dtype=bool)
    n_active = active.sum(axis=-1)
    first = np.argmax(active, axis=-1)
    rest = active.copy()
    np.put_along_axis(rest, first[..., None], False, axis=-1)
    second = np.argmax(rest, axis=-1)
    out = np.zeros(active.shape[:-1] + (3,), np.int64)
    out[..., 0] = n_active > 0
    out[..., 1] = np.where(n_active > 0, first + 1, 0)
    out[..., 2] = np.where(n_active > 1, second + 1, 0)
    return out


def policy_inputs(features, obs: np.ndarray, previous_alarm: float | None = None) -> np.ndarray:
    """Standardised agent inputs (E, T, size) of whole episodes; the previous-alarm input (if any) is
    ``previous_alarm`` (0: a quiet agent), by default its standardisation mean (input 0: uninformative)."""
    from .features import transform_episodes

    x = transform_episodes(features, obs)
    if features.previous_alarm:
        x[..., -1] = features.mean[-1] if previous_alarm is None else previous_alarm
    return features.standardise(x)


def _alarm_input_weights(policy, features):
    """The first policy layer's weights of the previous-alarm input (a view), or None."""
    if not features.previous_alarm:
        return None
    return policy.mlp_extractor.policy_net[0].weight[:, features.size - 1]


def fit_policy(
    policy, x: np.ndarray, y: np.ndarray, epochs: int, batch_size: int, learning_rate: float, seed: int, log=None
) -> list[float]:
    """Cross entropy of the policy's action distribution on decisions ``x`` (N, size) with target
    actions ``y`` (N, 3), Adam, shuffled minibatches (seeded); returns the mean loss per epoch."""
    import torch

    params = list(policy.mlp_extractor.policy_net.parameters()) + list(policy.action_net.parameters())
    opt = torch.optim.Adam(params, lr=learning_rate)
    gen = torch.Generator().manual_seed(int(seed))
    xt, yt = torch.as_tensor(x), torch.as_tensor(y)
    losses = []
    for epoch in range(int(epochs)):
        order = torch.randperm(len(xt), generator=gen)
        total = 0.0
        for s in range(0, len(order), batch_size):
            idx = order[s : s + batch_size]
            loss = -policy.get_distribution(xt[idx]).log_prob(yt[idx]).mean()
            opt.zero_grad()
            loss.backward()
            opt.step()
            total += float(loss.detach()) * len(idx)
        losses.append(total / len(xt))
        if log:
            log(f"pretraining epoch {epoch + 1}: cross entropy {losses[-1]:.4f}")
    return losses


def alarm_margins(policy, x: np.ndarray, batch: int = 65536) -> np.ndarray:
    """``logit(alarm on) - logit(alarm off)`` of the policy at decisions ``x`` (N, size)."""
    import torch

    out = []
    with torch.no_grad():
        for s in range(0, len(x), batch):
            logits = policy.get_distribution(torch.as_tensor(x[s : s + batch])).distribution[0].logits
            out.append((logits[:, 1] - logits[:, 0]).numpy())
    return np.concatenate(out) if out else np.zeros(0, np.float32)


def quiet_alarm(policy, x_before_onset: np.ndarray, margin: float) -> dict:
    """Shift the alarm logit so that the largest alarm margin over ``x_before_onset`` is ``-margin``
    (log-odds): every one of those decisions keeps the deterministic alarm (the larger logit) off;
    ``alarm_logit_shift`` > 0 lowers the alarm, < 0 raises it."""
    import torch

    peak = float(alarm_margins(policy, x_before_onset).max())
    shift = peak + float(margin)
    with torch.no_grad():
        policy.action_net.bias[1] -= shift
    return {"peak_margin_before_onset": peak, "alarm_logit_shift": shift, "decisions_before_onset": len(x_before_onset)}


def before_onset(episodes: dict) -> np.ndarray:
    """(E, T) bool: the valid decisions before the episode's first onset (where an alarm is false)."""
    return episodes["valid"].astype(bool) & (episodes["t_s"] < episodes["first_onset"][:, None])


def final_quiet_alarm(policy, features, episodes: dict, margin: float) -> dict:
    """After PPO: :func:`quiet_alarm` on every decision before the first onset of ``episodes`` with
    the previous alarm off.  The deterministic policy then never raises the alarm before an onset
    of them: it starts quiet, and while quiet its alarm margin is below ``-margin``."""
    x = policy_inputs(features, episodes["obs"], previous_alarm=0.0)
    return quiet_alarm(policy, x[before_onset(episodes)], margin)


def pretrain_policy(policy, features, episodes: dict, spec: dict, seed: int, log=None) -> dict:
    """Steps 1-3 of the module docstring on training ``episodes`` (:func:`~.replay.load_episodes`)
    with ``spec`` = {epochs, batch_size, learning_rate, alarm_margin}; returns what it did."""
    allowed = {"epochs", "batch_size", "learning_rate", "alarm_margin"}
    unknown = set(spec) - allowed
    if unknown:
        raise ValueError(f"pretrain: unknown keys {sorted(unknown)}; allowed: {sorted(allowed)}")
    valid = episodes["valid"].astype(bool)
    x = policy_inputs(features, episodes["obs"])
    y = gated_targets(episodes["active"])
    w = _alarm_input_weights(policy, features)
    if w is not None:
        import torch

        with torch.no_grad():
            w.zero_()
    losses = fit_policy(
        policy,
        x[valid],
        y[valid],
        epochs=int(spec.get("epochs", 3)),
        batch_size=int(spec.get("batch_size", 1024)),
        learning_rate=float(spec.get("learning_rate", 1e-3)),
        seed=seed,
        log=log,
    )
    quiet = quiet_alarm(policy, x[before_onset(episodes)], float(spec.get("alarm_margin", 1.0)))
    if log:
        peak, shift = quiet["peak_margin_before_onset"], quiet["alarm_logit_shift"]
        log(f"alarm logit shifted by {-shift:.3f} (peak margin before onset {peak:.3f})")
    return {"cross_entropy": [round(v, 5) for v in losses], **quiet, "decisions": int(valid.sum())}
