"""The agents of the multi-agent track and what each observes (thesis section 5.1, table 6.2).

Four local monitoring agents, one per subsystem (``local_1`` Σ1 fuel pump, ``local_2`` Σ2 engine
block, ``local_3`` Σ3 exhaust receiver and turbocharger, ``local_4`` Σ4 air intake), each with the
monitoring modules M(l, q) of its subsystem (:data:`marine_fdi_env.diagnosis.modules.AGENTS`), and
the ``global`` agent that combines their messages.  A local observes the observation features of its
own modules only (:mod:`marine_fdi_env.envs.observation`: six per module) and the episode clock;
each module's residual already reads the module's sensor set and the interconnection sensors of
table 6.2, so these are the features the thesis's local agent computes.  With ``observe_sensors``
a local also sees the period means of the sensors its modules read (their sets and interconnection
sensors, :attr:`~marine_fdi_env.diagnosis.modules.ModuleSpec.all_sensors`) and the fuel setting.
"""

from __future__ import annotations

import numpy as np

from ..diagnosis.modules import AGENTS, MODULES
from ..engine.sensors import SENSOR_IDS
from ..envs.observation import MODULE_FEATURES

__all__ = [
    "LOCAL_AGENTS",
    "GLOBAL_AGENT",
    "AGENT_IDS",
    "subsystem_of",
    "local_modules",
    "local_sensors",
    "local_feature_names",
    "local_columns",
]

LOCAL_AGENTS: tuple[str, ...] = tuple(f"local_{a}" for a in sorted(AGENTS))
GLOBAL_AGENT = "global"
AGENT_IDS: tuple[str, ...] = LOCAL_AGENTS + (GLOBAL_AGENT,)


def subsystem_of(agent: str) -> int:
    """The subsystem l of ``local_l``; ``ValueError`` naming the local agents otherwise."""
    if agent not in LOCAL_AGENTS:
        raise ValueError(f"agent must be one of {', '.join(LOCAL_AGENTS)}, got {agent!r}")
    return int(agent.rpartition("_")[2])


def local_modules(agent: str) -> tuple[str, ...]:
    """The monitoring modules of a local agent, in ``MODULE_IDS`` order (table 6.2)."""
    return AGENTS[subsystem_of(agent)]


def local_sensors(agent: str) -> tuple[str, ...]:
    """The sensors a local agent's modules read (own sets and interconnection sensors), in ``SENSOR_IDS`` order."""
    mods = set(local_modules(agent))
    used = {s for m in MODULES if m.id in mods for s in m.all_sensors}
    return tuple(s for s in SENSOR_IDS if s in used)


def local_feature_names(agent: str, observe_sensors: bool = False) -> list[str]:
    """The observation features a local agent sees, in the environment's naming and order."""
    names = [f"{m}.{f}" for m in local_modules(agent) for f in MODULE_FEATURES] + ["time_fraction"]
    if observe_sensors:
        names += [f"{s}.relative_deviation" for s in local_sensors(agent)] + ["u.mean"]
    return names


def local_columns(agent: str, feature_names, observe_sensors: bool = False) -> np.ndarray:
    """The columns of the single-agent observation (``feature_names``) that a local agent sees."""
    pos = {n: j for j, n in enumerate(feature_names)}
    want = local_feature_names(agent, observe_sensors)
    missing = [n for n in want if n not in pos]
    if missing:
        raise ValueError(f"the observation has no feature {missing[0]!r} that {agent} needs")
    return np.array([pos[n] for n in want], dtype=np.int64)
