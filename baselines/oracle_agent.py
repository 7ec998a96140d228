"""The oracle: reads the ground truth and declares exactly the faults active now.

It marks the ceiling of every metric (zero delay at the decision resolution, exact isolation,
no false alarms); an agent cannot do better, only as well.  It is not a diagnoser.
"""

from __future__ import annotations

import numpy as np

from marine_fdi_env.envs.hypotheses import N_HYPOTHESES, one_hot

__all__ = ["OracleAgent"]


class OracleAgent:
    name = "oracle"

    def reset(self, seeds: list[int]) -> None:
        self.n = len(seeds)

    def act(self, obs: np.ndarray, infos: dict) -> np.ndarray:
        out = np.zeros((len(obs), N_HYPOTHESES), dtype=np.float32)
        for i, active in enumerate(infos["active_faults"]):
            out[i] = one_hot(active) if active else one_hot(["no_fault"])
        return out
