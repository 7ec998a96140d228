"""The multi-agent track, batched: N engines, four local agents and a global agent each.

:class:`MultiAgentBatchEnv` runs N episodes on the single-agent environment's
:class:`~marine_fdi_env.envs.core.EpisodeBatch` (one batched simulator and reference diagnoser), so
episode i is, bit for bit, the single environment's episode reset with seed ``seed + i`` (or the
scenario given): the same engine, noise, faults and observation features.  The PettingZoo
:class:`~marine_fdi_env.multiagent.parallel.MarineFDIParallelEnv` is this with N = 1.

**Timing.**  The locals' messages about decision k reach the global agent within decision period k:
the global declares for decision k from the messages of decision k, as a single agent declares from
its observation of period k, and the declaration is scored at decision k's time.  In a parallel
environment every agent acts in every step, so the hop is one step: in step j the locals send their
messages about decision j (their observation) and the global declares for decision j - 1 (its
observation holds the messages of step j - 1).  An episode of K decisions takes K + 1 steps: in the
first the global has no message yet (zeros; its action is not scored, ``infos["global"]["scored"]``
False) and in the last the locals see their last observation again (their messages are not read).
The engine does not react to declarations, so running the simulation one hop ahead of the
declarations changes nothing: every declaration is scored exactly as the single environment scores
the same declaration at the same decision.

**Rewards.**  ``rewards="team"`` (default): every agent receives the reward of the global's
declaration (``MarineFDI-v1``'s by default, any :class:`~marine_fdi_env.envs.reward.RewardConfigV1`
or v0 config), in the step it is scored.  ``rewards="local"``: the global keeps it and each local
is scored as a detector of the faults its own modules can see (those with a signature in its rows,
:func:`marine_fdi_env.diagnosis.structure.fault_signature_matrix`): its message raises its alarm when
any entry is >= 0.5 (a decision vector with a fired module), scored by the v1 reward's detection terms
against those faults alone (a false alarm, the detection delay, a missed detection), in the step it
sends the message.

No autoreset: :meth:`reset` starts N episodes and they run to their ends; a slot whose episode has
ended repeats its last observations, gets zero rewards and its actions are ignored until every slot
has ended (``done``).  :meth:`state` is the full single-agent observation (115 features), for
centralised training.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding

from ..diagnosis.modules import MODULE_IDS
from ..diagnosis.structure import fault_signature_matrix
from ..envs.core import EpisodeBatch
from ..envs.fault_windows import FaultWindows
from ..envs.hypotheses import N_FAULTS, N_HYPOTHESES, UNKNOWN, check_action
from ..envs.observation import feature_names, observation_bounds
from ..envs.reward import RewardConfigV1, make_reward_config
from ..envs.scenario_sampler import ScenarioConfig, ScenarioSpec, get_preset
from ..envs.scoring import DecisionScorer, StepOutcome
from ..envs.vector import reseed_slots
from .budgets import MessageBudget, get_budget
from .roles import AGENT_IDS, GLOBAL_AGENT, LOCAL_AGENTS, local_columns, local_modules

__all__ = ["MultiAgentBatchEnv", "REWARD_MODES", "visible_faults"]

REWARD_MODES = ("team", "local")


def visible_faults(agent: str) -> np.ndarray:
    """Bool (26,): the faults with a signature in a local agent's modules (the faults it can detect)."""
    support = fault_signature_matrix()[0]  # (19, 26)
    rows = [MODULE_IDS.index(m) for m in local_modules(agent)]
    return support[rows].any(axis=0)


class MultiAgentBatchEnv:
    """N episodes of the multi-agent track (module docstring).

    Arguments are those of :class:`~marine_fdi_env.envs.fdi_env.MarineFDIEnv` (``reward`` defaults
    to ``v1``; ``observe_sequential`` is not offered) plus ``num_envs``, ``message_budget`` (a name of
    :data:`~.budgets.BUDGETS` or a :class:`~.budgets.MessageBudget`) and ``rewards`` (``team`` or
    ``local``).  Observations, actions, rewards, terminations and infos are dicts over
    :data:`~.roles.AGENT_IDS` of arrays over the N slots.
    """

    def __init__(
        self,
        num_envs: int = 1,
        scenario_config: "str | ScenarioConfig | dict" = "default",
        message_budget: "str | MessageBudget | dict" = "decision",
        rewards: str = "team",
        decision_period_s: float = 1.0,
        observe_sensors: bool = False,
        reward=None,
        params: str = "thesis-12v28",
        dt: float = 0.01,
        diagnosis_cells: str = "sized",
        diagnosis_thresholds: str = "local",
    ) -> None:
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or num_envs < 1:
            raise ValueError(f"num_envs must be a positive integer, got {num_envs!r}")
        if rewards not in REWARD_MODES:
            raise ValueError(f"rewards must be one of {', '.join(REWARD_MODES)}, got {rewards!r}")
        self.num_envs = n = int(num_envs)
        self.budget = get_budget(message_budget)
        self.rewards_mode = rewards
        self.scenario_config = get_preset(scenario_config)
        self.reward_cfg = make_reward_config("v1" if reward is None else reward)
        self.observe_sensors = bool(observe_sensors)
        self.batch = EpisodeBatch(
            n,
            params,
            decision_period_s,
            dt,
            self.observe_sensors,
            self.reward_cfg,
            noise_scale=self.scenario_config.noise_scale,
            diagnosis_cells=diagnosis_cells,
            diagnosis_thresholds=diagnosis_thresholds,
        )
        self.feature_names = feature_names(self.observe_sensors)
        self.columns = {a: local_columns(a, self.feature_names, self.observe_sensors) for a in LOCAL_AGENTS}
        low, high = observation_bounds(self.observe_sensors)
        self.state_space = spaces.Box(low, high, dtype=np.float32)
        self.observation_spaces: dict[str, spaces.Space] = {
            a: spaces.Box(low[c], high[c], dtype=np.float32) for a, c in self.columns.items()
        }
        glow, ghigh = self.budget.bounds()
        self.observation_spaces[GLOBAL_AGENT] = spaces.Box(glow, ghigh, dtype=np.float32)
        self.action_spaces: dict[str, spaces.Space] = {a: self.budget.space(a) for a in LOCAL_AGENTS}
        self.action_spaces[GLOBAL_AGENT] = spaces.Box(0.0, 1.0, (N_HYPOTHESES,), dtype=np.float32)
        sizes = [self.budget.size(a) for a in LOCAL_AGENTS]
        ends = np.cumsum(sizes)
        self.message_slices = {a: slice(int(e - s), int(e)) for a, s, e in zip(LOCAL_AGENTS, sizes, ends)}
        self.possible_agents = AGENT_IDS
        self._rngs: list[np.random.Generator | None] = [None] * n
        self._started = False
        if self.rewards_mode == "local":
            if not isinstance(self.reward_cfg, RewardConfigV1):
                raise ValueError(
                    "rewards='local' scores the locals with the v1 reward's detection terms: reward must be v1"
                )
            self._visible = {a: visible_faults(a) for a in LOCAL_AGENTS}
            detect_only = replace(self.reward_cfg, isolation_per_s=0.0, final_isolation=0.0)
            self._local_scorers = {
                a: DecisionScorer(detect_only, n, self.batch.decision_period_s) for a in LOCAL_AGENTS
            }
            self._local_windows = {a: FaultWindows(n) for a in LOCAL_AGENTS}

    # ------------------------------------------------------------------------------ reset
    def _slot_rng(self, i: int) -> np.random.Generator:
        if self._rngs[i] is None:
            self._rngs[i], _ = seeding.np_random()
        return self._rngs[i]

    def reset(self, *, seed: "int | list[int | None] | None" = None, options: dict | None = None):
        """Start N episodes: scenarios drawn from each slot's ``np_random`` (seeded ``seed + i``, as the
        vector environment), or ``options={"scenarios": [ScenarioSpec | dict, ...]}``.  Returns
        (observations, infos)."""
        n = self.num_envs
        reseed_slots(self._rngs, seed)
        scenarios = None
        if options:
            if not isinstance(options, dict) or set(options) - {"scenarios"}:
                raise ValueError("options must be a dict with the single key 'scenarios' (one scenario per slot)")
            scenarios = [s if isinstance(s, ScenarioSpec) else ScenarioSpec.from_dict(s) for s in options["scenarios"]]
            if len(scenarios) != n:
                raise ValueError(f"options['scenarios'] must hold {n} scenarios, got {len(scenarios)}")
        if scenarios is None:
            scenarios = [self.scenario_config.sample(int(self._slot_rng(i).integers(0, 2**63 - 1))) for i in range(n)]
        b = self.batch
        b.start(range(n), scenarios)
        b.advance()
        self.decision = np.zeros(n, dtype=np.int64)  # the decision the locals see now
        self.sent_last = np.zeros(n, dtype=bool)  # the episode's last decision has been messaged
        self.pending = np.zeros(n, dtype=bool)  # messages wait for the global's declaration
        self.pending_last = np.zeros(n, dtype=bool)  # ... about the episode's last decision
        self.ended_by_failure = np.zeros(n, dtype=bool)
        self.done = np.zeros(n, dtype=bool)
        self.messages = np.zeros((n, self.budget.total_size), dtype=np.float32)
        self.obs_t = b.t.astype(float)  # the time of the decision the locals see [s]
        self._ctx_active = np.zeros((n, N_FAULTS), dtype=bool)
        self._ctx_first = np.zeros(n)
        self._ctx_last = np.zeros(n)
        self._ctx_t = np.zeros(n)
        self.outcome: StepOutcome | None = None  # the scores of the declarations of the last step
        self.scored = np.zeros(0, dtype=np.int64)  # their slots
        self.scored_t = np.zeros(0)  # and their decision times [s]
        if self.rewards_mode == "local":
            for a in LOCAL_AGENTS:
                vis = self._visible[a]
                for i, sc in enumerate(scenarios):
                    own = [f for f in sc.faults if vis[_fault_column(f.fault_id)]]
                    self._local_windows[a].set(i, own)
                    self._local_scorers[a].start(i, own)
        self._started = True
        infos = self._infos(np.zeros(0, dtype=np.int64), None)
        return self._observations(), infos

    # ------------------------------------------------------------------------------ step
    def step(self, actions: dict):
        """One hop (module docstring): the locals' messages about the decision they see, the global's
        declaration for the decision before.  Returns (observations, rewards, terminated, truncated,
        infos), each a dict over the agents of arrays over the slots."""
        if not self._started:
            raise RuntimeError("step() called before reset()")
        if self.done.all():
            raise RuntimeError("every episode of the batch has ended: call reset()")
        b, n = self.batch, self.num_envs
        missing = [a for a in AGENT_IDS if a not in actions]
        if missing:
            raise ValueError(f"actions must hold an action for every agent; missing {', '.join(missing)}")
        live = ~self.done
        rewards = {a: np.zeros(n) for a in AGENT_IDS}
        terminated = np.zeros(n, dtype=bool)
        truncated = np.zeros(n, dtype=bool)
        # the global's declarations for the decision messaged in the last step
        dec = np.flatnonzero(live & self.pending)
        self.outcome, self.scored, self.scored_t = None, dec, self._ctx_t[dec].copy()
        if len(dec):
            beliefs = check_action(actions[GLOBAL_AGENT], n_envs=n)[dec]
            out = b.scorer.score(
                beliefs, dec, self._ctx_active[dec], self._ctx_first[dec], self._ctx_last[dec], self._ctx_t[dec]
            )
            b.steps[dec] += 1
            ending = dec[self.pending_last[dec]]
            b.end_terms(out, dec, ending)
            self.outcome = out
            for a in AGENT_IDS if self.rewards_mode == "team" else (GLOBAL_AGENT,):
                rewards[a][dec] = out.reward
            terminated[ending] = self.ended_by_failure[ending]
            truncated[ending] = ~self.ended_by_failure[ending]
            self.done[ending] = True
            self.pending[dec] = False
        # the locals' messages about the decision they see
        snd = np.flatnonzero(live & ~self.sent_last)
        if len(snd):
            for a in LOCAL_AGENTS:
                m = self.budget.check(a, actions[a], n)
                self.messages[snd, self.message_slices[a]] = m[snd]
            act, first, last = b.active_matrix(snd)
            self._ctx_active[snd], self._ctx_first[snd], self._ctx_last[snd] = act, first, last
            self._ctx_t[snd] = b.t[snd]
            failed = b.failed[snd]
            at_end = ~failed & (b.t[snd] >= b.durations[snd] - 1e-9)
            is_last = failed | at_end
            self.ended_by_failure[snd] = failed
            going = snd[~is_last]
            if len(going):
                for f in b.advance(going):
                    if f in going and not self.done[f]:  # it failed while advancing: its decision was the last
                        is_last[np.searchsorted(snd, f)] = True
                        self.ended_by_failure[f] = True
            self.pending[snd] = True
            self.pending_last[snd] = is_last
            self.sent_last[snd] = is_last
            moved = snd[~is_last]
            self.decision[moved] += 1
            self.obs_t[moved] = b.t[moved]
            if self.rewards_mode == "local":
                self._local_rewards(snd, is_last, actions, rewards)
        infos = self._infos(dec, self.outcome)
        term = {a: terminated.copy() for a in AGENT_IDS}
        trunc = {a: truncated.copy() for a in AGENT_IDS}
        return self._observations(), rewards, term, trunc, infos

    def _local_rewards(self, snd: np.ndarray, is_last: np.ndarray, actions: dict, rewards: dict) -> None:
        n = self.num_envs
        for a in LOCAL_AGENTS:
            m = self.budget.check(a, actions[a], n)[snd]
            beliefs = np.zeros((len(snd), N_HYPOTHESES), dtype=np.float32)
            beliefs[:, UNKNOWN] = (m >= 0.5).any(axis=1)
            act, first, last = self._local_windows[a].active(snd, self._ctx_t[snd])
            sc = self._local_scorers[a]
            out = sc.score(beliefs, snd, act, first, last, self._ctx_t[snd])
            sc.end_terms(out, snd, snd[is_last])
            rewards[a][snd] = out.reward

    # ------------------------------------------------------------------------------ views
    def _observations(self) -> dict:
        obs = self.batch.obs
        out = {a: obs[:, c] for a, c in self.columns.items()}
        out[GLOBAL_AGENT] = self.messages.copy()
        return out

    def state(self) -> np.ndarray:
        """(N, 115) the full observation of the decision the locals see (for centralised training)."""
        return self.batch.obs.copy()

    def _infos(self, dec: np.ndarray, out: StepOutcome | None) -> dict:
        n = self.num_envs
        common = {"decision": self.decision.copy(), "t_s": self.obs_t.copy()}
        infos = {a: dict(common) for a in LOCAL_AGENTS}
        scored = np.zeros(n, dtype=bool)
        scored[dec] = True
        when = np.full(n, math.nan)
        when[dec] = self.scored_t
        g = {"scored": scored, "decision_time_s": when}
        if out is not None:
            alarm = np.zeros(n, dtype=bool)
            alarm[dec] = out.alarm
            g["alarm"] = alarm
        infos[GLOBAL_AGENT] = g
        return infos


_FAULT_COLUMN: dict[str, int] = {}


def _fault_column(fault_id: str) -> int:
    if not _FAULT_COLUMN:
        from ..engine.faults import FAULT_IDS

        _FAULT_COLUMN.update({f: j for j, f in enumerate(FAULT_IDS)})
    return _FAULT_COLUMN[fault_id]
