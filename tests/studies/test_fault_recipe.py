"""The recipe of docs/extending.md, "Add a process fault", end to end: the toy fault of the doc (a plugin file,
no file of the package edited) gets its measured tables from ``python -m studies.fault_tables --small`` in a
temporary folder, then is simulated, diagnosed, drawn in an environment episode and scored on its own suite."""

from __future__ import annotations

import json
import os
import subprocess
import sys

from marine_fdi_env.engine.faults import FAULT_IDS
from tests.integration.test_fault_registry import TOY, toy_fault_source
from tests.paths import ROOT

_PIPELINE = """
import json, sys
import gymnasium as gym
import marine_fdi_env
from marine_fdi_env.diagnosis.agent import ReferenceDiagnoser
from marine_fdi_env.diagnosis.sequential import SequentialDiagnoser
from marine_fdi_env.engine.simulator import Simulator
out = {}
sim = Simulator("thesis-12v28", n_engines=1, seeds=3, faults=["exhaust_valve_leak@30:2e-3"])
r = sim.run(200.0)
for name, cls in (("reference", ReferenceDiagnoser), ("sequential", SequentialDiagnoser)):
    d = cls("thesis-12v28", n_engines=1, dt=sim.dt)
    d.observe(r.measurements.transpose(1, 0, 2), r.truth_of("u").T)
    out[name] = d.report(0)
cfg = {"name": "toy", "fault_ids": ["exhaust_valve_leak"], "fault_count_weights": [0, 1, 0], "duration_s": 60.0,
       "onset_range_s": [10.0, 30.0]}
env = gym.make("MarineFDI-v1", scenario_config=cfg)
obs, info = env.reset(seed=0)
out["true_faults"] = info["true_faults"]
steps, done = 0, False
while not done:
    obs, reward, term, trunc, info = env.step(env.action_space.sample())
    steps, done = steps + 1, term or trunc
out["steps"] = steps
print(json.dumps(out))
"""


def _run(args, env, cwd, timeout=1800):
    out = subprocess.run(args, capture_output=True, text=True, cwd=cwd, env=env, timeout=timeout)
    assert out.returncode == 0, out.stdout[-4000:] + out.stderr[-4000:]
    return out.stdout


def test_the_recipe_measures_a_toy_fault_and_runs_it_through_the_benchmark(tmp_path):
    (tmp_path / "toy_fault.py").write_text(toy_fault_source())
    env = dict(os.environ, MARINE_FDI_FAULTS=str(tmp_path / "toy_fault.py"))
    env.pop("MARINE_FDI_TABLES", None)
    tables = tmp_path / "tables"
    said = _run(
        [sys.executable, "-m", "studies.fault_tables", "--faults", TOY, "--out", str(tables), "--small"], env, ROOT
    )
    suite = tables / "suites" / f"single-{TOY}-v1.json"
    for rel in (
        "env/detectability.json",
        "diagnosis/sure_cells.json",
        "diagnosis/sized_cells.json",
        "diagnosis/sequential_sure_cells.json",
        "diagnosis/sequential_sized_cells.json",
        "diagnosis/sure_cells_table_magnitudes.json",
        f"suites/single-{TOY}-v1.json",
    ):
        assert f"{tables / rel}: " in said, said  # it says what it wrote and where
    det = json.loads((tables / "env" / "detectability.json").read_text())["faults"]
    assert list(det) == list(FAULT_IDS) + [TOY] and det[TOY]["limit"] > 0
    shipped = json.loads((ROOT / "src/marine_fdi_env/data/env/detectability.json").read_text())["faults"]
    assert all(det[f] == shipped[f] for f in FAULT_IDS)  # the other faults' entries kept
    cells = json.loads((tables / "diagnosis" / "sized_cells.json").read_text())
    assert cells["fault_ids"] == list(FAULT_IDS) + [TOY]

    env["MARINE_FDI_TABLES"] = str(tables)
    res = json.loads(_run([sys.executable, "-c", _PIPELINE], env, tmp_path).strip().splitlines()[-1])
    for name in ("reference", "sequential"):
        assert res[name]["detected"], res[name]
    assert [TOY] in res["reference"]["final_minimal_diagnoses"], res["reference"]
    assert [f["id"] for f in res["true_faults"]] == [TOY] and res["steps"] == 60

    # its own suite, scored from the command line
    _run(
        [sys.executable, "-m", "marine_fdi_env.cli", "evaluate", "--agent", "reference", "--suite", str(suite),
         "--out", str(tmp_path / "leak.json"), "--no-progress"],
        env,
        tmp_path,
    )  # fmt: skip
    result = json.loads((tmp_path / "leak.json").read_text())
    assert result["n_scenarios"] == 6 and {e["scenario_id"].split("/")[0] for e in result["episodes"]} == {TOY}
    assert "detection_rate" in result["metrics"]
