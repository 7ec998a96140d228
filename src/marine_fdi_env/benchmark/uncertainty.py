"""Uncertainty of benchmark results: 95 % intervals, normalised scores and their interquartile mean.

A result is one agent on one suite; a learned agent has one result per training seed, all on the
same episodes.  :class:`Outcomes` holds the per-episode numbers of such a group as (seeds x
episodes) matrices.  Every interval is a percentile bootstrap (:func:`scipy.stats.bootstrap`,
``N_RESAMPLES`` resamples, a fixed generator seed: the same results give the same interval, bit
for bit) that resamples, independently,

* the training seeds (with replacement; one seed for a non-learned agent), and
* the episodes within each stratum (the fault class of the episode: sensor, process, mixed, none;
  or the suite, for scores across suites), keeping each stratum's size,

and recomputes the metric on every resample ("stratified bootstrap over episodes, and across
training seeds").  Two agents compared on one suite are resampled on the *same* episodes (paired),
so the interval of their difference (:func:`difference`) excludes what the shared episodes explain.

When every resample gives the same value (e.g. no false alarm in any episode of any seed) the
bootstrap interval has zero width, which claims a certainty 48 episodes cannot give; the interval
is then the exact one of one seed's episodes: Clopper-Pearson for a share, Garwood (Poisson) for a
rate per hour (``method: "exact"``).

Normalised score of a suite (D4RL style): ``100 (R - R_null) / (R_oracle - R_null)`` with R the
mean MarineFDI-v1 return over the suite's episodes: the null agent scores 0, the oracle 100.  It is
undefined where the null agent and the oracle earn the same (``nominal-v1``: neither raises an
alarm) and such suites are left out.  Across suites the interquartile mean (rliable's IQM: the
mean of the middle half of the seed x suite scores, :func:`scipy.stats.trim_mean` at 25 %) with the
same bootstrap, the episodes resampled within each suite.

The DX 2025 metrics (:func:`.metrics.dx_metrics`: ``dx_true_detection_rate``,
``dx_false_alarm_rate``, ``dx_fault_isolation_accuracy``) are ratios of decision counts pooled over
the episodes, resampled the same way (whole episodes: a decision is never resampled apart from its
episode).  When their bootstrap is degenerate the exact interval counts each episode as one trial
(an episode's decisions are not independent): Clopper-Pearson over the episodes that have a
decision of the kind the rate counts.

:func:`probability_of_improvement` is rliable's probability that one agent scores above another
(per suite, over pairs of training seeds, ties counting one half; averaged over the suites), with
the same bootstrap over the training seeds of both agents and the suites' shared episodes.
"""

from __future__ import annotations

import inspect
import math
import warnings
from dataclasses import dataclass
from typing import Callable, Mapping, Sequence

import numpy as np

from .metrics import FAULT_CLASSES, episode_outcome

__all__ = [
    "Estimate",
    "Outcomes",
    "RATE_METRICS",
    "CONFIDENCE",
    "N_RESAMPLES",
    "outcomes",
    "interval",
    "difference",
    "normalised_score",
    "iqm_score",
    "probability_of_improvement",
    "seed_spread",
    "DX_METRICS",
]

CONFIDENCE = 0.95
N_RESAMPLES = 2000
_RNG_SEED = 20_250_905  # fixed: the same results give the same intervals
_NEVER = math.inf

# the denominator of each DX rate: an episode with such decisions is one trial of the exact interval
_DX_TRIALS = {
    "dx_true_detection_rate": "dx_fault",
    "dx_false_alarm_rate": "dx_free",
    "dx_fault_isolation_accuracy": "dx_fault_alarm",
}
_FAULTY_ONLY = ("detection_rate", "isolation_accuracy", "median_detection_delay_censored_s")
# the metrics with intervals (pooled over seeds and episodes; see _statistic)
RATE_METRICS = (
    "detection_rate",
    "isolation_accuracy",
    "false_alarm_rate",
    "false_alarm_episode_rate",
    "mean_return",
    "median_detection_delay_censored_s",
)
# the DX 2025 metrics per decision (:func:`.metrics.dx_metrics`), with intervals too
DX_METRICS = ("dx_true_detection_rate", "dx_false_alarm_rate", "dx_fault_isolation_accuracy")
RATE_METRICS = RATE_METRICS + DX_METRICS


@dataclass(frozen=True)
class Estimate:
    """A metric and its 95 % interval (``None`` where undefined); ``method``: ``bootstrap``,
    ``exact`` (a degenerate bootstrap replaced by the exact interval) or ``none``."""

    value: float | None
    low: float | None
    high: float | None
    method: str = "bootstrap"

    def to_dict(self) -> dict:
        return {"value": self.value, "low": self.low, "high": self.high, "method": self.method}


@dataclass(frozen=True)
class Outcomes:
    """Per-episode numbers of one agent on one suite, one row per training seed (S x E arrays).

    faulty (E,): the episode has a fault; stratum (E,): its fault class; detected, isolated: 0/1 on
    faulty episodes (0 elsewhere); delay: detection delay [s] (inf: not detected; faulty only);
    false_alarms: count; fault_free_h: fault-free time [h]; ret: the episode's return; dx_*: the
    episode's DX decision counts (:class:`.metrics.EpisodeOutcome`; ``dx_share`` NaN where missing).
    """

    scenario_ids: tuple[str, ...]
    faulty: np.ndarray
    stratum: np.ndarray
    detected: np.ndarray
    isolated: np.ndarray
    delay: np.ndarray
    false_alarms: np.ndarray
    fault_free_h: np.ndarray
    ret: np.ndarray
    dx_fault: np.ndarray | None = None
    dx_fault_alarm: np.ndarray | None = None
    dx_free: np.ndarray | None = None
    dx_free_alarm: np.ndarray | None = None
    dx_share: np.ndarray | None = None

    @property
    def n_seeds(self) -> int:
        return int(self.detected.shape[0])


def outcomes(episode_lists: Sequence[Sequence[Mapping]]) -> Outcomes:
    """:class:`Outcomes` of one agent on one suite from the episode records of each training seed
    (the same scenarios in the same order in every list; ``ValueError`` otherwise)."""
    if not episode_lists:
        raise ValueError("no results to estimate from")
    ids = tuple(e["scenario_id"] for e in episode_lists[0])
    rows = []
    for eps in episode_lists:
        if tuple(e["scenario_id"] for e in eps) != ids:
            raise ValueError("the results of an agent's training seeds must hold the same episodes in the same order")
        rows.append([episode_outcome(e) for e in eps])
    first = rows[0]
    faulty = np.array([o["faulty"] for o in first], dtype=bool)
    stratum = np.array([FAULT_CLASSES.index(o["fault_class"]) for o in first], dtype=np.int64)

    def grid(f: Callable[[dict], float]) -> np.ndarray:
        return np.array([[f(o) for o in r] for r in rows], dtype=float)

    return Outcomes(
        scenario_ids=ids,
        faulty=faulty,
        stratum=stratum,
        detected=grid(lambda o: float(o["faulty"] and o["detected"])),
        isolated=grid(lambda o: float(bool(o["isolation_correct"]))),
        delay=grid(
            lambda o: (_NEVER if o["detection_delay_s"] is None else o["detection_delay_s"]) if o["faulty"] else _NEVER
        ),
        false_alarms=grid(lambda o: float(o["false_alarms"])),
        fault_free_h=grid(lambda o: o["fault_free_s"] / 3600.0),
        ret=grid(lambda o: o["episode_return"]),
        dx_fault=grid(lambda o: o["dx_fault"]),
        dx_fault_alarm=grid(lambda o: o["dx_fault_alarm"]),
        dx_free=grid(lambda o: o["dx_free"]),
        dx_free_alarm=grid(lambda o: o["dx_free_alarm"]),
        dx_share=grid(lambda o: np.nan if o["dx_share"] is None else o["dx_share"]),
    )


# ----------------------------------------------------------------------------- statistics
def _pick(a: np.ndarray, seeds: np.ndarray, eps: np.ndarray) -> np.ndarray:
    """a[seeds, eps] for resamples: seeds (B, S'), eps (B, E') -> (B, S', E')."""
    return a[seeds[:, :, None], eps[:, None, :]]


def _ratio_stat(num: np.ndarray, den: np.ndarray):
    def stat(seeds, eps):
        n, d = _pick(num, seeds, eps).sum(axis=(1, 2)), _pick(den, seeds, eps).sum(axis=(1, 2))
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(d > 0, n / np.where(d > 0, d, 1.0), np.nan)

    return stat


def _censored_median_stat(delay: np.ndarray, faulty: np.ndarray):
    def stat(seeds, eps):
        d = _pick(delay, seeds, eps)
        f = np.broadcast_to(faulty[eps][:, None, :], d.shape)
        d = np.where(f, d, np.nan).reshape(len(d), -1)
        with warnings.catch_warnings():  # a resample without faulty episodes has no median: NaN
            warnings.simplefilter("ignore", RuntimeWarning)
            m = np.nanmedian(np.where(np.isinf(d), 1e12, d), axis=1)
        return np.where(m >= 1e11, np.inf, m)

    return stat


def _statistic(o: Outcomes, metric: str):
    """The vectorised statistic of ``metric`` on resampled (seeds, episodes) indices."""
    faulty = np.broadcast_to(o.faulty.astype(float), o.detected.shape)
    if metric == "detection_rate":
        return _ratio_stat(o.detected, faulty)
    if metric == "isolation_accuracy":
        return _ratio_stat(o.isolated, faulty)
    if metric == "false_alarm_rate":
        return _ratio_stat(o.false_alarms, o.fault_free_h)
    if metric == "false_alarm_episode_rate":
        return _ratio_stat((o.false_alarms > 0).astype(float), np.ones_like(o.ret))
    if metric == "mean_return":
        return _ratio_stat(o.ret, np.ones_like(o.ret))
    if metric == "median_detection_delay_censored_s":
        return _censored_median_stat(o.delay, o.faulty)
    if metric == "dx_true_detection_rate":
        return _ratio_stat(o.dx_fault_alarm, o.dx_fault)
    if metric == "dx_false_alarm_rate":
        return _ratio_stat(o.dx_free_alarm, o.dx_free)
    if metric == "dx_fault_isolation_accuracy":
        return _ratio_stat(o.dx_share, o.dx_fault_alarm)
    raise ValueError(f"unknown metric {metric!r}; allowed: {', '.join(RATE_METRICS)}")


def _bootstrap(stat, seed_counts: Sequence[int], strata: Sequence[np.ndarray]) -> tuple[float, float]:
    """Percentile interval of ``stat(seed_indices, episode_indices)``: one (B, n) index array per
    entry of ``seed_counts`` (an agent's training seeds) and (B, E) episode indices, the seeds of
    each agent and the episodes of each stratum resampled independently
    (:func:`scipy.stats.bootstrap` with one sample each); a single seed or a one-episode stratum
    is kept as it is (nothing to resample)."""
    import warnings

    from scipy.stats import bootstrap

    free_seeds = [k for k, n in enumerate(seed_counts) if n > 1]
    free_strata = [np.asarray(x) for x in strata if len(x) > 1]
    fixed_eps = np.concatenate([np.asarray(x) for x in strata if len(x) <= 1] or [np.zeros(0, np.int64)])

    def joint(*samples, axis=-1):
        samples = [np.atleast_2d(np.asarray(x, dtype=np.int64)) for x in samples]
        B = samples[0].shape[0] if samples else 1
        seeds, j = [], 0
        for n in seed_counts:
            if n > 1:
                seeds.append(samples[j])
                j += 1
            else:
                seeds.append(np.zeros((B, 1), dtype=np.int64))
        parts = samples[j:] + [np.broadcast_to(fixed_eps, (B, len(fixed_eps)))]
        return stat(seeds, np.concatenate(parts, axis=-1))

    data = tuple(np.arange(seed_counts[k]) for k in free_seeds) + tuple(free_strata)
    if not data:  # nothing varies
        v = float(joint()[0])
        return v, v
    gen = np.random.default_rng(_RNG_SEED)
    kw = {"rng": gen} if "rng" in inspect.signature(bootstrap).parameters else {"random_state": gen}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a degenerate distribution is handled by the callers
        res = bootstrap(
            data,
            joint,
            n_resamples=N_RESAMPLES,
            vectorized=True,
            paired=False,
            method="percentile",
            confidence_level=CONFIDENCE,
            batch=200,
            **kw,
        )
    return float(res.confidence_interval.low), float(res.confidence_interval.high)


def _strata(stratum: np.ndarray, keep: np.ndarray | None = None) -> list[np.ndarray]:
    idx = np.arange(len(stratum))
    if keep is not None:
        idx = idx[keep]
    return [idx[stratum[idx] == k] for k in np.unique(stratum[idx])]


def _exact(metric: str, o: Outcomes, value: float) -> tuple[float, float]:
    """The exact 95 % interval of one seed's episodes for a degenerate bootstrap."""
    from scipy.stats import beta, chi2

    a = 1.0 - CONFIDENCE
    if metric in _DX_TRIALS:  # an episode is one trial: those with a decision of the kind counted
        n = int((getattr(o, _DX_TRIALS[metric])[0] > 0).sum())
        if n == 0:
            return value, value
    elif metric == "false_alarm_rate":
        k, hours = float(o.false_alarms[0].sum()), float(o.fault_free_h[0].sum())
        lo = 0.0 if k == 0 else chi2.ppf(a / 2, 2 * k) / 2
        return float(lo / hours), float(chi2.ppf(1 - a / 2, 2 * k + 2) / 2 / hours)
    else:
        n = int(o.faulty.sum()) if metric in ("detection_rate", "isolation_accuracy") else len(o.faulty)
    k = round(value * n)
    lo = 0.0 if k == 0 else float(beta.ppf(a / 2, k, n - k + 1))
    hi = 1.0 if k == n else float(beta.ppf(1 - a / 2, k + 1, n - k))
    return lo, hi


def interval(o: Outcomes, metric: str) -> Estimate:
    """``metric`` (one of :data:`RATE_METRICS`) over all seeds and episodes of ``o``, with its
    95 % stratified-bootstrap interval (module docstring)."""
    stat = _statistic(o, metric)
    all_seeds = np.arange(o.n_seeds)[None, :]
    value = float(stat(all_seeds, np.arange(len(o.faulty))[None, :])[0])
    if not math.isfinite(value):  # undefined, or a censored median not reached
        return Estimate(None, None, None, "none")
    keep = o.faulty if metric in _FAULTY_ONLY else None
    strata = _strata(o.stratum, keep)
    if not strata:
        return Estimate(value, None, None, "none")
    lo, hi = _bootstrap(lambda seeds, eps: stat(seeds[0], eps), [o.n_seeds], strata)
    if lo == hi and metric not in ("mean_return", "median_detection_delay_censored_s"):
        lo, hi = _exact(metric, o, value)
        return Estimate(value, lo, hi, "exact")
    return Estimate(value, lo, hi, "bootstrap")  # a censored median's high bound may be inf (not reached)


def difference(a: Outcomes, b: Outcomes, metric: str) -> Estimate:
    """``metric`` of ``a`` minus that of ``b`` on the same episodes, with the 95 % interval of the
    difference (the episodes resampled jointly, each agent's seeds independently)."""
    if a.scenario_ids != b.scenario_ids:
        raise ValueError("a difference needs two results on the same episodes")
    sa, sb = _statistic(a, metric), _statistic(b, metric)

    def stat(seeds, eps):
        return sa(seeds[0], eps) - sb(seeds[1], eps)

    all_eps = np.arange(len(a.faulty))[None, :]
    value = float(stat([np.arange(a.n_seeds)[None, :], np.arange(b.n_seeds)[None, :]], all_eps)[0])
    if not math.isfinite(value):
        return Estimate(None, None, None, "none")
    keep = a.faulty if metric in _FAULTY_ONLY else None
    lo, hi = _bootstrap(stat, [a.n_seeds, b.n_seeds], _strata(a.stratum, keep))
    return Estimate(value, lo, hi, "bootstrap")


# ----------------------------------------------------------------------------- normalised scores
def _norm_stat(o: Outcomes, null: Outcomes, oracle: Outcomes):
    """Vectorised per-seed normalised score (B, S) on resampled indices."""

    def stat(seeds, eps):
        r = _pick(o.ret, seeds, eps).mean(axis=2)
        r0 = null.ret[0][eps].mean(axis=1)[:, None]
        r1 = oracle.ret[0][eps].mean(axis=1)[:, None]
        with np.errstate(invalid="ignore", divide="ignore"):
            return 100.0 * (r - r0) / (r1 - r0)

    return stat


def _normalisable(null: Outcomes, oracle: Outcomes) -> bool:
    return abs(float(oracle.ret[0].mean() - null.ret[0].mean())) > 1e-9


def normalised_score(o: Outcomes, null: Outcomes, oracle: Outcomes) -> Estimate:
    """The suite's normalised score of ``o`` (null = 0, oracle = 100) over its seeds, with the 95 %
    interval (the null and oracle returns resampled on the same episodes); undefined (``none``)
    where the null agent and the oracle earn the same."""
    if not (o.scenario_ids == null.scenario_ids == oracle.scenario_ids):
        raise ValueError("normalising needs the null agent's and the oracle's results on the same episodes")
    if not _normalisable(null, oracle):
        return Estimate(None, None, None, "none")
    per_seed = _norm_stat(o, null, oracle)

    def stat(seeds, eps):
        return per_seed(seeds, eps).mean(axis=1)

    value = float(stat(np.arange(o.n_seeds)[None, :], np.arange(len(o.faulty))[None, :])[0])
    lo, hi = _bootstrap(lambda seeds, eps: stat(seeds[0], eps), [o.n_seeds], _strata(o.stratum))
    return Estimate(value, lo, hi, "bootstrap")


def iqm_score(per_suite: Sequence[tuple[Outcomes, Outcomes, Outcomes]]) -> Estimate:
    """Interquartile mean of the normalised scores over training seeds x suites (``per_suite``:
    (agent, null, oracle) outcomes of each suite; suites where the score is undefined are left out),
    with its 95 % interval: the seeds resampled once for all suites, each suite's episodes within it."""
    from scipy.stats import trim_mean

    usable = [t for t in per_suite if _normalisable(t[1], t[2])]
    if not usable:
        return Estimate(None, None, None, "none")
    n_seeds = usable[0][0].n_seeds
    if any(t[0].n_seeds != n_seeds for t in usable):
        raise ValueError("the IQM needs the same training seeds on every suite")
    stats = [_norm_stat(*t) for t in usable]
    sizes = [len(t[0].faulty) for t in usable]
    bounds = np.cumsum([0] + sizes)

    def stat(seeds, eps):  # eps: every suite's resampled episodes, concatenated
        scores = np.stack(
            [s(seeds, eps[:, bounds[k] : bounds[k + 1]] - bounds[k]) for k, s in enumerate(stats)], axis=2
        )  # (B, S, K)
        return trim_mean(scores.reshape(len(scores), -1), 0.25, axis=1)

    allseeds = np.arange(n_seeds)[None, :]
    value = float(stat(allseeds, np.arange(bounds[-1])[None, :])[0])
    lo, hi = _bootstrap(
        lambda seeds, eps: stat(seeds[0], eps),
        [n_seeds],
        [np.arange(bounds[k], bounds[k + 1]) for k in range(len(usable))],
    )
    return Estimate(value, lo, hi, "bootstrap")


def probability_of_improvement(per_suite: Sequence[tuple[Outcomes, Outcomes, Outcomes, Outcomes]]) -> Estimate:
    """rliable's probability of improvement of X over Y: per suite, the share of (X seed, Y seed) pairs
    whose normalised score is higher for X (ties one half), averaged over the suites; ``per_suite``:
    (X, Y, null, oracle) outcomes of each suite (suites where the score is undefined are left out).
    The 95 % interval resamples each agent's training seeds and each suite's episodes (shared by X and
    Y: the comparison is paired)."""
    usable = [t for t in per_suite if _normalisable(t[2], t[3])]
    if not usable:
        return Estimate(None, None, None, "none")
    nx, ny = usable[0][0].n_seeds, usable[0][1].n_seeds
    if any(t[0].n_seeds != nx or t[1].n_seeds != ny for t in usable):
        raise ValueError("the probability of improvement needs the same training seeds on every suite")
    sx = [_norm_stat(t[0], t[2], t[3]) for t in usable]
    sy = [_norm_stat(t[1], t[2], t[3]) for t in usable]
    bounds = np.cumsum([0] + [len(t[0].faulty) for t in usable])

    def stat(seeds, eps):  # seeds: [X's (B, nx), Y's (B, ny)]
        out = []
        for k in range(len(usable)):
            e = eps[:, bounds[k] : bounds[k + 1]] - bounds[k]
            a, b = sx[k](seeds[0], e)[:, :, None], sy[k](seeds[1], e)[:, None, :]
            out.append(((a > b) + 0.5 * (a == b)).mean(axis=(1, 2)))
        return np.mean(out, axis=0)

    whole = [np.arange(nx)[None, :], np.arange(ny)[None, :]]
    value = float(stat(whole, np.arange(bounds[-1])[None, :])[0])
    lo, hi = _bootstrap(stat, [nx, ny], [np.arange(bounds[k], bounds[k + 1]) for k in range(len(usable))])
    return Estimate(value, lo, hi, "bootstrap")


def seed_spread(o: Outcomes, metric: str) -> tuple[float, float] | None:
    """(lowest, highest) of ``metric`` over the training seeds taken one at a time."""
    stat = _statistic(o, metric)
    v = [float(stat(np.array([[s]]), np.arange(len(o.faulty))[None, :])[0]) for s in range(o.n_seeds)]
    v = [x for x in v if not math.isnan(x)]
    return (min(v), max(v)) if v else None
