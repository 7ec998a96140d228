"""Benchmark metrics over hand-built episode records with known answers."""

from __future__ import annotations

import json

import pytest

from marine_fdi_env.benchmark.metrics import compute_metrics, episode_outcome, validate_record


def fault(fid: str, onset: float, end: float | None = None) -> dict:
    cls = "sensor" if fid.startswith("S") else "process"
    return {"id": fid, "class": cls, "onset_s": onset, "magnitude": 1.0, "end_s": end}


def rec(changes, faults=(), *, duration=20.0, dp=1.0, sid="sc", **kw) -> dict:
    r = {
        "scenario_id": sid,
        "suite": "s",
        "seed": 0,
        "agent": "a",
        "duration_s": duration,
        "decision_period_s": dp,
        "n_samples": 100,
        "faults": list(faults),
        "profile": "constant",
        "declared_changes": [list(c) for c in changes],
        "terminated": False,
        "failure_reason": None,
        "compute_s": 0.01,
        "return": -1.0,
        "reward_terms": {"fa": -1.0},
    }
    r.update(kw)
    return r


def test_false_alarm_before_onset_and_detection_delay():
    r = rec([[1, [], False], [5, [], True], [6, [], False], [12, ["S1.1"], True]], [fault("S1.1", 10)])
    o = episode_outcome(r)
    assert o["false_alarms"] == 1
    assert o["fault_free_s"] == 10
    assert o["detection_time_s"] == 12 and o["detection_delay_s"] == 2
    assert o["isolation_time_s"] == 12 and o["isolation_delay_s"] == 2
    assert o["isolation_correct"] is True and o["fault_class"] == "sensor"


def test_alarm_on_from_first_decision_is_false_alarm():
    r = rec([[1, ["S1.1"], True]], duration=10.0)
    o = episode_outcome(r)
    assert o["false_alarms"] == 1 and o["fault_free_s"] == 10 and not o["faulty"]
    m = compute_metrics([r])
    assert m["fault_free_hours"] == pytest.approx(10 / 3600)
    assert m["false_alarm_rate"] == pytest.approx(360.0) == m["false_alarms_per_hour"]
    assert m["false_alarm_episode_rate"] == 1.0
    assert m["detection_rate"] is None and m["isolation_accuracy"] is None


def test_unknown_alarm_without_declared_fault_counts():
    r = rec([[1, [], False], [3, [], True], [4, [], False], [6, [], True]], duration=10.0)
    assert episode_outcome(r)["false_alarms"] == 2


def test_alarm_held_over_onset_detects_at_next_decision():
    r = rec([[1, [], False], [3, [], True]], [fault("S2.1", 4.5)])
    o = episode_outcome(r)
    assert o["false_alarms"] == 1
    assert o["detection_time_s"] == 5 and o["detection_delay_s"] == pytest.approx(0.5)
    assert o["isolation_time_s"] is None and o["isolation_correct"] is False


def test_alarm_exactly_at_onset_is_detection_not_false_alarm():
    r = rec([[1, [], False], [4, ["S2.1"], True]], [fault("S2.1", 4.0)])
    o = episode_outcome(r)
    assert o["false_alarms"] == 0 and o["detection_delay_s"] == 0 and o["isolation_delay_s"] == 0


def test_isolation_exact_match_and_mismatch():
    f = [fault("S1.1", 5)]
    wrong = rec([[1, [], False], [6, ["S1.1", "S2.1"], True]], f)
    o = episode_outcome(wrong)
    assert o["detection_delay_s"] == 1 and o["isolation_time_s"] is None
    assert o["isolation_correct"] is False and o["final_declared"] == ["S1.1", "S2.1"]
    fixed = rec([[1, [], False], [6, ["S1.1", "S2.1"], True], [9, ["S1.1"], True]], f)
    o = episode_outcome(fixed)
    assert o["isolation_time_s"] == 9 and o["isolation_delay_s"] == 4 and o["isolation_correct"]
    lost = rec([[1, [], False], [6, ["S1.1"], True], [9, ["S2.1"], True]], f)
    o = episode_outcome(lost)
    assert o["isolation_time_s"] == 6 and o["isolation_correct"] is False
    m = compute_metrics([wrong, fixed, lost])
    assert m["isolation_accuracy"] == pytest.approx(1 / 3)
    assert m["isolation_rate"] == pytest.approx(2 / 3)
    assert m["detection_rate"] == 1.0


def test_transient_fault_leaves_true_set():
    f = [fault("S3.1", 5, end=10)]
    cleared = rec([[1, [], False], [6, ["S3.1"], True], [12, [], False]], f)
    o = episode_outcome(cleared)
    assert o["final_true"] == [] and o["final_declared"] == [] and o["isolation_correct"] is True
    assert o["isolation_time_s"] == 6
    stuck = rec([[1, [], False], [6, ["S3.1"], True]], f)
    assert episode_outcome(stuck)["isolation_correct"] is False
    # declared only after the fault ended: the true set is empty then, so never isolated
    late = rec([[1, [], False], [11, ["S3.1"], True]], f)
    o = episode_outcome(late)
    assert o["detection_time_s"] == 11 and o["isolation_time_s"] is None


def test_multi_fault_isolation_delay_from_last_onset():
    f = [fault("S1.1", 5), fault("bore_damage", 10)]
    r = rec([[1, [], False], [6, ["S1.1"], True], [13, ["S1.1", "bore_damage"], True]], f)
    o = episode_outcome(r)
    assert o["fault_class"] == "mixed"
    assert o["detection_delay_s"] == 1
    assert o["isolation_time_s"] == 13 and o["isolation_delay_s"] == 3
    assert o["isolation_correct"] is True and o["fault_free_s"] == 5
    # both declared before the last onset: correct at the first decision >= last onset
    early = rec([[1, [], False], [3, ["S1.1", "S2.1"], True]], [fault("S1.1", 5), fault("S2.1", 9.5)])
    o = episode_outcome(early)
    assert o["false_alarms"] == 1 and o["detection_delay_s"] == 0
    assert o["isolation_time_s"] == 10 and o["isolation_delay_s"] == pytest.approx(0.5)


def test_undetected_when_episode_ends_or_trace_empty():
    f = [fault("S4.1", 15)]
    short = rec([[1, [], False]], f, duration=12.0, terminated=True, failure_reason="overspeed")
    o = episode_outcome(short)
    assert o["detection_time_s"] is None and o["fault_free_s"] == 12
    empty = rec([], [fault("S4.1", 5)])
    o = episode_outcome(empty)
    assert o["detection_time_s"] is None and o["isolation_correct"] is False
    m = compute_metrics([short, empty])
    assert m["detection_rate"] == 0.0 and m["median_detection_delay_s"] is None
    assert m["engine_failures"] == 1


def test_fractional_decision_period_float_times():
    ts = [round(0.1 * k, 10) for k in range(1, 4)]
    r = rec([[ts[0], [], False], [0.1 + 0.1 + 0.1, ["S1.2"], True]], [fault("S1.2", 0.25)], dp=0.1, duration=1.0)
    o = episode_outcome(r)
    assert o["detection_time_s"] == pytest.approx(0.3)
    assert o["detection_delay_s"] == pytest.approx(0.05)
    held = rec([[0.1, [], False], [0.2, ["S1.2"], True]], [fault("S1.2", 0.3)], dp=0.1, duration=1.0)
    o = episode_outcome(held)
    assert o["false_alarms"] == 1 and o["detection_delay_s"] == pytest.approx(0.0, abs=1e-9)


def test_delay_percentiles_with_few_values():
    f = [fault("S1.1", 5)]
    one = rec([[1, [], False], [6, ["S1.1"], True]], f)
    two = rec([[1, [], False], [7, ["S1.1"], True]], f)
    m = compute_metrics([one])
    assert m["median_detection_delay_s"] == 1 and m["p90_detection_delay_s"] == 1
    m = compute_metrics([one, two])
    assert m["median_detection_delay_s"] == pytest.approx(1.5)
    assert m["p90_detection_delay_s"] == pytest.approx(1.9)
    assert m["median_isolation_delay_s"] == pytest.approx(1.5)


def test_censored_median_counts_missed_faults_as_never_detected():
    f = [fault("S1.1", 5)]
    d1 = rec([[1, [], False], [6, ["S1.1"], True]], f, sid="a")  # delay 1
    d3 = rec([[1, [], False], [8, ["S1.1"], True]], f, sid="b")  # delay 3
    miss = rec([[1, [], False]], f, sid="c")
    m = compute_metrics([d1, d3])
    assert m["median_detection_delay_censored_s"] == m["median_detection_delay_s"] == pytest.approx(2.0)
    m = compute_metrics([d1, d3, miss])  # 1, 3, never -> 3; the plain median stays 2
    assert m["median_detection_delay_censored_s"] == pytest.approx(3.0) and m["median_detection_delay_s"] == 2.0
    m = compute_metrics([d1, miss, dict(miss, scenario_id="d")])  # fewer than half detected: not reached
    assert m["median_detection_delay_censored_s"] is None and m["median_detection_delay_s"] == 1.0
    assert compute_metrics([rec([[1, [], False]])])["median_detection_delay_censored_s"] is None  # no fault


def test_belief_compute_return_and_json():
    f = [fault("S1.1", 5)]
    a = rec([[1, [], False]], f, belief_on_truth=[[5, 0.2], [6, 0.4]], compute_s=2.0, n_samples=100)
    b = rec([[1, [], False]], f, belief_on_truth=[[5, 1.0]], compute_s=1.0, n_samples=200, **{"return": 3.0})
    m = compute_metrics([a, b])
    assert m["belief_on_truth"] == pytest.approx((0.3 + 1.0) / 2)
    assert m["compute_s_per_sample"] == pytest.approx(3.0 / 300)
    assert m["mean_return"] == pytest.approx(1.0)
    assert compute_metrics([rec([[1, [], False]], f)])["belief_on_truth"] is None
    json.dumps(m, allow_nan=False)
    empty = compute_metrics([])
    assert empty["n_episodes"] == 0 and empty["false_alarm_rate"] is None
    json.dumps(empty, allow_nan=False)


def test_per_class_and_per_fault_split():
    recs = [
        rec([[1, [], False], [6, ["S1.1"], True]], [fault("S1.1", 5)], sid="s1"),
        rec([[1, [], False]], [fault("S1.1", 5)], sid="s2"),
        rec([[1, [], False], [8, ["bore_damage"], True]], [fault("bore_damage", 5)], sid="p"),
        rec([[1, [], False], [6, ["S2.1"], True]], [fault("S2.1", 5), fault("valve_seizing", 6)], sid="m"),
        rec([[1, [], False], [2, [], True]], sid="n", duration=3600.0),
    ]
    m = compute_metrics(recs)
    bc = m["by_class"]
    assert set(bc) == {"sensor", "process", "mixed", "none"}
    assert bc["sensor"]["n_episodes"] == 2 and bc["sensor"]["detection_rate"] == 0.5
    assert bc["process"]["median_detection_delay_s"] == 3
    assert bc["mixed"]["n_faulty"] == 1 and bc["mixed"]["isolation_accuracy"] == 0.0
    assert bc["none"]["detection_rate"] is None and bc["none"]["false_alarm_rate"] == pytest.approx(1.0)
    assert list(m["by_fault"]) == ["S1.1", "bore_damage"]
    assert m["by_fault"]["S1.1"]["n_episodes"] == 2
    assert m["detection_rate"] == pytest.approx(3 / 4)
    assert m["false_alarm_episode_rate"] == pytest.approx(1 / 5)
    assert m["fault_free_hours"] == pytest.approx(1 + 4 * 5 / 3600)
    json.dumps(m, allow_nan=False)


@pytest.mark.parametrize(
    "mutate, field",
    [
        (lambda r: r.pop("duration_s"), "duration_s"),
        (lambda r: r.pop("declared_changes"), "declared_changes"),
        (lambda r: r.update(seed="1"), "seed"),
        (lambda r: r.update(n_samples=True), "n_samples"),
        (lambda r: r.update(decision_period_s=0.0), "decision_period_s"),
        (lambda r: r.update(compute_s=float("nan")), "compute_s"),
        (lambda r: r.update(terminated=1), "terminated"),
        (lambda r: r.update(failure_reason=3), "failure_reason"),
        (lambda r: r["faults"].append(fault("S9.9", 1)), "faults[1].id"),
        (lambda r: r["faults"][0].update({"class": "process"}), "faults[0].class"),
        (lambda r: r["faults"][0].pop("onset_s"), "faults[0].onset_s"),
        (lambda r: r["faults"][0].update(end_s=2.0), "faults[0].end_s"),
        (lambda r: r["declared_changes"].append([0.5, [], False]), "declared_changes[1]"),
        (lambda r: r["declared_changes"].append([3, [], "yes"]), "declared_changes[1]"),
        (lambda r: r["declared_changes"].append([3, ["no_fault"], True]), "declared_changes[1]"),
        (lambda r: r.update(belief_on_truth=[[1, 1.5]]), "belief_on_truth[0]"),
    ],
)
def test_validation_errors_name_field_and_scenario(mutate, field):
    r = rec([[1, [], False]], [fault("S1.1", 5)], sid="bad-scenario")
    mutate(r)
    with pytest.raises(ValueError) as e:
        compute_metrics([r])
    assert f"'{field}'" in str(e.value) and "bad-scenario" in str(e.value)


def test_validate_rejects_non_dict():
    with pytest.raises(ValueError, match="dict"):
        validate_record([1, 2])
    validate_record(rec([[1, [], False]]))
