"""The multi-agent track: the thesis's distributed scheme asked of learning (docs/multiagent.md).

Four local monitoring agents, one per subsystem, each observing only its own monitoring modules
(thesis table 6.2), send messages under a budget (:mod:`.budgets`) to a global agent that declares
the fault set, scored by the single-agent environment's metrics and ``MarineFDI-v1`` reward, on the
same simulator, scenarios, seeds and suites:

* :func:`parallel_env`: a PettingZoo ``ParallelEnv`` (one engine; the ``multiagent`` extra);
* :class:`~.batch.MultiAgentBatchEnv`: the same for N engines per call (training, scoring);
* :mod:`.team`: policies for the locals and the global as one benchmark agent (``evaluate``, ``sweep``)
  and on the batched environment (:mod:`.evaluate`: a suite scored through the multi-agent path).
"""

from __future__ import annotations

from .batch import MultiAgentBatchEnv
from .budgets import BUDGETS, MessageBudget, get_budget
from .roles import AGENT_IDS, GLOBAL_AGENT, LOCAL_AGENTS

__all__ = [
    "parallel_env",
    "MultiAgentBatchEnv",
    "MessageBudget",
    "BUDGETS",
    "get_budget",
    "AGENT_IDS",
    "LOCAL_AGENTS",
    "GLOBAL_AGENT",
]


def parallel_env(**kwargs):
    """The multi-agent track as a PettingZoo ``ParallelEnv`` (:class:`~.parallel.MarineFDIParallelEnv`);
    arguments of :class:`~.batch.MultiAgentBatchEnv` without ``num_envs``."""
    from ..errors import require_extra

    require_extra("pettingzoo", "the multi-agent ParallelEnv")
    from .parallel import MarineFDIParallelEnv

    return MarineFDIParallelEnv(**kwargs)
