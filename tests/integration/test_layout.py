"""The package layout: moving code between subpackages changes no result.

``tests/data/layout_records.json`` holds the episode records (without the wall-clock fields) of a
few agents on subsets of ``thesis-v1`` and ``single-v1``, made by the code *before* the move (its
commit is in the file).  Re-evaluating the same subsets must give the same records, bit for bit
(exact equality of the JSON-loaded values).  Regenerate only on a deliberate behaviour change:
``python -m tests.integration.test_layout`` (from the repository root) (and say why in the commit).
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from tests.paths import ROOT

FIXTURE = ROOT / "tests" / "data" / "layout_records.json"
# scenario indices of the shipped suites: faults of every kind, nominal runs, several magnitudes
SUBSETS = {"thesis-v1": (0, 5, 10, 15), "single-v1": (0, 40, 80, 140)}
AGENTS = ("reference", "random", "classifier-v1+reference")


def _records(agent: str, suite: str, idx, tmp: Path) -> list[dict]:
    from marine_fdi_env.benchmark.evaluate import WALL_CLOCK_FIELDS, evaluate
    from marine_fdi_env.benchmark.suites import load_suite

    sc = load_suite(suite).scenarios
    f = tmp / f"{suite}-subset.json"  # same suite name: records compare as the suite's
    f.write_text(
        json.dumps(
            {
                "name": suite,
                "version": 1,
                "description": "layout fixture",
                "env": {"decision_period_s": 1.0, "params": "thesis-12v28", "observe_sensors": False},
                "scenarios": [sc[i].to_dict() for i in idx],
            }
        )
    )
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
                k for k in sorted(set(old) | set(new)) if old.get(k) != new.get(k)
            )


if __name__ == "__main__":  # regenerate the fixture with the code in this checkout
    import tempfile

    commit = subprocess.run(
        ["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True, check=True
    ).stdout.strip()
    with tempfile.TemporaryDirectory() as d:
        runs = make_all(Path(d))
    FIXTURE.parent.mkdir(parents=True, exist_ok=True)
    FIXTURE.write_text(
        json.dumps(
            {
                "made_by_commit": commit,
                "subsets": SUBSETS,
                "agents": AGENTS,
                "wall_clock_fields_left_out": ["compute_s", "feature_compute_s", "agent_compute_s"],
                "runs": runs,
            },
            separators=(",", ":"),
        )
        + "\n"
    )
    print(f"wrote {FIXTURE} ({FIXTURE.stat().st_size} bytes) from {commit}", file=sys.stderr)


# ----------------------------------------------------------------------------- layers and names
def test_info_imports_finds_no_circle_and_no_backward_import(tmp_path):
    """``python -m marine_fdi_env.info --imports`` on the installed package, run outside the repository (an empty
    folder: not the clone's parent, where a clone named ``marine_fdi_env`` would shadow the package as a namespace
    package): exit 0, and every module of the package (engine, agents, training included) is in the graph."""
    out = subprocess.run(
        [sys.executable, "-m", "marine_fdi_env.info", "--imports"], capture_output=True, text=True, cwd=tmp_path
    )
    assert out.returncode == 0, out.stdout + out.stderr
    assert "no import circle, no backward import between layers" in out.stdout
    from marine_fdi_env.layers import layer_of, package_modules

    mods = package_modules()
    for name in (
        "marine_fdi_env.engine.simulator",
        "marine_fdi_env.engine.subsystems.gas_path",
        "marine_fdi_env.baselines.reference_agent",
        "marine_fdi_env.training.train",
    ):
        assert name in mods
    assert layer_of("marine_fdi_env.engine.params") == "params" and layer_of("marine_fdi_env.engine.model") == "engine"
    assert layer_of("marine_fdi_env.training.rl") == "agents" and layer_of("marine_fdi_env") == "top"


def test_info_imports_reports_circles_and_backward_imports(tmp_path):
    """The check can fail: a module-level circle, a circle through a function-level import, a
    diagnosis module reaching the environments, an import of the CLI and an import of the repository's
    studies are all reported."""
    from marine_fdi_env.layers import check_imports, print_imports

    src = {
        "marine_fdi_env.engine.a": "from marine_fdi_env.engine import b\n",
        "marine_fdi_env.engine.b": "def f():\n    from .a import x\n",
        "marine_fdi_env.diagnosis.d": "from ..envs.e import y\n",
        "marine_fdi_env.envs.e": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from ..diagnosis import d\n"
        "def g():\n    from marine_fdi_env import cli\n",
        "marine_fdi_env.cli": "",
        "marine_fdi_env.benchmark.s": "def h():\n    from studies.validation.study import trial\n",
    }
    mods = {}
    for name, text in src.items():
        f = tmp_path / (name.replace(".", "_") + ".py")
        f.write_text(text)
        mods[name] = f
    res = check_imports(mods)
    assert res["cycles"] == [["marine_fdi_env.engine.a", "marine_fdi_env.engine.b"]]
    back = {(e.importer, e.imported) for e in res["backward"]}
    assert back == {
        ("marine_fdi_env.diagnosis.d", "marine_fdi_env.envs.e"),
        ("marine_fdi_env.envs.e", "marine_fdi_env.cli"),
    }  # not the TYPE_CHECKING import
    assert [(e.importer, e.imported) for e in res["studies"]] == [
        ("marine_fdi_env.benchmark.s", "studies.validation.study")
    ]
    assert print_imports(res, file=open(tmp_path / "out.txt", "w")) == 1


def test_the_validation_stages_import_one_way(tmp_path):
    """Inside validation/ each stage is a layer: data in -> fit -> select -> explain -> report.  Every module of
    validation/ is in a stage (the package __init__ aside), and an import against that order is reported."""
    from marine_fdi_env.layers import VALIDATION_STAGES, check_imports, layer_of, package_modules

    stages = {layer_of(m) for m in package_modules() if m.startswith("marine_fdi_env.validation.")}
    assert stages == set(VALIDATION_STAGES)
    assert layer_of("marine_fdi_env.validation") == "validation"
    assert layer_of("marine_fdi_env.validation.measured.readers") == "validation.measured"
    src = {
        "marine_fdi_env.validation.measured.a": "def f():\n    from ..fit.problem import FitProblem\n",
        "marine_fdi_env.validation.fit.problem": "from ..measured import a\n",
        "marine_fdi_env.validation.explain.e": "from ..select.s import x\nfrom ..report.r import y\n",
        "marine_fdi_env.validation.select.s": "",
        "marine_fdi_env.validation.report.r": "",
    }
    mods = {}
    for name, text in src.items():
        f = tmp_path / (name.replace(".", "_") + ".py")
        f.write_text(text)
        mods[name] = f
    back = {(e.importer, e.imported) for e in check_imports(mods)["backward"]}
    assert back == {
        ("marine_fdi_env.validation.measured.a", "marine_fdi_env.validation.fit.problem"),
        ("marine_fdi_env.validation.explain.e", "marine_fdi_env.validation.report.r"),
    }


def test_agents_and_models_are_named_under_the_namespace(tmp_path):
    """Built-in agents, shipped model folders and the models package are under marine_fdi_env;
    an agent.json with a pre-move class name fails with the new spelling in the message."""
    from marine_fdi_env.benchmark.agent_api import BUILTIN_AGENTS, load_agent
    from marine_fdi_env.benchmark.agent_registry import MODELS_PACKAGE, models_dir

    assert all(t.startswith("marine_fdi_env.baselines.") for t in BUILTIN_AGENTS.values())
    assert MODELS_PACKAGE == "marine_fdi_env.training"
    for meta in Path(models_dir()).glob("*/agent.json"):
        assert json.loads(meta.read_text())["class"].startswith("marine_fdi_env.training.agents:"), meta
    d = tmp_path / "old"
    d.mkdir()
    (d / "agent.json").write_text(json.dumps({"class": "no_such_pkg_xyz.agents:SB3Agent", "kwargs": {}}))
    with pytest.raises(ValueError, match="cannot import 'no_such_pkg_xyz.agents'"):
        load_agent(str(d))
    out = subprocess.run(
        [
            sys.executable,
            "-c",
            "from marine_fdi_env.benchmark.agent_api import _import\n"
            "_import('training.agents:SB3Agent', 'old/agent.json')",
        ],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )  # outside the repository
    assert "write 'marine_fdi_env.training.agents:SB3Agent' in the agent.json" in out.stderr
