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

``cells`` chooses the reference's measured sure cells (``thesis``, ``grid`` or ``sized``, the
default; :mod:`marine_fdi_env.diagnosis.cell_sets`) through the environment option
``diagnosis_cells``; the agents ``reference-thesis`` and ``reference-grid`` are this agent with the
other two.  ``thresholds`` chooses the reading of the observer modules' thresholds
(:mod:`marine_fdi_env.diagnosis.thresholds`) through the environment option
``diagnosis_thresholds``, with the cells measured at that reading: the agents
``reference-lipschitz``, ``reference-no-interconnection``, ``reference-table-6.1`` and
``reference-table-6.1-m4`` are this agent with the readings ``thesis-lipschitz``, ... (a name
without ``thesis-`` so that none is confused with the cell set ``reference-thesis``).
"""

from __future__ import annotations

import numpy as np

from marine_fdi_env.diagnosis.cell_sets import DEFAULT_CELLS, check_cells
from marine_fdi_env.diagnosis.thresholds import DEFAULT_THRESHOLDS, check_thresholds
from marine_fdi_env.envs.hypotheses import HYPOTHESES, N_HYPOTHESES, UNKNOWN

__all__ = [
    "ReferenceAgent",
    "ReferenceThesisAgent",
    "ReferenceGridAgent",
    "ReferenceLipschitzAgent",
    "ReferenceNoInterconnectionAgent",
    "ReferenceTable61Agent",
    "ReferenceTable61M4Agent",
    "belief_from_diagnoses",
    "beliefs_from_conclusions",
    "memoised_belief",
    "cells_name",
    "thresholds_name",
    "with_cells",
    "with_thresholds",
]

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


_NOT_DETECTED = np.zeros(N_HYPOTHESES, dtype=np.float32)


def beliefs_from_conclusions(detected, diagnoses, memo: dict) -> np.ndarray:
    """:func:`belief_from_diagnoses` of every slot (rows of ``detected`` and ``diagnoses``), each distinct set of
    diagnoses computed once (``memo``: the caller's cache, keyed by the diagnoses' fault ids; a diagnoser's
    conclusion changes rarely, so most decisions find theirs there)."""
    return np.stack([memoised_belief(g, memo) if d else _NOT_DETECTED for d, g in zip(detected, diagnoses)])


def memoised_belief(diagnoses, memo: dict) -> np.ndarray:
    """:func:`belief_from_diagnoses` of a detected fault with ``diagnoses``, from ``memo`` (keyed by the diagnoses'
    fault ids) when it holds them; the caller must not change the array it returns."""
    key = tuple(tuple(x) for x in diagnoses)
    b = memo.get(key)
    if b is None:
        b = memo[key] = belief_from_diagnoses(True, diagnoses)
    return b


def cells_name(base: str, cells: str) -> str:
    """The agent name of a diagnoser agent with a cell set: ``base`` for the default, else
    ``base-cells``."""
    return base if check_cells(cells) == DEFAULT_CELLS else f"{base}-{cells}"


def thresholds_name(base: str, thresholds: str) -> str:
    """The agent name of a diagnoser agent with a threshold reading: ``base`` for the default, else
    ``base-`` and the reading without its ``thesis-`` prefix (``reference-lipschitz``)."""
    if check_thresholds(thresholds) == DEFAULT_THRESHOLDS:
        return base
    return f"{base}-{thresholds.removeprefix('thesis-')}"


class ReferenceAgent:
    """The reference diagnoser's conclusion as a declaration (module docstring)."""

    def __init__(self, cells: str = DEFAULT_CELLS, thresholds: str = DEFAULT_THRESHOLDS) -> None:
        self.cells = check_cells(cells)
        self.thresholds = check_thresholds(thresholds)
        if self.thresholds == DEFAULT_THRESHOLDS:
            self.name = cells_name("reference", cells)
            self.env_kwargs = {"diagnosis_cells": self.cells}
        else:
            self.name = cells_name(thresholds_name("reference", thresholds), cells)
            self.env_kwargs = {"diagnosis_cells": self.cells, "diagnosis_thresholds": self.thresholds}
        self._beliefs: dict = {}

    def reset(self, seeds: list[int]) -> None:
        self.n = len(seeds)

    def act(self, obs: np.ndarray, infos: dict) -> np.ndarray:
        ref = infos["reference"]
        return beliefs_from_conclusions(ref["detected"], ref["diagnoses"], self._beliefs)


def with_cells(base: type, cells: str) -> type:
    """``base`` (an agent class taking ``cells``) with another cell set, as a class constructible
    without arguments (how the agent registry builds its agents)."""
    check_cells(cells)

    def __init__(self) -> None:
        base.__init__(self, cells)

    name = f"{base.__name__.removesuffix('Agent')}{cells.capitalize()}Agent"
    return type(
        name,
        (base,),
        {"__init__": __init__, "__module__": base.__module__, "__doc__": f"{base.__name__} with the {cells} cells."},
    )


ReferenceThesisAgent = with_cells(ReferenceAgent, "thesis")
ReferenceGridAgent = with_cells(ReferenceAgent, "grid")


def with_thresholds(base: type, thresholds: str) -> type:
    """``base`` (an agent class taking ``cells`` and ``thresholds``) with another threshold reading,
    as a class constructible without arguments (how the agent registry builds its agents)."""
    check_thresholds(thresholds)

    def __init__(self) -> None:
        base.__init__(self, DEFAULT_CELLS, thresholds)

    words = thresholds.removeprefix("thesis-").replace(".", "").split("-")
    name = f"{base.__name__.removesuffix('Agent')}{''.join(w.capitalize() for w in words)}Agent"
    return type(
        name,
        (base,),
        {
            "__init__": __init__,
            "__module__": base.__module__,
            "__doc__": f"{base.__name__} with the observers' thresholds read as {thresholds} (its own measured cells).",
        },
    )


ReferenceLipschitzAgent = with_thresholds(ReferenceAgent, "thesis-lipschitz")
ReferenceNoInterconnectionAgent = with_thresholds(ReferenceAgent, "thesis-no-interconnection")
ReferenceTable61Agent = with_thresholds(ReferenceAgent, "thesis-table-6.1")
ReferenceTable61M4Agent = with_thresholds(ReferenceAgent, "thesis-table-6.1-m4")
