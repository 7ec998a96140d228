"""A candidate combination scored against the current model of a selection step (:mod:`.selection`, step 4 of
its docstring): the cross-validated score, the penalised score ``S exp(2 k / M)``, the gain and the F-test of the
drop per added parameter."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy import stats

from ..fit.fitting import Combination, FitResult, cell_losses
from ..fit.problem import FitProblem

__all__ = ["CandidateScore", "f_test_p", "paired_p", "finite_or_none"]


@dataclass
class CandidateScore:
    """A candidate combination scored against the current model of its greedy step.

    in_sample_score : mean robust loss per cell of the full-data fit.  cv_score : the same for the
    cross-validated predictions (NaN when the candidate was screened out, see ``screened``).
    """

    combination: Combination
    added: str
    fit: FitResult
    in_sample_score: float
    cv_pred: np.ndarray | None = None
    cv_score: float = math.nan
    penalised: float = math.nan
    gain: float = math.nan
    p_value: float = math.nan
    p_value_points: float = math.nan
    point_losses: np.ndarray | None = None
    screened: str = ""
    folds: list | None = None
    notes: list[str] = field(default_factory=list)
    #: for a pair of mechanisms added together: the two single candidates of the same step
    members: tuple | None = None

    @property
    def cross_validated(self) -> bool:
        return self.cv_pred is not None

    def score(
        self,
        problem: FitProblem,
        pred: np.ndarray,
        folds,
        M: int,
        penalty: float,
        current_S: float,
        current_k: int,
        current_L: np.ndarray | None = None,
        rows: np.ndarray | None = None,
    ) -> None:
        """Record the cross-validated predictions ``pred`` (and fold fits): score, penalised score, gain and F-test
        against the current model (score ``current_S``, ``current_k`` parameters), the paired test over ``rows``
        when the current model's point losses ``current_L`` are given."""
        L, _ = cell_losses(problem, pred)
        self.folds, self.cv_pred, self.point_losses = folds, pred, L
        self.cv_score = float(L.sum() / M)
        self.penalised = self.cv_score * math.exp(penalty * self.fit.k / M)
        self.gain = (current_S - self.cv_score) / current_S if current_S > 0 else 0.0
        self.p_value = f_test_p(current_S, self.cv_score, current_k, self.fit.k, M)
        if current_L is not None:
            self.p_value_points = paired_p(current_L, L, rows)

    def as_dict(self) -> dict[str, Any]:
        d = {
            "mechanism": self.added,
            "id": self.combination.mechanisms[-1].id,
            "combination": list(self.combination.labels),
            "n_params": self.fit.k,
            "in_sample_score": self.in_sample_score,
            "cv_score": finite_or_none(self.cv_score),
            "penalised_score": finite_or_none(self.penalised),
            "gain_vs_current": finite_or_none(self.gain),
            "p_value": finite_or_none(self.p_value),
            "p_value_points": finite_or_none(self.p_value_points),
            "fit": self.fit.values(),
            "fit_stderr": dict(zip(self.combination.names, map(float, self.fit.stderr))),
            "nuisance": self.fit.nuisance_values(),
        }
        if self.combination.valves:
            d["openings"] = {
                k: [None if not math.isfinite(x) else float(x) for x in v] for k, v in self.fit.openings.items()
            }
        if self.screened:
            d["screened"] = self.screened
        if self.notes:
            d["notes"] = list(self.notes)
        return d


def finite_or_none(x: float) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


def f_test_p(S_current: float, S_cand: float, k_current: int, k_cand: int, M: int) -> float:
    """One-sided F-test of the drop of the cross-validated loss per added parameter against the
    candidate's loss per residual degree of freedom (the likelihood-ratio test of nested least squares,
    on cross-validated residuals)."""
    dk = max(k_cand - k_current, 1)
    dof = max(M - k_cand, 1)
    if S_cand <= 0:
        return 0.0 if S_current > 0 else 1.0
    F = ((S_current - S_cand) * M / dk) / (S_cand * M / dof)
    return float(stats.f.sf(F, dk, dof)) if F > 0 else 1.0


def paired_p(current: np.ndarray, cand: np.ndarray, rows: np.ndarray) -> float:
    d = current[rows] - cand[rows]
    if d.size < 2 or np.allclose(d, d[0]):
        return 0.0 if d.size and d[0] > 0 and d.size >= 2 else 1.0
    return float(stats.ttest_1samp(d, 0.0, alternative="greater").pvalue)
