"""Message budgets: what a local agent may send to the global agent per decision period.

A budget gives each module of a local's subsystem ``per_module`` entries per decision, each a bit
(``kind="bits"``) or a float32 number (``kind="numbers"``, within ±:data:`MESSAGE_BOUND`, the
observation's own bound on a log-compressed ratio).  Everything a local sends counts: decisions,
residual summaries, beliefs.  The named budgets span the axis of the multi-agent track:

=============  ======  ==========  ============================================  ===============
budget         kind    per module  what fits (e.g.)                              bits / decision
=============  ======  ==========  ============================================  ===============
``decision``   bits    1           the thesis's decision vector D^(l) (eq. 5.19)  19
``scalar``     numbers 1           one number per module (its running peak        608
                                   ratio, a learned summary)
``features``   numbers 6           the module's six observation features          3648
=============  ======  ==========  ============================================  ===============

(19 modules in all: 2, 6, 5 and 6 per subsystem.)  A :class:`MessageBudget` of another size is
accepted everywhere a name is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from gymnasium import spaces

from ..diagnosis.modules import MODULE_IDS
from ..envs.observation import RATIO_CAP
from .roles import LOCAL_AGENTS, local_modules

__all__ = ["MessageBudget", "BUDGETS", "MESSAGE_BOUND", "get_budget"]

MESSAGE_BOUND = float(np.float32(math.log1p(RATIO_CAP)))  # [-]: the observation's bound on log(1 + ratio)
KINDS = ("bits", "numbers")


@dataclass(frozen=True)
class MessageBudget:
    """What each local sends per decision (module docstring).

    name : the budget's name.  kind : ``bits`` (entries 0 or 1) or ``numbers`` (float32 within
    ±MESSAGE_BOUND).  per_module : entries per module of the local's subsystem [1/decision].
    """

    name: str
    kind: str
    per_module: int

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"message budget kind must be one of {', '.join(KINDS)}, got {self.kind!r}")
        if isinstance(self.per_module, bool) or not isinstance(self.per_module, int) or self.per_module < 1:
            raise ValueError(f"message budget per_module must be a positive integer, got {self.per_module!r}")

    @property
    def bits_per_entry(self) -> int:
        return 1 if self.kind == "bits" else 32

    def size(self, agent: str) -> int:
        """Entries a local agent sends per decision."""
        return self.per_module * len(local_modules(agent))

    @property
    def total_size(self) -> int:
        """Entries all locals send per decision (the global agent's observation)."""
        return self.per_module * len(MODULE_IDS)

    @property
    def bits_per_decision(self) -> int:
        """Bits all locals send per decision period [bit]."""
        return self.total_size * self.bits_per_entry

    def space(self, agent: str) -> spaces.Space:
        """A local agent's action space: its message."""
        n = self.size(agent)
        if self.kind == "bits":
            return spaces.MultiBinary(n)
        return spaces.Box(-MESSAGE_BOUND, MESSAGE_BOUND, (n,), dtype=np.float32)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(low, high) of the concatenated messages of every local, float32 (the global's observation)."""
        lo = 0.0 if self.kind == "bits" else -MESSAGE_BOUND
        hi = 1.0 if self.kind == "bits" else MESSAGE_BOUND
        return np.full(self.total_size, lo, np.float32), np.full(self.total_size, hi, np.float32)

    def check(self, agent: str, message, n: int) -> np.ndarray:
        """A batch of messages (n, size) of ``agent`` as float32; ``ValueError`` naming what breaks the budget."""
        shape = (n, self.size(agent))
        try:
            m = np.asarray(message)
        except ValueError:
            raise ValueError(f"{agent}: message must be a numeric array of shape {shape[1:]}") from None
        if m.dtype.kind not in "biuf" or m.size != shape[0] * shape[1]:
            raise ValueError(
                f"{agent}: message must be {shape[1]} numbers per decision ({self.per_module} per module, "
                f"budget {self.name!r}), got {m.shape} of dtype {m.dtype}"
            )
        with np.errstate(over="ignore"):
            m = m.reshape(shape).astype(np.float32)
        if self.kind == "bits":
            if not np.all((m == 0.0) | (m == 1.0)):
                raise ValueError(f"{agent}: budget {self.name!r} sends bits: every entry must be 0 or 1")
        elif not np.all(np.isfinite(m)) or np.any(np.abs(m) > MESSAGE_BOUND):
            raise ValueError(f"{agent}: budget {self.name!r} sends finite numbers within ±{MESSAGE_BOUND:.4f}")
        return m

    def to_dict(self) -> dict:
        return {"name": self.name, "kind": self.kind, "per_module": self.per_module}


BUDGETS: dict[str, MessageBudget] = {
    "decision": MessageBudget("decision", "bits", 1),
    "scalar": MessageBudget("scalar", "numbers", 1),
    "features": MessageBudget("features", "numbers", 6),
}


def get_budget(budget: "str | MessageBudget | dict") -> MessageBudget:
    """A budget from its name, a :class:`MessageBudget` or its dict."""
    if isinstance(budget, MessageBudget):
        return budget
    if isinstance(budget, dict):
        return MessageBudget(str(budget.get("name", "custom")), budget.get("kind"), budget.get("per_module"))
    if budget not in BUDGETS:
        raise ValueError(f"message_budget must be one of {', '.join(BUDGETS)} or a MessageBudget, got {budget!r}")
    return BUDGETS[budget]


def _check_locals() -> None:
    assert sum(len(local_modules(a)) for a in LOCAL_AGENTS) == len(MODULE_IDS)


_check_locals()
