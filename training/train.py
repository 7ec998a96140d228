"""Train a learned diagnoser for ``MarineFDI-v1`` / ``MarineFDI-v0`` (RL Zoo style): :func:`train_agent`.

    marine-fdi train --algo ppo --env MarineFDI-v1 --seed 0   # the shipped PPO: replayed v1 episodes
    marine-fdi train --algo ppo --seed 0                      # PPO on the live batched env (v0 entry)
    marine-fdi train --algo ppo_lstm --seed 0                 # RecurrentPPO (sb3-contrib)
    marine-fdi train --algo classifier --seed 0               # supervised GRU diagnoser
    marine-fdi train --algo ppo --seed -1                     # draw a seed (logged and saved)

Hyperparameters: ``training/hyperparams/ALGO.yml``, keyed by env id; ``--params key=value ...``
overrides entries (values parsed as YAML), ``--n-timesteps`` the PPO budget.  The run directory
(``--out``, default ``training/logs/ALGO_sSEED``) receives the model, ``config.json`` (algorithm,
hyperparameters, seed, observation space, the exact command, CPU time), ``learning_curve.csv``
and ``agent.json``, so ``marine-fdi evaluate --agent DIR`` runs it.  The shipped models in
``training/models/`` were made with the command recorded in their ``config.json``.

CPU time is the process CPU time (all threads; simulation, features and learning together,
including the data generation of the classifier and of the replayed PPO, cached or not).
An entry with ``replay: true`` (``ppo.yml``, ``MarineFDI-v1``) trains on recorded episodes
(:mod:`marine_fdi_env.training.rl`); the others on the live environment.
"""

from __future__ import annotations

import os
import platform
import time
from pathlib import Path

import numpy as np
import yaml

from marine_fdi_env.envs.fdi_env import ENV_ID
from marine_fdi_env.envs.observation import feature_names

from .artifacts import _observation_meta, _write_curve, save_meta  # noqa: F401 - used here and by tests
from .datasets import _dataset, _ensure_dataset, dataset_scenarios, scenario_config_of  # noqa: F401

__all__ = ["train_agent", "load_hyperparams", "train_sb3", "train_classifier_run", "ALGOS"]

ALGOS = ("ppo", "ppo_lstm", "classifier")
HERE = Path(__file__).resolve().parent


def load_hyperparams(algo: str, env_id: str = ENV_ID, overrides: dict | None = None) -> dict:
    f = HERE / "hyperparams" / f"{algo}.yml"
    if not f.is_file():
        raise ValueError(f"{f}: no hyperparameter file for algo {algo!r}")
    data = yaml.safe_load(f.read_text())
    if env_id not in data:
        raise ValueError(f"{f}: no entry for env id {env_id!r} (has {', '.join(data)})")
    hp = dict(data[env_id])
    hp.update(overrides or {})
    return hp


def train_sb3(algo: str, seed: int, hp: dict, out: Path | None, log=print) -> tuple[object, dict]:
    """Train PPO / RecurrentPPO on the batched env; returns (model, config)."""
    import torch
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.utils import set_random_seed
    from stable_baselines3.common.vec_env import VecFrameStack, VecMonitor

    from .vec_adapter import SB3VecEnv

    hp = dict(hp)
    c0, w0 = time.process_time(), time.perf_counter()
    torch.set_num_threads(int(hp.pop("torch_threads", 1)))
    n_envs = int(hp.pop("n_envs"))
    n_timesteps = int(hp.pop("n_timesteps"))
    action_mode = hp.pop("action_mode", "discrete")
    frame_stack = int(hp.pop("frame_stack", 1))
    with_reference = bool(hp.pop("reference_features", False))
    scenario = hp.pop("scenario_config", "default")
    policy = hp.pop("policy")
    pk = hp.pop("policy_kwargs", None)
    policy_kwargs = eval(pk, {"dict": dict}) if isinstance(pk, str) else (pk or {})  # RL Zoo convention
    set_random_seed(seed)
    env = SB3VecEnv(n_envs, scenario_config=scenario, action_mode=action_mode, seed=seed,
                    reference_features=with_reference)
    env = VecMonitor(env)
    if frame_stack > 1:
        env = VecFrameStack(env, frame_stack)
    if algo == "ppo":
        from stable_baselines3 import PPO as Algo
    else:
        from sb3_contrib import RecurrentPPO as Algo
    model = Algo(policy, env, seed=seed, device="cpu", verbose=0, policy_kwargs=policy_kwargs, **hp)
    curve: list[dict] = []

    class Curve(BaseCallback):
        def __init__(self):
            super().__init__()
            self.returns: list[float] = []

        def _on_step(self) -> bool:
            for info in self.locals.get("infos", []):
                if "episode" in info:
                    self.returns.append(float(info["episode"]["r"]))
            return True

        def _on_rollout_end(self) -> None:
            row = {"timesteps": int(self.num_timesteps), "episodes": len(self.returns),
                   "mean_return_last": float(np.mean(self.returns[-n_envs:])) if self.returns else "",
                   "cpu_s": round(time.process_time() - c0, 2), "wall_s": round(time.perf_counter() - w0, 2)}
            curve.append(row)
            if log:
                log(f"{row['timesteps']:8d} steps  episodes {row['episodes']:5d}  "
                    f"return {row['mean_return_last']}  cpu {row['cpu_s']:.0f} s")

    model.learn(total_timesteps=n_timesteps, callback=Curve())
    cfg = {"name": algo, "algo": algo, "env_id": ENV_ID, "seed": seed, "n_envs": n_envs,
           "n_timesteps": n_timesteps, "action_mode": action_mode, "frame_stack": frame_stack,
           "scenario_config": scenario, "policy": policy, "policy_kwargs": pk, "hyperparams": hp,
           "observation": dict(_observation_meta(), reference_features=with_reference), "n_parameters": int(sum(p.numel() for p in model.policy.parameters())),
           "cpu_s": round(time.process_time() - c0, 1), "wall_s": round(time.perf_counter() - w0, 1)}
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        model.save(out / "model.zip")
        _write_curve(out / "learning_curve.csv", curve)
        cfg["model_bytes"] = (out / "model.zip").stat().st_size
    return model, cfg


# ----------------------------------------------------------------------------- supervised
def train_classifier_run(seed: int, hp: dict, out: Path | None, use_cache: bool = True, log=print):
    """Data export, GRU training and alarm-threshold calibration; returns (model, config)."""
    import torch

    from .classifier import calibrate_threshold, episode_scores, train_classifier

    hp = dict(hp)
    c0, w0 = time.process_time(), time.perf_counter()
    torch.set_num_threads(int(hp.pop("torch_threads", 1)))
    data_cpu = fresh_cpu = 0.0
    parts, weights = [], []
    for spec in hp["datasets"] + [hp["calibration"]]:
        arr, cpu, fresh = _dataset(spec, use_cache, log)
        parts.append(arr)
        weights.append(np.full(len(arr["obs"]), float(spec.get("weight", 1.0)), dtype=np.float32))
        data_cpu += cpu
        fresh_cpu += cpu if fresh else 0.0
    cal_data = parts.pop()
    weights.pop()
    data = {k: np.concatenate([p[k] for p in parts]) for k in ("obs", "active", "valid")}
    c_train = time.process_time()
    res = train_classifier(data, seed=seed, hidden=int(hp["hidden"]), embed=int(hp["embed"]),
                           epochs=int(hp["epochs"]), batch_size=int(hp["batch_size"]), lr=float(hp["lr"]),
                           weight_decay=float(hp["weight_decay"]), alarm_weight=float(hp["alarm_weight"]),
                           drop_features=tuple(hp.get("drop_features", ())), feature_names=feature_names(False),
                           ewma_features=tuple(hp.get("ewma_features", ())), ewma_taus=tuple(hp.get("ewma_taus", ())),
                           episode_weight=np.concatenate(weights), log=log)
    train_cpu = time.process_time() - c_train
    probs = episode_scores(res.model, cal_data["obs"])
    cal = calibrate_threshold(probs[..., -1], cal_data["valid"], target_per_hour=float(hp["target_false_alarms_per_hour"]),
                              margin=float(hp["margin_logodds"]))
    log(f"alarm threshold {cal['alarm_threshold']:.4f} (calibration peak {cal['calibration_peak']:.4f} over "
        f"{cal['calibration_episodes']} fault-free episodes)")
    cpu_here = time.process_time() - c0
    cfg = {"name": "classifier", "algo": "classifier", "env_id": ENV_ID, "seed": seed, "hyperparams": hp,
           "architecture": {"kind": "gru", "n_features": int(data["obs"].shape[-1]), "hidden": int(hp["hidden"]),
                            "embed": int(hp["embed"]), "ewma_idx": res.model.ewma_idx,
                            "ewma_taus": res.model.ewma_taus},
           "declaration": {"alarm_threshold": cal["alarm_threshold"],
                           "isolation_threshold": float(hp["isolation_threshold"]),
                           "use_reference": hp.get("use_reference", False), "calibration": cal},
           "observation": _observation_meta(), "training_episodes": int(len(data["obs"])),
           "n_parameters": int(sum(p.numel() for p in res.model.parameters())),
           "cpu_s_data": round(data_cpu, 3), "cpu_s_train": round(train_cpu, 1),
           # a data export cached from an earlier run still counts
           "cpu_s": round(cpu_here - fresh_cpu + data_cpu, 1), "wall_s": round(time.perf_counter() - w0, 1)}
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        torch.save(res.model.state_dict(), out / "model.pt")
        _write_curve(out / "learning_curve.csv", res.curve)
        cfg["model_bytes"] = (out / "model.pt").stat().st_size
    return res.model, cfg


def train_agent(algo: str, seed: int, out: Path, *, env_id: str = ENV_ID, overrides: dict | None = None,
                use_cache: bool = True, command: str = "", seed_drawn: bool = False) -> dict:
    """Train ``algo`` with ``seed`` and save the model, ``config.json`` and ``agent.json`` in ``out``; returns the
    config (``command``: the command that makes the model, recorded in it; ``seed_drawn``: the seed was drawn)."""
    hp = load_hyperparams(algo, env_id, overrides)
    if algo == "classifier":
        _, cfg = train_classifier_run(seed, hp, out, use_cache=use_cache)
        agent_class = "marine_fdi_env.training.agents:ClassifierAgent"
    elif hp.get("replay"):  # PPO on recorded MarineFDI-v1 episodes (training/rl.py)
        from .rl import train_ppo_replay

        _, cfg = train_ppo_replay(seed, hp, out, use_cache=use_cache)
        agent_class = "marine_fdi_env.training.agents:SB3Agent"
    else:
        _, cfg = train_sb3(algo, seed, hp, out)
        agent_class = "marine_fdi_env.training.agents:SB3Agent"
    cfg.update(command=command, seed_drawn=seed_drawn, cpu_minutes=round(cfg["cpu_s"] / 60.0, 2),
               machine={"cpus": os.cpu_count(), "python": platform.python_version()})
    save_meta(out, cfg, agent_class)
    return cfg
