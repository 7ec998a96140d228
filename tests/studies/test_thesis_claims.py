"""The catalogue of the thesis's chapter-6 claims (studies.diagnosis.thesis_claims)."""

from collections import Counter
from pathlib import Path

import pytest

from marine_fdi_env.diagnosis.modules import MODULE_IDS
from marine_fdi_env.diagnosis.structure import thesis_tables
from marine_fdi_env.engine.faults import FAULT_IDS, PROCESS_FAULT_DEFAULTS, PROCESS_FAULT_IDS
from marine_fdi_env.engine.sensors import SENSOR_IDS, SENSORS
from marine_fdi_env.scenarios import SCENARIOS
from studies.diagnosis import thesis_claims
from studies.diagnosis.thesis_claims import (
    CLAIMS,
    COUNTS,
    KINDS,
    TABLE_6_3,
    TABLE_ONE_CELLS,
    THESIS_TEXT,
    claim,
    claims,
    diagnoses,
)

_SET_KINDS = ("interim_set", "final_set")


@pytest.fixture(scope="module")
def thesis_lines() -> list[str]:
    if not THESIS_TEXT.is_file():
        pytest.skip(f"thesis text not found at {THESIS_TEXT} (it lives in ../shared beside the repository)")
    return THESIS_TEXT.read_text(encoding="utf-8").split("\n")


@pytest.mark.parametrize("c", CLAIMS, ids=lambda c: c.id)
def test_quote_is_on_its_line(c, thesis_lines):
    assert 1 <= c.line <= len(thesis_lines)
    assert c.quote in thesis_lines[c.line - 1], f"{c.id}: quote not on line {c.line}"


def test_thesis_text_path_is_beside_the_repository():
    repo_root = Path(thesis_claims.__file__).resolve().parents[2]
    assert THESIS_TEXT == repo_root.parent / "shared" / "seed" / "000_57fb347d9df6a23d.txt"


def test_quote_lengths_and_kinds():
    for c in CLAIMS:
        assert 30 <= len(c.quote) <= 200, c.id
        assert c.kind in KINDS, c.id
        assert c.section and c.unit and c.size, c.id


def test_ids_are_unique():
    ids = [c.id for c in CLAIMS]
    assert len(ids) == len(set(ids))
    assert claim(ids[0]) is CLAIMS[0]
    with pytest.raises(KeyError):
        claim("6.9/nothing")


def test_ids_exist_in_the_package():
    for c in CLAIMS:
        assert c.fault is None or c.fault in FAULT_IDS, c.id
        assert c.module is None or c.module in MODULE_IDS, c.id
        assert c.scenario is None or c.scenario in SCENARIOS, c.id


def test_counts_per_kind():
    assert Counter(c.kind for c in CLAIMS) == Counter(COUNTS)
    assert sum(COUNTS.values()) == len(CLAIMS) == 121
    assert {c.fault for c in claims("sensor_detection")} == set(SENSOR_IDS)
    assert {c.fault for c in claims("min_detectable")} == set(PROCESS_FAULT_IDS)
    per_fault = [c.fault for c in claims("process_detection") if c.fault is not None]
    assert sorted(per_fault) == sorted(PROCESS_FAULT_IDS)
    assert {c.scenario for c in claims("final_set")} == set(SCENARIOS)
    assert {c.scenario for c in claims("module_order")} == set(SCENARIOS)
    with pytest.raises(ValueError):
        claims("no_such_kind")


def test_set_and_order_values_hold_known_ids():
    for c in claims("module_order"):
        for group in c.value:
            assert group and all(m in MODULE_IDS for m in group), c.id
    for c in claims("process_signature"):
        if c.fault is not None:
            assert all(m in MODULE_IDS for m in c.value), c.id
    for c in (*claims("interim_set"), *claims("final_set")):
        for d in (*c.value, *(c.reading or ())):
            assert d and all(f in FAULT_IDS for f in d), c.id
        assert diagnoses(c)


def test_examples_are_consistent_with_the_scenarios():
    for name, sc in SCENARIOS.items():
        injected = {s.fault_id: s.onset_s for s in sc.fault_specs()}
        events = [c for c in claims("event_time") if c.scenario == name]
        order = next(c for c in claims("module_order") if c.scenario == name)
        assert [m for g in order.value for m in g] == [c.module for c in events]
        for c in events:
            assert c.fault in injected and c.onset_s == injected[c.fault] and c.value >= c.onset_s, c.id
        final = next(c for c in claims("final_set") if c.scenario == name)
        assert any(set(d) == set(injected) for d in diagnoses(final)), name


def test_kpi_spread_pairs_are_the_one_cells_of_the_thesis_tables():
    ones = {
        (m, f)
        for t in thesis_tables().values()
        for r, m in enumerate(t.rows)
        for k, f in enumerate(t.columns)
        if f in SENSOR_IDS and t.values[r][k] == 1
    }
    pairs = {(c.module, c.fault) for c in claims("kpi_spread")}
    assert pairs == ones == {(m, f) for f, ms in TABLE_ONE_CELLS.items() for m in ms}
    assert len(pairs) == 35
    own = {(m, f) for m, f in pairs if m[1:] == f[1:]}
    assert len(own) == 19
    assert all(c.value == 0.003 and c.unit == "s" for c in claims("kpi_spread"))


def test_table_6_3_and_6_4_transcriptions_match_the_package():
    for s in SENSORS:
        bound, magnitude, _ = TABLE_6_3[s.id]
        assert s.noise_bound == pytest.approx(bound) and s.fault_magnitude == pytest.approx(magnitude), s.id
    for c in claims("process_detection"):
        if c.fault is not None:
            assert c.onset_s == PROCESS_FAULT_DEFAULTS[c.fault].onset_s, c.id


def test_sensor_claims_carry_the_sizes():
    for c in claims("sensor_detection"):
        assert 5.0 <= c.size_pct_of_max <= 10.0, c.id
        assert c.size_pct_no_noise is not None and c.size_pct_no_noise < c.size_pct_of_max, c.id
        assert f"{c.size_pct_of_max:g} %" in c.size, c.id
