"""The agent interface of the benchmark, and how ``marine-fdi evaluate --agent NAME|PATH`` finds one.

An agent diagnoses N episodes at once (the vector environment's batch)::

    class MyAgent:
        name = "mine"
        def reset(self, seeds: list[int]) -> None: ...            # new episodes, one seed each
        def act(self, obs: np.ndarray, infos: dict) -> np.ndarray: # (N, D) -> beliefs (N, 28)

``obs`` is the vector environment's observation batch and ``infos`` its info dict (one array per
key, Gymnasium's vector convention: ``infos["reference"]["diagnoses"][i]`` ...).  Agents that
read ground truth (``true_faults``, ``active_faults``) are oracles and say so in their name.

NAME is one of :data:`BUILTIN_AGENTS` (``null``, ``random``, ``reference``, ``sequential``,
``oracle``, from ``baselines/``).  An agent may name environment options it needs in an
``env_kwargs`` attribute (``sequential``: ``{"observe_sequential": True}``); ``evaluate`` adds them
to the suite's.  PATH is a directory holding ``agent.json``::

    {"class": "package.module:ClassName", "kwargs": {...}}

whose class has ``from_dir(path, **kwargs)`` returning the agent (trained models ship this way).
"""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Protocol

import numpy as np
from .jsonfile import read_json

__all__ = ["Agent", "BUILTIN_AGENTS", "load_agent"]


class Agent(Protocol):
    name: str

    def reset(self, seeds: list[int]) -> None: ...

    def act(self, obs: np.ndarray, infos: dict) -> np.ndarray: ...


BUILTIN_AGENTS = {
    "null": "baselines.null_agent:NullAgent",
    "random": "baselines.random_agent:RandomAgent",
    "reference": "baselines.reference_agent:ReferenceAgent",
    "sequential": "baselines.sequential_agent:SequentialAgent",
    "oracle": "baselines.oracle_agent:OracleAgent",
}


def _import(target: str, where: str):
    mod_name, _, attr = target.partition(":")
    if not mod_name or not attr:
        raise ValueError(f"{where}: 'class' must look like 'package.module:ClassName', got {target!r}")
    try:
        mod = importlib.import_module(mod_name)
    except ImportError as e:
        raise ValueError(f"{where}: cannot import {mod_name!r} ({e})") from None
    try:
        return getattr(mod, attr)
    except AttributeError:
        raise ValueError(f"{where}: module {mod_name!r} has no {attr!r}") from None


def load_agent(spec: str) -> Agent:
    """A built-in agent by name, or the agent stored in a directory (see module docstring)."""
    if spec in BUILTIN_AGENTS:
        return _import(BUILTIN_AGENTS[spec], f"built-in agent {spec!r}")()
    path = Path(spec)
    if not path.exists():
        raise ValueError(f"unknown agent {spec!r}: not a built-in ({', '.join(BUILTIN_AGENTS)}) and no such path")
    meta_file = path / "agent.json" if path.is_dir() else path
    if not meta_file.is_file():
        raise ValueError(f"agent directory {path} has no agent.json")
    meta = read_json(meta_file, "agent description")
    if not isinstance(meta, dict) or "class" not in meta:
        raise ValueError(f"{meta_file}: must be a JSON object with a 'class' entry")
    cls = _import(meta["class"], str(meta_file))
    if not hasattr(cls, "from_dir"):
        raise ValueError(f"{meta_file}: {meta['class']} has no from_dir(path) constructor")
    kwargs = meta.get("kwargs", {})
    if not isinstance(kwargs, dict):
        raise ValueError(f"{meta_file}: 'kwargs' must be an object")
    return cls.from_dir(meta_file.parent, **kwargs)
