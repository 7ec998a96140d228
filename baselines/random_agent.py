"""The random agent: a declaration that changes at random, independent of the observations.

Each decision, with probability ``switch_prob`` (default 1/60: about once a minute), it drops its
declaration and declares one hypothesis drawn uniformly from the 28 (a fault id, ``no_fault``
or ``unknown``).  It starts declaring nothing.  Seeded per episode, so results reproduce.
"""

from __future__ import annotations

import numpy as np

from marine_fdi_env.envs.hypotheses import N_HYPOTHESES

__all__ = ["RandomAgent"]


class RandomAgent:
    name = "random"

    def __init__(self, switch_prob: float = 1.0 / 60.0) -> None:
        if not 0.0 <= switch_prob <= 1.0:
            raise ValueError(f"switch_prob must lie in [0, 1], got {switch_prob!r}")
        self.switch_prob = switch_prob

    def reset(self, seeds: list[int]) -> None:
        self.rngs = [np.random.default_rng(s) for s in seeds]
        self.belief = np.zeros((len(seeds), N_HYPOTHESES), dtype=np.float32)

    def act(self, obs: np.ndarray, infos: dict) -> np.ndarray:
        for i, rng in enumerate(self.rngs):
            if rng.random() < self.switch_prob:
                self.belief[i] = 0.0
                self.belief[i, rng.integers(N_HYPOTHESES)] = 1.0
        return self.belief.copy()
