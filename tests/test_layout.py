"""The package layout: the engine subpackage move changes no result (issue 15, item 9).

``tests/data/layout_records.json`` holds the episode records (without the wall-clock fields) of a
few agents on subsets of ``thesis-v1`` and ``single-v1``, made by the code *before* the move (its
commit is in the file).  Re-evaluating the same subsets must give the same records, bit for bit
(exact equality of the JSON-loaded values).  Regenerate only on a deliberate behaviour change:
``python tests/test_layout.py`` (and say why in the commit).
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
FIXTURE = ROOT / "tests" / "data" / "layout_records.json"
# scenario indices of the shipped suites: faults of every kind, nominal runs, several magnitudes
SUBSETS = {"thesis-v1": (0, 5, 10, 15), "single-v1": (0, 40, 80, 140)}
AGENTS = ("reference", "random", "classifier+reference")


def _records(agent: str, suite: str, idx, tmp: Path) -> list[dict]:
    from marine_fdi_env.envs.evaluate import WALL_CLOCK_FIELDS, evaluate
    from marine_fdi_env.envs.suites import load_suite

    sc = load_suite(suite).scenarios
    f = tmp / f"{suite}-subset.json"  # same suite name: records compare as the suite's
    f.write_text(json.dumps({"name": suite, "version": 1, "description": "layout fixture",
                             "env": {"decision_period_s": 1.0, "params": "thesis-12v28", "observe_sensors": False},
                             "scenarios": [sc[i].to_dict() for i in idx]}))
    res = evaluate(agent, str(f), tmp / f"{agent}_{suite}.json", backend="serial", batch_size=4, progress=False)
    recs = [{k: v for k, v in r.items() if k not in WALL_CLOCK_FIELDS} for r in res["episodes"]]
    return json.loads(json.dumps(recs))  # exactly what a JSON round trip keeps


def make_all(tmp: Path) -> dict:
    return {f"{a}/{s}": _records(a, s, idx, tmp) for a in AGENTS for s, idx in SUBSETS.items()}


def test_suite_records_unchanged_by_the_move(tmp_path):
    frozen = json.loads(FIXTURE.read_text())
    assert set(frozen["runs"]) == {f"{a}/{s}" for a in AGENTS for s in SUBSETS}
    now = make_all(tmp_path)
    for key, recs in frozen["runs"].items():
        assert len(now[key]) == len(recs) == len(SUBSETS[key.split("/")[1]]), key
        for old, new in zip(recs, now[key]):
            assert new == old, f"{key} {old['scenario_id']}: " + ", ".join(
                k for k in sorted(set(old) | set(new)) if old.get(k) != new.get(k))


if __name__ == "__main__":  # regenerate the fixture with the code in this checkout
    import tempfile

    commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True,
                            check=True).stdout.strip()
    with tempfile.TemporaryDirectory() as d:
        runs = make_all(Path(d))
    FIXTURE.parent.mkdir(parents=True, exist_ok=True)
    FIXTURE.write_text(json.dumps({"made_by_commit": commit, "subsets": SUBSETS, "agents": AGENTS,
                                   "wall_clock_fields_left_out": ["compute_s", "feature_compute_s", "agent_compute_s"],
                                   "runs": runs}, separators=(",", ":")) + "\n")
    print(f"wrote {FIXTURE} ({FIXTURE.stat().st_size} bytes) from {commit}", file=sys.stderr)
