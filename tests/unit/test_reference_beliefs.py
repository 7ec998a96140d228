"""The reference and sequential agents' declarations from a diagnoser's conclusion (baselines/reference_agent.py)."""

from __future__ import annotations

import numpy as np

from marine_fdi_env.baselines.reference_agent import belief_from_diagnoses, beliefs_from_conclusions
from marine_fdi_env.engine.faults import FAULT_IDS
from marine_fdi_env.envs.hypotheses import UNKNOWN


def test_beliefs_from_conclusions_equal_one_belief_per_slot():
    """The memoised beliefs of a batch equal :func:`belief_from_diagnoses` slot by slot, bit for bit, whatever the
    memo holds from earlier batches (ties at half the diagnoses, unknown, not detected, two-fault diagnoses)."""
    rng = np.random.default_rng(5)
    faults = list(FAULT_IDS[:5])
    memo: dict = {}
    for _ in range(50):
        detected = rng.random(8) < 0.8
        diagnoses = [
            [list(rng.choice(faults, size=rng.integers(1, 3), replace=False)) for _ in range(rng.integers(0, 4))]
            for _ in range(8)
        ]
        want = np.stack([belief_from_diagnoses(bool(d), g) for d, g in zip(detected, diagnoses)])
        got = beliefs_from_conclusions(detected, diagnoses, memo)
        assert got.dtype == want.dtype and np.array_equal(got, want)
    assert 0 < len(memo) < 50 * 8


def test_a_belief_declares_the_faults_of_every_smallest_diagnosis():
    """Two smallest diagnoses sharing one fault: that fault 1.0, the others half (0.49: not declared); no
    diagnosis: unknown; not detected: nothing."""
    a, b, c = FAULT_IDS[:3]
    bel = belief_from_diagnoses(True, [[a, b], [a, c], [a, b, c]])
    idx = {f: i for i, f in enumerate(FAULT_IDS)}
    assert bel[idx[a]] == 1.0 and bel[idx[b]] == np.float32(0.49) and bel[idx[c]] == np.float32(0.49)
    assert belief_from_diagnoses(True, [])[UNKNOWN] == 1.0
    assert not belief_from_diagnoses(False, [[a]]).any()
