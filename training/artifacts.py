"""What a training run writes beside its model: the observation it was trained on, the learning
curve (CSV) and the ``config.json`` / ``agent.json`` of the model folder."""

from __future__ import annotations

import csv
import json
from pathlib import Path

from marine_fdi_env.envs.observation import feature_names

__all__ = []


def _observation_meta(observe_sensors: bool = False) -> dict:
    names = feature_names(observe_sensors)
    return {"size": len(names), "observe_sensors": observe_sensors, "feature_names": names}


def _write_curve(path: Path, rows: list[dict]) -> None:
    keys = list(dict.fromkeys(k for r in rows for k in r))
    with path.open("w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=keys)
        w.writeheader()
        w.writerows(rows)


def save_meta(out: Path, cfg: dict, agent_class: str) -> None:
    (out / "config.json").write_text(json.dumps(cfg, indent=1) + "\n")
    (out / "agent.json").write_text(json.dumps({"class": agent_class, "kwargs": {}}, indent=1) + "\n")


# ----------------------------------------------------------------------------- reinforcement learning
