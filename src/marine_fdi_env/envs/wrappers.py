"""Wrappers for ``MarineFDI-v0``."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from .hypotheses import HYPOTHESES, N_HYPOTHESES

__all__ = ["DiscreteHypothesis"]


class DiscreteHypothesis(gym.ActionWrapper):
    """Declare one hypothesis at a time: ``Discrete(28)`` over :data:`HYPOTHESES`.

    Action k puts belief 1 on hypothesis k (a fault id, ``no_fault`` = 26 or ``unknown`` = 27)
    and 0 elsewhere; ``no_fault`` is "nothing is wrong" (no alarm).  Multiple-fault diagnoses
    cannot be expressed: use the default Box action for those.
    """

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self.action_space = spaces.Discrete(N_HYPOTHESES)
        self.hypotheses = HYPOTHESES

    def action(self, action) -> np.ndarray:
        a = np.asarray(action)
        if a.shape not in ((), (1,)) or not np.issubdtype(a.dtype, np.integer):
            raise ValueError(f"action must be one integer in [0, {N_HYPOTHESES}), got {action!r}")
        k = int(a.reshape(()))
        if not 0 <= k < N_HYPOTHESES:
            raise ValueError(f"action must be an integer in [0, {N_HYPOTHESES}), got {k}")
        b = np.zeros(N_HYPOTHESES, dtype=np.float32)
        b[k] = 1.0
        return b
