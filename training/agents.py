"""Trained models as benchmark agents (``marine-fdi evaluate --agent NAME`` or ``--agent MODEL_FOLDER``).

A model directory holds ``agent.json`` (``{"class": "marine_fdi_env.training.agents:SB3Agent"}`` or
``"marine_fdi_env.training.agents:ClassifierAgent"``), ``config.json`` (algorithm, hyperparameters, seed,
observation size and feature names, the command that trained it, training CPU time), the
weights (``model.zip`` for SB3, ``model.pt`` for the classifier) and ``learning_curve.csv``.

Loading checks what it reads and raises ``ValueError`` naming the file and the problem (missing,
unreadable or corrupt, made for another observation space) instead of a stack trace from inside
torch or SB3.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from marine_fdi_env.envs.hypotheses import N_HYPOTHESES, UNKNOWN
from marine_fdi_env.envs.observation import feature_names

from .model_config import check_observation, read_config

__all__ = ["SB3Agent", "ClassifierAgent", "read_config", "check_observation"]


def __getattr__(name: str):
    """``DecentralisedAgent`` (the multi-agent track's learned teams, :mod:`.decentralised_agent`), imported
    when a model folder names it: every ``agent.json`` of ``training/models`` names a class of this module."""
    if name == "DecentralisedAgent":
        from .decentralised_agent import DecentralisedAgent

        return DecentralisedAgent
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _need_file(f: Path) -> Path:
    if not f.is_file():
        raise ValueError(f"{f}: missing model file")
    if f.stat().st_size == 0:
        raise ValueError(f"{f}: empty model file")
    return f


def _open_model_dir(path, weights: str) -> tuple[Path, dict, Path]:
    """(directory, checked config, weights file) of a model directory."""
    path = Path(path)
    cfg = read_config(path)
    check_observation(cfg, path / "config.json")
    return path, cfg, _need_file(path / weights)


def _check_batch(obs: np.ndarray, size: int, where: Path) -> np.ndarray:
    obs = np.asarray(obs, dtype=np.float32)
    if obs.ndim != 2 or obs.shape[1] != size:
        raise ValueError(f"{where}: model expects observations of {size} features, got shape {obs.shape}")
    return obs


class SB3Agent:
    """A Stable-Baselines3 policy (PPO, or RecurrentPPO from sb3-contrib), deterministic actions.

    ``model``: the PPO policy (:func:`~marine_fdi_env.training.sb3_inference.load_policy`), or the
    RecurrentPPO model (``algo`` ``ppo_lstm``).
    """

    def __init__(self, model, cfg: dict, where: Path) -> None:
        self.model = model
        self.cfg = cfg
        self.where = where
        self.name = cfg.get("name", cfg.get("algo", "sb3"))
        self.training_seed = cfg.get("seed")
        self.action_mode = cfg["action_mode"]
        self.frame_stack = int(cfg.get("frame_stack", 1))
        self.recurrent = cfg["algo"] == "ppo_lstm"
        if not self.recurrent:  # eval mode once (predict sets it at every call)
            from .sb3_inference import prepare

            prepare(model)
        self.obs_size = int(cfg["observation"]["size"])
        self.with_reference = bool(cfg["observation"].get("reference_features", False))
        # the agent's own input preprocessing (training/features.py), for models trained with it
        self.features = None
        if cfg.get("features") is not None:
            from .features import AgentFeatures

            self.features = AgentFeatures.from_dict(cfg["features"], feature_names(False))

    @classmethod
    def from_dir(cls, path, model: str | None = None, **kwargs) -> "SB3Agent":
        if model is not None:  # an agent directory that uses a model stored elsewhere (e.g. seed0/)
            path = (Path(path) / model).resolve()
        path, cfg, f = _open_model_dir(path, "model.zip")
        algo = cfg.get("algo")
        import zipfile

        if not zipfile.is_zipfile(f):
            raise ValueError(f"{f}: corrupt model file (not a zip archive as saved by stable-baselines3)")
        try:
            import torch

            torch.set_num_threads(1)
            if algo == "ppo_lstm":
                from sb3_contrib import RecurrentPPO

                model = RecurrentPPO.load(f, device="cpu")
            elif algo == "ppo":
                from .sb3_inference import load_policy

                model = load_policy(f)  # the policy alone: what acting needs
            else:
                raise ValueError(f"{path / 'config.json'}: unknown algo {algo!r} (ppo, ppo_lstm)")
        except ValueError:
            raise
        except Exception as e:  # noqa: BLE001 - any failure inside SB3/torch is a bad file
            raise ValueError(f"{f}: corrupt or unreadable model ({type(e).__name__}: {e})") from None
        from .vec_adapter import N_REFERENCE_FEATURES

        extra = N_REFERENCE_FEATURES if cfg["observation"].get("reference_features") else 0
        want = ((int(cfg["observation"]["size"]) + extra) * int(cfg.get("frame_stack", 1)),)
        if cfg.get("features") is not None:
            want = (len(cfg["features"]["mean"]),)
        if tuple(model.observation_space.shape) != want:
            raise ValueError(
                f"{f}: model made for another observation space (shape "
                f"{tuple(model.observation_space.shape)}, this environment gives {want})"
            )
        return cls(model, cfg, path)

    def reset(self, seeds: list[int]) -> None:
        n = len(seeds)
        self.stack = None
        self.state = None
        self.episode_start = np.ones(n, dtype=bool)
        self.n = n
        self.feature_state = self.features.initial_state(n) if self.features is not None else None

    def _stacked(self, obs: np.ndarray) -> np.ndarray:
        if self.frame_stack == 1:
            return obs
        k = obs.shape[1]
        if self.stack is None:  # SB3's VecFrameStack starts with zeros
            self.stack = np.zeros((len(obs), self.frame_stack * k), dtype=np.float32)
        self.stack = np.roll(self.stack, -k, axis=1)
        self.stack[:, -k:] = obs
        return self.stack

    def act(self, obs: np.ndarray, infos: dict) -> np.ndarray:
        from .sb3_inference import deterministic_actions
        from .vec_adapter import reference_features, to_belief

        x = _check_batch(obs, self.obs_size, self.where)
        if self.features is not None:
            x = self.features(x, self.feature_state)
        if self.with_reference:
            x = np.concatenate([x, reference_features(infos["reference"], len(x))], axis=1)
        x = self._stacked(x)
        if self.recurrent:
            a, self.state = self.model.predict(
                x, state=self.state, episode_start=self.episode_start, deterministic=True
            )
            self.episode_start[:] = False
        else:
            a = deterministic_actions(self.model, x)  # the policy's predict actions, bit for bit
        beliefs = to_belief(a, self.action_mode)
        if self.features is not None:
            from .replay import declaration_masks

            self.features.set_alarm(self.feature_state, declaration_masks(beliefs)[1])
        return beliefs


class ClassifierAgent:
    """The GRU diagnoser of :mod:`marine_fdi_env.training.classifier` with its calibrated declaration rule.

    ``use_reference`` (default: the model's ``declaration.use_reference``): ``False``, the
    classifier alone (its own latched alarm and faults; the row ``classifier``); ``"first"`` or
    ``"fallback"``, a hybrid that also takes the reference diagnoser's alarm and isolation (the row
    ``classifier+reference``; see :meth:`act`).  An agent directory can point at a model elsewhere:
    ``agent.json`` ``{"class": "marine_fdi_env.training.agents:ClassifierAgent", "kwargs": {"model": "../classifier",
    "use_reference": "first"}}`` (``training/models/classifier+reference``).
    """

    def __init__(self, model, cfg: dict, where: Path, use_reference: bool | None = None) -> None:
        self.model = model
        self.cfg = cfg
        self.where = where
        d = cfg["declaration"]
        self.alarm_threshold = float(d["alarm_threshold"])
        self.isolation_threshold = float(d.get("isolation_threshold", 0.5))
        # False: the classifier alone; "fallback": also alarm when the reference has detected, and
        # declare the reference's isolation when the classifier declares no fault; "first": the
        # reference's isolation whenever it has one, the classifier's otherwise
        self.use_reference = d.get("use_reference", False) if use_reference is None else use_reference
        if self.use_reference not in (False, "fallback", "first"):
            raise ValueError(
                f"{where / 'config.json'}: declaration.use_reference must be false, 'fallback' or "
                f"'first', got {self.use_reference!r}"
            )
        base = cfg.get("name", "classifier")
        self.name = f"{base}+reference" if self.use_reference else base
        self.training_seed = cfg.get("seed")
        self.obs_size = int(cfg["observation"]["size"])
        conf = d.get("isolation_conformal")
        self.conformal_quantile = None if conf is None else float(conf["quantile"])
        # the agent's own preprocessing (training/features.py), for models trained with it
        self.features = None
        if cfg.get("features") is not None:
            from .features import AgentFeatures

            self.features = AgentFeatures.from_dict(cfg["features"], feature_names(False))

    @classmethod
    def from_dir(cls, path, model: str | None = None, **kwargs) -> "ClassifierAgent":
        if model is not None:  # an agent directory that uses a model stored elsewhere
            path = (Path(path) / model).resolve()
        path, cfg, f = _open_model_dir(path, "model.pt")
        if "declaration" not in cfg or "architecture" not in cfg:
            raise ValueError(
                f"{path / 'config.json'}: not a classifier config (needs 'declaration' and 'architecture')"
            )
        import torch

        from .classifier import GRUDiagnoser

        torch.set_num_threads(1)
        try:
            state = torch.load(f, map_location="cpu", weights_only=True)
        except Exception as e:  # noqa: BLE001
            raise ValueError(f"{f}: corrupt or unreadable model ({type(e).__name__}: {e})") from None
        if not isinstance(state, dict):
            raise ValueError(f"{f}: corrupt model (not a state dict)")
        arch = cfg["architecture"]
        model = GRUDiagnoser(
            int(arch["n_features"]),
            hidden=int(arch["hidden"]),
            embed=int(arch["embed"]),
            ewma_idx=arch.get("ewma_idx", ()),
            ewma_taus=arch.get("ewma_taus", ()),
        )
        w = state.get("inp.weight")
        if w is None or not hasattr(w, "shape"):
            raise ValueError(f"{f}: corrupt model (no input layer weights)")
        if w.shape[1] != model.n_inputs:
            raise ValueError(
                f"{f}: model made for another observation space ({w.shape[1]} inputs, this "
                f"environment and config.json give {model.n_inputs})"
            )
        try:
            model.load_state_dict(state)
        except Exception as e:  # noqa: BLE001
            raise ValueError(f"{f}: weights do not fit the architecture in config.json ({e})") from None
        model.eval()
        return cls(model, cfg, path, **kwargs)

    def reset(self, seeds: list[int]) -> None:
        self.n = len(seeds)
        self.h = None
        self.alarm = np.zeros(self.n, dtype=bool)
        self.feature_state = self.features.initial_state(self.n) if self.features is not None else None
        self.reference_beliefs: dict = {}  # the reference's belief per distinct set of diagnoses

    def act(self, obs: np.ndarray, infos: dict) -> np.ndarray:
        import torch

        x = _check_batch(obs, self.obs_size, self.where)
        if self.features is not None:  # unstandardised: the network standardises its inputs itself
            x = self.features.raw(x, self.feature_state)
        with torch.inference_mode():
            logits, self.h = self.model(torch.as_tensor(x[:, None, :]), self.h)
            p = torch.sigmoid(logits[:, 0]).numpy()
        self.alarm |= p[:, -1] >= self.alarm_threshold
        ref = infos.get("reference") if self.use_reference else None
        if ref is not None:
            detected = np.asarray(ref["detected"], dtype=bool)
            self.alarm |= detected
        alarmed = np.flatnonzero(self.alarm)
        declared = np.zeros((len(x), p.shape[1] - 1), dtype=bool)  # the faults each slot declares
        if self.conformal_quantile is None:
            declared[alarmed] = p[alarmed, :-1] >= self.isolation_threshold
        else:
            from .classifier import conformal_sets

            declared[alarmed] = conformal_sets(p[alarmed, :-1], self.isolation_threshold, self.conformal_quantile)
        if ref is not None:
            from marine_fdi_env.baselines.reference_agent import memoised_belief

            for i in alarmed[detected[alarmed]]:
                rb = memoised_belief(ref["diagnoses"][i], self.reference_beliefs)[:-2] >= 0.5
                if rb.any() and (self.use_reference == "first" or not declared[i].any()):
                    declared[i] = rb
        out = np.zeros((len(x), N_HYPOTHESES), dtype=np.float32)
        out[:, :-2][declared] = 1.0
        out[alarmed[~declared[alarmed].any(axis=1)], UNKNOWN] = 1.0
        return out
