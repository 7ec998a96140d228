"""What a training run writes beside its model: the observation it was trained on, the learning
curve (CSV) and the ``config.json`` / ``agent.json`` of the model folder."""

from __future__ import annotations

import csv
import json
import os
import platform
from pathlib import Path

from marine_fdi_env.envs.observation import feature_names
from marine_fdi_env.outputs import prepare_out

__all__ = ["save_sb3_agent", "observation_meta", "write_curve", "machine_record"]


def machine_record() -> dict:
    """Where a model was trained: cores, Python, the CPU's model name and the numerical libraries' versions.

    The CPU matters for bit-for-bit retraining: torch's BLAS (Intel MKL) picks its matrix-multiply kernels by
    CPU vendor, and the backward pass's long sums round differently on another kind of CPU (training/NOTES.md)."""
    import numpy as np

    cpu = platform.processor()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.partition(":")[2].strip()
                break
    except OSError:
        pass
    rec = {"cpus": os.cpu_count(), "python": platform.python_version(), "cpu": cpu, "numpy": np.__version__}
    try:
        import torch

        rec["torch"] = torch.__version__
    except ImportError:
        pass
    return rec


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


def save_sb3_agent(model, folder: "str | Path", venv=None, *, name: str | None = None) -> Path:
    """Save a Stable-Baselines3 PPO trained on :class:`~marine_fdi_env.training.vec_adapter.SB3VecEnv`
    as a benchmark agent: ``folder`` gets ``model.zip``, ``config.json`` and ``agent.json``, so
    ``marine-fdi evaluate --agent FOLDER`` scores it.

    ``venv`` is the training env (its action mode and whether it appends the reference features;
    default: the model's own env); ``name`` the agent's name in results (default: the folder's name).
    Only the parent of ``folder`` is created if missing, never more levels."""
    venv = venv if venv is not None else model.get_env()
    while venv is not None and not hasattr(venv, "action_mode") and hasattr(venv, "venv"):
        venv = venv.venv  # VecMonitor, VecNormalize, ... around the adapter
    if venv is None or not hasattr(venv, "action_mode"):
        raise ValueError("save_sb3_agent needs the SB3VecEnv the model was trained on (venv=...)")
    out = prepare_out(folder, "folder")
    model.save(out / "model.zip")
    cfg = {
        "name": name or out.resolve().name,
        "algo": "ppo",
        "action_mode": venv.action_mode,
        "frame_stack": 1,
        "observation": dict(_observation_meta(), reference_features=bool(venv.with_reference)),
        "n_parameters": int(sum(p.numel() for p in model.policy.parameters())),
        "model_bytes": (out / "model.zip").stat().st_size,
    }
    save_meta(out, cfg, "marine_fdi_env.training.agents:SB3Agent")
    return out


def observation_meta(observe_sensors: bool = False) -> dict:
    """The ``observation`` entry of a model's ``config.json`` (size, options, feature names)."""
    return _observation_meta(observe_sensors)


def write_curve(path: Path, rows: list[dict]) -> None:
    """A learning curve as CSV (one row per epoch or rollout)."""
    _write_curve(path, rows)
