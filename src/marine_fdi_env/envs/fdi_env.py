"""``MarineFDI-v0`` and ``MarineFDI-v1`` (this class with another reward): fault detection and
isolation on a simulated marine diesel engine."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from .core import EpisodeBatch
from .hypotheses import HYPOTHESES, N_HYPOTHESES, check_action
from .observation import feature_names, observation_bounds
from .rendering import supported_render_mode
from .reward import RewardConfig, RewardConfigV1, make_reward_config
from .scenario_sampler import ScenarioConfig, ScenarioSpec, get_preset

__all__ = ["MarineFDIEnv", "ENV_ID", "ENV_ID_V1", "env_id_for"]

ENV_ID = "MarineFDI-v0"
ENV_ID_V1 = "MarineFDI-v1"


def env_id_for(reward) -> str:
    """The registered id whose reward this is (``MarineFDI-v0`` or ``MarineFDI-v1``)."""
    return ENV_ID_V1 if isinstance(make_reward_config(reward), RewardConfigV1) else ENV_ID


def _scenario_from_options(options) -> ScenarioSpec | None:
    if not options:
        return None
    if not isinstance(options, dict):
        raise ValueError(f"options must be a dict, got {type(options).__name__}")
    bad = set(options) - {"scenario"}
    if bad:
        raise ValueError(f"unknown reset options {sorted(bad)}; allowed: ['scenario']")
    sc = options.get("scenario")
    if sc is None or isinstance(sc, ScenarioSpec):
        return sc
    return ScenarioSpec.from_dict(sc)


class MarineFDIEnv(gym.Env):
    """Diagnose faults of a 12-cylinder turbocharged marine diesel engine as they appear.

    ## Description
    The mean-value first-principle model of the thesis engine (``thesis-12v28``: fuel pump,
    Seiliger-cycle engine block, exhaust receiver and turbocharger, air intake and intercooler)
    runs with 19 redundant sensors sampled every 0.01 s.  At reset a scenario is drawn: a
    fuel-setting profile, 0-2 faults (19 sensor faults, 7 process faults) with onsets and
    magnitudes, and the noise.  Every ``decision_period_s`` the agent sees what the reference
    diagnoser's 19 monitoring modules computed (residuals against adaptive thresholds) and
    declares what it believes is wrong.  The engine does not react to the declarations: the
    task is to diagnose early, correctly and without false alarms.

    ## Action space
    ``Box(0, 1, (28,), float32)``: a belief per hypothesis, in the order of
    :data:`~marine_fdi_env.envs.hypotheses.HYPOTHESES`: the 26 fault ids (``S1.1`` ... ``S4.6``,
    then ``valve_seizing``, ``bore_damage``, ``turbine_seal_leak``, ``turbine_lubrication_loss``,
    ``compressor_seal_leak``, ``compressor_lubrication_loss``, ``intercooler_blockage``), then
    ``no_fault``, then ``unknown``.  Fault ids with belief >= 0.5 are *declared*; declaring any
    fault id or ``unknown`` raises the *alarm*.  :class:`~marine_fdi_env.envs.wrappers.DiscreteHypothesis`
    turns this into ``Discrete(28)`` (one hypothesis at a time).

    ## Observation space
    ``Box(low, high, (115,), float32)`` (135 with ``observe_sensors=True``, 76 more with
    ``observe_sequential=True``: the ``sequential`` diagnoser's CUSUM states); per module, over the
    period: log(1 + max |r|/threshold), log(1 + mean |r|/threshold), the signed mean of
    r/threshold (log-compressed), share of samples violating, fired-this-episode flag, time since
    first violation / episode length; then the episode's
    time fraction (:mod:`marine_fdi_env.envs.observation` has the table and bounds;
    ``env.unwrapped.feature_names`` the names).

    ## Rewards
    ``MarineFDI-v0`` (``reward="v0"``, default of this class), per decision
    (:mod:`marine_fdi_env.envs.reward`): -1 for an alarm while no fault is active;
    +0.5 exp(-delay/30 s) for an alarm while a fault is active; +1 exp(-delay/30 s) when the
    declared set equals the active set; -0.25 for a declared set that is wrong; -0.02 per
    decision that misses an active fault.  ``MarineFDI-v1`` (``reward="v1"``), derived from the
    metrics: -40 per false alarm (rising alarm edge before the first onset), -0.01 per second of
    detection delay, -1 once for a fault never detected, +0.1 per second of exact isolation, +1
    when the last declared set is exact.
    Each term is in ``info["reward_terms"]``.

    ## Starting state
    The engine at the steady state of the profile's initial fuel setting; the first observation
    covers the first decision period (the diagnoser's observers start on its first sample).

    ## Episode end
    Truncation after ``duration_s`` (default 300 s: 300 decisions); termination when the engine
    leaves its physical range (stall, air excess ratio < 1, ...; ``info["engine_failure"]``
    gives the time and reason).

    ## Arguments
    ``gymnasium.make("marine_fdi_env:MarineFDI-v0", scenario_config="default",
    decision_period_s=1.0, observe_sensors=False, reward=RewardConfig(), params="thesis-12v28",
    dt=0.01, observe_sequential=False, diagnosis_cells="sized", diagnosis_thresholds="local")``
    (``MarineFDI-v1``: ``reward="v1"``, or a ``RewardConfigV1``); ``diagnosis_thresholds`` reads the
    reference's observer thresholds another way (``thesis-lipschitz``, ...,
    :mod:`marine_fdi_env.diagnosis.thresholds`: the observation's thresholds change with it);
    ``scenario_config`` is a preset name (``default``, ``single``, ``multi``,
    ``nominal``, ``incipient``, ``transfer``, ``sensor-kinds``), a
    :class:`~marine_fdi_env.envs.scenario_sampler.ScenarioConfig` or its dict.
    ``reset(options={"scenario": ScenarioSpec | dict})`` runs a given scenario instead of a drawn
    one (the frozen suites do this).  ``render_mode``: ``"ansi"`` (one line of text per decision) or
    None; another mode warns and renders nothing, as Gymnasium's own environments do (so that
    Stable-Baselines3's ``make_vec_env``, which asks for ``"rgb_array"``, works unchanged).

    ## info
    ``t_s``, ``scenario_id``, ``profile``, ``true_faults`` (id, class, onset, magnitude, end),
    ``active_faults``, ``engine_failure`` (None, or ``engine``, ``time_s``, ``reason``; ``engine`` is
    0 here and the sub-env index in the vector env, whose slots without a failure carry engine -1,
    time NaN, reason ""), ``reference`` (the reference diagnoser's detection and
    minimal diagnoses), ``sequential`` (the same for the ``sequential`` diagnoser, with
    ``observe_sequential=True`` only), and after a step ``decision_time_s``, ``declared``, ``alarm``,
    ``belief_on_truth``, ``reward_terms``.  (Wall-clock numbers are kept out of ``info`` so that
    equal seeds give equal infos; ``env.unwrapped.feature_compute_s`` has the time spent on the
    observation features this episode.)

    ## Version history
    * v0: first release (simulator, reference diagnoser and suites of marine-fdi-env 0.1).
    * v1: the reward derived from the metrics (docs/environment.md); everything else as v0.
    """

    metadata = {"render_modes": ["ansi"], "render_fps": 1}

    def __init__(
        self,
        scenario_config: "str | ScenarioConfig | dict" = "default",
        decision_period_s: float = 1.0,
        observe_sensors: bool = False,
        reward: "RewardConfig | RewardConfigV1 | dict | str | None" = None,
        params: str = "thesis-12v28",
        dt: float = 0.01,
        render_mode: str | None = None,
        observe_sequential: bool = False,
        diagnosis_cells: str = "sized",
        diagnosis_thresholds: str = "local",
    ) -> None:
        self.scenario_config = get_preset(scenario_config)
        reward = make_reward_config(reward)
        self.render_mode = supported_render_mode(render_mode, self.metadata["render_modes"])
        self.batch = EpisodeBatch(
            1,
            params,
            decision_period_s,
            dt,
            observe_sensors,
            reward,
            noise_scale=self.scenario_config.noise_scale,
            observe_sequential=observe_sequential,
            diagnosis_cells=diagnosis_cells,
            diagnosis_thresholds=diagnosis_thresholds,
        )
        low, high = observation_bounds(observe_sensors, observe_sequential)
        self.observation_space = spaces.Box(low, high, dtype=np.float32)
        self.action_space = spaces.Box(0.0, 1.0, (N_HYPOTHESES,), dtype=np.float32)
        self.feature_names = feature_names(observe_sensors, observe_sequential)
        self.hypotheses = HYPOTHESES
        self._done = True
        self._last_info: dict = {}

    @property
    def feature_compute_s(self) -> float:
        """Wall time [s] spent computing observation features (the residual generators) this episode."""
        return float(self.batch.compute_s[0])

    @property
    def decision_period_s(self) -> float:
        return self.batch.decision_period_s

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        super().reset(seed=seed)
        scenario = _scenario_from_options(options)
        if scenario is None:
            scenario = self.scenario_config.sample(int(self.np_random.integers(0, 2**63 - 1)))
        self.batch.start([0], [scenario])
        self.batch.advance()
        self._done = False
        info = self.batch.info(0)
        self._last_info = info
        return self.batch.obs[0].copy(), info

    def step(self, action):
        if self._done:
            raise RuntimeError("step() called on a finished episode: call reset() first")
        belief = check_action(action)
        out = self.batch.score(belief[None], [0])
        b = self.batch
        b.steps[0] += 1
        terminated = truncated = False
        t = b.time(0)
        duration = b.scenarios[0].duration_s
        if b.failure[0] is not None:
            terminated = True
        elif t >= duration - 1e-9:
            truncated = True
        else:
            failed = b.advance()
            terminated = len(failed) > 0
        if terminated or truncated:
            b.end_terms(out, [0], [0])  # v1: a missed detection is charged at the last decision
        info = b.info(0)
        info.update(
            declared=list(out.declared[0]),
            alarm=bool(out.alarm[0]),
            belief_on_truth=None if math.isnan(out.belief_on_truth[0]) else float(out.belief_on_truth[0]),
            reward_terms={k: float(v[0]) for k, v in out.terms.items()},
            decision_time_s=t,
        )
        if terminated:
            info["termination_reason"] = f"engine failure: {b.failure[0]['reason']}"
        self._done = terminated or truncated
        self._last_info = info
        return b.obs[0].copy(), float(out.reward[0]), terminated, truncated, info

    def render(self):
        if self.render_mode != "ansi":
            return None
        i = self._last_info
        return (
            f"t={i.get('t_s', 0.0):7.2f} s  active={i.get('active_faults')}  declared={i.get('declared')}  "
            f"alarm={i.get('alarm')}  reference={i.get('reference', {}).get('diagnoses')}"
        )
