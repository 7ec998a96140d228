"""Scoring declarations: the reward terms, declared sets, alarms and belief on the truth of one
decision of N slots.

The score of a declaration depends on the faults active at the decision time and, for
``MarineFDI-v1``, on the slot's earlier declarations (:class:`~.reward.RewardV1` keeps them); never
on the engine.  So the environments and the benchmark's shared-trajectory evaluation
(:mod:`marine_fdi_env.benchmark.lockstep`, which scores many agents on one simulation) use this one
scorer, and a slot's numbers do not depend on the other slots (every operation is per row).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..engine.faults import FAULT_IDS
from .hypotheses import DECLARE_THRESHOLD, N_FAULTS, UNKNOWN
from .reward import REWARD_TERMS, REWARD_TERMS_V1, RewardConfig, RewardConfigV1, RewardV1, score

__all__ = ["StepOutcome", "DecisionScorer", "row_members"]


def row_members(mask: np.ndarray) -> list[np.ndarray]:
    """The column indices of the True entries of each row of a 2-d bool mask, ascending."""
    rows, cols = np.nonzero(mask)
    counts = np.bincount(rows, minlength=len(mask))
    ends = np.cumsum(counts)
    return [cols[a:b] for a, b in zip((ends - counts).tolist(), ends.tolist())]


def declared_ids(decl: np.ndarray) -> list[tuple[str, ...]]:
    """The declared fault ids of each row of a (n, 26) bool mask, in :data:`FAULT_IDS` order."""
    out: list[tuple[str, ...]] = [()] * len(decl)
    rows, cols = np.nonzero(decl)
    if len(rows):
        ids: dict[int, list[str]] = {}
        for r, c in zip(rows.tolist(), cols.tolist()):
            ids.setdefault(r, []).append(FAULT_IDS[c])
        for r, names in ids.items():
            out[r] = tuple(names)
    return out


@dataclass
class StepOutcome:
    """Scores of one decision for every scored slot."""

    reward: np.ndarray  # (N,)
    terms: dict[str, np.ndarray]  # term -> (N,)
    declared: list[tuple[str, ...]]
    alarm: np.ndarray  # (N,) bool
    belief_on_truth: np.ndarray  # (N,) (NaN when no fault is active)


class DecisionScorer:
    """The reward of ``n`` slots (v0 is stateless; v1 keeps per-slot state between decisions)."""

    def __init__(self, reward: RewardConfig | RewardConfigV1 | None, n: int, decision_period_s: float) -> None:
        self.cfg = reward or RewardConfig()
        self.decision_period_s = float(decision_period_s)
        self.v1 = RewardV1(self.cfg, int(n)) if isinstance(self.cfg, RewardConfigV1) else None
        self.terms = REWARD_TERMS_V1 if self.v1 is not None else REWARD_TERMS

    def start(self, slot: int, faults) -> None:
        """A new episode with ``faults`` in ``slot``."""
        if self.v1 is not None:
            self.v1.start(slot, min((f.onset_s for f in faults), default=math.inf))

    def score(
        self,
        beliefs: np.ndarray,
        slots,
        active: np.ndarray,
        first_onset: np.ndarray,
        last_onset: np.ndarray,
        t: np.ndarray,
    ) -> StepOutcome:
        """Score the declarations ``beliefs`` (len(slots), 28) made at times ``t`` with the faults
        ``active`` ((len(slots), 26) bool; first and last onset of the active ones)."""
        slots = np.asarray(slots, dtype=np.int64)
        decl = beliefs[:, :N_FAULTS] >= DECLARE_THRESHOLD
        alarm = decl.any(axis=1) | (beliefs[:, UNKNOWN] >= DECLARE_THRESHOLD)
        if self.v1 is None:
            terms = score(self.cfg, decl, alarm, active, first_onset, last_onset, t)
        else:
            terms = self.v1.score(slots, decl, alarm, active, t, self.decision_period_s)
        reward = sum(terms[k] for k in self.terms)
        total = beliefs.sum(axis=1, dtype=np.float64)
        on_truth = np.where(active, beliefs[:, :N_FAULTS], 0.0).sum(axis=1, dtype=np.float64)
        with np.errstate(invalid="ignore", divide="ignore"):
            share = np.where(total > 0, on_truth / total, 0.0)
        share = np.where(active.any(axis=1), share, np.nan)
        declared = declared_ids(decl)
        return StepOutcome(reward, terms, declared, alarm, share)

    def end_terms(self, outcome: StepOutcome, slots, ended) -> None:
        """Add the one-off end-of-episode terms (v1: ``missed_detection``, ``final_isolation``) of the
        ``ended`` slots to ``outcome`` (scored over ``slots``); nothing for v0."""
        if self.v1 is None or not len(ended):
            return
        pos = {int(s): j for j, s in enumerate(np.asarray(slots))}
        rows = np.array([pos[int(s)] for s in ended], dtype=np.int64)
        for k, extra in self.v1.end(np.asarray(ended, dtype=np.int64)).items():
            outcome.terms[k][rows] += extra
            outcome.reward[rows] += extra
