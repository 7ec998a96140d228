"""studies/agents/isolation_diagnosis.py: the outcome of a final declaration, and the declaration read at
each episode's last valid decision."""

import numpy as np

from marine_fdi_env.envs.hypotheses import N_HYPOTHESES, UNKNOWN
from studies.agents.isolation_diagnosis import last_declarations, outcome


def _set(*ids) -> np.ndarray:
    s = np.zeros(26, dtype=bool)
    s[list(ids)] = True
    return s


def test_outcomes_of_a_final_declaration():
    pair = _set(3, 7)
    assert outcome(False, _set(3, 7), pair) == "no alarm"
    assert outcome(True, _set(), pair) == "unknown"
    assert outcome(True, _set(7, 3), pair) == "exact set"
    assert outcome(True, _set(7), pair) == "one of the two"
    assert outcome(True, _set(7, 9), pair) == "other"
    assert outcome(True, _set(9), _set(9)) == "exact set"
    assert outcome(True, _set(9, 3), _set(9)) == "other"


class _Clock:
    """Declares fault t at decision t from decision 2 on (``unknown`` at decision 1, quiet at 0)."""

    def reset(self, seeds):
        self.t = 0

    def act(self, obs, infos):
        b = np.zeros((len(obs), N_HYPOTHESES), dtype=np.float32)
        if self.t == 1:
            b[:, UNKNOWN] = 1.0
        elif self.t >= 2:
            b[:, self.t] = 1.0
        self.t += 1
        return b


def test_the_declaration_is_read_at_each_episodes_last_valid_decision():
    valid = np.zeros((4, 6), dtype=bool)
    for i, n in enumerate((1, 2, 4, 6)):
        valid[i, :n] = True
    alarm, faults = last_declarations(_Clock(), np.zeros((4, 6, 3), dtype=np.float32), valid)
    assert alarm.tolist() == [False, True, True, True]
    assert faults.sum(axis=1).tolist() == [0, 0, 1, 1]  # quiet, unknown, fault 3, fault 5
    assert faults[2, 3] and faults[3, 5]
