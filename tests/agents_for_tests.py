"""Agents used by the tests (loaded as ``tests/agents_for_tests.py:ClassName``)."""

import os
import time

import numpy as np

from marine_fdi_env.envs.hypotheses import N_HYPOTHESES


class SlowRandomAgent:
    """The random agent's declarations, sleeping ``$SLOW_AGENT_SLEEP_S`` seconds per decision (so a
    test can interrupt a run in the middle); results do not depend on the sleep."""

    name = "slow-random"

    def reset(self, seeds):
        self.rngs = [np.random.default_rng(s) for s in seeds]
        self.belief = np.zeros((len(seeds), N_HYPOTHESES), dtype=np.float32)

    def act(self, obs, infos):
        time.sleep(float(os.environ.get("SLOW_AGENT_SLEEP_S", "0")))
        for i, rng in enumerate(self.rngs):
            if rng.random() < 0.05:
                self.belief[i] = 0.0
                self.belief[i, rng.integers(N_HYPOTHESES)] = 1.0
        return self.belief.copy()
