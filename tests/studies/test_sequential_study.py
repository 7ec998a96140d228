"""The sequential diagnoser: CUSUM tests on the reference residuals, streaming, detection of faults
below the worst-case thresholds, and its place in the environment and the evaluation."""

from __future__ import annotations

import numpy as np

from marine_fdi_env.diagnosis.batch import diagnose_batch
from marine_fdi_env.diagnosis.sequential import cusum_blocks, load_calibration
from studies.diagnosis.sequential_calibration import cusum_offline, profile_for


def test_cusum_kernel_equals_the_textbook_recursion():
    """The compiled, streaming kernel on per-sample data = Page's two-sided CUSUM on the block
    means (sum of block / block length) with the same normalisation, fed in uneven pieces."""
    cal = load_calibration()
    rng = np.random.default_rng(3)
    N, B, block = 3, 700, 100
    R = rng.normal(size=(N, B, 19)) * cal.scale[:, -1] * 3.0 + cal.mean[:, -1] + 0.8 * cal.scale[:, -1]
    U = np.full((N, B), 1.2)  # above the last node: the last node's normalisation
    ratio = np.full((N, B), 0.7)
    acc, st = np.zeros((N, 22)), np.zeros((N, 19, 2))
    first, feats = np.full((N, 19), np.nan), np.zeros((N, 19, 3))
    off = np.array([np.inf, 2, 1 / 30, 0.02, 3.0])  # the receiver test switched off
    gstate = np.zeros((N, 4))
    gstate[:, 1] = np.nan
    for a, b in ((0, 130), (130, 131), (131, 700)):
        cusum_blocks(
            R[:, a:b],
            U[:, a:b],
            ratio[:, a:b],
            np.zeros((N, 0, 19), dtype=bool),
            0.01,
            np.full(N, a * 0.01),
            block,
            cal.u_nodes,
            cal.mean,
            cal.scale,
            cal.k,
            cal.h * 0.2,
            np.zeros(19),
            cal.r_max,
            acc,
            st,
            first,
            feats,
            np.array([8, 9]),
            off,
            np.ones(5),
            np.zeros((N, 5, 2)),
            np.zeros(N, dtype=np.int64),
            np.zeros(N, dtype=np.int64),
            np.full(N, np.nan),
            gstate,
        )
    bm = R.reshape(N, B // block, block, 19).mean(axis=2)
    z = np.clip((bm - cal.mean[:, -1]) / cal.scale[:, -1], -10, 10)
    blocks, _ = cusum_offline(z, cal.k, cal.h * 0.2, np.zeros(19, dtype=int))
    expected = np.where(blocks >= 0, (blocks + 1) * block * 0.01 - 0.01, np.nan)
    assert np.allclose(first, expected, equal_nan=True)
    assert np.isnan(first).sum() < first.size  # something fired


def test_no_alarm_on_fault_free_runs_of_every_family():
    runs = [profile_for(9_500_000_000 + i) for i in range(10)]
    reps = diagnose_batch([[] for _ in runs], [s for _, s in runs], [p for p, _ in runs], 300.0, diagnoser="sequential")
    assert not any(r["detected"] for r in reps), [
        (p, r["module_detection_times_s"]) for (p, _), r in zip(runs, reps) if r["detected"]
    ]
