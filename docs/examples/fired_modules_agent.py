"""A minimal custom agent for ``marine-fdi evaluate --agent docs/examples/fired_modules_agent.py:FiredModulesAgent``.

It raises the alarm (belief 1 on ``unknown``: "a fault, I cannot say which") once at least
``min_modules`` of the 19 monitoring modules have fired in the episode, and never names a fault.
See docs/agent_api.md.
"""

import numpy as np

from marine_fdi_env.envs.hypotheses import N_HYPOTHESES, UNKNOWN
from marine_fdi_env.envs.observation import feature_names

FIRED = [i for i, name in enumerate(feature_names(False)) if name.endswith(".fired")]  # 19 columns of obs


class FiredModulesAgent:
    name = "fired-modules"  # the agent's name in results and reports

    def __init__(self, min_modules: int = 2):
        self.min_modules = min_modules

    def reset(self, seeds: list[int]) -> None:
        """New episodes, one seed each (this agent draws no random numbers)."""

    def act(self, obs: np.ndarray, infos: dict) -> np.ndarray:
        """(N, 115) observations -> (N, 28) beliefs over the 26 faults, no_fault, unknown."""
        fired = obs[:, FIRED].sum(axis=1)
        beliefs = np.zeros((len(obs), N_HYPOTHESES), dtype=np.float32)
        beliefs[fired >= self.min_modules, UNKNOWN] = 1.0
        return beliefs
