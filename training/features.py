"""The reinforcement-learning agent's own input preprocessing (computed from the observations alone).

:class:`AgentFeatures` turns the environment's per-decision observation (115 residual features)
into the policy's input, causally and per episode:

1. features listed in ``drop`` are removed (by default the episode clock ``time_fraction``: with
   it a policy learns "late in an episode there usually is a fault", see the classifier);
2. exponentially weighted moving averages of the ``ewma_features`` (the 19 signed residual means)
   with time constants ``taus`` [decisions] are appended, started at 0 at each episode start:
   the agent's accumulation of a small persistent residual bias (as :class:`marine_fdi_env.training.classifier.GRUDiagnoser`);
3. with ``previous_alarm``, whether the agent's own previous declaration raised the alarm (0 at
   an episode start): the agent knows what it declared, and MarineFDI-v1 charges a false alarm
   when the alarm *rises*, so the value of raising it depends on it;
4. everything is standardised with a fixed mean and scale (measured once on the training
   episodes, stored with the model) and clipped to +-10.

The same object runs in training (:mod:`marine_fdi_env.training.replay`, :mod:`marine_fdi_env.training.vec_adapter`) and in
the evaluated agent (:class:`marine_fdi_env.training.agents.SB3Agent`), so both see identical inputs.
"""

from __future__ import annotations

import numpy as np

__all__ = ["AgentFeatures"]

CLIP = 10.0


class AgentFeatures:
    """Observation -> policy input (module docstring); state per slot: EWMAs and previous alarm."""

    def __init__(self, feature_names: list[str], drop=("time_fraction",), ewma_features=("signed_mean_ratio",),
                 taus=(5.0, 20.0, 60.0), previous_alarm: bool = True, mean=None, scale=None) -> None:
        names = list(feature_names)
        unknown = [d for d in drop if d not in names]
        if unknown:
            raise ValueError(f"features to drop {unknown} are not observation features")
        self.feature_names = names
        self.drop = tuple(drop)
        self.keep = np.array([i for i, n in enumerate(names) if n not in self.drop], dtype=np.int64)
        self.ewma_features = tuple(ewma_features)
        self.ewma_idx = np.array([i for i, n in enumerate(names) if any(n.endswith("." + f) for f in ewma_features)],
                                 dtype=np.int64)
        self.taus = tuple(float(t) for t in taus) if len(self.ewma_idx) else ()
        # tau-major, as GRUDiagnoser.augment: [all features at tau 0, all at tau 1, ...]
        self.alpha = np.repeat(np.array([1.0 / t for t in self.taus], dtype=np.float32), len(self.ewma_idx))
        self.previous_alarm = bool(previous_alarm)
        self.size = len(self.keep) + len(self.alpha) + int(self.previous_alarm)
        self.mean = np.zeros(self.size, np.float32) if mean is None else np.asarray(mean, np.float32)
        self.scale = np.ones(self.size, np.float32) if scale is None else np.asarray(scale, np.float32)
        if self.mean.shape != (self.size,) or self.scale.shape != (self.size,):
            raise ValueError(f"feature standardisation must have {self.size} entries, got {self.mean.shape}, "
                             f"{self.scale.shape}")

    # ------------------------------------------------------------------ state
    def initial_state(self, n: int) -> dict:
        return {"ewma": np.zeros((n, len(self.alpha)), np.float32), "alarm": np.zeros(n, np.float32)}

    def restart(self, state: dict, slots) -> None:
        """Slots that start a new episode."""
        state["ewma"][slots] = 0.0
        state["alarm"][slots] = 0.0

    def set_alarm(self, state: dict, alarm: np.ndarray) -> None:
        """Record the alarm flag of the declarations just made."""
        state["alarm"][:] = np.asarray(alarm, np.float32)

    # ------------------------------------------------------------------ transform
    def raw(self, obs: np.ndarray, state: dict, update: bool = True) -> np.ndarray:
        """Unstandardised inputs for observations (n, D); advances the EWMAs (unless ``update`` is
        False: a terminal observation's inputs without touching the state)."""
        obs = np.asarray(obs, np.float32)
        parts = [obs[:, self.keep]]
        if len(self.alpha):
            src = np.tile(obs[:, self.ewma_idx], (1, len(self.taus)))
            ewma = state["ewma"] + self.alpha * (src - state["ewma"])
            if update:
                state["ewma"] = ewma
            parts.append(ewma)
        if self.previous_alarm:
            parts.append(state["alarm"][:, None])
        return np.concatenate(parts, axis=1).astype(np.float32)

    def standardise(self, x: np.ndarray) -> np.ndarray:
        return np.clip((x - self.mean) / self.scale, -CLIP, CLIP).astype(np.float32)

    def __call__(self, obs: np.ndarray, state: dict, update: bool = True) -> np.ndarray:
        return self.standardise(self.raw(obs, state, update))

    def fit(self, episodes: np.ndarray, valid: np.ndarray, alarm_share: float = 0.5) -> "AgentFeatures":
        """Set the standardisation from whole training episodes (E, T, D) (``valid`` (E, T)); the
        previous-alarm input is a 0/1 flag, scaled as a Bernoulli(``alarm_share``)."""
        E, T, _ = episodes.shape
        state = self.initial_state(E)
        rows = []
        for k in range(T):
            x = self.raw(episodes[:, k], state)
            rows.append(x[valid[:, k]])
        flat = np.concatenate(rows).astype(np.float64)
        self.mean = flat.mean(0).astype(np.float32)
        self.scale = np.maximum(flat.std(0), 1e-3).astype(np.float32)
        if self.previous_alarm:
            self.mean[-1] = alarm_share
            self.scale[-1] = float(np.sqrt(alarm_share * (1 - alarm_share)))
        return self

    # ------------------------------------------------------------------ storage
    def to_dict(self) -> dict:
        return {"drop": list(self.drop), "ewma_features": list(self.ewma_features), "taus": list(self.taus),
                "previous_alarm": self.previous_alarm, "mean": [float(x) for x in self.mean],
                "scale": [float(x) for x in self.scale]}

    @classmethod
    def from_dict(cls, d: dict, feature_names: list[str]) -> "AgentFeatures":
        return cls(feature_names, drop=d["drop"], ewma_features=d["ewma_features"], taus=d["taus"],
                   previous_alarm=d["previous_alarm"], mean=d["mean"], scale=d["scale"])
