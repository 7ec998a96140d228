"""A Stable-Baselines3 policy's deterministic actions for a batch of observations, bit for bit what
``policy.predict(obs, deterministic=True)`` returns, without its per-call work.

``predict`` switches the network to eval mode, checks and copies the observation, runs the network
under ``torch.no_grad`` and, for discrete actions, builds one ``torch.distributions.Categorical``
per action dimension (validating its arguments) only to take the argmax of its probabilities.
At a decision of a benchmark batch (32 engines, a 256 x 256 MLP) that work costs more than the
network itself.  :func:`deterministic_actions` runs the same tensor operations in the same order on
the same dtypes (the network, then per categorical dimension ``logits - logsumexp(logits)``, its
softmax and the argmax, as ``Categorical`` and SB3's ``mode`` compute them) under
``torch.inference_mode``; other action distributions take SB3's own ``get_actions``.
``tests/unit/test_sb3_inference.py`` checks the equality against ``predict``.

The caller puts the policy in eval mode once (:func:`prepare`); recurrent policies keep ``predict``.

:func:`load_policy` reads the policy of a ``model.zip`` without the algorithm object: SB3's
``PPO.load`` also builds the training state (a rollout buffer, an Adam optimizer whose first
construction imports ``torch._dynamo``) and reseeds the global random generators with the training
seed: loading every registered agent takes 0.8-0.9 s of CPU instead of 1.5-1.6 s
(``load_agents_cpu_s`` of ``benchmarks/lockstep_costs.py``).  The network and its weights are the same.
"""

from __future__ import annotations

import numpy as np
import torch
import torch.nn.functional as F
from gymnasium import spaces
from stable_baselines3.common.distributions import CategoricalDistribution, MultiCategoricalDistribution
from stable_baselines3.common.policies import BaseModel

__all__ = ["load_policy", "prepare", "deterministic_actions"]


class _NoOptimizer:
    """Stands in for the optimizer an SB3 policy builds: inference does not train."""

    def __init__(self, params, **kwargs) -> None:
        pass


def load_policy(path):
    """The policy of an SB3 on-policy model file, as ``PPO.load(path, device="cpu").policy`` (the same
    network and weights)."""
    from stable_baselines3.common.save_util import load_from_zip_file

    data, params, _ = load_from_zip_file(path, device="cpu")
    kwargs = {k: v for k, v in data.get("policy_kwargs", {}).items() if k != "device"}
    policy = data["policy_class"](
        data["observation_space"],
        data["action_space"],
        lambda _: 0.0,  # the learning rate: only the optimizer reads it
        use_sde=data.get("use_sde", False),
        **dict(kwargs, optimizer_class=_NoOptimizer),
    )
    policy.load_state_dict(params["policy"])
    return policy


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
