"""Action wrappers for ``MarineFDI-v0`` and ``MarineFDI-v1``."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from .actions import action_space, to_belief
from .hypotheses import HYPOTHESES, N_HYPOTHESES

__all__ = ["DiscreteHypothesis", "GatedAction"]


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


class GatedAction(gym.ActionWrapper):
    """``MultiDiscrete([2, 27, 27])``: an alarm switch, a fault and a second fault (0 = none, 1 + k =
    fault id k); the ``gated`` mode of :mod:`~marine_fdi_env.envs.actions`.

    Only the switch can cost a false alarm; the faults are free to explore while it is off, which is
    what lets a standard PPO learn here (``make_vec_env(ENV_ID, wrapper_class=GatedAction)``).
    """

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self.action_space = action_space("gated")

    def action(self, action) -> np.ndarray:
        a = np.asarray(action)
        if (
            a.shape != (3,)
            or not np.issubdtype(a.dtype, np.integer)
            or not self.action_space.contains(a.astype(np.int64))
        ):
            raise ValueError(f"action must be 3 integers (alarm 0/1, fault 0-26, second fault 0-26), got {action!r}")
        return to_belief(a[None], "gated")[0]
