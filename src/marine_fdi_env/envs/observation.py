"""Observation of ``MarineFDI-v0``: residual and adaptive-threshold features of the 19 monitoring
modules of the reference diagnoser over one decision period.

Per module M (in :data:`marine_fdi_env.diagnosis.modules.MODULE_IDS` order), over the samples of
the period, with ``ratio = |residual| / threshold`` (> 1: the module's ARR is violated):

=====  ===========================  ===============================================  ==========
#      feature                      definition                                       bounds
=====  ===========================  ===============================================  ===============
0      ``log_max_ratio``            log(1 + min(max ratio, 1000))                    [0, 6.909]
1      ``log_mean_ratio``           log(1 + min(mean ratio, 1000))                   [0, 6.909]
2      ``signed_mean_ratio``        s log(1 + min(|m|, 1000)), m = mean of r/thr,    [-6.909, 6.909]
                                    s = sign(m)
3      ``violation_fraction``       share of the period's samples with ratio > 1     [0, 1]
4      ``fired``                    1 once the module has fired this episode          {0, 1}
5      ``since_first_violation``    (t - first violation time) / episode length       [0, 1]
=====  ===========================  ===============================================  ===============

The signed mean keeps what the unsigned ratios lose: a small fault shifts a residual's mean one way
while the noise averages out, long before the worst-case threshold is crossed (the adaptive
thresholds bound the noise's extremes, not its mean), so a learner can accumulate the evidence.

then one global feature, ``time_fraction`` = t / episode length in [0, 1]; with
``observe_sensors=True``, the period means of the 19 sensors as relative deviations from the
nominal reading, clipped to [-1, 1], and the period mean of the applied fuel setting in [0, 1.2];
and last, with ``observe_sequential=True``, per module the state of the ``sequential`` diagnoser's
CUSUM tests at the end of the period (:mod:`marine_fdi_env.diagnosis.sequential`):

=====  ===========================  ===============================================  ==========
#      feature                      definition                                       bounds
=====  ===========================  ===============================================  ==========
0      ``cusum_up``                 S+ / h (the test fires above 1), capped          [0, 10]
1      ``cusum_down``               S- / h, capped                                   [0, 10]
2      ``block_z``                  the last 1 s block's normalised residual mean    [-10, 10]
3      ``seq_fired``                1 once the sequential module has fired           {0, 1}
=====  ===========================  ===============================================  ==========

(cost: one more compiled pass over the period's residuals and the sequential decision logic,
about 0.05 µs per engine-sample; ``benchmarks/env.py --observe-sequential``).  The default
observation (115 features) is unchanged by these options.
A sensor that dropped out (NaN) gives a violated, saturated module (ratio = 1000) and a sensor
feature of 0.  Everything is float32 and finite.
"""

from __future__ import annotations

import math

import numpy as np

from ..diagnosis.modules import MODULE_IDS
from ..diagnosis.peak_ratio import RATIO_CAP, period_stats
from ..diagnosis.sequential import SEQUENTIAL_FEATURES, Z_CAP
from ..engine.sensors import SENSOR_IDS

__all__ = [
    "MODULE_FEATURES",
    "RATIO_CAP",
    "observation_size",
    "observation_bounds",
    "feature_names",
    "module_features",
    "SEQUENTIAL_FEATURES",
]

MODULE_FEATURES = (
    "log_max_ratio",
    "log_mean_ratio",
    "signed_mean_ratio",
    "violation_fraction",
    "fired",
    "since_first_violation",
)
_LOG_CAP = math.log1p(RATIO_CAP)
N_MODULES = len(MODULE_IDS)


def observation_size(observe_sensors: bool, observe_sequential: bool = False) -> int:
    return (
        N_MODULES * len(MODULE_FEATURES)
        + 1
        + (len(SENSOR_IDS) + 1 if observe_sensors else 0)
        + (N_MODULES * len(SEQUENTIAL_FEATURES) if observe_sequential else 0)
    )


def feature_names(observe_sensors: bool, observe_sequential: bool = False) -> list[str]:
    names = [f"{m}.{f}" for m in MODULE_IDS for f in MODULE_FEATURES] + ["time_fraction"]
    if observe_sensors:
        names += [f"{s}.relative_deviation" for s in SENSOR_IDS] + ["u.mean"]
    if observe_sequential:
        names += [f"{m}.{f}" for m in MODULE_IDS for f in SEQUENTIAL_FEATURES]
    return names


def observation_bounds(observe_sensors: bool, observe_sequential: bool = False) -> tuple[np.ndarray, np.ndarray]:
    per = np.array(
        [[0.0, 0.0, -_LOG_CAP, 0.0, 0.0, 0.0], [_LOG_CAP, _LOG_CAP, _LOG_CAP, 1.0, 1.0, 1.0]], dtype=np.float32
    )
    low = np.concatenate([np.tile(per[0], N_MODULES), [0.0]])
    high = np.concatenate([np.tile(per[1], N_MODULES), [1.0]])
    if observe_sensors:
        low = np.concatenate([low, -np.ones(len(SENSOR_IDS)), [0.0]])
        high = np.concatenate([high, np.ones(len(SENSOR_IDS)), [1.2]])
    if observe_sequential:
        low = np.concatenate([low, np.tile([0.0, 0.0, -Z_CAP, 0.0], N_MODULES)])
        high = np.concatenate([high, np.tile([Z_CAP, Z_CAP, Z_CAP, 1.0], N_MODULES)])
    return low.astype(np.float32), high.astype(np.float32)


def module_features(
    R: np.ndarray,
    THR: np.ndarray,
    first_violation: np.ndarray,
    t_now: np.ndarray,
    duration_s: np.ndarray,
    stats: np.ndarray | None = None,
) -> np.ndarray:
    """Features (N, 19 * 6 + 1) from residuals and thresholds (N, B, 19) of one period.

    first_violation : (N, 19) time of each module's first violation this episode (NaN: never).
    t_now : (N,) each engine's time at the end of the period [s]; duration_s : (N,) episode lengths.
    stats : (N, 19, 4) the period statistics if already computed (the reference diagnoser's
    ``BlockOutput.stats``, the same numbers as :func:`~marine_fdi_env.diagnosis.peak_ratio.period_stats`);
    else computed here.
    """
    duration_s = np.broadcast_to(np.asarray(duration_s, dtype=float), t_now.shape)
    N = R.shape[0]
    if stats is None:
        stats = np.empty((N, N_MODULES, 4))
        period_stats(np.ascontiguousarray(R, dtype=np.float64), np.ascontiguousarray(THR, dtype=np.float64), stats)
    out = np.empty((N, N_MODULES, len(MODULE_FEATURES)))
    out[:, :, 0] = np.log1p(stats[:, :, 0])
    out[:, :, 1] = np.log1p(stats[:, :, 1])
    m = stats[:, :, 2]
    out[:, :, 2] = np.sign(m) * np.log1p(np.abs(m))
    out[:, :, 3] = stats[:, :, 3]
    fired = ~np.isnan(first_violation)
    out[:, :, 4] = fired
    since = np.where(fired, t_now[:, None] - np.nan_to_num(first_violation), 0.0) / duration_s[:, None]
    out[:, :, 5] = np.clip(since, 0.0, 1.0)
    time_frac = np.clip(t_now / duration_s, 0.0, 1.0)[:, None]
    return np.concatenate([out.reshape(N, -1), time_frac], axis=1).astype(np.float32)


def sensor_features(Y: np.ndarray, U: np.ndarray, nominal: np.ndarray) -> np.ndarray:
    """Period means of the sensors (N, B, 19) relative to nominal readings (19,), and of u (N, B)."""
    with np.errstate(invalid="ignore"):
        rel = Y.mean(axis=1) / nominal - 1.0
    rel = np.clip(np.nan_to_num(rel, nan=0.0, posinf=1.0, neginf=-1.0), -1.0, 1.0)
    u = np.clip(U.mean(axis=1), 0.0, 1.2)[:, None]
    return np.concatenate([rel, u], axis=1).astype(np.float32)
