"""Benchmark metrics for ``MarineFDI-v0``: pure functions over per-episode records.

This docstring is the benchmark's contract (in the spirit of the LiU-ICE / DX diagnosis
competitions).

Episode record
--------------
One JSON-ready dict per scenario (written by ``marine-fdi evaluate``)::

    scenario_id: str, suite: str, seed: int, agent: str, profile: str,
    duration_s: float        simulated time of the episode (shorter if terminated early)
    decision_period_s: float (> 0)
    n_samples: int           sensor samples processed
    faults: [{"id", "class": "sensor"|"process", "onset_s", "magnitude", "end_s": float|None}]
    declared_changes: [[t_s, [sorted fault ids], alarm], ...]
    belief_on_truth: [[t_s, share], ...]          (optional)
    terminated: bool, failure_reason: str|None, compute_s: float,
    return: float, reward_terms: {name: float}
    feature_compute_s, agent_compute_s: float, n_decisions: int   (optional: compute_s split into
                             the shared observation features and the agent's own decisions)

``declared_changes`` is the decision trace as change points: the first entry is at the first
decision time ``t0``; a new entry whenever the declared set or the alarm flag changes.  Decisions
are taken at ``t0 + k * decision_period_s`` (k = 0, 1, ...) up to ``duration_s``; the state at a
decision time ``t`` is that of the last entry with ``t_s <= t``.  An empty trace means the agent
never decided (no alarm, nothing declared).

Definitions
-----------
* **Faulty episode**: ``faults`` is non-empty.  *First onset* / *last onset*: min / max of
  ``onset_s`` over the faults.
* **Fault-free time**: ``[0, min(first onset, duration_s))``, or ``[0, duration_s)`` without
  faults.  ``fault_free_hours`` is its total length over all episodes, in hours.
* **False alarm**: a rising edge of the alarm flag (an entry with alarm on whose predecessor has it
  off, or a first entry with alarm on) at a decision time ``t < first onset`` (any ``t`` for a
  fault-free episode).
  ``false_alarm_rate`` (= ``false_alarms_per_hour``) = total false alarms / ``fault_free_hours``;
  ``false_alarm_episode_rate`` = share of episodes with at least one false alarm.
* **Detection**: detection time = first decision time ``t >= first onset`` at which the alarm is
  on (an alarm raised before the onset and still on counts at the first decision after it).
  ``detection_rate`` = share of faulty episodes with a detection time; detection delay
  = detection time - first onset.
* **Isolation**: the true set at ``t`` is ``{id : onset_s <= t and (end_s is None or end_s > t)}``
  (intermittent faults are treated as active from onset to end).  Isolation is correct at ``t``
  when the declared set equals the true set exactly.  Isolation time = first decision time
  ``t >= last onset`` with correct isolation and a non-empty true set (declaring nothing after a
  transient fault ended is not an isolation); isolation delay = isolation time - last onset.
  ``isolation_accuracy`` = share of faulty episodes whose final declared set (last entry of the
  trace; empty without decisions) equals the true set at the final decision time (at
  ``duration_s`` without decisions).
* ``belief_on_truth`` = mean over faulty episodes that carry a non-empty ``belief_on_truth`` of the
  per-episode mean share; ``None`` if no episode has one.
* Delays: ``median_*`` and ``p90_*`` over the episodes where the delay exists, linear
  interpolation between closest ranks (numpy's default); ``None`` when there are none.
  ``median_detection_delay_censored_s``: the median detection delay over *all* faulty episodes,
  an undetected episode counting as never detected (+inf), i.e. the delay by which half of the
  faulty episodes are detected (the Kaplan-Meier median without censoring before the episode
  end); ``None`` when that is not reached (the middle rank is an undetected episode) or there is
  no faulty episode.  Unlike ``median_detection_delay_s`` it does not improve when an agent
  detects fewer of the hard faults.
* ``compute_s_per_sample`` = sum ``compute_s`` / sum ``n_samples``;
  ``feature_compute_s_per_sample`` = sum ``feature_compute_s`` / sum ``n_samples`` and
  ``agent_compute_s_per_decision`` = sum ``agent_compute_s`` / sum ``n_decisions`` over the
  records that carry them (``None`` if none does); ``mean_return`` = mean
  ``return``; ``engine_failures`` = number of episodes with ``terminated`` true;
  ``isolation_rate`` = share of faulty episodes with an isolation time.
* A ratio with an empty denominator is ``None`` (never NaN).

DX metrics (:func:`dx_metrics`)
------------------------------
The DX 2025 diagnosis competition's three (LiU-ICE engine; ``marine-fdi score-raw`` computes them on
100 Hz samples), here per decision, pooled over all decisions of all episodes:

* ``true_detection_rate`` (TDR): share of the decisions with a fault active (the true set at ``t``
  non-empty) at which the alarm is on;
* ``false_alarm_rate`` (FAR): share of the decisions with no fault active at which the alarm is on
  (also after a fault that ended);
* ``fault_isolation_accuracy`` (FIA): mean, over the decisions with a fault active and the alarm
  on, of the agent's share of belief on the true faults (``belief_on_truth`` of that decision);
  ``None`` when a record lacks the share of one of those decisions.

A decision grid point is a decision ``t0 + k * decision_period_s`` for ``k < n_decisions`` (or up to
the last decision time when a record has no ``n_decisions``).

Breakdown: ``by_class`` holds the same metrics for episodes whose faults are all ``sensor``, all
``process``, ``mixed``, and ``none`` (fault-free; only the false-alarm metrics are meaningful);
``by_fault`` for single-fault episodes (one distinct fault id), keyed by fault id.
"""

from __future__ import annotations

import bisect
import math
from contextlib import contextmanager
from dataclasses import asdict, dataclass
from typing import Any, Callable, Iterable, Mapping, Sequence

import numpy as np

from ..engine.faults import FAULT_IDS, fault_class

__all__ = [
    "EpisodeOutcome",
    "validate_record",
    "episode_outcome",
    "compute_metrics",
    "aggregate",
    "dx_metrics",
    "dx_aggregate",
    "metric_blocks",
    "FAULT_CLASSES",
    "DX_KEYS",
    "scored_once",
]

FAULT_CLASSES: tuple[str, ...] = ("sensor", "process", "mixed", "none")
_EPS = 1e-9
_FAULT_ID_SET = frozenset(FAULT_IDS)


# ----------------------------------------------------------------------------- validation


def _fail(sid: Any, field: str, msg: str) -> ValueError:
    return ValueError(f"episode record {sid!r}: field {field!r} {msg}")


def _is_num(v: Any) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _num(
    rec: Mapping,
    key: str,
    sid: Any,
    *,
    field: str | None = None,
    positive: bool = False,
    nonneg: bool = False,
    optional: bool = False,
) -> None:
    name = field or key
    if key not in rec:
        raise _fail(sid, name, "is missing")
    v = rec[key]
    if v is None and optional:
        return
    if not _is_num(v):
        raise _fail(sid, name, f"must be a finite number, got {v!r}")
    if positive and v <= 0:
        raise _fail(sid, name, f"must be > 0, got {v!r}")
    if nonneg and v < 0:
        raise _fail(sid, name, f"must be >= 0, got {v!r}")


def _typed(rec: Mapping, key: str, types: type | tuple[type, ...], sid: Any, *, optional: bool = False) -> None:
    if key not in rec:
        raise _fail(sid, key, "is missing")
    v = rec[key]
    if v is None and optional:
        return
    tup = types if isinstance(types, tuple) else (types,)
    if not isinstance(v, tup) or (isinstance(v, bool) and bool not in tup):
        names = "/".join(t.__name__ for t in tup) + (" or null" if optional else "")
        raise _fail(sid, key, f"must be {names}, got {v!r}")


def validate_record(rec: Any) -> None:
    """Check one episode record; ``ValueError`` naming the field and the scenario_id."""
    if not isinstance(rec, Mapping):
        raise ValueError(f"episode record must be a dict, got {type(rec).__name__}")
    sid = rec.get("scenario_id", "<no scenario_id>")
    for key in ("scenario_id", "suite", "agent", "profile"):
        _typed(rec, key, str, sid)
    _typed(rec, "seed", int, sid)
    _typed(rec, "n_samples", int, sid)
    if rec["n_samples"] < 0:
        raise _fail(sid, "n_samples", "must be >= 0")
    _num(rec, "duration_s", sid, nonneg=True)
    _num(rec, "decision_period_s", sid, positive=True)
    _num(rec, "compute_s", sid, nonneg=True)
    _num(rec, "return", sid)
    _typed(rec, "terminated", bool, sid)
    _typed(rec, "failure_reason", str, sid, optional=True)
    _typed(rec, "reward_terms", dict, sid)
    for name, v in rec["reward_terms"].items():
        if not isinstance(name, str) or not _is_num(v):
            raise _fail(sid, "reward_terms", f"must map str to finite numbers, got {name!r}: {v!r}")
    _typed(rec, "faults", list, sid)
    for i, f in enumerate(rec["faults"]):
        fld = f"faults[{i}]"
        if not isinstance(f, Mapping):
            raise _fail(sid, fld, f"must be a dict, got {f!r}")
        if "id" not in f:
            raise _fail(sid, f"{fld}.id", "is missing")
        if f["id"] not in _FAULT_ID_SET:
            raise _fail(sid, f"{fld}.id", f"must be a fault id, got {f['id']!r}")
        if "class" not in f:
            raise _fail(sid, f"{fld}.class", "is missing")
        if f["class"] != fault_class(f["id"]):
            raise _fail(sid, f"{fld}.class", f"must be {fault_class(f['id'])!r} for {f['id']}, got {f['class']!r}")
        _num(f, "onset_s", sid, field=f"{fld}.onset_s", nonneg=True)
        _num(f, "magnitude", sid, field=f"{fld}.magnitude")
        _num(f, "end_s", sid, field=f"{fld}.end_s", optional=True)
        if f["end_s"] is not None and f["end_s"] <= f["onset_s"]:
            raise _fail(sid, f"{fld}.end_s", f"must be > onset_s, got {f['end_s']!r}")
    _typed(rec, "declared_changes", list, sid)
    prev_t = -math.inf
    for i, entry in enumerate(rec["declared_changes"]):
        fld = f"declared_changes[{i}]"
        if not (isinstance(entry, (list, tuple)) and len(entry) == 3):
            raise _fail(sid, fld, f"must be [t_s, [fault ids], alarm], got {entry!r}")
        t, ids, alarm = entry
        if not _is_num(t) or t <= prev_t:
            raise _fail(sid, fld, f"time must be a finite number increasing along the trace, got {t!r}")
        prev_t = t
        if not isinstance(ids, (list, tuple)) or any(x not in _FAULT_ID_SET for x in ids):
            raise _fail(sid, fld, f"declared set must be a list of fault ids, got {ids!r}")
        if not isinstance(alarm, bool):
            raise _fail(sid, fld, f"alarm must be a bool, got {alarm!r}")
    bot = rec.get("belief_on_truth")
    if bot is not None:
        if not isinstance(bot, list):
            raise _fail(sid, "belief_on_truth", f"must be a list of [t_s, share], got {bot!r}")
        for i, entry in enumerate(bot):
            if not (
                isinstance(entry, (list, tuple))
                and len(entry) == 2
                and _is_num(entry[0])
                and _is_num(entry[1])
                and -_EPS <= entry[1] <= 1 + _EPS
            ):
                raise _fail(sid, f"belief_on_truth[{i}]", f"must be [t_s, share in 0..1], got {entry!r}")


# ----------------------------------------------------------------------------- one episode


@dataclass(frozen=True)
class EpisodeOutcome:
    """Per-episode scoring (times in s; ``None`` where undefined)."""

    scenario_id: str
    suite: str
    agent: str
    fault_class: str  # sensor | process | mixed | none
    fault_ids: tuple[str, ...]  # distinct ids, sorted
    first_onset_s: float | None
    last_onset_s: float | None
    fault_free_s: float
    false_alarms: int
    detection_time_s: float | None
    detection_delay_s: float | None
    isolation_time_s: float | None
    isolation_delay_s: float | None
    final_declared: tuple[str, ...]
    final_true: tuple[str, ...]
    isolation_correct: bool | None  # None for fault-free episodes
    belief_on_truth: float | None
    n_samples: int
    compute_s: float
    episode_return: float
    terminated: bool
    failure_reason: str | None
    feature_compute_s: float | None = None
    agent_compute_s: float | None = None
    n_decisions: int | None = None
    # the DX counts (decisions): with a fault active, and of those with the alarm on; without a fault, and
    # of those with the alarm on; the sum of the share of belief on the truth over the alarmed faulty ones
    # (None: a share missing from the record)
    dx_fault: int = 0
    dx_fault_alarm: int = 0
    dx_free: int = 0
    dx_free_alarm: int = 0
    dx_share: float | None = 0.0

    @property
    def faulty(self) -> bool:
        return bool(self.fault_ids)

    @property
    def detected(self) -> bool:
        return self.detection_time_s is not None

    def to_dict(self) -> dict:
        d = asdict(self)
        for k in ("fault_ids", "final_declared", "final_true"):
            d[k] = list(d[k])
        d["faulty"], d["detected"] = self.faulty, self.detected
        return d


@dataclass(frozen=True)
class _Trace:
    """Decision trace with the decision-time grid."""

    times: tuple[float, ...]
    sets: tuple[frozenset[str], ...]
    alarms: tuple[bool, ...]
    period: float
    last_decision: float  # last decision time of the episode (-inf if none)

    @classmethod
    def from_record(cls, rec: Mapping) -> "_Trace":
        ch = rec["declared_changes"]
        times = tuple(float(c[0]) for c in ch)
        period = float(rec["decision_period_s"])
        if times:
            t0, dur = times[0], max(float(rec["duration_s"]), times[-1])
            last = t0 + math.floor((dur - t0) / period + _EPS) * period
            last = max(last, times[-1])
        else:
            last = -math.inf
        return cls(times, tuple(frozenset(c[1]) for c in ch), tuple(bool(c[2]) for c in ch), period, last)

    def grid_ceil(self, t: float) -> float:
        """First decision time >= t."""
        t0 = self.times[0]
        if t <= t0:
            return t0
        k = math.ceil((t - t0) / self.period - _EPS)
        g = t0 + k * self.period
        return t if abs(g - t) <= _EPS * max(1.0, abs(t)) else g

    def state(self, t: float) -> tuple[frozenset[str], bool]:
        i = bisect.bisect_right(self.times, t + _EPS) - 1
        return (self.sets[i], self.alarms[i]) if i >= 0 else (frozenset(), False)

    def first_time(
        self, start: float, breaks: Iterable[float], pred: Callable[[float, frozenset[str], bool], bool]
    ) -> float | None:
        """First decision time t >= start with ``pred(t, declared, alarm)``.

        The predicate must be constant between consecutive points of ``breaks`` ∪ change times.
        """
        if not self.times:
            return None
        pts = sorted({start, *self.times, *breaks})
        pts = [p for p in pts if p >= start]
        for i, p in enumerate(pts):
            t = self.grid_ceil(p)
            if t > self.last_decision + _EPS:
                return None
            if i + 1 < len(pts) and t >= pts[i + 1] - _EPS:
                continue  # no decision inside this segment; the next one starts at/after t
            declared, alarm = self.state(t)
            if pred(t, declared, alarm):
                return t
        return None


def _true_set(faults: Sequence[Mapping], t: float) -> frozenset[str]:
    return frozenset(
        f["id"] for f in faults if f["onset_s"] <= t + _EPS and (f["end_s"] is None or f["end_s"] > t + _EPS)
    )


def _class_of(faults: Sequence[Mapping]) -> str:
    classes = {f["class"] for f in faults}
    if not classes:
        return "none"
    return classes.pop() if len(classes) == 1 else "mixed"


def _dx_counts(rec: Mapping, tr: _Trace) -> dict:
    """The DX counts of one episode over its decision grid (module docstring).  One pass over the grid:
    the declaration in force at ``t`` is the last change at or before ``t`` (:meth:`_Trace.state`, found
    by walking the changes as ``t`` grows), a fault is active at ``t`` as in :func:`_true_set`."""
    if not tr.times:
        return {}
    t0, period = tr.times[0], tr.period
    n = rec.get("n_decisions")
    if not isinstance(n, int) or isinstance(n, bool) or n < 1:
        n = int(round((tr.last_decision - t0) / period)) + 1
    shares = {round(float(t), 6): float(v) for t, v in (rec.get("belief_on_truth") or [])}
    spans = [(f["onset_s"], f["end_s"]) for f in rec["faults"]]
    times, alarms, last = tr.times, tr.alarms, len(tr.times) - 1
    fault = fault_alarm = free = free_alarm = 0
    share: float | None = 0.0
    i = -1
    for k in range(n):
        t = t0 + k * period
        te = t + _EPS
        while i < last and times[i + 1] <= te:
            i += 1
        alarm = i >= 0 and alarms[i]
        if any(on <= te and (end is None or end > te) for on, end in spans):
            fault += 1
            if alarm:
                fault_alarm += 1
                v = shares.get(round(t, 6))
                share = None if v is None or share is None else share + v
        else:
            free += 1
            free_alarm += int(alarm)
    return {
        "dx_fault": fault,
        "dx_fault_alarm": fault_alarm,
        "dx_free": free,
        "dx_free_alarm": free_alarm,
        "dx_share": share,
    }


_SCORED: dict[int, tuple[Mapping, EpisodeOutcome]] | None = None


@contextmanager
def scored_once():
    """Within the block, each record (the same object) is scored once: :func:`compute_metrics`,
    :func:`dx_metrics` and :func:`.uncertainty.outcomes` of the same records share the outcomes (the
    records must not change inside the block).  ``marine-fdi verify`` and the leaderboard use it."""
    global _SCORED
    outer = _SCORED
    if outer is None:
        _SCORED = {}
    try:
        yield
    finally:
        _SCORED = outer


def _outcome(rec: Mapping) -> EpisodeOutcome:
    if _SCORED is not None:
        hit = _SCORED.get(id(rec))
        if hit is not None and hit[0] is rec:
            return hit[1]
        out = _score(rec)
        _SCORED[id(rec)] = (rec, out)  # the record kept alive: its id is not reused inside the block
        return out
    return _score(rec)


def _score(rec: Mapping) -> EpisodeOutcome:
    validate_record(rec)
    faults = rec["faults"]
    tr = _Trace.from_record(rec)
    duration = float(rec["duration_s"])
    first = min((float(f["onset_s"]) for f in faults), default=None)
    last = max((float(f["onset_s"]) for f in faults), default=None)
    fault_free_end = duration if first is None else min(first, duration)

    false_alarms = 0
    for i, (t, alarm) in enumerate(zip(tr.times, tr.alarms)):
        rising = alarm and (i == 0 or not tr.alarms[i - 1])
        if rising and (first is None or t < first - _EPS):
            false_alarms += 1

    det = iso = None
    final_declared: frozenset[str] = tr.sets[-1] if tr.sets else frozenset()
    final_true: frozenset[str] = frozenset()
    if faults:
        det = tr.first_time(first, (), lambda t, d, a: a)
        breaks = [float(f["onset_s"]) for f in faults] + [float(f["end_s"]) for f in faults if f["end_s"] is not None]
        iso = tr.first_time(last, breaks, lambda t, d, a: bool(d) and d == _true_set(faults, t))
        final_true = _true_set(faults, tr.last_decision if tr.times else duration)

    bot = None
    shares = [float(s) for _, s in (rec.get("belief_on_truth") or [])]
    if faults and shares:
        bot = sum(shares) / len(shares)

    return EpisodeOutcome(
        scenario_id=rec["scenario_id"],
        suite=rec["suite"],
        agent=rec["agent"],
        fault_class=_class_of(faults),
        fault_ids=tuple(sorted({f["id"] for f in faults})),
        first_onset_s=first,
        last_onset_s=last,
        fault_free_s=max(fault_free_end, 0.0),
        false_alarms=false_alarms,
        detection_time_s=det,
        detection_delay_s=None if det is None else max(det - first, 0.0),
        isolation_time_s=iso,
        isolation_delay_s=None if iso is None else max(iso - last, 0.0),
        final_declared=tuple(sorted(final_declared)),
        final_true=tuple(sorted(final_true)),
        isolation_correct=(final_declared == final_true) if faults else None,
        belief_on_truth=bot,
        n_samples=int(rec["n_samples"]),
        compute_s=float(rec["compute_s"]),
        episode_return=float(rec["return"]),
        terminated=bool(rec["terminated"]),
        failure_reason=rec["failure_reason"],
        **_compute_split(rec),
        **_dx_counts(rec, tr),
    )


def _compute_split(rec: Mapping) -> dict:
    """The optional split of ``compute_s`` (features / agent) of a record; checked when present."""
    keys = ("feature_compute_s", "agent_compute_s", "n_decisions")
    if not any(k in rec for k in keys):
        return {}
    sid = rec.get("scenario_id")
    for k in keys[:2]:
        _num(rec, k, sid, nonneg=True)
    _typed(rec, "n_decisions", int, sid)
    return {
        "feature_compute_s": float(rec["feature_compute_s"]),
        "agent_compute_s": float(rec["agent_compute_s"]),
        "n_decisions": int(rec["n_decisions"]),
    }


def episode_outcome(record: Mapping) -> dict:
    """Score one episode record (see the module docstring); JSON-ready dict."""
    return _outcome(record).to_dict()


# ----------------------------------------------------------------------------- aggregation


def _ratio(num: float, den: float) -> float | None:
    return float(num) / float(den) if den else None


def _pct(values: Sequence[float], q: float) -> float | None:
    return float(np.percentile(np.asarray(values, dtype=float), q)) if values else None


_NEVER = 1e300  # stands for +inf in the censored median (numpy's interpolation turns inf into NaN)


def _censored_median(delays: Sequence[float], n_faulty: int) -> float | None:
    """Median over n_faulty episodes of which ``delays`` were detected, the others never."""
    if not n_faulty:
        return None
    v = np.concatenate([np.asarray(delays, dtype=float), np.full(n_faulty - len(delays), _NEVER)])
    m = float(np.percentile(v, 50))
    return m if m < _NEVER / 1e3 else None


def aggregate(outcomes: Sequence[EpisodeOutcome]) -> dict:
    """Flat metrics over a group of scored episodes."""
    faulty = [o for o in outcomes if o.faulty]
    det = [o.detection_delay_s for o in faulty if o.detection_delay_s is not None]
    iso = [o.isolation_delay_s for o in faulty if o.isolation_delay_s is not None]
    ff_hours = sum(o.fault_free_s for o in outcomes) / 3600.0
    n_fa = sum(o.false_alarms for o in outcomes)
    fa_rate = _ratio(n_fa, ff_hours)
    bots = [o.belief_on_truth for o in faulty if o.belief_on_truth is not None]
    split = [o for o in outcomes if o.n_decisions is not None]
    return {
        "n_episodes": len(outcomes),
        "n_faulty": len(faulty),
        "fault_free_hours": ff_hours,
        "n_false_alarms": n_fa,
        "false_alarm_rate": fa_rate,
        "false_alarms_per_hour": fa_rate,
        "false_alarm_episode_rate": _ratio(sum(o.false_alarms > 0 for o in outcomes), len(outcomes)),
        "detection_rate": _ratio(len(det), len(faulty)),
        "median_detection_delay_s": _pct(det, 50),
        "p90_detection_delay_s": _pct(det, 90),
        "median_detection_delay_censored_s": _censored_median(det, len(faulty)),
        "isolation_rate": _ratio(len(iso), len(faulty)),
        "isolation_accuracy": _ratio(sum(bool(o.isolation_correct) for o in faulty), len(faulty)),
        "median_isolation_delay_s": _pct(iso, 50),
        "p90_isolation_delay_s": _pct(iso, 90),
        "belief_on_truth": sum(bots) / len(bots) if bots else None,
        "compute_s_per_sample": _ratio(sum(o.compute_s for o in outcomes), sum(o.n_samples for o in outcomes)),
        "feature_compute_s_per_sample": _ratio(sum(o.feature_compute_s for o in split), sum(o.n_samples for o in split))
        if split
        else None,
        "agent_compute_s_per_decision": _ratio(sum(o.agent_compute_s for o in split), sum(o.n_decisions for o in split))
        if split
        else None,
        "mean_return": (sum(o.episode_return for o in outcomes) / len(outcomes)) if outcomes else None,
        "engine_failures": sum(o.terminated for o in outcomes),
    }


def compute_metrics(records: Sequence[Mapping]) -> dict:
    """Overall metrics plus ``by_class`` (sensor/process/mixed/none) and ``by_fault``."""
    outcomes = [_outcome(r) for r in records]
    out = aggregate(outcomes)
    out["by_class"] = {c: aggregate([o for o in outcomes if o.fault_class == c]) for c in FAULT_CLASSES}
    single: dict[str, list[EpisodeOutcome]] = {}
    for o in outcomes:
        if len(o.fault_ids) == 1:
            single.setdefault(o.fault_ids[0], []).append(o)
    order = {f: i for i, f in enumerate(FAULT_IDS)}
    out["by_fault"] = {f: aggregate(single[f]) for f in sorted(single, key=order.__getitem__)}
    return out


# ----------------------------------------------------------------------------- DX metrics
DX_KEYS = ("true_detection_rate", "false_alarm_rate", "fault_isolation_accuracy")


def dx_aggregate(outcomes: Sequence[EpisodeOutcome]) -> dict:
    """The DX metrics (module docstring) pooled over the decisions of a group of scored episodes."""
    fault = sum(o.dx_fault for o in outcomes)
    alarmed = sum(o.dx_fault_alarm for o in outcomes)
    free = sum(o.dx_free for o in outcomes)
    shares = [o.dx_share for o in outcomes]
    return {
        "true_detection_rate": _ratio(alarmed, fault),
        "false_alarm_rate": _ratio(sum(o.dx_free_alarm for o in outcomes), free),
        "fault_isolation_accuracy": None if any(v is None for v in shares) else _ratio(sum(shares), alarmed),
        "n_fault_decisions": fault,
        "n_fault_free_decisions": free,
    }


def dx_metrics(records: Sequence[Mapping]) -> dict:
    """The DX 2025 metrics per decision (module docstring) over ``records``, and ``by_class``."""
    outcomes = [_outcome(r) for r in records]
    out = dx_aggregate(outcomes)
    out["by_class"] = {c: dx_aggregate([o for o in outcomes if o.fault_class == c]) for c in FAULT_CLASSES}
    return out


def metric_blocks(records: Sequence[Mapping]) -> dict:
    """``{"metrics": compute_metrics(records), "dx_metrics": dx_metrics(records)}``: the scores of a results
    object, of an entry's suite and of a sweep's cell."""
    return {"metrics": compute_metrics(records), "dx_metrics": dx_metrics(records)}
