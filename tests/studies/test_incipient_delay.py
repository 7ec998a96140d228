"""studies/agents/incipient_delay.py: detection, censored and paired medians from per-episode delays."""

import pytest

from studies.agents.incipient_delay import delay_table


def test_censored_and_paired_medians_per_agent():
    noise = {f"e{i}": 1.0 for i in range(5)}
    faulty = {"e0", "e1", "e2", "e3"}  # e4 is fault-free
    delays = {
        "reference": {"e0": (40.0, 0), "e1": (None, 0), "e2": (60.0, 0), "e3": (None, 0), "e4": (None, 0)},
        "agent": {"e0": (20.0, 0), "e1": (100.0, 0), "e2": (None, 0), "e3": (120.0, 0), "e4": (None, 1)},
    }
    ref, agent = delay_table(delays, noise, faulty)
    assert ref["noise"] == "1x" and ref["faulty"] == 4 and ref["detection"] == 0.5
    assert ref["censored_median_s"] is None  # the middle ranks (60 s, never) include an undetected episode
    assert "pairs" not in ref
    assert agent["detection"] == 0.75 and agent["censored_median_s"] == pytest.approx(110.0)  # (100 + 120) / 2
    assert agent["pairs"] == 1 and agent["paired_median_s"] == 20.0 and agent["reference_paired_median_s"] == 40.0
    assert agent["false_alarms"] == 1 and agent["episodes"] == 5


def test_rows_per_noise_scale_and_overall_when_several_scales():
    noise = {"a": 0.5, "b": 1.5}
    rows = delay_table({"x": {"a": (10.0, 0), "b": (30.0, 0)}}, noise, {"a", "b"})
    assert [r["noise"] for r in rows] == ["all", "0.5x", "1.5x"]
    assert rows[0]["censored_median_s"] == 20.0 and rows[2]["censored_median_s"] == 30.0
