"""Intervals, normalised scores and their IQM (marine_fdi_env.benchmark.uncertainty)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import beta, chi2, trim_mean

from marine_fdi_env.benchmark.uncertainty import (
    difference,
    interval,
    iqm_score,
    normalised_score,
    outcomes,
    seed_spread,
)


def _episode(sid: str, fault: str | None, delay: float | None, ret: float = 0.0, false_alarm: bool = False) -> dict:
    """A 100 s episode: a fault at 50 s (sensor S1.1 or process bore_damage) detected after ``delay``."""
    trace = [[1.0, [], False]]
    if false_alarm:
        trace += [[10.0, [], True], [11.0, [], False]]
    if delay is not None:
        trace.append([50.0 + delay, [fault] if fault else [], True])
    faults = (
        []
        if fault is None
        else [
            {
                "id": fault,
                "class": "sensor" if fault.startswith("S") else "process",
                "onset_s": 50.0,
                "magnitude": 1.0,
                "end_s": None,
            }
        ]
    )
    return {
        "scenario_id": sid,
        "suite": "s",
        "seed": 0,
        "agent": "a",
        "profile": "constant",
        "duration_s": 100.0,
        "decision_period_s": 1.0,
        "n_samples": 1000,
        "faults": faults,
        "declared_changes": trace,
        "terminated": False,
        "failure_reason": None,
        "compute_s": 0.0,
        "return": ret,
        "reward_terms": {},
    }


def _suite(detected: list[bool], fault: str = "S1.1", **kw) -> list[dict]:
    return [_episode(f"e{i}", fault, 2.0 if d else None, **kw) for i, d in enumerate(detected)]


def test_a_share_and_its_bootstrap_interval_are_reproducible_and_contain_it():
    o = outcomes([_suite([True] * 30 + [False] * 10)])
    e = interval(o, "detection_rate")
    assert e.value == pytest.approx(0.75) and e.method == "bootstrap"
    assert e.low < 0.75 < e.high and e.high - e.low < 0.35
    assert interval(o, "detection_rate") == e  # a fixed generator: the same interval, bit for bit
    # about the binomial standard error: 1.96 sqrt(p (1 - p) / n) = 0.134 either side
    assert (e.high - e.low) / 2 == pytest.approx(1.96 * np.sqrt(0.75 * 0.25 / 40), rel=0.25)


def test_strata_keep_their_size():
    """Every sensor-fault episode detected, no process-fault one: resampling within the strata keeps 20
    of 40 detected in every resample (zero width, so the exact interval of one seed is given)."""
    eps = _suite([True] * 20) + [_episode(f"p{i}", "bore_damage", None) for i in range(20)]
    e = interval(outcomes([eps]), "detection_rate")
    assert e.value == 0.5 and e.method == "exact"
    assert (e.low, e.high) == pytest.approx((beta.ppf(0.025, 20, 21), beta.ppf(0.975, 21, 20)))


def test_no_false_alarm_gives_the_exact_poisson_and_clopper_pearson_bounds():
    o = outcomes([[_episode(f"n{i}", None, None) for i in range(48)]])  # 48 fault-free 100 s episodes
    fa = interval(o, "false_alarm_rate")
    hours = 48 * 100 / 3600
    assert fa.value == 0.0 and fa.method == "exact" and fa.low == 0.0
    assert fa.high == pytest.approx(chi2.ppf(0.975, 2) / 2 / hours)  # 3.69 events / 1.33 h
    ep = interval(o, "false_alarm_episode_rate")
    assert ep.high == pytest.approx(1 - 0.025 ** (1 / 48))  # Clopper-Pearson upper bound of 0 / 48


def test_training_seeds_widen_the_interval_when_they_disagree():
    a, b = _suite([True] * 36 + [False] * 4), _suite([True] * 20 + [False] * 20)
    one = interval(outcomes([a]), "detection_rate")
    same = interval(outcomes([a, a, a]), "detection_rate")
    mixed = interval(outcomes([a, b, a]), "detection_rate")
    assert same.value == one.value == 0.9 and mixed.value == pytest.approx((36 + 20 + 36) / 120)
    assert (mixed.high - mixed.low) > (same.high - same.low)
    assert seed_spread(outcomes([a, b, a]), "detection_rate") == (0.5, 0.9)
    with pytest.raises(ValueError, match="same episodes"):
        outcomes([a, a[:-1]])


def test_difference_is_paired_on_the_episodes():
    a = _suite([True] * 30 + [False] * 10)
    b = _suite([True] * 30 + [False] * 10)
    d = difference(outcomes([a]), outcomes([b]), "detection_rate")
    assert (d.value, d.low, d.high) == (0.0, 0.0, 0.0)  # the same outcome on every episode: no doubt at all
    c = _suite([True] * 20 + [False] * 20)
    d1, d2 = (
        difference(outcomes([a]), outcomes([c]), "detection_rate"),
        difference(outcomes([c]), outcomes([a]), "detection_rate"),
    )
    assert d1.value == pytest.approx(0.25) and d1.low > 0  # 10 more episodes detected, never fewer
    assert d2.value == pytest.approx(-d1.value) and d2.high == pytest.approx(-d1.low)


def test_normalised_scores_put_null_at_0_and_oracle_at_100():
    n = 20
    null = outcomes([[_episode(f"e{i}", "S1.1", None, ret=-2.0 - 0.1 * i) for i in range(n)]])
    oracle = outcomes([[_episode(f"e{i}", "S1.1", 0.5, ret=20.0 + 0.1 * i) for i in range(n)]])
    half = outcomes([[_episode(f"e{i}", "S1.1", 1.0, ret=9.0) for i in range(n)]])
    assert normalised_score(null, null, oracle).value == pytest.approx(0.0)
    assert normalised_score(oracle, null, oracle).value == pytest.approx(100.0)
    s = normalised_score(half, null, oracle)
    assert s.value == pytest.approx(100 * (9.0 + 2.95) / (20.95 + 2.95)) and s.low < s.value < s.high
    # undefined where null and oracle earn the same (a fault-free suite)
    quiet = outcomes([[_episode(f"q{i}", None, None) for i in range(n)]])
    assert normalised_score(quiet, quiet, quiet).value is None


def test_iqm_is_the_25_percent_trimmed_mean_over_seeds_and_suites():
    suites = []
    for k, r in enumerate((0.0, 5.0, 10.0, 15.0, 20.0)):
        ids = [f"s{k}e{i}" for i in range(10)]
        null = outcomes([[dict(_episode(i, "S1.1", None, ret=0.0)) for i in ids]])
        oracle = outcomes([[dict(_episode(i, "S1.1", 0.5, ret=20.0)) for i in ids]])
        agent = outcomes([[dict(_episode(i, "S1.1", 1.0, ret=r)) for i in ids]])
        suites.append((agent, null, oracle))
    e = iqm_score(suites)
    assert e.value == pytest.approx(trim_mean([0, 25, 50, 75, 100], 0.25)) == pytest.approx(50.0)
    assert e.low == e.high == pytest.approx(50.0)  # constant returns within each suite
