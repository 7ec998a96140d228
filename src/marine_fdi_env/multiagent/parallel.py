"""The multi-agent track as a PettingZoo ``ParallelEnv``: one engine, four local agents and a global one.

:class:`MarineFDIParallelEnv` is :class:`~.batch.MultiAgentBatchEnv` with one slot, in PettingZoo's
form (``pettingzoo`` is imported here only: the ``multiagent`` extra).  Its timing, rewards and
message budgets are the batch's; its episode is, bit for bit, ``MarineFDI-v1``'s with the same seed.
"""

from __future__ import annotations

import functools

import numpy as np
from pettingzoo import ParallelEnv

from .batch import MultiAgentBatchEnv
from .roles import AGENT_IDS

__all__ = ["MarineFDIParallelEnv"]


class MarineFDIParallelEnv(ParallelEnv):
    """Diagnose a marine diesel engine with the thesis's information structure (docs/multiagent.md).

    ## Agents
    ``local_1`` .. ``local_4`` (one per subsystem: fuel pump, engine block, exhaust receiver and
    turbocharger, air intake) and ``global``.

    ## Observation spaces
    ``local_l``: ``Box`` of the six observation features of each of its monitoring modules (table 6.2)
    and the episode clock (13, 37, 31, 37 features); with ``observe_sensors`` also its sensors'
    period means and the fuel setting.  ``global``: ``Box`` of the messages of the four locals,
    concatenated in agent order (zeros before the first message).

    ## Action spaces
    ``local_l``: its message under the budget (``decision``: ``MultiBinary`` of one bit per module;
    ``scalar``: one float32 per module; ``features``: six per module; :mod:`.budgets`).  ``global``:
    ``Box(0, 1, (28,))``, the single-agent action (belief over the 26 faults, ``no_fault``,
    ``unknown``).

    ## Rewards, timing, episode end
    The team shares the ``MarineFDI-v1`` reward of the global's declaration (``rewards="local"``:
    the locals are scored as detectors of their own faults instead).  A step is a message hop: the
    global declares for the decision whose messages it observes, so an episode of K decisions lasts
    K + 1 steps, all agents ending together (:mod:`.batch`).

    ## Arguments
    ``parallel_env(scenario_config="default", message_budget="decision", rewards="team",
    decision_period_s=1.0, observe_sensors=False, reward="v1", params="thesis-12v28", dt=0.01,
    diagnosis_cells="sized", diagnosis_thresholds="local")``.  ``reset(seed=, options={"scenario":
    ScenarioSpec | dict})``: other option keys are ignored (PettingZoo's API test passes its own).
    ``state()``: the single-agent observation (115 features) for centralised training.
    """

    metadata = {"name": "marine_fdi_v1", "render_modes": [], "is_parallelizable": True}

    def __init__(self, **kwargs) -> None:
        self.env = MultiAgentBatchEnv(num_envs=1, **kwargs)
        self.possible_agents = list(AGENT_IDS)
        self.agents: list[str] = []
        self.render_mode = None
        self.state_space = self.env.state_space

    @functools.lru_cache(maxsize=None)
    def observation_space(self, agent):
        return self.env.observation_spaces[agent]

    @functools.lru_cache(maxsize=None)
    def action_space(self, agent):
        return self.env.action_spaces[agent]

    def reset(self, seed=None, options=None):
        opts = None
        if isinstance(options, dict) and options.get("scenario") is not None:
            opts = {"scenarios": [options["scenario"]]}
        obs, infos = self.env.reset(seed=seed, options=opts)
        self.agents = list(AGENT_IDS)
        return _first(obs), _first_infos(infos)

    def step(self, actions):
        acts = {a: np.asarray(actions[a])[None] for a in AGENT_IDS if a in actions}
        for a in AGENT_IDS:  # an agent that has ended acts no more; its action is never read then
            acts.setdefault(a, np.zeros((1,) + self.action_space(a).shape, dtype=self.action_space(a).dtype))
        obs, rew, term, trunc, infos = self.env.step(acts)
        out = (
            _first(obs),
            {a: float(r[0]) for a, r in rew.items()},
            {a: bool(t[0]) for a, t in term.items()},
            {a: bool(t[0]) for a, t in trunc.items()},
            _first_infos(infos),
        )
        if self.env.done[0]:
            self.agents = []
        return out

    def state(self) -> np.ndarray:
        return self.env.state()[0]

    def render(self):
        return None

    def close(self) -> None:
        pass


def _first(d: dict) -> dict:
    return {a: v[0] for a, v in d.items()}


def _first_infos(infos: dict) -> dict:
    return {
        a: {k: v[0].item() if hasattr(v[0], "item") else v[0] for k, v in info.items()} for a, info in infos.items()
    }
