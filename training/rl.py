"""PPO on MarineFDI-v1, learning from recorded episodes (:mod:`marine_fdi_env.training.replay`).

``marine-fdi train --algo ppo --env MarineFDI-v1 --seed 0`` runs :func:`train_ppo_replay`
with the ``MarineFDI-v1`` entry of ``training/hyperparams/ppo.yml``:

1. the training episodes are simulated once (``marine-fdi dataset`` exports of the ``datasets``
   specs: scenario presets or configs with their own seeds, never a suite; cached in
   ``training/.cache``, whose export CPU time still counts);
2. the agent's input preprocessing (:class:`marine_fdi_env.training.features.AgentFeatures`: EWMAs of the signed
   residual means, the previous alarm, no clock) is standardised on them;
3. ``validation_fraction`` of the episodes are held out: every ``eval_every`` rollouts the
   deterministic policy is scored on them (isolation, false alarms, return), for the learning
   curve only (the shipped policy is the last one, not the best on validation);
4. PPO (Stable-Baselines3) learns on the rest, replayed under MarineFDI-v1's reward with the
   ``pair`` action (a hypothesis and an optional second fault).

The policy sees only the observation features (no ``info["reference"]``), and learns only from
the reward.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from marine_fdi_env.envs.observation import feature_names
from marine_fdi_env.envs.reward import REWARD_TERMS_V1, RewardConfigV1, make_reward_config

from .features import AgentFeatures
from .replay import ReplayVecEnv, load_episodes

__all__ = ["train_ppo_replay", "evaluate_on_episodes", "plot_learning_curve"]


def _subset(ep: dict, idx: np.ndarray) -> dict:
    out = {k: v[idx] for k, v in ep.items() if k != "feature_names"}
    out["feature_names"] = ep["feature_names"]
    return out


def evaluate_on_episodes(
    model, episodes: dict, features: AgentFeatures, action_mode: str, reward: RewardConfigV1
) -> dict:
    """Deterministic policy on every episode of ``episodes`` once: mean return and the metrics
    the reward terms reveal (isolation at the end, detection, false alarms)."""
    n = len(episodes["obs"])
    env = ReplayVecEnv(episodes, n, action_mode, reward=reward, features=features, order="sequential")
    obs = env.reset()
    done_eps: dict[int, dict] = {}
    while len(done_eps) < n:
        act, _ = model.predict(obs, deterministic=True)
        ep_before = env.episode.copy()
        obs, _, dones, infos = env.step(act)
        for i in np.flatnonzero(dones):
            if int(ep_before[i]) not in done_eps:
                done_eps[int(ep_before[i])] = infos[i]["episode"]
    faulty = np.isfinite(episodes["first_onset"])
    last = episodes["valid"].sum(axis=1) - 1
    n_faults = episodes["active"][np.arange(n), last].sum(axis=1)
    r = [done_eps[e] for e in range(n)]
    terms = {t: np.array([x["terms"][t] for x in r]) for t in REWARD_TERMS_V1}
    iso = terms["final_isolation"] > 0
    by = {
        f"val_isolation_accuracy_{k}_faults": float(np.mean(iso[n_faults == k])) if np.any(n_faults == k) else None
        for k in (1, 2)
    }
    return {
        "val_return": float(np.mean([x["r"] for x in r])),
        "val_isolation_accuracy": float(np.mean(iso[faulty])) if faulty.any() else None,
        **by,
        "val_detection_rate": float(np.mean(terms["missed_detection"][faulty] == 0)) if faulty.any() else None,
        "val_false_alarm_episodes": int(np.sum(terms["false_alarm"] < 0)),
        "val_false_alarm_episodes_fault_free": int(np.sum(terms["false_alarm"][~faulty] < 0)),
        "val_episodes": n,
    }


def train_ppo_replay(seed: int, hp: dict, out: Path | None, use_cache: bool = True, log=print):
    """Train PPO on replayed MarineFDI-v1 episodes; returns (model, config)."""
    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.logger import Logger
    from stable_baselines3.common.utils import set_random_seed
    from stable_baselines3.common.vec_env import VecNormalize

    from .datasets import _ensure_dataset, for_training_seed

    hp = dict(hp)
    c0, w0 = time.process_time(), time.perf_counter()
    torch.set_num_threads(int(hp.pop("torch_threads", 1)))
    hp.pop("replay")
    name = hp.pop("name", "ppo")
    stride = int(hp.pop("data_seed_stride", 0))
    datasets = [for_training_seed(spec, seed, stride) for spec in hp.pop("datasets")]
    n_envs = int(hp.pop("n_envs"))
    n_timesteps = int(hp.pop("n_timesteps"))
    action_mode = hp.pop("action_mode", "pair")
    feat_hp = dict(hp.pop("features", {}))
    val_fraction = float(hp.pop("validation_fraction", 0.1))
    eval_every = int(hp.pop("eval_every", 10))
    norm_reward = bool(hp.pop("normalize_reward", True))
    alarm_logit = hp.pop("initial_alarm_logit", None)
    single_logit = hp.pop("initial_single_logit", None)
    pretrain = hp.pop("pretrain", None)
    final_alarm_margin = hp.pop("final_alarm_margin", None)
    reward = make_reward_config(hp.pop("reward", "v1"))
    policy = hp.pop("policy")
    pk = hp.pop("policy_kwargs", None)
    policy_kwargs = eval(pk, {"dict": dict}) if isinstance(pk, str) else (pk or {})  # RL Zoo convention

    data_cpu = fresh_cpu = 0.0
    dirs = []
    for spec in datasets:
        d, cpu, fresh = _ensure_dataset(spec, use_cache, log)
        dirs.append(d)
        data_cpu += cpu
        fresh_cpu += cpu if fresh else 0.0
    episodes = load_episodes(dirs)
    names = feature_names(False)
    if episodes["feature_names"] != names:
        raise ValueError("the exported datasets have other observation features than this environment")
    rng = np.random.default_rng(seed)
    perm = rng.permutation(len(episodes["obs"]))
    n_val = int(round(val_fraction * len(perm)))
    val, train = _subset(episodes, np.sort(perm[:n_val])), _subset(episodes, np.sort(perm[n_val:]))
    features = AgentFeatures(names, **feat_hp).fit(train["obs"], train["valid"])
    log = log or (lambda *_: None)
    log(f"{len(train['obs'])} training episodes, {n_val} validation episodes; policy input {features.size}")

    set_random_seed(seed)
    env = ReplayVecEnv(train, n_envs, action_mode, seed=seed, reward=reward, features=features)
    venv = (
        VecNormalize(env, norm_obs=False, norm_reward=norm_reward, gamma=float(hp.get("gamma", 0.99)))
        if norm_reward
        else env
    )
    model = PPO(policy, venv, seed=seed, device="cpu", verbose=0, policy_kwargs=policy_kwargs, **hp)
    # SB3 makes an empty /tmp/SB3-<date> folder per learn() without a logger of its own; ours writes nowhere
    model.set_logger(Logger(None, []))
    if alarm_logit is not None:  # start from a quiet policy: P(alarm on) = sigmoid(initial_alarm_logit)
        if action_mode != "gated":
            raise ValueError("initial_alarm_logit needs action_mode 'gated'")
        import torch

        with torch.no_grad():
            model.policy.action_net.bias[1] += float(alarm_logit)
    if single_logit is not None:  # start by naming one fault: the second-fault head prefers "none"
        if action_mode != "gated":
            raise ValueError("initial_single_logit needs action_mode 'gated'")
        import torch

        with torch.no_grad():
            model.policy.action_net.bias[2 + 27] += float(single_logit)
    pretraining = None
    if pretrain:  # a supervised start (training/pretrain.py), then PPO fine-tunes
        if action_mode != "gated":
            raise ValueError("pretrain needs action_mode 'gated'")
        from .pretrain import pretrain_policy

        pretraining = pretrain_policy(model.policy, features, train, dict(pretrain), seed, log)
        if n_val:
            pretraining["validation"] = evaluate_on_episodes(model, val, features, action_mode, reward)
            log(f"pretrained policy on the validation episodes: {pretraining['validation']}")
        pretraining["cpu_s"] = round(time.process_time() - c0 - fresh_cpu + data_cpu, 2)
    curve: list[dict] = []

    class Curve(BaseCallback):
        def __init__(self):
            super().__init__()
            self.eps: list[dict] = []
            self.rollouts = 0

        def _on_step(self) -> bool:
            for info in self.locals.get("infos", []):
                if "episode" in info:
                    self.eps.append(info["episode"])
            return True

        def _on_rollout_end(self) -> None:
            self.rollouts += 1
            if self.rollouts % eval_every:
                return
            recent = self.eps[-n_envs:]
            row = {
                "timesteps": int(self.num_timesteps),
                "episodes": len(self.eps),
                "train_return": float(np.mean([e["r"] for e in recent])) if recent else None,
            }
            for t in REWARD_TERMS_V1:
                row[f"train_{t}"] = float(np.mean([e["terms"][t] for e in recent])) if recent else None
            if n_val:
                row.update(evaluate_on_episodes(self.model, val, features, action_mode, reward))
            row["cpu_s"] = round(time.process_time() - c0 - fresh_cpu + data_cpu, 2)
            row["wall_s"] = round(time.perf_counter() - w0, 2)
            curve.append(row)
            f = lambda v: "–" if v is None else f"{v:.3f}"  # noqa: E731
            log(
                f"{row['timesteps']:9d} steps  return {f(row['train_return'])}  val iso "
                f"{f(row.get('val_isolation_accuracy'))} (1 fault {f(row.get('val_isolation_accuracy_1_faults'))}, "
                f"2 faults {f(row.get('val_isolation_accuracy_2_faults'))})  val detection "
                f"{f(row.get('val_detection_rate'))}  val FA episodes {row.get('val_false_alarm_episodes')}  "
                f"val return {f(row.get('val_return'))}  cpu {row['cpu_s']:.0f} s"
            )

    model.learn(total_timesteps=n_timesteps, callback=Curve())
    final_alarm = None
    if final_alarm_margin is not None:  # the alarm quiet before every training onset (training/pretrain.py)
        if action_mode != "gated":
            raise ValueError("final_alarm_margin needs action_mode 'gated'")
        from .pretrain import final_quiet_alarm

        final_alarm = final_quiet_alarm(model.policy, features, train, float(final_alarm_margin))
        log(f"final alarm logit shifted by {-final_alarm['alarm_logit_shift']:.3f}")
    final = evaluate_on_episodes(model, val, features, action_mode, reward) if n_val else {}
    cpu_total = time.process_time() - c0 - fresh_cpu + data_cpu  # a cached export still counts
    cfg = {
        "name": name,
        "algo": "ppo",
        "env_id": "MarineFDI-v1",
        "seed": seed,
        "n_envs": n_envs,
        "n_timesteps": n_timesteps,
        "action_mode": action_mode,
        "frame_stack": 1,
        "scenario_config": "replay of the datasets below",
        "policy": policy,
        "policy_kwargs": pk,
        "hyperparams": dict(
            hp,
            normalize_reward=norm_reward,
            validation_fraction=val_fraction,
            data_seed_stride=stride,
            eval_every=eval_every,
            initial_alarm_logit=alarm_logit,
            initial_single_logit=single_logit,
            **({"pretrain": dict(pretrain)} if pretrain else {}),
            **({"final_alarm_margin": final_alarm_margin} if final_alarm_margin is not None else {}),
        ),
        "reward": reward.to_dict(),
        "datasets": datasets,
        "training_episodes": int(len(train["obs"])),
        "validation_episodes": n_val,
        "validation": final,
        **({"pretraining": pretraining} if pretraining else {}),
        **({"final_alarm": final_alarm} if final_alarm else {}),
        "features": features.to_dict(),
        "observation": dict(_observation_meta(), reference_features=False),
        "n_parameters": int(sum(p.numel() for p in model.policy.parameters())),
        "cpu_s_data": round(data_cpu, 3),
        "cpu_s": round(cpu_total, 1),
        "wall_s": round(time.perf_counter() - w0, 1),
    }
    if out is not None:
        from .artifacts import _write_curve

        out.mkdir(parents=True, exist_ok=True)
        model.save(out / "model.zip")
        _write_curve(out / "learning_curve.csv", curve)
        plot_learning_curve(curve, out / "learning_curve.png", title=f"{name}: PPO on MarineFDI-v1 (seed {seed})")
        cfg["model_bytes"] = (out / "model.zip").stat().st_size
    return model, cfg


def _observation_meta() -> dict:
    from .artifacts import _observation_meta as meta

    return meta()


def plot_learning_curve(curve: list[dict], path: Path, title: str = "") -> Path | None:
    """Training return and, on the held-out episodes, isolation accuracy and false alarms vs steps."""
    if not curve:
        return None
    from marine_fdi_env.plotting import pyplot

    try:
        plt = pyplot()
    except RuntimeError:  # the training extra does not need matplotlib: no curve then
        return None

    x = [r["timesteps"] / 1e6 for r in curve]
    fig, axes = plt.subplots(1, 3, figsize=(13, 3.6))
    axes[0].plot(x, [r["train_return"] for r in curve], label="training episodes")
    if "val_return" in curve[0]:
        axes[0].plot(x, [r["val_return"] for r in curve], label="held-out episodes (deterministic)")
    axes[0].set_ylabel("MarineFDI-v1 return")
    axes[0].legend(fontsize="small")
    if "val_isolation_accuracy" in curve[0]:
        axes[1].plot(x, [100 * (r["val_isolation_accuracy"] or 0) for r in curve], label="isolation accuracy")
        axes[1].plot(x, [100 * (r["val_detection_rate"] or 0) for r in curve], label="detection rate")
        axes[1].set_ylabel("% of faulty held-out episodes")
        axes[1].set_ylim(0, 100)
        axes[1].legend(fontsize="small")
        axes[2].plot(x, [r["val_false_alarm_episodes"] for r in curve], color="C3")
        axes[2].set_ylabel(f"held-out episodes with a false alarm (of {curve[0]['val_episodes']})")
    for ax in axes:
        ax.set_xlabel("decisions [millions]")
        ax.grid(alpha=0.3)
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
