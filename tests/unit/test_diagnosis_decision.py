"""Module decisions (eq. 5.19), minimal-hitting-set diagnosis vs the thesis's enumeration, the
thesis's local/global logic (eq. 5.20-5.22) and the four examples of section 6.4."""

from __future__ import annotations

import math
from itertools import combinations

import numpy as np
import pytest

from marine_fdi_env.diagnosis import decision as dc
from marine_fdi_env.diagnosis import structure as st
from marine_fdi_env.diagnosis.modules import MODULE_IDS
from marine_fdi_env.engine.faults import FAULT_IDS

FSM = st.fault_signature_matrix()[0]
TH = st.thesis_signature_matrix()
EXONERATION = {"none": None, "checked": st.checked_sensor_matrix(), "thesis1": TH == 1, "fsm": True}


# ----------------------------------------------------------------------------- eq. 5.19
def test_latch_decisions():
    v = np.zeros((6, 19), dtype=bool)
    v[2, 3] = True  # a single violation latches
    v[4, 0] = v[5, 0] = True
    lat = dc.latch_decisions(v, times=np.arange(6) * 0.5)
    assert lat.decisions[:, 3].tolist() == [False, False, True, True, True, True]
    assert lat.decisions[:, 0].tolist() == [False] * 4 + [True, True]
    assert lat.first_index[3] == 2 and lat.first_index[0] == 4 and lat.first_index[1] == -1
    assert lat.first_time[3] == 1.0 and lat.first_time[0] == 2.0 and math.isnan(lat.first_time[1])
    # batch of runs, 0/1 input
    lat2 = dc.latch_decisions(np.stack([v, np.zeros_like(v)]).astype(int))
    assert lat2.decisions.shape == (2, 6, 19) and (lat2.first_index[1] == -1).all()
    assert lat2.first_time[0, 3] == 2.0  # sample index without times
    empty = dc.latch_decisions(np.zeros((0, 19), dtype=bool))
    assert empty.decisions.shape == (0, 19) and (empty.first_index == -1).all()
    with pytest.raises(ValueError, match="shape"):
        dc.latch_decisions(np.zeros((5, 18), dtype=bool))
    with pytest.raises(ValueError, match="times"):
        dc.latch_decisions(v, times=np.arange(5))
    with pytest.raises(ValueError, match="boolean"):
        dc.latch_decisions(np.full((2, 19), 0.5))


# ----------------------------------------------------------------------------- minimal hitting sets
def test_minimal_hitting_sets_small():
    fs = frozenset
    assert set(dc.minimal_hitting_sets([{"a", "b"}, {"b", "c"}])) == {fs("b"), fs("ac")}
    assert dc.minimal_hitting_sets([]) == [fs()]
    assert dc.minimal_hitting_sets([{"a"}, set()]) == []
    assert set(dc.minimal_hitting_sets([{1, 2}, {3, 4}], max_cardinality=1)) == set()
    assert len(dc.minimal_hitting_sets([{1, 2}, {3, 4}], max_cardinality=2)) == 4


def _random_family(rng, n_items, n_sets):
    return [set(rng.choice(n_items, size=rng.integers(1, 6), replace=False).tolist()) for _ in range(n_sets)]


@pytest.mark.parametrize("k", [1, 2, 3, 4, None])
def test_berge_equals_brute_force_on_random_families(k):
    rng = np.random.default_rng(7)
    for _ in range(60):
        fam = _random_family(rng, 12, int(rng.integers(1, 9)))
        b = set(dc.minimal_hitting_sets(fam, k))
        e = set(dc.brute_force_minimal_hitting_sets(fam, k))
        assert b == e, fam


def test_berge_equals_toolbox_mhs():
    fdt = pytest.importorskip("faultdiagnosistoolbox", exc_type=ImportError)
    rng = np.random.default_rng(3)
    for _ in range(40):
        fam = _random_family(rng, 10, int(rng.integers(1, 7)))
        ours = set(dc.minimal_hitting_sets(fam, None))
        theirs = {frozenset(int(x) for x in h) for h in fdt.MHS([sorted(c) for c in fam])}
        assert ours == theirs


def test_minimal_diagnoses_equal_enumeration_on_random_fired_sets():
    rng = np.random.default_rng(11)
    for trial in range(60):
        fired = rng.random(19) < rng.uniform(0.05, 0.6)
        for name in ("none", "checked", "thesis1", "fsm"):
            ex = EXONERATION[name]
            a = dc.minimal_diagnoses(fired, exoneration=ex)
            b = dc.minimal_diagnoses(fired, exoneration=ex, method="brute")
            c = dc.brute_force_diagnoses(fired, exoneration=ex)
            assert a == b == c, (trial, name, fired.nonzero())
            for d in a:  # every diagnosis explains every fired module
                assert all(FSM[i, [FAULT_IDS.index(f) for f in d]].any() for i in np.flatnonzero(fired))


def test_minimal_diagnoses_single_faults():
    """Every single fault's own signature yields a diagnosis set containing it (no exoneration),
    and with full exoneration it is a minimal diagnosis unless its column is inside another's."""
    for j, f in enumerate(FAULT_IDS):
        fired = FSM[:, j]
        ds = dc.minimal_diagnoses(fired)
        assert frozenset([f]) in ds
        dx = dc.minimal_diagnoses(fired, exoneration=True)
        assert frozenset([f]) in dx
        # the faults whose column equals this one are the other single-fault diagnoses
        same = {FAULT_IDS[i] for i in range(26) if (FSM[:, i] == fired).all()}
        assert {next(iter(d)) for d in dx if len(d) == 1} == same


def test_minimal_diagnoses_edge_cases():
    assert dc.minimal_diagnoses(np.zeros(19, bool)) == [frozenset()]
    assert dc.minimal_diagnoses([]) == [frozenset()]
    # a fired module whose whole support is exonerated: no diagnosis
    assert dc.minimal_diagnoses(["M3.5"], exoneration=True) == []
    assert dc.minimal_diagnoses(["M1.1", "M1.2"]) == [frozenset({"valve_seizing"}), frozenset({"S1.1", "S1.2"})]
    with pytest.raises(ValueError, match="unknown module"):
        dc.minimal_diagnoses(["M9.9"])
    with pytest.raises(ValueError, match="shape"):
        dc.minimal_diagnoses(np.zeros(18, bool))
    with pytest.raises(ValueError, match="method"):
        dc.minimal_diagnoses(["M1.1"], method="magic")


def test_candidate_classes_and_sorting():
    ds = dc.minimal_diagnoses(["M1.1", "M1.2"])
    assert dc.candidates(ds) == ("S1.1", "S1.2", "valve_seizing")
    assert dc.candidate_classes(ds) == {"S1.1": "sensor", "S1.2": "sensor", "valve_seizing": "process"}
    assert dc.sorted_diagnoses(ds) == [["valve_seizing"], ["S1.1", "S1.2"]]


# ----------------------------------------------------------------------------- thesis examples (section 6.4)
def _predicted(ex):
    """Decision vector and detection times our FSM predicts for the injected faults (every
    structural cell fires at the fault's onset)."""
    (f1, t1), (_, t2) = ex.injected
    fired = st.multiple_fault_signature(ex.injected_set)
    c1 = st.multiple_fault_signature([f1])
    return fired, np.where(c1, t1, np.where(fired, t2, np.nan))


# (example, decision vectors, exoneration, temporal) -> (number of minimal diagnoses of size <= 3,
# injected set among them).  Documented in docs/diagnosis_structure.md section 6.
EXPECTED = {
    ("6.4.1", "thesis", "none", False): (12, False),
    ("6.4.1", "thesis", "checked", False): (4, False),
    ("6.4.1", "thesis", "checked", True): (5, True),
    ("6.4.1", "thesis", "thesis1", False): (2, False),
    ("6.4.1", "thesis", "thesis1", True): (2, True),
    ("6.4.1", "thesis", "fsm", False): (0, False),
    ("6.4.1", "predicted", "none", False): (12, False),
    ("6.4.1", "predicted", "checked", False): (6, False),
    ("6.4.1", "predicted", "checked", True): (6, False),
    ("6.4.1", "predicted", "fsm", False): (3, False),
    ("6.4.1", "predicted", "fsm", True): (4, True),
    ("6.4.2", "thesis", "none", False): (10, True),
    ("6.4.2", "thesis", "checked", False): (2, True),
    ("6.4.2", "thesis", "checked", True): (2, True),
    ("6.4.2", "thesis", "thesis1", False): (1, True),
    ("6.4.2", "thesis", "thesis1", True): (1, True),
    ("6.4.2", "thesis", "fsm", False): (0, False),
    ("6.4.2", "predicted", "none", False): (10, True),
    ("6.4.2", "predicted", "checked", False): (5, True),
    ("6.4.2", "predicted", "checked", True): (3, True),
    ("6.4.2", "predicted", "fsm", False): (3, True),
    ("6.4.2", "predicted", "fsm", True): (2, True),
    ("6.4.3", "thesis", "none", False): (30, True),
    ("6.4.3", "thesis", "checked", False): (4, True),
    ("6.4.3", "thesis", "checked", True): (3, True),
    ("6.4.3", "thesis", "thesis1", False): (1, True),
    ("6.4.3", "thesis", "thesis1", True): (1, True),
    ("6.4.3", "thesis", "fsm", False): (0, False),
    ("6.4.3", "predicted", "none", False): (30, True),
    ("6.4.3", "predicted", "checked", False): (5, True),
    ("6.4.3", "predicted", "checked", True): (4, True),
    ("6.4.3", "predicted", "fsm", False): (1, True),
    ("6.4.3", "predicted", "fsm", True): (1, True),
    ("6.4.4", "thesis", "none", False): (42, True),
    ("6.4.4", "thesis", "checked", False): (8, True),
    ("6.4.4", "thesis", "checked", True): (6, True),
    ("6.4.4", "thesis", "thesis1", False): (1, True),
    ("6.4.4", "thesis", "thesis1", True): (1, True),
    ("6.4.4", "thesis", "fsm", False): (0, False),
    ("6.4.4", "predicted", "none", False): (44, True),
    ("6.4.4", "predicted", "checked", False): (10, True),
    ("6.4.4", "predicted", "checked", True): (10, True),
    ("6.4.4", "predicted", "fsm", False): (2, True),
    ("6.4.4", "predicted", "fsm", True): (2, True),
}


@pytest.mark.parametrize("key", sorted(EXPECTED))
def test_thesis_examples_minimal_diagnoses(key):
    name, vectors, exo, temporal = key
    ex = dc.THESIS_EXAMPLES["thesis-" + name]
    if vectors == "thesis":
        fired, times = dc.fired_vector(ex.final_fired), ex.detection_times()
    else:
        fired, times = _predicted(ex)
    kw = dict(
        exoneration=EXONERATION[exo], detection_times=times if temporal else None, settle_s=dc.default_settle_times()
    )
    ds = dc.minimal_diagnoses(fired, **kw)
    assert ds == dc.minimal_diagnoses(fired, method="brute", **kw)  # Berge == enumeration
    if not temporal:
        assert ds == dc.brute_force_diagnoses(fired, exoneration=EXONERATION[exo])
    assert (len(ds), ex.injected_set in ds) == EXPECTED[key]


def test_example_642_contains_the_two_process_faults():
    ex = dc.THESIS_EXAMPLES["thesis-6.4.2"]
    fired = dc.fired_vector(ex.final_fired)
    # D^(1) = [1 1], D^(2) = [1 1 1 1 0 0], others 0
    assert fired.astype(int).tolist() == [1, 1, 1, 1, 1, 1] + [0] * 13
    ds = dc.minimal_diagnoses(fired)
    assert frozenset({"valve_seizing", "bore_damage"}) in ds
    # ... but so is {S1.1, S1.2}: both pairs have the same structural signature
    assert frozenset({"S1.1", "S1.2"}) in ds
    assert (
        st.multiple_fault_signature(["S1.1", "S1.2"]) == st.multiple_fault_signature(["valve_seizing", "bore_damage"])
    ).all()


def test_example_641_injected_set_is_not_minimal_statically():
    """S3.4's column lies inside S4.2's, so {S4.2} alone explains everything unless the order of
    detections is used (S3.4's modules fired 60 s before S4.2's certain modules)."""
    ex = dc.THESIS_EXAMPLES["thesis-6.4.1"]
    assert set(st.fault_modules("S3.4")) < set(st.fault_modules("S4.2"))
    fired = dc.fired_vector(ex.final_fired)
    assert frozenset({"S4.2"}) in dc.minimal_diagnoses(fired)
    ds = dc.minimal_diagnoses(
        fired, exoneration=TH == 1, detection_times=ex.detection_times(), settle_s=dc.default_settle_times()
    )
    assert ds == [frozenset({"S3.4", "S4.2"}), frozenset({"S2.2", "S2.4", "S3.4"})]
    assert len(dc.candidates(ds)) <= len(ex.thesis_candidates)


def test_thesis_knowledge_isolates_642_643_644_uniquely():
    """With the thesis's certain cells ('1' of tables 6.5-6.8) as exoneration the thesis's final
    diagnoses come out unique, as it reports."""
    for name in ("thesis-6.4.2", "thesis-6.4.3", "thesis-6.4.4"):
        ex = dc.THESIS_EXAMPLES[name]
        ds = dc.minimal_diagnoses(ex.final_fired, exoneration=TH == 1)
        assert ds == [ex.injected_set], name


# ----------------------------------------------------------------------------- thesis logic eq. 5.20-5.22
@pytest.mark.parametrize(
    "name, d_chi, minimal",
    [
        ("thesis-6.4.1", [0, 1, 1, 1], [{"S4.2"}, {"S2.2", "S2.4", "S3.4"}]),
        ("thesis-6.4.2", [1, 1, 0, 0], [{"valve_seizing", "bore_damage"}]),
        ("thesis-6.4.3", [0, 1, 0, 1], [{"S2.2", "compressor_seal_leak"}]),
        ("thesis-6.4.4", [0, 0, 1, 1], [{"S3.2", "turbine_lubrication_loss"}]),
    ],
)
def test_thesis_global_diagnosis_on_the_examples(name, d_chi, minimal):
    ex = dc.THESIS_EXAMPLES[name]
    r = dc.thesis_global_diagnosis(ex.final_fired)
    assert r.d_chi.tolist() == d_chi  # the global decision vectors printed in section 6.4
    assert r.minimal == [frozenset(m) for m in minimal]
    # the joint reading of eq. 5.21 is consistency-based diagnosis with the thesis's '1' cells as
    # exoneration and its '1'/'*' cells as support
    assert r.minimal == dc.minimal_diagnoses(ex.final_fired, support=TH != 0, exoneration=TH == 1)
    assert set(ex.injected_set) <= set(r.global_candidates)


def test_thesis_local_sets_first_epochs():
    # 6.4.3, 20 s <= t < 156.8 s: D^(2) = [0 1 0 0 0 0] -> D_s^(2) = {f_2^(2)}
    r = dc.thesis_global_diagnosis(["M2.2"])
    assert r.local[2] == [frozenset({"S2.2"})] and r.local[1] == r.local[3] == r.local[4] == []
    assert r.d_chi.tolist() == [0, 1, 0, 0]
    assert r.minimal == [frozenset({"S2.2"})]
    # 6.4.1, 175 s <= t < 235 s: D^(3) = [0 0 0 1 1]; the thesis lists f_4^(3), f_5^(3), {f_4, f_5}
    r = dc.thesis_global_diagnosis(["M3.4", "M3.5"])
    assert frozenset({"S3.4"}) in r.local[3] and frozenset({"S3.4", "S3.5"}) in r.local[3]
    assert frozenset({"S3.5"}) not in r.local[3]  # f_5^(3) alone leaves ε(3,4) unexplained
    assert r.d_chi.tolist() == [0, 0, 1, 0]
    # eq. 5.20 read literally: a local fault that no other agent reads (S2.5) gives D_chi^(2) = 0;
    # the examples' reading gives 1 whenever the agent has fired
    lit = dc.thesis_global_diagnosis(["M2.5"], dchi_rule="eq5.20")
    assert lit.local[2] == [frozenset({"S2.5"})] and lit.d_chi.tolist() == [0, 0, 0, 0]
    assert dc.thesis_global_diagnosis(["M2.5"]).d_chi.tolist() == [0, 1, 0, 0]
    with pytest.raises(ValueError, match="dchi_rule"):
        dc.thesis_global_diagnosis(["M2.2"], dchi_rule="x")


def test_thesis_logic_on_the_derived_fsm():
    """With our FSM read as all-'1' (exact pattern matching) the thesis logic equals full exoneration."""
    rng = np.random.default_rng(5)
    for _ in range(15):
        fired = FSM[:, rng.choice(26, size=int(rng.integers(1, 3)), replace=False)].any(axis=1)
        r = dc.thesis_global_diagnosis(fired, matrix=FSM.astype(np.int8))
        assert r.minimal == dc.minimal_diagnoses(fired, exoneration=True)


# ----------------------------------------------------------------------------- streaming state
def _record(ex, dt=0.1, t_end=300.0):
    t = np.arange(0.0, t_end, dt)
    v = np.zeros((t.size, 19), dtype=bool)
    for t0, mods in ex.epochs:
        for m in mods:
            v[t >= t0 - 1e-9, MODULE_IDS.index(m)] = True
    return t, v


def test_diagnosis_state_recomputes_only_on_changes():
    ex = dc.THESIS_EXAMPLES["thesis-6.4.2"]
    t, v = _record(ex)
    s = dc.DiagnosisState()
    changes = 0
    for k in range(t.size):
        changes += s.update(v[k], t[k])
    assert changes == s.n_recomputations == len(ex.epochs) == 3
    assert s.detected and s.first_detection_time == pytest.approx(146.1)
    assert s.detection_times[MODULE_IDS.index("M1.1")] == pytest.approx(207.1)
    assert math.isnan(s.detection_times[MODULE_IDS.index("M3.1")])
    assert s.fired_modules == ex.final_fired
    assert s.diagnoses == dc.minimal_diagnoses(ex.final_fired)
    assert s.classes["bore_damage"] == "process"
    s.reset()
    assert not s.detected and s.diagnoses == [frozenset()]


def test_diagnose_decisions_events_and_temporal_state():
    ex = dc.THESIS_EXAMPLES["thesis-6.4.1"]
    t, v = _record(ex)
    # transient violations are latched
    v[:, :] = False
    for t0, mods in ex.epochs:
        k = int(np.searchsorted(t, t0 - 1e-9))
        for m in mods:
            v[k, MODULE_IDS.index(m)] = True
    events = dc.diagnose_decisions(v, t, exoneration=TH == 1, temporal=True)
    assert [round(e.time, 6) for e in events] == [175.0, 235.0]
    assert events[0].fired == ("M3.4", "M3.5")
    assert events[-1].diagnoses == [frozenset({"S3.4", "S4.2"}), frozenset({"S2.2", "S2.4", "S3.4"})]
    static = dc.diagnose_decisions(v, t, exoneration=TH == 1)
    assert static[-1].diagnoses[0] == frozenset({"S4.2"})


def test_default_settle_times():
    s = dc.default_settle_times()
    assert s.shape == (26,) and (s[:19] == 5.0).all() and np.isinf(s[19:]).all()
    with pytest.raises(ValueError, match="settle_s"):
        dc.minimal_diagnoses(["M1.1"], exoneration=True, detection_times=np.zeros(19), settle_s=np.zeros(3))


def test_bounded_cardinality_cost_is_small():
    """All 2^19 fired sets are out of reach, but the worst cases are cheap: all modules fired."""
    import time

    t0 = time.perf_counter()
    for k in (3, 4):
        dc.minimal_diagnoses(np.ones(19, bool), max_cardinality=k)
    assert time.perf_counter() - t0 < 1.0
    assert len(dc.minimal_diagnoses(np.ones(19, bool), max_cardinality=None)) > 0


def test_combinations_helper_sanity():
    # the brute-force reference enumerates exactly sum_{r<=3} C(26, r) combinations
    assert sum(1 for r in range(4) for _ in combinations(range(26), r)) == 2952
