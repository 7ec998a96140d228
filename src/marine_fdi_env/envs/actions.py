"""Action modes for learners: the SB3-friendly action spaces of ``MarineFDI-v0/v1`` and their beliefs.

``box``: ``Box(-1, 1, (28,))`` rescaled to beliefs ``(a + 1) / 2`` (Gaussian policies prefer a
symmetric box); ``discrete``: ``Discrete(28)``, action k declares hypothesis k alone (k = 26 is
``no_fault``, the quiet action); ``pair``: ``MultiDiscrete([28, 27])``, a hypothesis plus an
optional second fault (0 = none, 1 + k = fault id k); ``gated``: ``MultiDiscrete([2, 27, 27])``, an
alarm switch (0: quiet, whatever follows), a fault and a second fault (0 = none, 1 + k = fault id
k); with the alarm on and no fault named the declaration is ``unknown``.  ``gated`` separates the
decision that costs a false alarm (the switch) from the choice of faults, which is free while the
switch is off: the mode a standard PPO learns with here (docs/learned_agents.md).
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from ..engine.faults import FAULT_IDS
from .hypotheses import N_HYPOTHESES

__all__ = ["ACTION_MODES", "action_space", "to_belief"]

ACTION_MODES = ("box", "discrete", "pair", "gated")


def action_space(action_mode: str) -> spaces.Space:
    """The SB3 action space of an action mode (module docstring)."""
    if action_mode == "box":
        return spaces.Box(-1.0, 1.0, (N_HYPOTHESES,), dtype=np.float32)
    if action_mode == "discrete":
        return spaces.Discrete(N_HYPOTHESES)
    if action_mode == "pair":
        return spaces.MultiDiscrete([N_HYPOTHESES, len(FAULT_IDS) + 1])
    if action_mode == "gated":
        return spaces.MultiDiscrete([2, len(FAULT_IDS) + 1, len(FAULT_IDS) + 1])
    raise ValueError(f"action_mode must be one of {ACTION_MODES}, got {action_mode!r}")


def to_belief(actions: np.ndarray, action_mode: str) -> np.ndarray:
    """SB3 actions (N, 28) in [-1, 1], (N,) ints, (N, 2) pairs or (N, 3) gated triples -> beliefs (N, 28)."""
    if action_mode == "box":
        a = np.asarray(actions, dtype=np.float32).reshape(-1, N_HYPOTHESES)
        return np.clip((a + 1.0) * 0.5, 0.0, 1.0).astype(np.float32)
    if action_mode == "discrete":
        k = np.asarray(actions, dtype=np.int64).reshape(-1)
        out = np.zeros((len(k), N_HYPOTHESES), dtype=np.float32)
        out[np.arange(len(k)), k] = 1.0
        return out
    if action_mode == "pair":
        a = np.asarray(actions, dtype=np.int64).reshape(-1, 2)
        out = np.zeros((len(a), N_HYPOTHESES), dtype=np.float32)
        out[np.arange(len(a)), a[:, 0]] = 1.0
        second = np.flatnonzero(a[:, 1] > 0)
        out[second, a[second, 1] - 1] = 1.0
        return out
    if action_mode == "gated":
        a = np.asarray(actions, dtype=np.int64).reshape(-1, 3)
        out = np.zeros((len(a), N_HYPOTHESES), dtype=np.float32)
        on = a[:, 0] == 1
        out[~on, len(FAULT_IDS)] = 1.0  # no_fault
        for col in (1, 2):
            named = np.flatnonzero(on & (a[:, col] > 0))
            out[named, a[named, col] - 1] = 1.0
        blank = np.flatnonzero(on & (a[:, 1] == 0) & (a[:, 2] == 0))
        out[blank, N_HYPOTHESES - 1] = 1.0  # unknown
        return out
    raise ValueError(f"action_mode must be one of {ACTION_MODES}, got {action_mode!r}")
