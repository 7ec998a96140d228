"""The action of ``MarineFDI-v0``: a fault-hypothesis declaration.

The action is a belief vector ``b`` over 28 hypotheses: the 26 fault ids of
:data:`marine_fdi_env.engine.faults.FAULT_IDS` (19 sensor faults ``S1.1`` ... ``S4.6``, then the 7 process
faults), then ``no_fault``, then ``unknown``.  Each entry lies in [0, 1].

* The **declared set** is the fault ids with ``b >= 0.5`` (several may be declared at once: a
  multiple-fault diagnosis).
* The agent raises an **alarm** when it declares any fault id or ``unknown`` (``b >= 0.5``):
  "a fault is present, I cannot (yet) say which".  ``no_fault`` is informational; declaring it
  together with a fault is allowed and the fault wins.
* The **share of belief on the truth** is ``sum(b[true ids]) / sum(b)`` (0 when ``sum(b) = 0``).
"""

from __future__ import annotations

import numpy as np

from ..engine.faults import FAULT_IDS

__all__ = ["HYPOTHESES", "N_HYPOTHESES", "NO_FAULT", "UNKNOWN", "DECLARE_THRESHOLD", "check_action", "one_hot"]

HYPOTHESES: tuple[str, ...] = FAULT_IDS + ("no_fault", "unknown")
N_HYPOTHESES = len(HYPOTHESES)
NO_FAULT = HYPOTHESES.index("no_fault")
UNKNOWN = HYPOTHESES.index("unknown")
N_FAULTS = len(FAULT_IDS)
DECLARE_THRESHOLD = 0.5
_INDEX = {h: i for i, h in enumerate(HYPOTHESES)}


def check_action(action, n_envs: int | None = None) -> np.ndarray:
    """The action as a float32 array (28,) (or (n_envs, 28)); ``ValueError`` naming what is wrong."""
    shape = (N_HYPOTHESES,) if n_envs is None else (n_envs, N_HYPOTHESES)
    try:
        a = np.asarray(action)
    except ValueError:  # ragged nested sequences
        raise ValueError(f"action must be a numeric array of shape {shape}, got a ragged sequence") from None
    if a.dtype.kind not in "biuf":
        raise ValueError(f"action must be a numeric array of shape {shape}, got dtype {a.dtype}")
    if a.shape != shape:
        raise ValueError(
            f"action must have shape {shape} (belief over {', '.join(HYPOTHESES[:2])}, ..., "
            f"no_fault, unknown), got {a.shape}"
        )
    with np.errstate(over="ignore"):  # beyond the float32 range: inf, refused below
        a = a.astype(np.float32)
    if not np.all(np.isfinite(a)):
        raise ValueError("action must be finite (a belief in [0, 1] per hypothesis)")
    if np.any(a < 0.0) or np.any(a > 1.0):
        raise ValueError("action entries must lie in [0, 1] (a belief per hypothesis)")
    return a


def one_hot(hypotheses) -> np.ndarray:
    """Belief 1 on the given hypotheses (fault ids, ``no_fault`` or ``unknown``), 0 elsewhere."""
    b = np.zeros(N_HYPOTHESES, dtype=np.float32)
    for h in hypotheses:
        if h not in _INDEX:
            raise ValueError(f"unknown hypothesis {h!r}; allowed: {', '.join(HYPOTHESES)}")
        b[_INDEX[h]] = 1.0
    return b
