"""The rules by which the selection names causes, in one object: ``marine-fdi validate``, the replicas and the
open-world study configure :func:`~.selection.select_causes` through :class:`SelectionRules` alone."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from ..fit.problem import HELD_OUT_VALVES
from .evidence import BESIDE_VALVE, BESIDE_VALVE_DEFAULT
from .unexplained import ALPHA_UNEXPLAINED

__all__ = ["SelectionRules", "RuleError"]


class RuleError(ValueError):
    """A selection rule outside what it allows: ``rule`` names the field, ``requirement`` says what is allowed and
    what was given (the message is both); a command line names its option instead (``--max-causes``)."""

    def __init__(self, rule: str, requirement: str):
        self.rule, self.requirement = rule, requirement
        super().__init__(f"{rule} {requirement}")


@dataclass(frozen=True)
class SelectionRules:
    """How :func:`~.selection.select_causes` names causes (defaults: the pipeline's rules).

    max_causes : most mechanisms combined.  alpha : significance level of a named cause (Bonferroni over a step's
    candidates).  alpha_unexplained : family-wise level of what is reported as unexplained.  min_gain : least
    relative drop of the score a cause must bring (fraction).  penalty : the score is penalised by
    ``exp(penalty k / M)`` for k free parameters over M measured cells.  cv_all : cross-validate every candidate,
    not only those that can still win.  max_folds : at most this many cross-validation folds for single-engine data
    (None: leave one point out).  pairs : also try pairs of physical mechanisms at each step.  prune : the final
    removal step.  exchange : the exchange of a named physical cause for a sensor calibration.  beside_valve : how a
    cause joining a model with a valve earns its place (:data:`~.evidence.BESIDE_VALVE`).  held_out_valves : how
    cross-validation predicts a valve's opening at a left-out point (:data:`~.fit.problem.HELD_OUT_VALVES`; the
    :class:`~.fit.problem.FitProblem` is built with it).
    """

    max_causes: int = 4
    alpha: float = 0.01
    alpha_unexplained: float = ALPHA_UNEXPLAINED
    min_gain: float = 0.10
    penalty: float = 2.0
    cv_all: bool = False
    max_folds: int | None = None
    pairs: bool = True
    prune: bool = True
    exchange: bool = True
    beside_valve: str = BESIDE_VALVE_DEFAULT
    held_out_valves: str = "schedule"

    def __post_init__(self) -> None:
        """Every rule checked here, once: a :class:`RuleError` names the first one out of its range."""
        if self.beside_valve not in BESIDE_VALVE:
            raise RuleError("beside_valve", f"must be one of {', '.join(BESIDE_VALVE)}, got {self.beside_valve!r}")
        if self.held_out_valves not in HELD_OUT_VALVES:
            raise RuleError(
                "held_out_valves", f"must be one of {', '.join(HELD_OUT_VALVES)}, got {self.held_out_valves!r}"
            )
        if self.max_causes < 0:
            raise RuleError("max_causes", f"must be >= 0, got {self.max_causes}")
        for name in ("alpha", "alpha_unexplained"):
            if not 0.0 < getattr(self, name) < 1.0:
                raise RuleError(name, f"must lie in (0, 1), got {getattr(self, name)}")
        if self.max_folds is not None and self.max_folds < 2:
            raise RuleError("max_folds", f"must be >= 2 (unset: leave one point out), got {self.max_folds}")

    def replace(self, **changes: Any) -> SelectionRules:
        """A copy with ``changes`` (checked like the constructor's arguments)."""
        unknown = set(changes) - {f.name for f in dataclasses.fields(self)}
        if unknown:
            raise TypeError(f"unknown selection rule(s): {', '.join(sorted(unknown))}")
        return dataclasses.replace(self, **changes)
