"""The ``sequential`` diagnoser as a benchmark agent: CUSUM tests on the reference diagnoser's
residuals with the same structural isolation logic (:mod:`marine_fdi_env.diagnosis.sequential`).

The environment runs the tests when asked (``observe_sequential=True``, which this agent's
``env_kwargs`` request from ``marine-fdi evaluate``) and reports their conclusion in
``info["sequential"]``; the agent declares from its minimal diagnoses exactly as the ``reference``
agent does from the reference's (:func:`marine_fdi_env.baselines.reference_agent.belief_from_diagnoses`).
``cells`` as for the reference agent: ``sequential-thesis`` and ``sequential-grid`` are this agent
with the table-size and the grid cells.
"""

from __future__ import annotations

import numpy as np

from marine_fdi_env.baselines.reference_agent import beliefs_from_conclusions, cells_name, with_cells
from marine_fdi_env.diagnosis.cell_sets import DEFAULT_CELLS, check_cells

__all__ = ["SequentialAgent", "SequentialThesisAgent", "SequentialGridAgent"]


class SequentialAgent:
    """The sequential diagnoser's conclusion as a declaration (module docstring)."""

    def __init__(self, cells: str = DEFAULT_CELLS) -> None:
        self.cells = check_cells(cells)
        self.name = cells_name("sequential", cells)
        self.env_kwargs = {"observe_sequential": True, "diagnosis_cells": self.cells}
        self._beliefs: dict = {}

    def reset(self, seeds: list[int]) -> None:
        self.n = len(seeds)

    def act(self, obs: np.ndarray, infos: dict) -> np.ndarray:
        if "sequential" not in infos:
            raise ValueError("the sequential agent needs the environment made with observe_sequential=True")
        seq = infos["sequential"]
        return beliefs_from_conclusions(seq["detected"], seq["diagnoses"], self._beliefs)


SequentialThesisAgent = with_cells(SequentialAgent, "thesis")
SequentialGridAgent = with_cells(SequentialAgent, "grid")
