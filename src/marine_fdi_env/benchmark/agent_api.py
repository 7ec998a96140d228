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
``oracle``, from ``baselines/``) or a shipped model (``classifier``, ``ppo-v1``, ...: every folder of
``training/models/``, see :mod:`.agent_registry` and ``marine-fdi agents``).  An agent may name
environment options it needs in an ``env_kwargs`` attribute (``sequential``:
``{"observe_sequential": True}``); ``evaluate`` adds them to the suite's.  PATH is a directory
holding ``agent.json``::

    {"class": "package.module:ClassName", "kwargs": {...}}

whose class has ``from_dir(path, **kwargs)`` returning the agent (trained models ship this way),
or ``path/to/file.py:ClassName``: a class in a Python file, constructed without arguments (a
custom agent needs nothing else; see docs/agent_api.md).
"""

from __future__ import annotations

import importlib
import importlib.util
from pathlib import Path
from typing import Protocol

import numpy as np

from ..errors import MissingExtra
from ..jsonfile import read_json
from .agent_registry import BUILTIN_AGENTS, LEGACY_PACKAGES  # the names live in the registry

__all__ = [
    "Agent",
    "BUILTIN_AGENTS",
    "load_agent",
    "resolve_agent_spec",
    "agent_file_stem",
    "split_file_spec",
    "user_agent_files",
    "zoo_run_model",
]

ZOO_AGENT = "marine_fdi_env.training.zoo:ZooAgent"  # loads an RL Zoo run folder (needs the train extra)

_USER_FILES: set[str] = set()  # the agent files (path/to/file.py:Class) this process loaded, resolved


class Agent(Protocol):
    name: str

    def reset(self, seeds: list[int]) -> None: ...

    def act(self, obs: np.ndarray, infos: dict) -> np.ndarray: ...


def _import(target: str, where: str):
    mod_name, _, attr = target.partition(":")
    if not mod_name or not attr:
        raise ValueError(f"{where}: 'class' must look like 'package.module:ClassName', got {target!r}")
    try:
        mod = importlib.import_module(mod_name)
    except ImportError as e:
        hint = ""
        if mod_name.split(".")[0] in LEGACY_PACKAGES:  # a top-level baselines/training name: say the namespaced one
            top = mod_name.split(".")[0]
            hint = (
                f"; this project's {top!r} package is installed as 'marine_fdi_env.{top}': "
                f"write 'marine_fdi_env.{target}' in the agent.json"
            )
        raise ValueError(f"{where}: cannot import {mod_name!r} ({e}){hint}") from None
    try:
        return getattr(mod, attr)
    except AttributeError:
        raise ValueError(f"{where}: module {mod_name!r} has no {attr!r}") from None


def split_file_spec(spec: str) -> tuple[Path, str] | None:
    """``path/to/file.py:ClassName`` -> (path, ClassName); None for other specs."""
    head, sep, cls = str(spec).rpartition(":")
    if sep and head.endswith(".py") and cls.isidentifier():
        return Path(head), cls
    return None


def user_agent_files() -> frozenset[str]:
    """The resolved paths of the agent files (``path/to/file.py:Class``) loaded in this process: where
    the command line looks for the line of a user's agent that raised (:mod:`marine_fdi_env.cli.failures`)."""
    return frozenset(_USER_FILES)


def _at_line(exc: BaseException, path: Path) -> str:
    """`` at FILE:LINE``: the innermost line of ``path`` in the exception's traceback, or ""."""
    import traceback

    where = str(path.resolve())
    lines = [fs.lineno for fs in traceback.extract_tb(exc.__traceback__) if str(Path(fs.filename).resolve()) == where]
    return f" at {path}:{lines[-1]}" if lines else ""


def _load_file_agent(path: Path, cls_name: str, spec: str) -> Agent:
    import hashlib
    import importlib.util
    import sys

    if not path.is_file():
        raise ValueError(f"agent {spec!r}: no such file {str(path)!r}")
    _USER_FILES.add(str(path.resolve()))
    mod_name = "_marine_fdi_agent_" + hashlib.sha1(str(path.resolve()).encode()).hexdigest()[:12]
    mod = sys.modules.get(mod_name)
    if mod is None:
        ms = importlib.util.spec_from_file_location(mod_name, path)
        mod = importlib.util.module_from_spec(ms)
        sys.modules[mod_name] = mod  # dataclasses and pickling look the module up by name
        try:
            ms.loader.exec_module(mod)
        except Exception as e:  # noqa: BLE001 - any error in a user's file is a bad agent spec
            del sys.modules[mod_name]
            raise ValueError(
                f"agent {spec!r}: {path} failed to import ({type(e).__name__}: {e}{_at_line(e, path)})"
            ) from None
    cls = getattr(mod, cls_name, None)
    if cls is None:
        raise ValueError(f"agent {spec!r}: {path} has no {cls_name!r}")
    try:
        agent = cls()
    except Exception as e:  # noqa: BLE001
        raise ValueError(
            f"agent {spec!r}: {cls_name}() failed ({type(e).__name__}: {e}{_at_line(e, path)}); a custom agent "
            "class must be constructible without arguments"
        ) from None
    for attr in ("reset", "act"):
        if not callable(getattr(agent, attr, None)):
            raise ValueError(f"agent {spec!r}: {cls_name} has no {attr}() method (see docs/agent_api.md)")
    if not isinstance(getattr(agent, "name", None), str) or not agent.name:
        raise ValueError(f"agent {spec!r}: {cls_name} needs a non-empty string attribute 'name'")
    return agent


def resolve_agent_spec(spec: str) -> str:
    """``spec`` with file and folder paths made absolute (names unchanged), for other processes."""
    spec = str(spec)
    if spec in BUILTIN_AGENTS:
        return spec
    fs = split_file_spec(spec)
    if fs is not None:
        return f"{fs[0].resolve()}:{fs[1]}"
    p = Path(spec)
    return str(p.resolve()) if p.exists() else spec


def agent_file_stem(spec: str) -> str:
    """A short name for file names: the agent name, the model folder or the class name."""
    fs = split_file_spec(str(spec))
    if fs is not None:
        return fs[1]
    p = Path(str(spec))
    return p.name if p.exists() else str(spec).replace("/", "_")


def zoo_run_model(path: Path) -> Path | None:
    """The model of an RL Zoo run folder (``python -m rl_zoo3.train`` writes ``logs/ALGO/ENV_ID_N/`` with
    ``ENV_ID.zip`` beside the folder ``ENV_ID/`` of ``args.yml`` and ``config.yml``), or None."""
    path = Path(path)
    if not path.is_dir():
        return None
    for f in sorted(path.glob("*.zip")):
        if (path / f.stem / "args.yml").is_file() and (path / f.stem / "config.yml").is_file():
            return f
    return None


def load_agent(spec: str) -> Agent:
    """An agent by name, path (a model folder with agent.json, or an RL Zoo run folder) or ``file.py:Class``
    (see module docstring)."""
    spec = str(spec)
    if spec in BUILTIN_AGENTS:
        return _import(BUILTIN_AGENTS[spec], f"built-in agent {spec!r}")()
    fs = split_file_spec(spec)
    if fs is not None:
        return _load_file_agent(fs[0], fs[1], spec)
    path = Path(spec)
    if not path.exists():
        from .agent_registry import find_agent, list_agents

        entry = find_agent(spec)
        if entry is not None and entry.kind == "model":
            path = Path(entry.spec)
            if not entry.available:
                missing = [m for m in entry.needs if importlib.util.find_spec(m) is None] or list(entry.needs)
                raise MissingExtra(missing[0], f"agent {spec!r}")
        else:
            from ..suggest import did_you_mean

            known = [e.name for e in list_agents()]
            names = ", ".join(known)
            tail = find_agent(path.name) if path.name != spec else None
            if tail is not None:  # a shipped model's folder named by a path relative to the clone
                raise ValueError(
                    f"no such path {spec!r} here; the shipped agent {tail.name!r} is found by name from "
                    f"any folder: --agent {tail.name}"
                )
            raise ValueError(
                f"unknown agent {spec!r}{did_you_mean(spec, known)}: not a name ({names}; see 'marine-fdi "
                "agents'), "
                "no such path, and not path/to/file.py:ClassName"
            )
    meta_file = path / "agent.json" if path.is_dir() else path
    if path.is_dir() and not meta_file.is_file() and zoo_run_model(path) is not None:
        return _import(ZOO_AGENT, f"RL Zoo run {path}").from_dir(path)
    if not meta_file.is_file():
        raise ValueError(
            f"agent directory {path} has no agent.json (nor is it an RL Zoo run folder: ENV_ID.zip beside "
            "ENV_ID/args.yml)"
        )
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
