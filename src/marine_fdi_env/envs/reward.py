"""Reward of ``MarineFDI-v0``: early, correct, quiet diagnosis.

At every decision time t the declaration (see :mod:`.hypotheses`) is scored against the faults
active at t (onset <= t < end).  With ``T`` the true set, ``D`` the declared fault ids, ``A`` the
alarm flag, ``d1 = t - first onset`` and ``dT = t - last onset`` of the active faults:

=================  ============================================  ===========================
term               when                                          value (defaults)
=================  ============================================  ===========================
false_alarm        A and T = ∅                                   -1.0
missed             not A and T ≠ ∅                               -0.02
detection          A and T ≠ ∅                                   +0.5 exp(-d1 / 30 s)
isolation          D = T ≠ ∅                                     +1.0 exp(-dT / 30 s)
wrong_isolation    D ≠ ∅ and D ≠ T                               -0.25
=================  ============================================  ===========================

Summed over the decisions of an episode, the detection and isolation terms pay about
``w τ exp(-delay / τ) / period``: the earlier the correct declaration, the larger the return,
and a declaration that is never made pays nothing.  A false alarm costs far more per decision
than any single correct step pays, so quiet agents are not out-scored by trigger-happy ones
(an agent that always alarms loses ~1 per fault-free decision).  Every term is reported in
``info["reward_terms"]``; the weights are a :class:`RewardConfig`.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

__all__ = ["RewardConfig", "REWARD_TERMS", "score"]

REWARD_TERMS = ("false_alarm", "missed", "detection", "isolation", "wrong_isolation")


@dataclass(frozen=True)
class RewardConfig:
    """Weights of the reward terms (per decision) and the delay time constant tau_s [s]."""

    false_alarm: float = 1.0
    missed: float = 0.02
    detection: float = 0.5
    isolation: float = 1.0
    wrong_isolation: float = 0.25
    tau_s: float = 30.0

    def __post_init__(self) -> None:
        for k, v in asdict(self).items():
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise ValueError(f"reward config field {k!r} must be a finite number >= 0, got {v!r}")
        if self.tau_s <= 0:
            raise ValueError(f"reward config field 'tau_s' must be > 0, got {self.tau_s!r}")


def score(cfg: RewardConfig, declared: np.ndarray, alarm: np.ndarray, active: np.ndarray, first_onset: np.ndarray,
          last_onset: np.ndarray, t: np.ndarray) -> dict[str, np.ndarray]:
    """Reward terms of n decisions (arrays over decisions).

    declared, active : (n, 26) bool masks of the declared and the active fault ids;
    alarm : (n,) bool; first_onset, last_onset : (n,) onsets of the active faults [s] (any value
    where none is active); t : (n,) decision times [s].
    """
    any_active = active.any(axis=1)
    exact = any_active & np.all(declared == active, axis=1)
    wrong = declared.any(axis=1) & ~np.all(declared == active, axis=1)
    zero = np.zeros(len(t))
    with np.errstate(over="ignore"):
        det = cfg.detection * np.exp(-(t - first_onset) / cfg.tau_s)
        iso = cfg.isolation * np.exp(-(t - last_onset) / cfg.tau_s)
    return {
        "false_alarm": np.where(alarm & ~any_active, -cfg.false_alarm, zero),
        "missed": np.where(~alarm & any_active, -cfg.missed, zero),
        "detection": np.where(alarm & any_active, det, zero),
        "isolation": np.where(exact, iso, zero),
        "wrong_isolation": np.where(wrong, -cfg.wrong_isolation, zero),
    }
