"""A model folder's ``config.json``: reading it and checking its observation space (every trained agent's
loader uses these: :mod:`.agents`, :mod:`.decentralised_agent`)."""

from __future__ import annotations

from pathlib import Path

from marine_fdi_env.envs.observation import feature_names
from marine_fdi_env.jsonfile import read_json

__all__ = ["read_config", "check_observation"]


def read_config(path: Path) -> dict:
    f = Path(path) / "config.json"
    if not f.is_file():
        raise ValueError(f"{f}: missing (a model directory needs config.json beside its weights)")
    cfg = read_json(f, "model config")
    if not isinstance(cfg, dict) or "observation" not in cfg:
        raise ValueError(f"{f}: not a model config (no 'observation' entry)")
    return cfg


def check_observation(cfg: dict, where: Path, observe_sensors: bool = False) -> int:
    """The per-decision observation size of a model; ValueError if it is not this env's."""
    ob = cfg["observation"]
    names = feature_names(bool(ob.get("observe_sensors", observe_sensors)))
    if ob.get("feature_names") != names:
        size = ob.get("size")
        same = " with different names" if size == len(names) else ""
        raise ValueError(
            f"{where}: model made for another observation space ({size} features{same}); "
            f"this environment has {len(names)} features ({names[0]}, ..., {names[-1]})"
        )
    return len(names)
