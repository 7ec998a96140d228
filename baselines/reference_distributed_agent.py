"""The thesis's distributed scheme as an agent: local decision vectors -> global decision matrix.

The thesis (sections 5.3-5.4, eq. 5.19-5.22) distributes diagnosis over four local monitoring
agents and a global one.  Local agent l latches each of its modules' ARR violations into its
decision vector D^(l) (eq. 5.19) and sends it on; the global agent combines the four vectors with
the fault signature tables of the agents (tables 6.5-6.8) and the global decision matrix F^chi
(table 6.9) into the multiple-fault diagnoses consistent with both (eq. 5.20-5.22;
:func:`marine_fdi_env.diagnosis.decision.thesis_global_diagnosis`).

As a team of the multi-agent track (:mod:`marine_fdi_env.multiagent`), at the ``decision`` budget:

* local l (:class:`DecisionVectorLocal`): its message is D^(l), the ``fired`` feature of each of
  its modules (1 from the module's first violation on: the latched decision of eq. 5.19);
* global (:class:`ThesisGlobal`): the minimal diagnoses of the thesis's logic on D = [D^(1) ...
  D^(4)] (up to ``max_cardinality`` = 2 faults, as ``reference``), turned into a declaration by the
  ``reference`` agent's rule (:func:`~marine_fdi_env.baselines.reference_agent.belief_from_diagnoses`:
  the faults in more than half of the smallest diagnoses; ``unknown`` when detected and none is).

``reference-distributed`` is that team as a benchmark agent of the single-agent environment
(``marine-fdi evaluate --agent reference-distributed``); in the multi-agent environments the same
policies declare the same at every decision (tested).  Unlike ``reference``, it uses no detection
times, no running peaks and no measured sure cells: only which modules have fired, and the thesis's
tables.
"""

from __future__ import annotations

import numpy as np

from marine_fdi_env.diagnosis.decision import thesis_global_diagnosis
from marine_fdi_env.envs.observation import MODULE_FEATURES
from marine_fdi_env.multiagent.budgets import BUDGETS
from marine_fdi_env.multiagent.roles import LOCAL_AGENTS, local_modules
from marine_fdi_env.multiagent.team import Team, TeamAgent

from .reference_agent import belief_from_diagnoses

__all__ = ["DecisionVectorLocal", "ThesisGlobal", "reference_distributed_team", "ReferenceDistributedAgent"]

_FIRED = MODULE_FEATURES.index("fired")


class DecisionVectorLocal:
    """Local agent l: its decision vector D^(l) (one bit per module, eq. 5.19) from its observation."""

    def __init__(self, agent: str) -> None:
        n = len(local_modules(agent))
        self.columns = np.arange(n) * len(MODULE_FEATURES) + _FIRED

    def reset(self, seeds: list[int]) -> None:
        """No state: the ``fired`` feature is already latched."""

    def message(self, obs: np.ndarray) -> np.ndarray:
        return (np.asarray(obs)[:, self.columns] >= 0.5).astype(np.float32)


class ThesisGlobal:
    """The global agent: the thesis's logic on the decision vectors (eq. 5.20-5.22), declared by the
    ``reference`` agent's rule; each distinct decision vector is diagnosed once (memoised)."""

    def __init__(self, max_cardinality: int = 2) -> None:
        self.max_cardinality = int(max_cardinality)
        self._memo: dict[bytes, np.ndarray] = {}

    def reset(self, seeds: list[int]) -> None:
        """No state: the declaration is a function of the decision vectors."""

    def belief(self, bits: np.ndarray) -> np.ndarray:
        """The belief (28,) of one decision vector (19,) of 0/1."""
        key = np.packbits(bits.astype(bool)).tobytes()
        b = self._memo.get(key)
        if b is None:
            fired = bits.astype(bool)
            if not fired.any():
                b = belief_from_diagnoses(False, [])
            else:
                r = thesis_global_diagnosis(fired, max_cardinality=self.max_cardinality)
                b = belief_from_diagnoses(True, [sorted(d) for d in r.minimal])
            self._memo[key] = b
        return b

    def declare(self, messages: np.ndarray) -> np.ndarray:
        return np.stack([self.belief(row) for row in np.asarray(messages)])


def reference_distributed_team(max_cardinality: int = 2) -> Team:
    """The thesis's distributed scheme as a team at the ``decision`` budget (module docstring)."""
    return Team(
        "reference-distributed",
        BUDGETS["decision"],
        {a: DecisionVectorLocal(a) for a in LOCAL_AGENTS},
        ThesisGlobal(max_cardinality),
    )


class ReferenceDistributedAgent(TeamAgent):
    """``reference-distributed``: :func:`reference_distributed_team` as a benchmark agent."""

    def __init__(self) -> None:
        super().__init__(reference_distributed_team())
