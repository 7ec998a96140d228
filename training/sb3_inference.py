"""A Stable-Baselines3 policy's deterministic actions for a batch of observations, bit for bit what
``policy.predict(obs, deterministic=True)`` returns, without its per-call work.

``predict`` switches the network to eval mode, checks and copies the observation, runs the network
under ``torch.no_grad`` and, for discrete actions, builds one ``torch.distributions.Categorical``
per action dimension (validating its arguments) only to take the argmax of its probabilities.
At a decision of a benchmark batch (32 engines, a 256 x 256 MLP) that work costs about as much as
the network.  :func:`deterministic_actions` runs the same tensor operations in the same order on
the same dtypes (the network, then per categorical dimension ``logits - logsumexp(logits)``, its
softmax and the argmax, as ``Categorical`` and SB3's ``mode`` compute them) under
``torch.inference_mode``; other action distributions take SB3's own ``get_actions``.
``tests/unit/test_sb3_inference.py`` checks the equality against ``predict``.

The caller puts the policy in eval mode once (:func:`prepare`); recurrent policies keep ``predict``.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F
from gymnasium import spaces
from stable_baselines3.common.distributions import CategoricalDistribution, MultiCategoricalDistribution
from stable_baselines3.common.policies import BaseModel

__all__ = ["prepare", "deterministic_actions"]


def prepare(policy) -> None:
    """Eval mode, once (``predict`` sets it at every call)."""
    policy.set_training_mode(False)


def _categorical_mode(logits: torch.Tensor) -> torch.Tensor:
    """``Categorical(logits=logits).probs.argmax(1)`` with the distribution's own operations."""
    normalised = logits - logits.logsumexp(dim=-1, keepdim=True)
    return torch.argmax(F.softmax(normalised, dim=-1), dim=1)


def deterministic_actions(policy, obs: np.ndarray) -> np.ndarray:
    """Actions (N, *action shape) of an SB3 ``ActorCriticPolicy`` in eval mode for observations (N, *obs shape)."""
    x = np.array(obs).reshape((-1, *policy.observation_space.shape))  # as predict: a copy, the batch shape
    dist = policy.action_dist
    with torch.inference_mode():
        t = torch.as_tensor(x)
        if isinstance(dist, (CategoricalDistribution, MultiCategoricalDistribution)):
            features = BaseModel.extract_features(policy, t, policy.pi_features_extractor)  # as get_distribution
            latent = policy.mlp_extractor.forward_actor(features)
            logits = policy.action_net(latent)
            if isinstance(dist, CategoricalDistribution):
                a = _categorical_mode(logits)
            else:
                heads = torch.split(logits, list(dist.action_dims), dim=1)
                a = torch.stack([_categorical_mode(h) for h in heads], dim=1)
        else:
            a = policy.get_distribution(t).get_actions(deterministic=True)
        actions = a.numpy().reshape((-1, *policy.action_space.shape))
    if isinstance(policy.action_space, spaces.Box):
        if policy.squash_output:
            return policy.unscale_action(actions)
        return np.clip(actions, policy.action_space.low, policy.action_space.high)
    return actions
