"""The null agent: never declares anything (the floor of every detection metric, and zero false alarms)."""

from __future__ import annotations

import numpy as np

from marine_fdi_env.envs.hypotheses import N_HYPOTHESES

__all__ = ["NullAgent"]


class NullAgent:
    name = "null"

    def reset(self, seeds: list[int]) -> None:
        self.n = len(seeds)

    def act(self, obs: np.ndarray, infos: dict) -> np.ndarray:
        return np.zeros((len(obs), N_HYPOTHESES), dtype=np.float32)
