"""One diagnoser, several cell sets: the decisions with each cell set made on one stream of
residuals equal those of a diagnoser made with that cell set alone."""

from __future__ import annotations

import numpy as np
import pytest

from marine_fdi_env.diagnosis.agent import ReferenceDiagnoser
from marine_fdi_env.diagnosis.cell_sets import CELL_SETS
from marine_fdi_env.diagnosis.sequential import SequentialDiagnoser, SequentialStage, pressure_ratio
from marine_fdi_env.engine.simulator import Simulator

FAULTS = [["S4.2@2", "S3.4@20:20"], ["S2.2@1", "S3.3@4"], ["bore_damage@1:0.003"], ["S1.1@5:0.5"]]
BLOCK = 100  # the environment's decision period at dt = 0.01 s


@pytest.fixture(scope="module")
def stream():
    res = Simulator("thesis-12v28", 4, seeds=33, faults=FAULTS).run(60.0)
    return res.measurements.transpose(1, 0, 2), res.truth_of("u").T


def _blocks(Y, U):
    return [(Y[:, a : a + BLOCK], U[:, a : a + BLOCK]) for a in range(0, Y.shape[1], BLOCK)]


def _conclusions(states) -> list:
    return [(st.diagnoses, st.first_detection_time, st.n_recomputations) for st in states]


def test_reference_decides_with_every_cell_set_on_one_stream(stream):
    shared = ReferenceDiagnoser(n_engines=4, cells="thesis")
    for c in CELL_SETS:
        shared.add_cells(c)
    assert shared.cell_sets == ("thesis", "grid", "sized")
    alone = {c: ReferenceDiagnoser(n_engines=4, cells=c) for c in CELL_SETS}
    for y, u in _blocks(*stream):
        out = shared.observe(y, u)
        for d in alone.values():
            mine = d.observe(y, u)
            np.testing.assert_array_equal(mine.features, out.features)
    got = {c: _conclusions(shared.decider(c).decisions) for c in CELL_SETS}
    assert got == {c: _conclusions(d.decisions) for c, d in alone.items()}
    assert len({repr([g[0] for g in v]) for v in got.values()}) > 1  # the cell sets conclude differently here
    np.testing.assert_array_equal(shared.first_violation, alone["sized"].first_violation)
    with pytest.raises(RuntimeError, match="before the first block"):
        shared.add_cells("grid")
    with pytest.raises(ValueError, match="cells must be one of the cell sets decided"):
        ReferenceDiagnoser(n_engines=1).decider("grid")


def test_sequential_decides_with_every_cell_set_on_one_stream(stream):
    ref = ReferenceDiagnoser(n_engines=4, exoneration="none")
    stage = SequentialStage(4, cells="grid")
    for c in CELL_SETS:
        stage.add_cells(c)
    alone = {c: SequentialDiagnoser(n_engines=4, cells=c) for c in CELL_SETS}
    for k, (y, u) in enumerate(_blocks(*stream)):
        t0 = np.full(4, k * BLOCK * 0.01)
        out = ref.observe(y, u)
        stage.update(out.residuals, u, pressure_ratio(y), out.violations, t0, out.thresholds, out.peaks)
        for d in alone.values():
            d.observe(y, u)
    got = {c: _conclusions(stage.decider(c).decisions) for c in CELL_SETS}
    assert got == {c: _conclusions(d.stage.decisions) for c, d in alone.items()}
    assert len({repr([g[0] for g in v]) for v in got.values()}) > 1
