"""Gymnasium environment ``MarineFDI-v0`` for fault detection and isolation.

Importing :mod:`marine_fdi_env` registers it::

    env = gymnasium.make("marine_fdi_env:MarineFDI-v0")
    envs = gymnasium.make_vec("marine_fdi_env:MarineFDI-v0", num_envs=64, vectorization_mode="vector_entry_point")
"""

from __future__ import annotations

ENV_ID = "MarineFDI-v0"


def register_envs() -> None:
    """Register ``MarineFDI-v0`` (single and vector entry points) with Gymnasium, once."""
    import gymnasium

    if ENV_ID in gymnasium.registry:
        return
    gymnasium.register(
        id=ENV_ID,
        entry_point="marine_fdi_env.envs.fdi_env:MarineFDIEnv",
        vector_entry_point="marine_fdi_env.envs.vector:MarineFDIVectorEnv",
        disable_env_checker=False,
    )
