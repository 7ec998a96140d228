"""Sure cells over a magnitude grid: the derivation rule, the replay of the decision logic on
module firing times, and the declaration rule the agents share."""

from __future__ import annotations

import numpy as np

from marine_fdi_env.diagnosis.decision import declared_faults
from marine_fdi_env.diagnosis.modules import MODULE_IDS
from marine_fdi_env.diagnosis.sure_cells import SureCells, load_sure_cells
from marine_fdi_env.engine.faults import FAULT_IDS
from studies.diagnosis.certainty import derive_sure_cells, grid_magnitudes, replay_declarations

M = {m: i for i, m in enumerate(MODULE_IDS)}


def _grid(rows):
    """rows: (fault, {module: time after onset}) per run."""
    times = np.full((len(rows), len(MODULE_IDS)), np.nan)
    runs = []
    for k, (f, fired) in enumerate(rows):
        runs.append(
            {"fault": f, "magnitude": 1.0, "grid_index": 0, "profile": "constant", "family": "constant", "seed": k}
        )
        for m, t in fired.items():
            times[k, M[m]] = t
    return {
        "runs": runs,
        "n_seeds": 1,
        "duration_s": 300.0,
        "sensor_onset_s": 30.0,
        "times_after_onset_s": {"reference": times.tolist()},
    }


def test_a_cell_is_sure_only_if_it_fires_at_every_size():
    # S3.4: its own module always fires; M3.5 only at the larger size; undetected runs do not count
    grid = _grid(
        [
            ("S3.4", {"M3.4": 0.0, "M3.5": 0.0, "M4.6": 1.0}),
            ("S3.4", {"M3.4": 2.0}),
            ("S3.4", {}),
            ("S3.4", {"M2.2": -5.0}),
        ]
    )  # a firing before the onset is not a detection
    d = derive_sure_cells(grid, "reference")
    sure = np.asarray(d["sure"], dtype=bool)
    j = FAULT_IDS.index("S3.4")
    assert sure[M["M3.4"], j] and not sure[M["M3.5"], j] and not sure[M["M4.6"], j]
    assert d["detected_runs"][j] == 2 and d["runs"][j] == 4
    assert d["lag_s"][M["M3.4"]][j] == 0.0


def test_replay_rules_out_a_fault_whose_sure_module_stays_silent():
    from marine_fdi_env.diagnosis.structure import checked_sensor_matrix

    sure = checked_sensor_matrix().copy()  # every sensor fault surely fires its own module (S3.2: M3.2)
    sure[M["M2.2"], FAULT_IDS.index("bore_damage")] = True
    sure[M["M3.3"], FAULT_IDS.index("turbine_lubrication_loss")] = True
    sc = SureCells(sure, np.zeros((19, 26)), np.zeros(26), {})
    t = np.full(19, np.nan)
    t[M["M3.4"]] = 40.0  # only M3.4 fires: S3.2 (same support) is exonerated after its grace period
    rep = replay_declarations(t, "S3.4", sc, 300.0)
    assert rep["declared_end"] == ["S3.4"] and not rep["wrong"] and rep["isolated_from_s"] is not None
    rep = replay_declarations(t, "S3.2", sc, 300.0)  # had the truth been S3.2: a wrong isolation
    assert rep["wrong"] and rep["ruled_out_end"]


def test_declaration_rule():
    assert declared_faults([frozenset({"S1.1"})]) == ["S1.1"]
    assert declared_faults([frozenset({"S1.1"}), frozenset({"S3.1"})]) == []  # a tie declares nothing
    assert declared_faults([frozenset({"S1.1", "S2.2"}), frozenset({"S1.1", "S3.1"}), frozenset({"S4.1"})]) == [
        "S4.1"
    ]  # smallest cardinality first
    assert declared_faults([]) == []


def test_grid_spans_half_the_detectability_limit_to_the_table_size():
    g = grid_magnitudes("S3.4")
    assert len(g) == 5 and g[0] < g[-1] and np.isclose(g[-1], 48.0)
    held = grid_magnitudes("S3.4", held_out=True)
    assert all(lo < h < hi for lo, h, hi in zip(g[:-1], held, g[1:]))


def test_shipped_sure_cells_are_within_the_structure():
    from marine_fdi_env.diagnosis.structure import fault_signature_matrix

    support = fault_signature_matrix()[0]
    for name in ("sure_cells.json", "sequential_sure_cells.json"):
        sc = load_sure_cells(name)
        assert sc.sure.any() and not (sc.sure & ~support).any()
        assert np.all(sc.grace_times() >= 2.0) and np.all(sc.settle_times() >= 2.0)
