"""Fault signature matrices derived from the module structure, detectability/isolability, and
the comparison with the thesis's tables 6.5-6.8 (thesis lines 1331-1370)."""

from __future__ import annotations

import numpy as np
import pytest

from marine_fdi_env.diagnosis import structure as st
from marine_fdi_env.diagnosis.modules import EQUATION_FAULTS, MODULE_IDS, MODULES
from marine_fdi_env.engine.faults import FAULT_IDS, PROCESS_FAULT_IDS
from marine_fdi_env.engine.sensors import SENSOR_IDS
from tests.paths import ROOT

DOC = ROOT / "docs" / "diagnosis_structure.md"


def col(fault):
    return st.fault_modules(fault)


# ----------------------------------------------------------------------------- the derived FSM
def test_fsm_shape_and_ids():
    fsm, mods, faults = st.fault_signature_matrix()
    assert fsm.shape == (19, 26) and fsm.dtype == bool
    assert mods == MODULE_IDS and faults == FAULT_IDS
    assert len(faults) == 26 and faults[:19] == SENSOR_IDS and faults[19:] == PROCESS_FAULT_IDS
    fsm[0, 0] = not fsm[0, 0]  # a copy: the cached matrix is untouched
    assert st.fault_signature_matrix()[0][0, 0] != fsm[0, 0]


def test_fsm_follows_the_rules_of_modules_py():
    fsm, _, _ = st.fault_signature_matrix()
    for i, m in enumerate(MODULES):
        expected = set(m.all_sensors) | {f for e in m.equations for f in EQUATION_FAULTS[e]}
        assert {f for j, f in enumerate(FAULT_IDS) if fsm[i, j]} == expected, m.id


@pytest.mark.parametrize(
    "fault, modules",
    [
        ("S4.3", ("M2.1", "M2.3", "M2.5", "M3.1", "M3.3", "M4.1", "M4.3", "M4.5")),
        ("S4.4", ("M2.2", "M2.4", "M2.6", "M3.2", "M3.4", "M4.2", "M4.4", "M4.6")),
        ("S4.2", ("M2.2", "M2.4", "M2.6", "M3.2", "M3.4", "M3.5", "M4.2", "M4.6")),
        ("S1.1", ("M1.1", "M2.1", "M2.3", "M2.5", "M3.1", "M3.3", "M4.1", "M4.5")),
        ("S2.5", ("M2.5",)),
        ("S2.1", ("M2.1", "M3.3")),
        ("S3.5", ("M3.5", "M4.5", "M4.6")),
        ("S4.5", ("M4.5",)),
        ("valve_seizing", ("M1.1", "M1.2")),
        (
            "bore_damage",
            (
                "M2.1",
                "M2.2",
                "M2.3",
                "M2.4",
                "M2.5",
                "M2.6",
                "M3.1",
                "M3.2",
                "M3.3",
                "M3.4",
                "M4.1",
                "M4.2",
                "M4.5",
                "M4.6",
            ),
        ),
        ("turbine_seal_leak", ("M3.1", "M3.2")),
        ("turbine_lubrication_loss", ("M3.3", "M3.4")),
        ("compressor_seal_leak", ("M4.1", "M4.2")),
        ("compressor_lubrication_loss", ("M4.3", "M4.4")),
        ("intercooler_blockage", ("M4.5", "M4.6")),
    ],
)
def test_hand_checked_columns(fault, modules):
    assert col(fault) == modules


def test_fault_support_rows():
    assert st.fault_support("M3.5") == ("S3.2", "S3.4", "S3.5", "S4.2")
    assert st.fault_support("M1.1") == ("S1.1", "valve_seizing")
    with pytest.raises(ValueError, match="unknown module"):
        st.fault_support("M5.1")
    with pytest.raises(ValueError, match="unknown fault"):
        st.fault_modules("S9.9")


def test_multiple_fault_signature_is_union_of_columns():
    v = st.multiple_fault_signature(["S2.2", "compressor_seal_leak"])
    assert [m for m, x in zip(MODULE_IDS, v) if x] == ["M2.2", "M3.4", "M4.1", "M4.2"]


def test_checked_sensor_matrix():
    c = st.checked_sensor_matrix()
    fsm = st.fault_signature_matrix()[0]
    assert c.sum() == 19 and not (c & ~fsm).any()  # certain cells are structural cells
    assert c.sum(axis=1).tolist() == [1] * 19
    assert not c[:, 19:].any()


# ----------------------------------------------------------------------------- agents, propagation
def test_agent_matrices_layout():
    am = st.agent_signature_matrices()
    assert sorted(am) == [1, 2, 3, 4]
    a1 = am[1]
    assert a1.columns == ("S1.1", "S1.2", "valve_seizing")
    assert a1.matrix.astype(int).tolist() == [[1, 0, 1], [0, 1, 1]]  # table 6.5 exactly
    a2 = am[2]
    assert a2.local_sensor_faults == ("S2.1", "S2.2", "S2.3", "S2.4", "S2.5", "S2.6")
    assert a2.propagated_sensor_faults == ("S1.1", "S1.2", "S4.1", "S4.2", "S4.3", "S4.4")
    assert a2.propagated_process_faults == () and a2.local_process_faults == ("bore_damage",)
    a3 = am[3]
    assert a3.propagated_sensor_faults == (
        "S1.1",
        "S1.2",
        "S2.1",
        "S2.2",
        "S2.3",
        "S2.4",
        "S4.1",
        "S4.2",
        "S4.3",
        "S4.4",
    )
    assert a3.propagated_process_faults == ("bore_damage",)
    assert a3.local_process_faults == ("turbine_seal_leak", "turbine_lubrication_loss")
    a4 = am[4]
    assert a4.propagated_sensor_faults == ("S1.1", "S1.2", "S3.1", "S3.2", "S3.3", "S3.4", "S3.5")
    assert a4.propagated_process_faults == ("bore_damage",)
    assert a4.column_group("S3.5") == "propagated_sensor_faults"
    for a, m in am.items():
        assert m.matrix.shape == (len(m.module_ids), len(m.columns))


def test_global_propagation_matrix():
    g, agents, faults = st.global_propagation_matrix()
    assert g.shape == (4, 26) and agents == (1, 2, 3, 4)
    reach = st.fault_reach()
    # the thesis's description of table 6.9 (line ~1353), which our structure reproduces for sensors
    assert reach["S1.1"] == reach["S1.2"] == (1, 2, 3, 4)  # Σ1 sensor faults reach every agent
    for s in ("S2.1", "S2.2", "S2.3", "S2.4"):
        assert reach[s] == (2, 3)  # Σ2 -> M(3)
    assert reach["S2.5"] == reach["S2.6"] == (2,)
    for s in ("S3.1", "S3.2", "S3.3", "S3.4", "S3.5"):
        assert reach[s] == (3, 4)  # Σ3 -> M(4)
    for s in ("S4.1", "S4.2", "S4.3", "S4.4"):
        assert reach[s] == (2, 3, 4)  # Σ4 -> M(2), M(3)
    assert reach["S4.5"] == reach["S4.6"] == (4,)  # used by no other agent
    # process faults: only the bore damage propagates (through the engine speed); the thesis says none
    assert reach["bore_damage"] == (2, 3, 4)
    for p in PROCESS_FAULT_IDS:
        if p != "bore_damage":
            assert len(reach[p]) == 1
    j = FAULT_IDS.index
    assert g[0, j("S1.1")] == 1 and g[1, j("S1.1")] == st.STAR
    assert g[2, j("bore_damage")] == st.STAR and g[1, j("bore_damage")] == 1


# ----------------------------------------------------------------------------- detectability / isolability
def test_every_fault_structurally_detectable():
    det = st.detectability()
    assert all(det.values()) and len(det) == 26
    assert st.isolability_report()["undetectable"] == []


def test_isolability_matrix_definition():
    fsm = st.fault_signature_matrix()[0]
    iso = st.isolability_matrix()
    for i in range(26):
        assert not iso[i, i]
        for j in range(26):
            if i != j:
                subset = not (fsm[:, i] & ~fsm[:, j]).any()
                assert iso[i, j] == (not subset)


def test_isolability_classes():
    rep = st.isolability_report()
    # mutually non-isolable (identical columns): the two redundant-chain pairs of Σ3
    assert rep["identical_groups"] == [("S3.1", "S3.3"), ("S3.2", "S3.4")]
    assert rep["n_non_isolable_ordered_pairs"] == 64
    nif = rep["not_isolable_from"]
    assert nif["turbine_seal_leak"] == ["bore_damage"]
    assert nif["compressor_seal_leak"] == ["bore_damage"]
    assert nif["turbine_lubrication_loss"] == ["bore_damage"]
    assert nif["intercooler_blockage"] == ["S3.5", "bore_damage"]
    assert nif["S2.5"] == ["S1.1", "S2.3", "S4.1", "S4.3", "bore_damage"]
    assert nif["S4.1"] == ["S1.1", "S4.3", "bore_damage"]
    assert rep["isolable_from_all"] == [
        "S1.1",
        "S1.2",
        "S3.5",
        "S4.2",
        "S4.3",
        "S4.4",
        "valve_seizing",
        "bore_damage",
        "compressor_lubrication_loss",
    ]
    assert ("S3.1", "S3.3") in st.non_isolable_pairs() and ("S3.3", "S3.1") in st.non_isolable_pairs()


# ----------------------------------------------------------------------------- thesis tables
def test_thesis_tables_transcription():
    t = st.thesis_tables()
    assert sorted(t) == ["6.5", "6.6", "6.7", "6.8"]
    assert [len(t[k].columns) for k in sorted(t)] == [3, 13, 17, 16]
    assert t["6.7"].symbols[-2:] == ("f_x,tur^(3)", "f_z,Tsl^(3)")
    assert t["6.7"].value("M3.5", "S3.3") == 1 and t["6.7"].value("M3.5", "S3.1") == "*"
    assert t["6.6"].value("M2.5", "bore_damage") == "*"
    assert t["6.8"].value("M4.6", "S1.1") == "*" and t["6.8"].value("M4.6", "S3.5") == 0
    assert t["6.7"].value("M3.1", "bore_damage") == 0  # not a column
    th = st.thesis_signature_matrix()
    assert th.shape == (19, 26) and set(np.unique(th)) <= {0, 1, 2}
    # each table has 0/1/'*' only, and every row of every table has its module's own sensor as 1
    for tab in t.values():
        for r, m in enumerate(tab.rows):
            assert set(tab.values[r]) <= {0, 1, "*"}
            own = next(x for x in MODULES if x.id == m).checked_sensor
            assert tab.value(m, own) == 1


def test_thesis_global_matrix_matches_its_description():
    tg = st.thesis_global_propagation_matrix()
    j = FAULT_IDS.index
    # "sensor faults from Σ1 may propagate toward all the other agents"
    assert (tg[:, j("S1.1")] != 0).all() and (tg[:, j("S1.2")] != 0).all()
    # "process faults do not propagate": each process fault column has exactly one nonzero (= 1)
    for p in PROCESS_FAULT_IDS:
        assert sorted(tg[:, j(p)].tolist()) == [0, 0, 0, 1]
    # S4.5, S4.6 are used by no other agent
    assert tg[:, j("S4.5")].tolist() == [0, 0, 0, 1]


# The documented list of cells where the derived FSM differs from tables 6.5-6.8
# (docs/diagnosis_structure.md section 5).  A change here must be explained there.
EXPECTED_DIFFERENCES = [
    ("6.6", "M2.1", "S4.3", "ours_only"),
    ("6.6", "M2.2", "S4.4", "ours_only"),
    ("6.7", "M3.1", "bore_damage", "ours_only"),
    ("6.7", "M3.2", "bore_damage", "ours_only"),
    ("6.7", "M3.3", "bore_damage", "ours_only"),
    ("6.7", "M3.4", "bore_damage", "ours_only"),
    ("6.7", "M3.5", "S3.1", "thesis_only"),
    ("6.7", "M3.5", "S3.2", "ours_only"),
    ("6.7", "M3.5", "S3.3", "thesis_only"),
    ("6.7", "M3.5", "S4.1", "thesis_only"),
    ("6.8", "M4.1", "bore_damage", "ours_only"),
    ("6.8", "M4.2", "bore_damage", "ours_only"),
    ("6.8", "M4.5", "bore_damage", "ours_only"),
    ("6.8", "M4.6", "S1.1", "thesis_only"),
    ("6.8", "M4.6", "S3.5", "ours_only"),
    ("6.8", "M4.6", "bore_damage", "ours_only"),
]


def test_compare_with_thesis_is_the_documented_list():
    diffs = st.compare_with_thesis()
    assert [(d.table, d.module, d.fault, d.kind) for d in diffs] == EXPECTED_DIFFERENCES
    for d in diffs:
        assert d.reason and d.thesis_symbol == st.THESIS_SYMBOLS[d.fault]
        if d.fault == "bore_damage":
            assert "speed" in d.reason and "has no column" in d.reason
        if d.module == "M3.5":
            assert "table 6.2" in d.reason
    # table 6.5 agrees completely, and outside the listed cells the supports agree
    fsm = st.fault_signature_matrix()[0]
    th = st.thesis_signature_matrix() != 0
    listed = {(MODULE_IDS.index(m), FAULT_IDS.index(f)) for _, m, f, _ in EXPECTED_DIFFERENCES}
    diff_cells = {(int(i), int(j)) for i, j in zip(*np.nonzero(fsm != th))}
    assert diff_cells == listed


def test_documentation_holds_the_generated_tables():
    text = DOC.read_text(encoding="utf-8")
    for name, table in st.markdown_tables().items():
        assert table in text, f"docs/diagnosis_structure.md is out of date: table {name!r}"


# ----------------------------------------------------------------------------- faultdiagnosistoolbox cross-check
def test_structural_model_is_varstruc():
    md = st.structural_model()
    assert md["type"] == "VarStruc"  # the toolbox silently ignores other spellings
    assert len(md["rels"]) == len(md["eq_names"])
    assert set(md["f"]) == set(FAULT_IDS)
    # every fault in exactly one relation (the toolbox's convention)
    counts = {f: sum(f in r for r in md["rels"]) for f in FAULT_IDS}
    assert set(counts.values()) == {1}


def test_toolbox_crosscheck():
    pytest.importorskip("faultdiagnosistoolbox", exc_type=ImportError)
    r = st.toolbox_crosscheck()
    assert r["accepted"]
    assert r["fsm_equal"] and r["isolability_equal"]
    assert r["model_undetectable"] == [] and len(r["model_detectable"]) == 26
    assert r["lost_pairs"] == []
    # with all MSO sets of the model every fault is isolable from every other one: the 64
    # non-isolable ordered pairs are a property of the 19 chosen ARRs, not of the model
    assert sorted(r["gained_pairs"]) == sorted(st.non_isolable_pairs())
    assert r["model_redundancy"] == 19
    assert r["module_msos"]["M3.5"] == ["turbine", "sensor_S3.2", "sensor_S3.4", "sensor_S3.5", "sensor_S4.2"]
