"""Train a learned diagnoser for ``MarineFDI-v1`` / ``MarineFDI-v0`` (RL Zoo style): :func:`train_agent`.

    marine-fdi train --algo ppo --env MarineFDI-v1 --seed 0   # the shipped PPO: replayed v1 episodes
    marine-fdi train --algo ppo --seed 0                      # PPO on the live batched env (v0 entry)
    marine-fdi train --algo ppo_lstm --seed 0                 # RecurrentPPO (sb3-contrib)
    marine-fdi train --algo classifier --seed 0               # supervised GRU diagnoser (v1)
    marine-fdi train --algo classifier --hyperparams robust --seed 0   # the noise-invariant GRU diagnoser
    marine-fdi train --algo ppo --hyperparams robust --seed 0          # the noise-invariant PPO (replayed v1)
    marine-fdi train --algo ppo --seed -1                     # draw a seed (logged and saved)

Hyperparameters: ``training/hyperparams/ALGO.yml``, keyed by env id or by a configuration name
(``--hyperparams robust``: the noise-invariant agents); ``--params key=value ...``
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

import time
from pathlib import Path

import numpy as np
import yaml

from marine_fdi_env.envs.fdi_env import ENV_ID
from marine_fdi_env.envs.observation import feature_names

from .artifacts import _observation_meta, _write_curve, machine_record, save_meta  # noqa: F401 - used here and by tests
from .datasets import (  # noqa: F401
    _dataset,
    _ensure_dataset,
    dataset_scenarios,
    for_training_seed,
    minari_id,
    scenario_config_of,
)

__all__ = ["train_agent", "load_hyperparams", "train_sb3", "train_classifier_run", "training_specs", "ALGOS"]

ALGOS = ("ppo", "ppo_lstm", "classifier")
HERE = Path(__file__).resolve().parent


def load_hyperparams(algo: str, env_id: str = ENV_ID, overrides: dict | None = None) -> dict:
    """The entry ``env_id`` of ``training/hyperparams/ALGO.yml`` (an env id, or the name of a named
    configuration such as ``robust``), with ``overrides``."""
    f = HERE / "hyperparams" / f"{algo}.yml"
    if not f.is_file():
        raise ValueError(f"{f}: no hyperparameter file for algo {algo!r}")
    data = yaml.safe_load(f.read_text())
    if env_id not in data:
        raise ValueError(f"{f}: no entry {env_id!r} (has {', '.join(data)})")
    hp = dict(data[env_id])
    hp.update(overrides or {})
    n = hp.get("n_timesteps")
    if n is not None and (isinstance(n, bool) or not isinstance(n, int) or n < 1):
        raise ValueError(f"n_timesteps must be a positive integer, got {n!r}")
    return hp


def train_sb3(algo: str, seed: int, hp: dict, out: Path | None, log=print) -> tuple[object, dict]:
    """Train PPO / RecurrentPPO on the batched env; returns (model, config)."""
    import torch
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.logger import Logger
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
    env = SB3VecEnv(
        n_envs, scenario_config=scenario, action_mode=action_mode, seed=seed, reference_features=with_reference
    )
    env = VecMonitor(env)
    if frame_stack > 1:
        env = VecFrameStack(env, frame_stack)
    if algo == "ppo":
        from stable_baselines3 import PPO as Algo
    else:
        from sb3_contrib import RecurrentPPO as Algo
    model = Algo(policy, env, seed=seed, device="cpu", verbose=0, policy_kwargs=policy_kwargs, **hp)
    # SB3 makes an empty /tmp/SB3-<date> folder per learn() without a logger of its own; ours writes nowhere
    model.set_logger(Logger(None, []))
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
            row = {
                "timesteps": int(self.num_timesteps),
                "episodes": len(self.returns),
                "mean_return_last": float(np.mean(self.returns[-n_envs:])) if self.returns else "",
                "cpu_s": round(time.process_time() - c0, 2),
                "wall_s": round(time.perf_counter() - w0, 2),
            }
            curve.append(row)
            if log:
                log(
                    f"{row['timesteps']:8d} steps  episodes {row['episodes']:5d}  "
                    f"return {row['mean_return_last']}  cpu {row['cpu_s']:.0f} s"
                )

    model.learn(total_timesteps=n_timesteps, callback=Curve())
    cfg = {
        "name": algo,
        "algo": algo,
        "env_id": ENV_ID,
        "seed": seed,
        "n_envs": n_envs,
        "n_timesteps": n_timesteps,
        "action_mode": action_mode,
        "frame_stack": frame_stack,
        "scenario_config": scenario,
        "policy": policy,
        "policy_kwargs": pk,
        "hyperparams": hp,
        "observation": dict(_observation_meta(), reference_features=with_reference),
        "n_parameters": int(sum(p.numel() for p in model.policy.parameters())),
        "cpu_s": round(time.process_time() - c0, 1),
        "wall_s": round(time.perf_counter() - w0, 1),
    }
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        model.save(out / "model.zip")
        _write_curve(out / "learning_curve.csv", curve)
        cfg["model_bytes"] = (out / "model.zip").stat().st_size
    return model, cfg


# ----------------------------------------------------------------------------- supervised
def training_specs(hp: dict, seed: int) -> tuple[list[dict], dict | None, dict | None]:
    """(training datasets, alarm-calibration set, isolation-calibration set) a run with ``seed``
    simulates: the specs of ``hp`` with their seeds moved by ``data_seed_stride x seed``."""
    stride = int(hp.get("data_seed_stride", 0))
    one = lambda spec: None if spec is None else for_training_seed(spec, seed, stride)  # noqa: E731
    return ([one(s) for s in hp["datasets"]], one(hp.get("calibration")), one(hp.get("isolation_calibration")))


def train_classifier_run(seed: int, hp: dict, out: Path | None, use_cache: bool = True, log=print):
    """Data export, GRU training, alarm-threshold and isolation calibration; returns (model, config)."""
    import torch

    from .classifier import calibrate_isolation, calibrate_threshold, episode_scores, train_classifier
    from .features import AgentFeatures, transform_episodes

    hp = dict(hp)
    c0, w0 = time.process_time(), time.perf_counter()
    torch.set_num_threads(int(hp.pop("torch_threads", 1)))
    # data_source=minari minari_root=ROOT: every dataset through a Minari dataset under ROOT (docs/minari.md)
    source = str(hp.pop("data_source", "npz"))
    if source not in ("npz", "minari"):
        raise ValueError(f"data_source must be npz or minari, got {source!r}")
    minari_root = hp.pop("minari_root", None)
    if source == "minari" and not minari_root:
        raise ValueError("data_source=minari needs minari_root=ROOT (a Minari datasets root)")
    datasets, calibration, iso_calibration = training_specs(hp, seed)
    names = feature_names(False)
    features = AgentFeatures(names, **hp["features"]) if hp.get("features") else None
    data_cpu = fresh_cpu = 0.0

    def load(spec):
        nonlocal data_cpu, fresh_cpu
        arr, cpu, fresh = _dataset(spec, use_cache, log, minari_root if source == "minari" else None)
        data_cpu += cpu
        fresh_cpu += cpu if fresh else 0.0
        if features is not None:  # the agent's own preprocessing, computed once
            arr["obs"] = transform_episodes(features, arr["obs"])
        return arr

    parts = [load(spec) for spec in datasets]
    weights = [
        np.full(len(p["obs"]), float(spec.get("weight", 1.0)), dtype=np.float32) for p, spec in zip(parts, datasets)
    ]
    data = {k: np.concatenate([p[k] for p in parts]) for k in ("obs", "active", "valid")}
    del parts
    in_names = features.input_names() if features is not None else names
    c_train = time.process_time()
    res = train_classifier(
        data,
        seed=seed,
        hidden=int(hp["hidden"]),
        embed=int(hp["embed"]),
        epochs=int(hp["epochs"]),
        batch_size=int(hp["batch_size"]),
        lr=float(hp["lr"]),
        weight_decay=float(hp["weight_decay"]),
        alarm_weight=float(hp["alarm_weight"]),
        drop_features=tuple(hp.get("drop_features", ())),
        feature_names=in_names,
        ewma_features=tuple(hp.get("ewma_features", ())),
        ewma_taus=tuple(hp.get("ewma_taus", ())),
        episode_weight=np.concatenate(weights),
        balance_alarm=bool(hp.get("balance_alarm", False)),
        lr_schedule=str(hp.get("lr_schedule", "constant")),
        log=log,
    )
    train_cpu = time.process_time() - c_train
    n_train = int(len(data["obs"]))
    del data
    cal_data = load(calibration)
    probs = episode_scores(res.model, cal_data["obs"])
    cal = calibrate_threshold(
        probs[..., -1],
        cal_data["valid"],
        target_per_hour=float(hp["target_false_alarms_per_hour"]),
        margin=float(hp["margin_logodds"]),
    )
    log(
        f"alarm threshold {cal['alarm_threshold']:.4f} (calibration peak {cal['calibration_peak']:.4f} over "
        f"{cal['calibration_episodes']} fault-free episodes)"
    )
    declaration = {
        "alarm_threshold": cal["alarm_threshold"],
        "isolation_threshold": float(hp["isolation_threshold"]),
        "use_reference": hp.get("use_reference", False),
        "calibration": cal,
    }
    if iso_calibration is not None:
        iso = load(iso_calibration)
        conf = calibrate_isolation(
            episode_scores(res.model, iso["obs"]),
            iso["active"],
            iso["valid"],
            alpha=float(hp["isolation_alpha"]),
            isolation_threshold=float(hp["isolation_threshold"]),
        )
        declaration["isolation_conformal"] = conf
        log(
            f"isolation: declare the most probable set unless it is less decisive than at alpha {conf['alpha']} "
            f"(score quantile {conf['quantile']:.4f} over {conf['episodes']} faulty episodes)"
        )
    cpu_here = time.process_time() - c0
    arch = {
        "kind": "gru",
        "n_features": int(res.model.n_features),
        "hidden": int(hp["hidden"]),
        "embed": int(hp["embed"]),
        "ewma_idx": res.model.ewma_idx,
        "ewma_taus": res.model.ewma_taus,
    }
    cfg = {
        "name": hp.get("name", "classifier"),
        "algo": "classifier",
        "env_id": ENV_ID,
        "seed": seed,
        "hyperparams": hp,
        "datasets": datasets,
        "calibration_sets": [c for c in (calibration, iso_calibration) if c],
        "architecture": arch,
        "declaration": declaration,
        "observation": _observation_meta(),
        "training_episodes": n_train,
        "n_parameters": int(sum(p.numel() for p in res.model.parameters())),
        "cpu_s_data": round(data_cpu, 3),
        "cpu_s_train": round(train_cpu, 1),
        # a data export cached from an earlier run still counts
        "cpu_s": round(cpu_here - fresh_cpu + data_cpu, 1),
        "wall_s": round(time.perf_counter() - w0, 1),
    }
    if source == "minari":  # where the data came from: Minari datasets, by id
        sets = datasets + [c for c in (calibration, iso_calibration) if c]
        cfg["data_source"] = {"format": "minari", "root": str(minari_root), "dataset_ids": [minari_id(s) for s in sets]}
    if features is not None:
        cfg["features"] = features.to_dict()
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        torch.save(res.model.state_dict(), out / "model.pt")
        _write_curve(out / "learning_curve.csv", res.curve)
        cfg["model_bytes"] = (out / "model.pt").stat().st_size
    return res.model, cfg


def train_agent(
    algo: str,
    seed: int,
    out: Path,
    *,
    env_id: str = ENV_ID,
    overrides: dict | None = None,
    use_cache: bool = True,
    command: str = "",
    seed_drawn: bool = False,
    hyperparams: str | None = None,
) -> dict:
    """Train ``algo`` with ``seed`` and save the model, ``config.json`` and ``agent.json`` in ``out``; returns the
    config (``command``: the command that makes the model, recorded in it; ``seed_drawn``: the seed was drawn;
    ``hyperparams``: the entry of ``ALGO.yml`` to use, default ``env_id``)."""
    key = hyperparams or env_id
    hp = load_hyperparams(algo, key, overrides)
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
    cfg.update(
        hyperparams_entry=key,
        command=command,
        seed_drawn=seed_drawn,
        cpu_minutes=round(cfg["cpu_s"] / 60.0, 2),
        machine=machine_record(),
    )
    save_meta(out, cfg, agent_class)
    return cfg
