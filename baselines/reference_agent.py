"""The reference diagnoser (thesis scheme) as a benchmark agent.

The environment already runs the reference diagnoser to make its observations, and reports its
conclusion in ``info["reference"]`` (detected, minimal diagnoses); this agent turns that into a
declaration:

* not detected: nothing declared;
* it keeps the minimal diagnoses of smallest cardinality (the usual preference of
  consistency-based diagnosis: one fault is likelier than two at once);
* one such diagnosis D: belief 1 on every fault of D (its exact multiple-fault diagnosis);
* several: belief on each fault = share of the minimal diagnoses containing it, except that a
  fault in exactly half of them gets 0.49 (a tie is not a declaration: with diagnoses {A, C} and
  {B, C} it declares C, not A, B and C); ``unknown`` = 1 when no fault is declared (detected,
  not isolated);
* detected with no consistent diagnosis: ``unknown``.
"""

from __future__ import annotations

import numpy as np

from marine_fdi_env.envs.hypotheses import HYPOTHESES, N_HYPOTHESES, UNKNOWN

__all__ = ["ReferenceAgent", "belief_from_diagnoses"]

_INDEX = {h: i for i, h in enumerate(HYPOTHESES)}


def belief_from_diagnoses(detected: bool, diagnoses) -> np.ndarray:
    b = np.zeros(N_HYPOTHESES, dtype=np.float32)
    if not detected:
        return b
    diagnoses = [list(d) for d in diagnoses]
    if not diagnoses:
        b[UNKNOWN] = 1.0
        return b
    smallest = min(len(d) for d in diagnoses)
    diagnoses = [d for d in diagnoses if len(d) == smallest]
    counts = np.zeros(N_HYPOTHESES)
    for d in diagnoses:
        for f in d:
            counts[_INDEX[f]] += 1
    b[:] = counts / len(diagnoses)
    b[2 * counts == len(diagnoses)] = 0.49
    if not np.any(b >= 0.5):
        b[UNKNOWN] = 1.0
    return b


class ReferenceAgent:
    name = "reference"

    def reset(self, seeds: list[int]) -> None:
        self.n = len(seeds)

    def act(self, obs: np.ndarray, infos: dict) -> np.ndarray:
        ref = infos["reference"]
        return np.stack([belief_from_diagnoses(bool(d), g) for d, g in zip(ref["detected"], ref["diagnoses"])])
