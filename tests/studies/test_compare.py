"""studies.agents.compare's must-show rules: the censored median ("not reached" is worse than any number)
and the paired median over the episodes both agents detect."""

from __future__ import annotations

import json

import pytest

pytest.importorskip("torch")

import studies.agents.compare as cmp  # noqa: E402
from marine_fdi_env.benchmark.metrics import compute_metrics  # noqa: E402


def _episode(sid: str, delay):
    trace = [[1.0, [], False]] + ([[10.0 + delay, [], True]] if delay is not None else [])
    return {
        "scenario_id": sid,
        "suite": "incipient-v1",
        "seed": 0,
        "agent": "a",
        "profile": "constant",
        "duration_s": 300.0,
        "decision_period_s": 1.0,
        "n_samples": 30000,
        "faults": [{"id": "bore_damage", "class": "process", "onset_s": 10.0, "magnitude": 1.0, "end_s": None}],
        "declared_changes": trace,
        "belief_on_truth": [],
        "terminated": False,
        "failure_reason": None,
        "compute_s": 0.0,
        "return": 0.0,
        "reward_terms": {},
    }


def _write(tmp_path, agent, suite, delays):
    """The same episodes for every training seed of ``agent`` (one file per seed, as compare writes them)."""
    eps = [_episode(f"e{i}", d) for i, d in enumerate(delays)]
    for k, path in enumerate(cmp._result_paths(agent, suite)):
        seed = {"training_seed": k} if cmp._multi_seed(agent) else {}
        path.write_text(json.dumps(dict(agent=agent, suite=suite, metrics=compute_metrics(eps), episodes=eps, **seed)))


@pytest.fixture
def results(tmp_path, monkeypatch):
    monkeypatch.setattr(cmp, "RESULTS", tmp_path)
    monkeypatch.setattr(cmp, "_model_cfgs", lambda name: [])
    return tmp_path


def _checks(name: str) -> dict:
    return {k: (v, ok) for k, v, ok in cmp.must_shows() if k.startswith(name)}


def test_not_reached_reference_loses_to_any_censored_median(results):
    _write(results, "reference", "incipient-v1", [40.0, 50.0, None, None, None])  # 2 of 5: not reached
    _write(results, "classifier", "incipient-v1", [20.0, 30.0, 90.0, None, 100.0])  # 4 of 5
    checks = _checks("classifier: incipient-v1")
    censored = next(v for k, v in checks.items() if "censored" in k)
    assert censored[1] is True and censored[0].startswith("90.0 (") and "s vs not reached" in censored[0]
    paired = next(v for k, v in checks.items() if "paired" in k)
    # both detect e0, e1 (of each of the 3 training seeds): 25 s vs 45 s, reported beside the check
    assert (
        paired[1] == "reported"
        and "25.0 s vs 45.0 s" in paired[0]
        and "the 6 seed x episode pairs" in next(k for k in checks if "paired" in k)
    )


def test_an_agent_that_does_not_reach_its_median_fails(results):
    _write(results, "reference", "incipient-v1", [40.0, 50.0, 60.0, None, None])
    _write(results, "classifier", "incipient-v1", [5.0, None, None, None, None])
    checks = _checks("classifier: incipient-v1")
    censored = next(v for k, v in checks.items() if "censored" in k)
    assert censored[1] is False and censored[0].startswith("not reached vs 60.0 s")  # the middle of 5
    paired = next(v for k, v in checks.items() if "paired" in k)
    assert paired[1] == "reported" and "5.0 s vs 40.0 s" in paired[0]


def test_every_agent_row_says_what_it_is(results):
    """Each compared agent (sequential included) has its description and its 'reads the reference'
    flag: the tables are written for every row, with n/a where a result is missing."""
    assert set(cmp.WHAT) == set(cmp.AGENTS)
    table = cmp.compact_table(list(cmp.AGENTS))
    assert all(f"| {a} | " in table for a in cmp.AGENTS)
    assert "| sequential | no |" in table  # CUSUM on the residuals, not the reference's conclusion


def test_a_rate_over_training_seeds_is_judged_pooled_with_every_seed_shown(results):
    # seeds 0 and 1 detect all 10 episodes, seed 2 detects 8: pooled 28/30 = 93.3 % meets >= 90 %,
    # and the row names seed 2, which alone would not
    for k, path in enumerate(cmp._result_paths("classifier", "transfer-v2")):
        eps = [_episode(f"e{i}", None if (k == 2 and i < 2) else 5.0) for i in range(10)]
        path.write_text(
            json.dumps(
                dict(
                    agent="classifier", suite="transfer-v2", metrics=compute_metrics(eps), episodes=eps, training_seed=k
                )
            )
        )
    checks = _checks("classifier: transfer-v2 detection")
    text, met = next(iter(checks.values()))
    assert met is True and "93.3 %" in text and "seed 2 alone would not meet it" in text
