"""Size-aware exoneration (the ``sized`` cell set): the band rule, the derivation per band, the
decision logic on the thesis's examples, and the switch between the three cell sets."""

from __future__ import annotations

import json

import numpy as np
import pytest

from marine_fdi_env.diagnosis.cell_sets import CELL_SETS, check_cells, decision_state, size_blind_cells
from marine_fdi_env.diagnosis.decision import declared_faults
from marine_fdi_env.diagnosis.modules import MODULE_IDS
from marine_fdi_env.diagnosis.peak_ratio import PeakRecorder, peak_at, ratios, running_peaks
from marine_fdi_env.diagnosis.sized_cells import SIZED_FILES, SizedCells, load_sized_cells
from marine_fdi_env.diagnosis.structure import fault_signature_matrix
from marine_fdi_env.engine.faults import FAULT_IDS

M = {m: i for i, m in enumerate(MODULE_IDS)}
F = {f: j for j, f in enumerate(FAULT_IDS)}


def _cells(peak_col: dict, sure_col: dict, margin: float = 1.5, k: int = 3) -> SizedCells:
    """Cells with fault S3.4's envelope of some modules given per level and its sure modules per band."""
    peak = np.full((k, 19, 26), np.inf)
    peak[:, :, :] = 0.9
    sure = np.zeros((k, 19, 26), dtype=bool)
    for m, vals in peak_col.items():
        peak[:, M[m], F["S3.4"]] = vals
    for band, mods in sure_col.items():
        for m in mods:
            sure[band, M[m], F["S3.4"]] = True
    return SizedCells(sure, np.zeros((k, 19, 26)), np.zeros((19, 26), dtype=bool), peak, np.full(26, k), margin, {})


def test_band_rule_excess_over_the_smaller_sizes_envelope():
    c = _cells({"M3.4": [0.95, 1.2, 2.0]}, {})
    j = F["S3.4"]
    band = lambda q: int(c.bands(np.where(np.arange(19) == M["M3.4"], q, 0.5))[M["M3.4"], j])  # noqa: E731
    # below the threshold: no size information; past level 0 (never fired there) only: still band 0
    assert band(0.99) == 0 and band(1.01) == 0
    # past level 1 needs an excess 1.5x level 1's largest excess (0.2): q > 1.3
    assert band(1.29) == 0 and band(1.31) == 1
    # past level 2 (excess 1.0 -> q > 2.5): the top band, never beyond the measured levels
    assert band(2.49) == 1 and band(2.51) == 2 and band(100.0) == 2
    nxt = c.next_peak(np.where(np.arange(19) == M["M3.4"], 1.31, 0.5), np.arange(19) == M["M3.4"])
    assert np.isclose(nxt[M["M3.4"]], 2.5) and np.isinf(nxt[M["M3.5"]])


def test_a_module_the_fault_never_fired_puts_it_in_its_top_band_with_a_short_grace():
    import dataclasses

    c = _cells({"M3.4": [0.95, 1.2, 2.0]}, {})
    never = np.zeros((19, 26), dtype=bool)
    never[M["M4.6"], F["S3.4"]] = True
    c = dataclasses.replace(c, never_fired=never, lag_s=np.full((3, 19, 26), 10.0))
    b = c.bands(np.full(19, 0.5))
    assert b[M["M4.6"], F["S3.4"]] == 2 and b[M["M3.4"], F["S3.4"]] == 0
    rows = np.array([M["M4.6"], M["M3.4"]])
    g, s = c.timings(np.zeros((2, 26), dtype=int), rows)  # (explained module, fault, sure module)
    assert g[0, F["S3.4"], M["M3.5"]] == 2.0 and g[1, F["S3.4"], M["M3.5"]] == 17.0
    assert s[1, F["S3.4"], M["M3.5"]] == 17.0 and np.isinf(s[1, F["bore_damage"], 0])  # process: no time order


def test_shipped_sized_cells_are_consistent():
    support = fault_signature_matrix()[0]
    for diagnoser, name in SIZED_FILES.items():
        c = load_sized_cells(name)
        grid = size_blind_cells(diagnoser, "grid")
        assert not (c.sure & ~support[None]).any()
        # the envelope grows with the size level
        for j in range(26):
            env = c.peak[: c.n_levels[j], :, j]
            assert np.isfinite(env).all() and np.all(np.diff(env, axis=0) >= 0)
        # band 0 pools every size, the grid's and the added ones: never more sure cells than the grid
        assert not (c.sure[0] & ~grid.sure).any()
        # more cells are sure from the larger sizes up
        assert c.sure[c.n_levels - 1, :, np.arange(26)].sum() > c.sure[0].sum()


def test_the_switch_names_the_allowed_cell_sets():
    assert CELL_SETS == ("thesis", "grid", "sized")
    with pytest.raises(ValueError, match="cells must be one of thesis, grid, sized, got 'size'"):
        check_cells("size")
    for d in ("reference", "sequential"):
        for c in CELL_SETS:
            assert decision_state(d, c).temporal


def _replay_643(cells: str) -> list:
    """The decision logic on the module firings of thesis example 6.4.3 as the reference meets them
    (noise seed 0: S2.2 fires M2.2 at once, M3.4 by chance later, the compressor seal leak M4.1 and
    M4.2 just before the end), with their running peak ratios."""
    st = decision_state("reference", cells)
    events = [(20.0, "M2.2", 18.0), (101.4, "M3.4", 1.05), (293.8, "M4.1", 1.02), (296.7, "M4.2", 1.01)]
    fired, peaks = set(), np.full(19, 0.95)
    for t, m, q in events:
        fired.add(m)
        peaks[M[m]] = q
        st.update([x in fired for x in MODULE_IDS], t, peaks) if cells == "sized" else st.update(
            [x in fired for x in MODULE_IDS], t
        )
    st.advance(300.0)
    return st.diagnoses


def test_643_ends_on_the_injected_pair_not_on_bore_damage():
    # the grid cells hold no sure cell of bore_damage (none fires at every size), so {bore_damage}
    # alone explains every fired module and, as the smallest diagnosis, is declared; the sized cells
    # judge bore_damage as the cause of M4.1/M4.2 at a size past every measured one (it fired
    # neither at any size), where M2.1-M2.6 surely fire: they are silent, so it is exonerated
    grid = _replay_643("grid")
    assert [f for f in declared_faults(grid)] == ["bore_damage"]
    sized = _replay_643("sized")
    assert sized == [frozenset({"S2.2", "compressor_seal_leak"})], sized
    assert declared_faults(sized) == ["S2.2", "compressor_seal_leak"]


def test_peak_recorder_steps_and_replay_lookup():
    rec = PeakRecorder(1, 2)
    R = np.array([[[0.1, 0.5], [0.6, 0.5], [0.605, np.nan], [2.0, 0.5]]])
    THR = np.ones_like(R)
    rec.update(R, THR, np.array([10.0]), 0.5)
    ev = rec.events[0]
    assert ev[0] == [[10.5, 0.6], [11.5, 2.0]]  # 0.1 is below the floor; 0.605 is in 0.6's 2 % step
    assert ev[1] == [[10.0, 0.5], [11.0, 1000.0]]  # a residual that is not finite counts as the cap
    assert peak_at(ev[0], 11.0) == 0.6 and peak_at(ev[0], 10.0) == 0.0
    q = running_peaks(ratios(R, THR), np.array([[0.7, 0.0]]))
    assert np.allclose(q[0, :, 0], [0.7, 0.7, 0.7, 2.0])


def test_cells_option_of_diagnose(tmp_path):
    from marine_fdi_env.cli import main as cli_main

    run = tmp_path / "run.npz"
    assert cli_main(["simulate", "--duration", "20", "--fault", "S3.4@5", "--out", str(run)]) == 0
    out = {}
    for cells in CELL_SETS:
        path = tmp_path / f"{cells}.json"
        assert cli_main(["diagnose", "--run", str(run), "--out", str(path), "--cells", cells]) == 0
        out[cells] = json.loads(path.read_text())
        assert out[cells]["diagnoser"]["cells"] == cells
    # the cell set changes the isolation, never the detection
    assert len({json.dumps(o["module_detection_times_s"]) for o in out.values()}) == 1
    assert ["S3.4"] in out["sized"]["final_minimal_diagnoses"]
