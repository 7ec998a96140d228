"""The learned agents' own input preprocessing (computed from the observations alone).

:class:`AgentFeatures` turns the environment's per-decision observation (115 residual features)
into a learned agent's input, causally and per episode.  Two kinds of per-decision base features:

* ``noise_window = 0`` (the v1 agents): the observation features, less those listed in ``drop``
  (by default the episode clock ``time_fraction``: with it a policy learns "late in an episode
  there usually is a fault");
* ``noise_window = W > 0`` (the noise-invariant agents): per monitoring module, the period's
  signed mean, mean and maximum of ``r / thr`` (the observation's ``signed_mean_ratio``,
  ``log_mean_ratio``, ``log_max_ratio`` with their log undone) divided by the module's *noise
  level* ``sigma_m``: the mean of ``mean |r / thr|`` over the episode's first ``W`` decisions
  (the running mean until then), then frozen.  Every residual's noise scales with the sensors'
  noise, so a residual dominated by noise gives the same inputs at any sensor-noise level: a
  quieter sensor no longer looks different from the training data, and a noisier one no longer
  looks like a fault.  The threshold-bound features (``violation_fraction``, ``fired``,
  ``since_first_violation``: worst-case thresholds fixed for the nominal noise) and the clock are
  not used.  Inputs per module: ``slog(mean / sigma)``, ``log1p(mean|.| / sigma)``,
  ``log1p(max|.| / sigma)`` with ``slog(v) = sign(v) log1p(|v|)``.  It assumes the episode starts
  fault-free for ``W`` decisions (every suite's first onset is at 5 s or later; ``W = 4``).

Then, for both kinds:

1. exponentially weighted moving averages of the ``ewma_features`` (the signed means) with time
   constants ``taus`` [decisions] are appended, started at 0 at each episode start: the agent's
   accumulation of a small persistent residual bias;
2. with ``previous_alarm``, whether the agent's own previous declaration raised the alarm (0 at
   an episode start): MarineFDI-v1 charges a false alarm when the alarm *rises*;
3. everything is standardised with a fixed mean and scale (measured once on the training
   episodes, stored with the model) and clipped to +-10.

The same object runs in training (:mod:`marine_fdi_env.training.replay`, the classifier's data)
and in the evaluated agent (:mod:`marine_fdi_env.training.agents`), so both see identical inputs.
"""

from __future__ import annotations

import numpy as np

__all__ = ["AgentFeatures", "transform_episodes", "INVARIANT_FEATURES"]

CLIP = 10.0
# per module, the noise-invariant inputs (noise_window > 0); the first is the signed one the EWMAs accumulate
INVARIANT_FEATURES = ("signed_mean_over_noise", "mean_over_noise", "max_over_noise")
_SOURCES = ("signed_mean_ratio", "log_mean_ratio", "log_max_ratio")


def _slog(v: np.ndarray) -> np.ndarray:
    return np.sign(v) * np.log1p(np.abs(v))


class AgentFeatures:
    """Observation -> learned agent input (module docstring); state per slot: noise levels, EWMAs,
    previous alarm."""

    def __init__(
        self,
        feature_names: list[str],
        drop=("time_fraction",),
        ewma_features=("signed_mean_ratio",),
        taus=(5.0, 20.0, 60.0),
        previous_alarm: bool = True,
        noise_window: int = 0,
        mean=None,
        scale=None,
    ) -> None:
        names = list(feature_names)
        unknown = [d for d in drop if d not in names]
        if unknown:
            raise ValueError(f"features to drop {unknown} are not observation features")
        if not isinstance(noise_window, int) or isinstance(noise_window, bool) or noise_window < 0:
            raise ValueError(f"noise_window must be an integer >= 0 (decisions), got {noise_window!r}")
        self.feature_names = names
        self.drop = tuple(drop)
        self.noise_window = int(noise_window)
        self.ewma_features = tuple(ewma_features)
        if self.noise_window:
            modules = list(dict.fromkeys(n.rsplit(".", 1)[0] for n in names if n.endswith("." + _SOURCES[0])))
            self.modules = modules
            self.src_idx = np.array([[names.index(f"{m}.{s}") for s in _SOURCES] for m in modules], dtype=np.int64)
            self.keep = np.zeros(0, dtype=np.int64)
            n_base = len(INVARIANT_FEATURES) * len(modules)
            n_ewma_src = len(modules) if self.ewma_features else 0
        else:
            self.modules = []
            self.keep = np.array([i for i, n in enumerate(names) if n not in self.drop], dtype=np.int64)
            self.ewma_idx = np.array(
                [i for i, n in enumerate(names) if any(n.endswith("." + f) for f in ewma_features)], dtype=np.int64
            )
            n_base = len(self.keep)
            n_ewma_src = len(self.ewma_idx)
        self.taus = tuple(float(t) for t in taus) if n_ewma_src else ()
        # tau-major, as GRUDiagnoser.augment: [all features at tau 0, all at tau 1, ...]
        self.alpha = np.repeat(np.array([1.0 / t for t in self.taus], dtype=np.float32), n_ewma_src)
        self.previous_alarm = bool(previous_alarm)
        self.size = n_base + len(self.alpha) + int(self.previous_alarm)
        self.mean = np.zeros(self.size, np.float32) if mean is None else np.asarray(mean, np.float32)
        self.scale = np.ones(self.size, np.float32) if scale is None else np.asarray(scale, np.float32)
        if self.mean.shape != (self.size,) or self.scale.shape != (self.size,):
            raise ValueError(
                f"feature standardisation must have {self.size} entries, got {self.mean.shape}, {self.scale.shape}"
            )

    def input_names(self) -> list[str]:
        """The name of every input, in order."""
        if self.noise_window:
            base = [f"{m}.{f}" for f in INVARIANT_FEATURES for m in self.modules]
            src = [f"{m}.{INVARIANT_FEATURES[0]}" for m in self.modules]
        else:
            base = [self.feature_names[i] for i in self.keep]
            src = [self.feature_names[i] for i in self.ewma_idx]
        ewma = [f"ewma{t:g}({s})" for t in self.taus for s in src]
        return base + ewma + (["previous_alarm"] if self.previous_alarm else [])

    # ------------------------------------------------------------------ state
    def initial_state(self, n: int) -> dict:
        return {
            "ewma": np.zeros((n, len(self.alpha)), np.float32),
            "alarm": np.zeros(n, np.float32),
            "noise_sum": np.zeros((n, len(self.modules)), np.float64),
            "noise_n": np.zeros(n, np.int64),
        }

    def restart(self, state: dict, slots) -> None:
        """Slots that start a new episode."""
        for k in ("ewma", "alarm", "noise_sum", "noise_n"):
            state[k][slots] = 0

    def set_alarm(self, state: dict, alarm: np.ndarray) -> None:
        """Record the alarm flag of the declarations just made."""
        state["alarm"][:] = np.asarray(alarm, np.float32)

    # ------------------------------------------------------------------ transform
    def _invariant(self, obs: np.ndarray, state: dict, update: bool) -> tuple[np.ndarray, np.ndarray]:
        """(base inputs, EWMA source) of the noise-invariant kind; advances the noise level."""
        raw = obs[:, self.src_idx].astype(np.float64)  # (n, modules, 3): signed, mean, max (log scale)
        signed = np.sign(raw[..., 0]) * np.expm1(np.abs(raw[..., 0]))
        mean, peak = np.expm1(raw[..., 1]), np.expm1(raw[..., 2])
        learning = state["noise_n"] < self.noise_window
        total = state["noise_sum"] + np.where(learning[:, None], mean, 0.0)
        count = state["noise_n"] + learning
        if update:
            state["noise_sum"], state["noise_n"] = total, count
        sigma = np.maximum(total / np.maximum(count, 1)[:, None], 1e-6)
        z = signed / sigma
        base = np.concatenate([_slog(z), np.log1p(mean / sigma), np.log1p(peak / sigma)], axis=1)
        return base.astype(np.float32), _slog(z).astype(np.float32)

    def raw(self, obs: np.ndarray, state: dict, update: bool = True) -> np.ndarray:
        """Unstandardised inputs for observations (n, D); advances the state (unless ``update`` is
        False: a terminal observation's inputs without touching the state)."""
        obs = np.asarray(obs, np.float32)
        if self.noise_window:
            base, src = self._invariant(obs, state, update)
        else:
            base, src = obs[:, self.keep], obs[:, self.ewma_idx]
        parts = [base]
        if len(self.alpha):
            src = np.tile(src, (1, len(self.taus)))
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
        x = transform_episodes(self, episodes)
        flat = x[valid].astype(np.float64)
        self.mean = flat.mean(0).astype(np.float32)
        self.scale = np.maximum(flat.std(0), 1e-3).astype(np.float32)
        if self.previous_alarm:
            self.mean[-1] = alarm_share
            self.scale[-1] = float(np.sqrt(alarm_share * (1 - alarm_share)))
        return self

    # ------------------------------------------------------------------ storage
    def to_dict(self) -> dict:
        return {
            "drop": list(self.drop),
            "ewma_features": list(self.ewma_features),
            "taus": list(self.taus),
            "previous_alarm": self.previous_alarm,
            "noise_window": self.noise_window,
            "mean": [float(x) for x in self.mean],
            "scale": [float(x) for x in self.scale],
        }

    @classmethod
    def from_dict(cls, d: dict, feature_names: list[str]) -> "AgentFeatures":
        return cls(
            feature_names,
            drop=d["drop"],
            ewma_features=d["ewma_features"],
            taus=d["taus"],
            previous_alarm=d["previous_alarm"],
            noise_window=int(d.get("noise_window", 0)),
            mean=d["mean"],
            scale=d["scale"],
        )


def transform_episodes(features: AgentFeatures, episodes: np.ndarray, batch: int = 1024) -> np.ndarray:
    """Unstandardised inputs (E, T, size) of whole episodes (E, T, D), causally per episode (the
    previous-alarm input is 0: a quiet agent)."""
    E, T, _ = episodes.shape
    out = np.empty((E, T, features.size), np.float32)
    for s in range(0, E, batch):
        state = features.initial_state(min(batch, E - s))
        for k in range(T):
            out[s : s + batch, k] = features.raw(episodes[s : s + batch, k], state)
    return out
