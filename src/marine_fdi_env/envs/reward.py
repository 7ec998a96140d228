"""Rewards of ``MarineFDI-v0`` and ``MarineFDI-v1``: early, correct, quiet diagnosis.

``MarineFDI-v0`` (:class:`RewardConfig`, :func:`score`) is kept bit for bit; ``MarineFDI-v1``
(:class:`RewardConfigV1`, :class:`RewardV1`) is the reward derived from the benchmark's metrics
(docs/environment.md, "Reward of MarineFDI-v1"): its optimum is the metrics' optimum.

v0
--

At every decision time t the declaration (see :mod:`.hypotheses`) is scored against the faults
active at t (onset <= t < end).  With ``T`` the true set, ``D`` the declared fault ids, ``A`` the
alarm flag, ``d1 = t - first onset`` and ``dT = t - last onset`` of the active faults:

=================  ============================================  ===========================
term               when                                          value (defaults)
=================  ============================================  ===========================
false_alarm        A and T = ∅                                   -1.0
missed             not A and T ≠ ∅                               -0.02
detection          A and T ≠ ∅                                   +0.5 exp(-d1 / 30 s)
isolation          D = T ≠ ∅                                     +1.0 exp(-dT / 30 s)
wrong_isolation    D ≠ ∅ and D ≠ T                               -0.25
=================  ============================================  ===========================

Summed over the decisions of an episode, the detection and isolation terms pay about
``w τ exp(-delay / τ) / period``: the earlier the correct declaration, the larger the return,
and a declaration that is never made pays nothing.  A false alarm costs far more per decision
than any single correct step pays, so quiet agents are not out-scored by trigger-happy ones
(an agent that always alarms loses ~1 per fault-free decision).  Every term is reported in
``info["reward_terms"]``; the weights are a :class:`RewardConfig`.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

__all__ = [
    "RewardConfig",
    "REWARD_TERMS",
    "score",
    "RewardConfigV1",
    "REWARD_TERMS_V1",
    "RewardV1",
    "REWARD_VERSIONS",
    "make_reward_config",
    "score_record_v1",
    "score_records_v1",
]

REWARD_TERMS = ("false_alarm", "missed", "detection", "isolation", "wrong_isolation")
REWARD_TERMS_V1 = ("false_alarm", "detection_delay", "missed_detection", "isolation", "final_isolation")
REWARD_VERSIONS = ("v0", "v1")


def _check_weights(config) -> None:
    """Every field of a reward config is a finite number >= 0 (a bool is not a number here)."""
    for k, v in asdict(config).items():
        if not (isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v >= 0):
            raise ValueError(f"reward config field {k!r} must be a finite number >= 0, got {v!r}")


@dataclass(frozen=True)
class RewardConfig:
    """Weights of the reward terms (per decision) and the delay time constant tau_s [s]."""

    false_alarm: float = 1.0
    missed: float = 0.02
    detection: float = 0.5
    isolation: float = 1.0
    wrong_isolation: float = 0.25
    tau_s: float = 30.0

    version = "v0"

    def __post_init__(self) -> None:
        _check_weights(self)
        if self.tau_s <= 0:
            raise ValueError(f"reward config field 'tau_s' must be > 0, got {self.tau_s!r}")

    def to_dict(self) -> dict:
        return dict(asdict(self), version="v0")


def score(
    cfg: RewardConfig,
    declared: np.ndarray,
    alarm: np.ndarray,
    active: np.ndarray,
    first_onset: np.ndarray,
    last_onset: np.ndarray,
    t: np.ndarray,
) -> dict[str, np.ndarray]:
    """Reward terms of n decisions (arrays over decisions).

    declared, active : (n, 26) bool masks of the declared and the active fault ids;
    alarm : (n,) bool; first_onset, last_onset : (n,) onsets of the active faults [s] (any value
    where none is active); t : (n,) decision times [s].
    """
    any_active = active.any(axis=1)
    exact = any_active & np.all(declared == active, axis=1)
    wrong = declared.any(axis=1) & ~np.all(declared == active, axis=1)
    zero = np.zeros(len(t))
    with np.errstate(over="ignore"):
        det = cfg.detection * np.exp(-(t - first_onset) / cfg.tau_s)
        iso = cfg.isolation * np.exp(-(t - last_onset) / cfg.tau_s)
    return {
        "false_alarm": np.where(alarm & ~any_active, -cfg.false_alarm, zero),
        "missed": np.where(~alarm & any_active, -cfg.missed, zero),
        "detection": np.where(alarm & any_active, det, zero),
        "isolation": np.where(exact, iso, zero),
        "wrong_isolation": np.where(wrong, -cfg.wrong_isolation, zero),
    }


# --------------------------------------------------------------------------------------------- v1
@dataclass(frozen=True)
class RewardConfigV1:
    """Weights of the ``MarineFDI-v1`` reward (docs/environment.md derives them from the metrics).

    false_alarm : cost of one false alarm, counted as the metrics count it: a rising edge of the
        alarm at a decision before the episode's first onset.
    detection_delay_per_s : cost per second of detection delay (paid at every decision from the
        first onset until the alarm is first on).
    missed_detection : one-off cost at the end of a faulty episode whose fault was never detected
        (a miss is worse than any delay).
    isolation_per_s : pay per second during which the declared set equals the active set (non-empty).
    final_isolation : one-off pay at the end of a faulty episode whose last declared set equals
        the active set (the metrics' isolation accuracy).

    Dominance (tested): with ``false_alarm > (detection_delay_per_s + isolation_per_s) * duration_s
    + missed_detection + final_isolation`` no false alarm can pay for itself, whatever it buys
    later in the episode; the defaults satisfy it for episodes up to 345 s (the suites' are 300 s):
    :meth:`max_episode_s`.  A second of exact isolation is worth ten seconds of detection delay:
    isolation is what detection is for (docs/environment.md).
    """

    false_alarm: float = 40.0
    detection_delay_per_s: float = 0.01
    missed_detection: float = 1.0
    isolation_per_s: float = 0.1
    final_isolation: float = 1.0

    version = "v1"

    def __post_init__(self) -> None:
        _check_weights(self)

    def max_episode_s(self) -> float:
        """Longest episode [s] for which no false alarm can pay for itself (see class docstring)."""
        rate = self.detection_delay_per_s + self.isolation_per_s
        room = self.false_alarm - self.missed_detection - self.final_isolation
        if room <= 0:
            return 0.0
        return math.inf if rate == 0 else room / rate

    def to_dict(self) -> dict:
        return dict(asdict(self), version="v1")


class RewardV1:
    """The ``MarineFDI-v1`` reward of N episode slots; it keeps, per slot, what the metrics need
    from the past: the alarm at the previous decision (false alarms are rising edges), whether the
    fault has been detected (the delay stops counting at the first alarm after the onset) and
    whether the last decision's declared set was the active set (isolation accuracy).

    Per decision at time t (period dt), with ``t1`` the episode's first onset (+inf without
    faults), ``A`` the alarm, ``D`` the declared set and ``T`` the active set:

    =================  ====================================================  ============================
    term               when                                                  value
    =================  ====================================================  ============================
    false_alarm        A, not A at the previous decision, t < t1             -false_alarm
    detection_delay    t >= t1, not A, not detected before                   -detection_delay_per_s * dt
    isolation          D = T, T non-empty                                    +isolation_per_s * dt
    missed_detection   last decision of a faulty episode, never detected     -missed_detection
    final_isolation    last decision of a faulty episode, D = T              +final_isolation
    =================  ====================================================  ============================
    """

    def __init__(self, cfg: RewardConfigV1, n: int) -> None:
        self.cfg = cfg
        self.prev_alarm = np.zeros(n, dtype=bool)
        self.detected = np.zeros(n, dtype=bool)
        self.last_exact = np.zeros(n, dtype=bool)
        self.first_onset = np.full(n, math.inf)

    def start(self, slot: int, first_onset_s: float) -> None:
        """A new episode in ``slot`` (``first_onset_s``: +inf for a fault-free episode)."""
        self.prev_alarm[slot] = False
        self.detected[slot] = False
        self.last_exact[slot] = False
        self.first_onset[slot] = first_onset_s

    def score(
        self,
        slots: np.ndarray,
        declared: np.ndarray,
        alarm: np.ndarray,
        active: np.ndarray,
        t: np.ndarray,
        dt: "float | np.ndarray",
    ) -> dict[str, np.ndarray]:
        """Terms of one decision of ``slots`` (arrays over them; ``declared``, ``active``: (n, 26)
        bool masks, ``alarm``: (n,) bool, ``t``: decision times [s], ``dt``: decision period(s) [s]);
        updates the slots' state."""
        cfg = self.cfg
        slots = np.asarray(slots, dtype=np.int64)
        t1 = self.first_onset[slots]
        after = t >= t1 - 1e-9  # decision times are sums of sample steps: compared as the metrics do
        rising = alarm & ~self.prev_alarm[slots]
        waiting = after & ~alarm & ~self.detected[slots]
        same = np.all(declared == active, axis=1)
        zero = np.zeros(len(slots))
        terms = {
            "false_alarm": np.where(rising & ~after, -cfg.false_alarm, zero),
            "detection_delay": np.where(waiting, -cfg.detection_delay_per_s * dt, zero),
            "missed_detection": zero.copy(),
            "isolation": np.where(same & active.any(axis=1), cfg.isolation_per_s * dt, zero),
            "final_isolation": zero.copy(),
        }
        self.prev_alarm[slots] = alarm
        self.detected[slots] |= after & alarm
        self.last_exact[slots] = same
        return terms

    def end(self, slots) -> dict[str, np.ndarray]:
        """The one-off terms of episodes whose last decision was just scored."""
        slots = np.asarray(slots, dtype=np.int64)
        faulty = np.isfinite(self.first_onset[slots])
        return {
            "missed_detection": np.where(faulty & ~self.detected[slots], -self.cfg.missed_detection, 0.0),
            "final_isolation": np.where(faulty & self.last_exact[slots], self.cfg.final_isolation, 0.0),
        }


def score_record_v1(record: dict, cfg: RewardConfigV1 | None = None) -> dict[str, float]:
    """The ``MarineFDI-v1`` return of a recorded episode (a ``marine-fdi evaluate`` episode record:
    ``faults``, ``declared_changes``, ``decision_period_s``, ``duration_s``), replayed decision by
    decision through :class:`RewardV1`: ``{"return": ..., term: sum, ...}``.

    Decisions are at ``t0 + k * period`` up to ``duration_s`` (``t0``: the trace's first entry), the
    declaration at a decision is the last change at or before it, and a fault is active from its
    onset to its end (the metrics' conventions).  Lets stored results of any agent be scored with v1
    without running the simulator again.
    """
    return score_records_v1([record], cfg)[0]


def score_records_v1(records: list[dict], cfg: RewardConfigV1 | None = None) -> list[dict[str, float]]:
    """:func:`score_record_v1` of many records at once (one :class:`RewardV1` slot per record)."""
    from ..engine.faults import FAULT_IDS

    cfg = cfg or RewardConfigV1()
    col = {f: k for k, f in enumerate(FAULT_IDS)}
    n = len(records)
    r = RewardV1(cfg, n)
    grids, declared, alarms, active = [], [], [], []
    for i, rec in enumerate(records):
        trace, faults = rec["declared_changes"], rec["faults"]
        r.start(i, min((float(f["onset_s"]) for f in faults), default=math.inf))
        if not trace:
            grids.append(np.zeros(0))
            declared.append(None)
            alarms.append(None)
            active.append(None)
            continue
        period, t0, end = float(rec["decision_period_s"]), float(trace[0][0]), float(rec["duration_s"])
        t = t0 + period * np.arange(int(math.floor((end - t0) / period + 1e-9)) + 1)
        j = np.searchsorted(np.array([float(c[0]) for c in trace]), t + 1e-9, side="right") - 1
        sets = np.zeros((len(trace), len(FAULT_IDS)), dtype=bool)
        for k, c in enumerate(trace):
            sets[k, [col[f] for f in c[1]]] = True
        act = np.zeros((len(t), len(FAULT_IDS)), dtype=bool)
        for f in faults:
            on = t >= float(f["onset_s"]) - 1e-9
            if f.get("end_s") is not None:
                on &= t < float(f["end_s"]) - 1e-9
            act[on, col[f["id"]]] = True
        grids.append(t)
        declared.append(sets[j])
        alarms.append(np.array([bool(c[2]) for c in trace])[j])
        active.append(act)
    lengths = np.array([len(g) for g in grids], dtype=np.int64)
    periods = np.array([float(rec["decision_period_s"]) for rec in records])
    acc = {name: np.zeros(n) for name in REWARD_TERMS_V1}
    for k in range(int(lengths.max(initial=0))):
        live = np.flatnonzero(lengths > k)
        terms = r.score(
            live,
            np.stack([declared[i][k] for i in live]),
            np.array([alarms[i][k] for i in live]),
            np.stack([active[i][k] for i in live]),
            np.array([grids[i][k] for i in live]),
            periods[live],
        )
        for name, v in terms.items():
            acc[name][live] += v
    for name, v in r.end(np.arange(n)).items():
        acc[name] += v
    out = []
    for i in range(n):
        d = {name: float(acc[name][i]) for name in REWARD_TERMS_V1}
        d["return"] = sum(d[k] for k in REWARD_TERMS_V1)
        out.append(d)
    return out


def make_reward_config(spec) -> "RewardConfig | RewardConfigV1":
    """A reward config from ``None`` (v0 defaults), ``"v0"``, ``"v1"``, a config, or a dict (v0
    fields, or v1 fields with ``"version": "v1"``)."""
    if spec is None or spec == "v0":
        return RewardConfig()
    if spec == "v1":
        return RewardConfigV1()
    if isinstance(spec, (RewardConfig, RewardConfigV1)):
        return spec
    if isinstance(spec, dict):
        d = dict(spec)
        version = d.pop("version", "v0")
        if version not in REWARD_VERSIONS:
            raise ValueError(f"reward field 'version' must be one of {REWARD_VERSIONS}, got {version!r}")
        cls = RewardConfigV1 if version == "v1" else RewardConfig
        allowed = set(cls.__dataclass_fields__)
        bad = set(d) - allowed
        if bad:
            raise ValueError(f"unknown reward fields {sorted(bad)} for {version}; allowed: {sorted(allowed)}")
        return cls(**d)
    raise ValueError(f"reward must be 'v0', 'v1', a RewardConfig, a RewardConfigV1 or a dict, got {spec!r}")
