"""Gymnasium environments ``MarineFDI-v0`` and ``MarineFDI-v1`` for fault detection and isolation.

``MarineFDI-v1`` is ``MarineFDI-v0`` with the reward derived from the metrics
(:class:`~marine_fdi_env.envs.reward.RewardConfigV1`); observations, scenarios and infos are the
same.  Importing :mod:`marine_fdi_env` registers both::

    env = gymnasium.make("marine_fdi_env:MarineFDI-v0")
    envs = gymnasium.make_vec("marine_fdi_env:MarineFDI-v0", num_envs=64, vectorization_mode="vector_entry_point")
"""

from __future__ import annotations

ENV_ID = "MarineFDI-v0"
ENV_ID_V1 = "MarineFDI-v1"


def register_envs() -> None:
    """Register ``MarineFDI-v0`` and ``MarineFDI-v1`` (single and vector entry points) with Gymnasium, once."""
    import gymnasium

    for env_id, kwargs in ((ENV_ID, {}), (ENV_ID_V1, {"reward": "v1"})):
        if env_id in gymnasium.registry:
            continue
        gymnasium.register(
            id=env_id,
            entry_point="marine_fdi_env.envs.fdi_env:MarineFDIEnv",
            vector_entry_point="marine_fdi_env.envs.vector:MarineFDIVectorEnv",
            disable_env_checker=False,
            kwargs=kwargs,
        )
