"""The reference as it ships scores what its recorded results say (docs/data/results): a change to the
diagnoser that moves one number of one episode fails here.  Wall-clock fields aside."""

from __future__ import annotations

import json

import pytest

from marine_fdi_env.benchmark.evaluate import evaluate_agents
from tests.paths import ROOT

RESULTS = ROOT / "docs" / "data" / "results"
_WALL = ("compute_s", "feature_compute_s", "agent_compute_s", "load_average_1min", "package_version")


def _no_clock(o):
    if isinstance(o, dict):
        return {
            k: _no_clock(v)
            for k, v in o.items()
            if k not in _WALL and not k.endswith("compute_s_per_sample") and k != "agent_compute_s_per_decision"
        }
    if isinstance(o, list):
        return [_no_clock(v) for v in o]
    return o


@pytest.mark.parametrize("suite", ["thesis-v1", pytest.param("multi-v1", marks=pytest.mark.study)])
def test_the_reference_scores_as_recorded(suite, tmp_path):
    recorded = json.loads((RESULTS / f"reference_{suite}.json").read_text())
    now = evaluate_agents(["reference"], suite, [tmp_path / "r.json"], progress=False)[0]
    assert _no_clock(now["episodes"]) == _no_clock(recorded["episodes"])
    assert _no_clock(now["metrics"]) == _no_clock(recorded["metrics"])
