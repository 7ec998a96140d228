"""The reproduction table (studies.diagnosis.reproduction): its statistics and verdict rules, and one
column measured end to end at a tiny size, rendered to the page."""

from __future__ import annotations

import json
import math

import pytest

import studies.diagnosis.reproduction as rep
from marine_fdi_env.benchmark.suites import SUITE_NAMES
from studies.diagnosis.reproduction_table import (
    README_BEGIN,
    README_END,
    VERDICTS,
    median_ci,
    rate_ci,
    ratio_verdict,
    rows_for,
    window_verdict,
    write_table,
)
from studies.diagnosis.thesis_claims import claims


def test_the_censored_median_counts_a_miss_as_later_than_any_detection():
    med, lo, hi = median_ci([1.0, 2.0, None, None, None])
    assert math.isinf(med) and math.isinf(hi)
    med, lo, hi = median_ci([3.0, 1.0, 2.0, None, 5.0, 4.0, 6.0])
    assert med == 4.0 and lo <= med <= hi


def test_the_order_statistic_interval_covers_the_median_at_95_percent():
    # 20 draws: the ranks 6 and 15 (1-based) bound the median (exact binomial 95.9 % coverage)
    med, lo, hi = median_ci(list(range(1, 21)))
    assert (lo, hi) == (6.0, 15.0)


def test_verdicts_follow_the_factor_and_the_words():
    assert ratio_verdict(0.5) == "better" and ratio_verdict(1.4) == "reproduced" and ratio_verdict(1.6) == "worse"
    assert ratio_verdict(math.inf) == "not reproduced"
    assert window_verdict(0.5, 0.0, 1.0) == "reproduced" and window_verdict(2.0, 0.0, 1.0) == "worse"
    assert window_verdict(10.0, 80.0, 180.0) == "better"


def test_garwood_interval_of_no_event_in_200_hours():
    lo, hi = rate_ci(0, 200.0)
    assert lo == 0.0 and hi == pytest.approx(3.689 / 200.0, rel=1e-3)


@pytest.fixture(scope="module")
def tiny_column(tmp_path_factory):
    """The local column at 2 seeds, 0.1 engine-hours; the suites' scoring replaced by a stub (it is
    ``marine-fdi evaluate``, tested elsewhere)."""
    work = tmp_path_factory.mktemp("reproduction")
    stub = {
        s: {"episodes": 10, "faulty": 8, "isolated": 4, "detected": 6, "false_alarms": 0, "fault_free_hours": 1.0}
        for s in SUITE_NAMES
    }
    stub["nominal-v1"]["faulty"] = 0
    mp = pytest.MonkeyPatch()
    mp.setattr(rep, "_suite_metrics", lambda column, folder: stub)
    pct = {c.fault: c.size_pct_of_max for c in claims("sensor_detection")}
    col = rep.measure_column("local", pct, 2, 2, 2, 0.1, log=lambda *a: None)
    mp.undo()
    return work, col


def test_every_claim_gets_a_row_with_a_verdict(tiny_column):
    _, col = tiny_column
    rows = rows_for(col)
    ids = {r.claim for r in rows}
    scored = {c.id for c in claims() if not (c.kind == "process_detection" and c.fault is None)}
    assert ids == scored
    assert all(r.verdict in VERDICTS for r in rows)
    # every sensor claim at the table size and at the noise-rule size
    assert sum(r.kind == "sensor_detection" for r in rows) == 2 * len(claims("sensor_detection"))


def test_the_page_and_its_json_are_written_from_the_measured_columns(tiny_column, tmp_path):
    work, col = tiny_column
    settings = {"seeds": 2, "kpi_seeds": 2, "limit_seeds": 2, "hours": 0.1, "first_seed": rep.FIRST_SEED}
    col["settings"] = settings
    (work / "local.json").write_text(json.dumps(col))
    doc, data = tmp_path / "reproduction.md", tmp_path / "reproduction.json"
    readme = tmp_path / "README.md"
    readme.write_text(f"intro\n{README_BEGIN}\nold\n{README_END}\nrest\n")
    assert write_table(work, settings, doc=doc, data=data, readme=readme) == 0
    assert "claim by claim: " in readme.read_text() and "old" not in readme.read_text()
    out = json.loads(data.read_text())
    assert set(out["counts"]) == {"local"} and sum(out["counts"]["local"].values()) == len(out["rows"]["local"])
    text = doc.read_text()
    assert text.startswith("# The thesis, claim by claim") and "6.4.3/final" in text
    assert out["command"].startswith("python -m studies.diagnosis.reproduction --seeds 2")
