"""The fault registry: the shipped faults declared once, records checked, and a toy fault of a plugin (the recipe
of docs/extending.md) that simulates, is diagnosed, drawn by the environment and scored on a suite of its own
with stand-in tables, and is refused by name without its measured tables.  The recipe with the tables
measured: tests/studies/test_fault_recipe.py."""

from __future__ import annotations

import json
import math
import os
import re
import subprocess
import sys

import numpy as np
import pytest

from marine_fdi_env.diagnosis.modules import EQUATION_FAULTS
from marine_fdi_env.diagnosis.sized_cells import merge_sized_faults, select_sized_faults
from marine_fdi_env.diagnosis.structure import THESIS_SYMBOLS
from marine_fdi_env.diagnosis.sure_cells import merge_faults, select_faults
from marine_fdi_env.engine.fault_registry import (
    FAULT_TYPES,
    TERMS,
    FaultType,
    MissingFaultTable,
    check_table_faults,
    fault_type,
    suite_fault_ids,
)
from marine_fdi_env.engine.faults import FAULT_IDS, PROCESS_FAULT_DEFAULTS, PROCESS_FAULT_IDS, FaultSpec, fault_class
from marine_fdi_env.engine.model import HEALTHY_PF, PF_FIELDS, ProcessFaultValues
from marine_fdi_env.engine.sensors import SENSOR_IDS
from marine_fdi_env.engine.simulator import TRUTH_VARIABLES, Simulator
from tests.paths import ROOT

PACKAGE_DATA = ROOT / "src" / "marine_fdi_env" / "data"
TOY = "exhaust_valve_leak"


def toy_fault_source() -> str:
    """The toy fault's file, as docs/extending.md writes it (the recipe's code block)."""
    text = (ROOT / "docs" / "extending.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```python\n(.*?)```", text, flags=re.S)
    (src,) = [b for b in blocks if b.startswith("# toy_fault.py\n")]
    return src


# --------------------------------------------------------------------------------------- the shipped faults
def test_the_shipped_faults_derive_what_was_typed_by_hand():
    assert FAULT_IDS == SENSOR_IDS + PROCESS_FAULT_IDS and len(FAULT_IDS) == 26
    assert PROCESS_FAULT_IDS == (
        "valve_seizing",
        "bore_damage",
        "turbine_seal_leak",
        "turbine_lubrication_loss",
        "compressor_seal_leak",
        "compressor_lubrication_loss",
        "intercooler_blockage",
    )
    # table 6.4: (symbol, onset, kappa, magnitude, unit, subsystem)
    assert {f: tuple(vars(d).values()) for f, d in PROCESS_FAULT_DEFAULTS.items()} == {
        "valve_seizing": ("f_u", 20.0, 1e-2, 0.25, "-", 1),
        "bore_damage": ("f_z,V1", 15.0, 1e-5, 3e-3, "m3/s", 2),
        "turbine_seal_leak": ("f_x,tur", 15.0, 2e-5, 3.5e-4, "1/s", 3),
        "turbine_lubrication_loss": ("f_z,Tsl", 30.0, 1e3, 1.25, "K/s", 3),
        "compressor_seal_leak": ("f_x,int", 30.0, 1e-4, 5e-2, "1/s", 4),
        "compressor_lubrication_loss": ("f_z,Tinl", 30.0, 1e3, 2.5, "K/s", 4),
        "intercooler_blockage": ("f_z,Tc", 30.0, 1e-3, 2.0, "K/s", 4),
    }
    assert EQUATION_FAULTS == {
        "fuel": ("valve_seizing",),
        "cycle": ("bore_damage",),
        "torque": ("bore_damage",),
        "speed": ("bore_damage",),
        "receiver": ("turbine_seal_leak",),
        "mixing": ("turbine_lubrication_loss",),
        "turbine": (),
        "charge": ("compressor_seal_leak",),
        "inlet": ("compressor_lubrication_loss",),
        "comp_out": ("intercooler_blockage",),
    }
    assert [THESIS_SYMBOLS[f] for f in PROCESS_FAULT_IDS] == [
        "f_u^(1)",
        "f_z,V1^(2)",
        "f_x,tur^(3)",
        "f_z,Tsl^(3)",
        "f_x,int^(4)",
        "f_z,Tinl^(4)",
        "f_z,Tc^(4)",
    ]
    assert THESIS_SYMBOLS["S4.2"] == "f_2^(4)"
    # the kernels' term array: the seven fields of before, then the receiver leak that no shipped fault uses
    assert PF_FIELDS == ("f_u", "dV1_m3", "phi_tur", "dT_sl_K", "phi_int", "dT_inl_K", "dT_c_K", "phi_rec")
    assert HEALTHY_PF.tolist() == [1.0, 0, 0, 0, 0, 0, 0, 0]
    assert ProcessFaultValues().as_array(2).tolist() == [HEALTHY_PF.tolist()] * 2
    assert [f.term for f in FAULT_TYPES if f.kind == "process"] == list(PF_FIELDS[:7])
    assert fault_class("S1.1") == "sensor" and fault_class("bore_damage") == "process"
    assert suite_fault_ids(1) == FAULT_IDS and suite_fault_ids(1, "process") == PROCESS_FAULT_IDS


def test_a_fault_record_is_checked_where_it_is_declared():
    good = dict(
        kind="process", subsystem=3, term="phi_rec", law="ramp", symbol="f", unit="1/s", onset_s=1.0, magnitude=1e-3
    )
    FaultType("x", **good)
    for change, match in (
        ({"term": "nope"}, "term must be one of"),
        ({"law": "fraction"}, "needs a term that combines by multiply"),
        ({"magnitude": 1.0, "magnitude_range": (0.0, 0.5)}, "outside magnitude_range"),
        ({"kappa": -1.0}, "kappa"),
        ({"onset_s": None}, "onset_s"),
        ({"subsystem": 5}, "subsystem"),
    ):
        with pytest.raises(ValueError, match=match):
            FaultType("x", **{**good, **change})
    with pytest.raises(ValueError, match="fault id"):
        FaultType("a@b", **good)
    with pytest.raises(ValueError, match=r"must lie in \[0, inf\]"):  # the ranges hold for every spec of the fault
        FaultSpec("valve_seizing", 1.0, magnitude=-0.5)
    assert [t.healthy for t in TERMS] == HEALTHY_PF.tolist()
    with pytest.raises(MissingFaultTable, match="'a', 'b' have no entry in the measured table t.json"):
        check_table_faults("t.json", ["c"], ["a", "b", "c"])
    assert "S3.1" in fault_type("S3.1").description or fault_type("S3.1").kind == "sensor"


def test_cell_files_select_and_merge_per_fault_columns():
    for name, select, merge in (
        ("sure_cells.json", select_faults, merge_faults),
        ("sized_cells.json", select_sized_faults, merge_sized_faults),
        ("sequential_sized_cells.json", select_sized_faults, merge_sized_faults),
    ):
        data = json.loads((PACKAGE_DATA / "diagnosis" / name).read_text())
        assert select(data, FAULT_IDS) is data  # the shipped file as it is
        some = ["bore_damage", "S3.4", "S1.1"]
        part = select(data, some)
        assert part["fault_ids"] == some
        rest = select(data, [f for f in FAULT_IDS if f not in some])
        merged = merge(rest, part, FAULT_IDS)
        for key in ("sure", "lag_s", "n_levels", "magnitudes", "spread_s", "peak", "never_fired", "runs"):
            if key in data:
                assert merged[key] == data[key], (name, key)


# --------------------------------------------------------------------------------------- the toy fault
_TOY_RUN = """
import json, sys
import numpy as np
from marine_fdi_env import coldstart
coldstart.enable(stream=sys.stderr)
from marine_fdi_env.engine.faults import FAULT_IDS
from marine_fdi_env.engine.simulator import Simulator, TRUTH_VARIABLES
from marine_fdi_env.diagnosis.structure import fault_modules
from marine_fdi_env.envs.hypotheses import HYPOTHESES
out = {"fault_ids": FAULT_IDS, "modules": fault_modules("exhaust_valve_leak"), "hypotheses": len(HYPOTHESES)}
sim = Simulator("thesis-12v28", n_engines=2, seeds=[4, 4], faults=[["exhaust_valve_leak@5:5e-3"], []])
r = sim.run(30.0)
np.savez(sys.argv[1], measurements=r.measurements, truth=r.truth, value=r.fault_value, active=r.fault_active)
out["compiled"] = coldstart.announced()
refused = {}
def refuse(name, fn):
    try:
        fn()
    except Exception as e:
        refused[name] = type(e).__name__ + ": " + str(e)
from marine_fdi_env.diagnosis.agent import ReferenceDiagnoser
refuse("reference", lambda: ReferenceDiagnoser("thesis-12v28", n_engines=1, dt=0.01))
refuse("grid cells", lambda: ReferenceDiagnoser("thesis-12v28", n_engines=1, dt=0.01, cells="grid"))
import gymnasium as gym
import marine_fdi_env
refuse("env", lambda: gym.make("MarineFDI-v1").reset(seed=1))
from marine_fdi_env.benchmark.suites import single_fault_suite
refuse("suite", lambda: single_fault_suite("toy-v1", ["exhaust_valve_leak"]))
out["refused"] = refused
print(json.dumps(out))
"""


def _run_toy(tmp_path, script: str, *args, tables=None, timeout=600) -> dict:
    (tmp_path / "toy_fault.py").write_text(toy_fault_source())
    env = dict(os.environ, MARINE_FDI_FAULTS=str(tmp_path / "toy_fault.py"))
    env.pop("MARINE_FDI_TABLES", None)
    if tables is not None:
        env["MARINE_FDI_TABLES"] = str(tables)
    (tmp_path / "script.py").write_text(script)
    out = subprocess.run(
        [sys.executable, str(tmp_path / "script.py"), *map(str, args)],
        capture_output=True,
        text=True,
        cwd=ROOT,
        env=env,
        timeout=timeout,
    )
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_a_toy_fault_with_a_new_term_joins_the_registry_and_is_refused_without_its_tables(tmp_path):
    # the same engines without the plugin, in this process (this also fills the compiled functions' cache)
    base = Simulator("thesis-12v28", n_engines=2, seeds=[4, 4], faults=[[], []]).run(30.0)
    res = _run_toy(tmp_path, _TOY_RUN, tmp_path / "toy.npz")
    assert res["fault_ids"] == list(FAULT_IDS) + [TOY] and res["hypotheses"] == len(FAULT_IDS) + 3
    # its term enters the receiver, mixing, charge-air and compressor-outlet equations
    assert res["modules"] == ["M3.1", "M3.2", "M3.3", "M3.4", "M4.1", "M4.2", "M4.5", "M4.6"]
    assert not res["compiled"], "a fault of a plugin changes no compiled function: the cache must serve"
    run = np.load(tmp_path / "toy.npz")
    # the healthy engine is the same bit for bit with the plugin registered; the faulty one loses receiver
    # and charge-air pressure (less gas drives the turbine)
    assert np.array_equal(run["measurements"][:, 1], base.measurements[:, 1])
    assert np.array_equal(run["truth"][:, 1], base.truth[:, 1])
    assert run["value"].shape[2] == len(FAULT_IDS) + 1 and run["active"][-1, 0, -1] and not run["active"][0, 0, -1]
    leak = run["value"][-1, 0, -1]
    beta = -math.expm1(-1e-2 * 25.0)
    assert leak == pytest.approx(beta * 5e-3 * 25.0, rel=1e-12)  # the ramp law β R s
    x3, x4 = TRUTH_VARIABLES.index("x3"), TRUTH_VARIABLES.index("x4")
    assert run["truth"][-1, 0, x3] < base.truth[-1, 0, x3] - 5e3 and run["truth"][-1, 0, x4] < base.truth[-1, 0, x4]
    assert np.array_equal(run["measurements"][:499, 0], base.measurements[:499, 0])  # before the onset (5 s)
    # without its measured tables it is refused by name, naming the table and the command that makes it
    for name, tables in (
        ("reference", ["diagnosis/sized_cells.json"]),
        ("grid cells", ["diagnosis/sure_cells.json"]),
        ("env", ["env/detectability.json", "diagnosis/sized_cells.json"]),  # its reference diagnoser first
        ("suite", ["env/detectability.json"]),
    ):
        msg = res["refused"][name]
        assert msg.startswith("MissingFaultTable") and f"'{TOY}'" in msg and any(t in msg for t in tables), msg
        assert f"python -m studies.fault_tables --faults {TOY}" in msg


_TOY_PIPELINE = """
import json, sys
import gymnasium as gym
import marine_fdi_env
from marine_fdi_env.benchmark.evaluate import evaluate
from marine_fdi_env.diagnosis.agent import ReferenceDiagnoser
from marine_fdi_env.engine.simulator import Simulator
out = {}
sim = Simulator("thesis-12v28", n_engines=1, seeds=3, faults=["exhaust_valve_leak@5:1e-2"])
r = sim.run(60.0)
d = ReferenceDiagnoser("thesis-12v28", n_engines=1, dt=sim.dt)
d.observe(r.measurements.transpose(1, 0, 2), r.truth_of("u").T)
out["report"] = d.report(0)
cfg = {"name": "toy", "fault_ids": ["exhaust_valve_leak"], "fault_count_weights": [0, 1, 0], "duration_s": 20.0,
       "onset_range_s": [2.0, 10.0]}
env = gym.make("MarineFDI-v1", scenario_config=cfg)
obs, info = env.reset(seed=0)
out["true_faults"] = [f["id"] for f in info["true_faults"]]
steps, done = 0, False
while not done:
    obs, reward, term, trunc, info = env.step(env.action_space.sample())
    steps, done = steps + 1, term or trunc
out["steps"] = steps
res = evaluate("reference", sys.argv[1], sys.argv[2], progress=False)
out["episodes"] = [[e["scenario_id"], e["declared_changes"]] for e in res["episodes"]]
print(json.dumps(out))
"""


def stand_in_tables(folder, fault=TOY, like="turbine_seal_leak"):
    """Tables in which the toy fault has another fault's entries (what the plumbing needs, not a measurement)."""
    det = json.loads((PACKAGE_DATA / "env" / "detectability.json").read_text())
    det["faults"][fault] = dict(det["faults"][like], limit=1e-3, table_magnitude=1e-3, unit="1/s")
    (folder / "env").mkdir(parents=True)
    (folder / "env" / "detectability.json").write_text(json.dumps(det))
    (folder / "diagnosis").mkdir()
    for name, select, merge in (
        ("sure_cells.json", select_faults, merge_faults),
        ("sized_cells.json", select_sized_faults, merge_sized_faults),
    ):
        data = json.loads((PACKAGE_DATA / "diagnosis" / name).read_text())
        new = dict(select(data, [like]), fault_ids=[fault])
        (folder / "diagnosis" / name).write_text(json.dumps(merge(data, new, list(FAULT_IDS) + [fault])))
    return folder


def test_the_toy_fault_is_simulated_diagnosed_drawn_and_scored_with_its_tables(tmp_path):
    tables = stand_in_tables(tmp_path / "tables")
    suite = {
        "name": "toy-v1",
        "version": 1,
        "description": "the toy fault",
        "env": {"decision_period_s": 1.0, "params": "thesis-12v28", "observe_sensors": False},
        "scenarios": [
            {"scenario_id": f"leak{k}", "faults": [f"{TOY}@5:1e-2"], "profile": "constant", "noise_seed": k,
             "duration_s": 40.0}
            for k in (1, 2)
        ],
    }  # fmt: skip
    (tmp_path / "toy-v1.json").write_text(json.dumps(suite))
    res = _run_toy(tmp_path, _TOY_PIPELINE, tmp_path / "toy-v1.json", tmp_path / "res.json", tables=tables)
    assert res["report"]["detected"] and [TOY] in res["report"]["final_minimal_diagnoses"]
    assert res["true_faults"] == [TOY] and res["steps"] == 20
    assert [e[0] for e in res["episodes"]] == ["leak1", "leak2"]
    assert any(TOY in c[1] for e in res["episodes"] for c in e[1]), res["episodes"]


def test_the_compiled_functions_cache_key_follows_the_sources_of_their_layers(tmp_path, monkeypatch):
    """A kernel of the engine reads the registry's term indices from another file: the cache key of every
    compiled function holds a hash of the sources of its layer and those before it (``_jit.source_key``)."""
    import shutil

    from marine_fdi_env import _jit

    pkg = ROOT / "src" / "marine_fdi_env"
    for folder in ("engine", "diagnosis", "envs"):
        shutil.copytree(pkg / folder, tmp_path / folder, ignore=shutil.ignore_patterns("__pycache__"))
    monkeypatch.setattr(_jit, "_ROOT", tmp_path)
    key = _jit.source_key.__wrapped__
    engine, diagnosis, envs = (key(f"marine_fdi_env.{m}.x") for m in ("engine", "diagnosis", "envs"))
    assert len({engine, diagnosis, envs}) == 3 and key("marine_fdi_env.engine.subsystems.gas_path") == engine
    assert key("marine_fdi_env.benchmark.x") == envs  # outside the three: every source
    registry = tmp_path / "engine" / "fault_registry.py"
    registry.write_text(registry.read_text() + "\n# a change\n")
    assert key("marine_fdi_env.engine.model") != engine and key("marine_fdi_env.diagnosis.x") != diagnosis
    engine2 = key("marine_fdi_env.engine.model")
    (tmp_path / "diagnosis" / "agent.py").write_text("# another\n")
    assert key("marine_fdi_env.engine.model") == engine2  # a later layer does not recompile the engine
    assert key("marine_fdi_env.diagnosis.x") != diagnosis


@pytest.mark.parametrize("submodels", ["base", "inert", "all_on"])
def test_the_receiver_leak_term_takes_gas_from_the_turbine(submodels):
    """phi_rec: the turbine passes (1 - phi_rec) of the cylinders' gas, in the base model and in the extended gas
    path (inert submodels: the base model's numbers), and 0 is the model without the term."""
    from marine_fdi_env.engine.model import EngineModel
    from marine_fdi_env.engine.params import load_params
    from marine_fdi_env.engine.steady_state import steady_state
    from tests.unit.test_submodels import ALL_ON, INERT

    p = load_params("thesis-12v28")
    if submodels != "base":
        p = p.replace(submodels={"inert": INERT, "all_on": ALL_ON}[submodels])
    m = EngineModel(p)
    ss = steady_state(m, np.array([0.7, 0.9]))
    healthy = m.algebraic(ss.x1, ss.x3, ss.x4)
    zero = m.algebraic(ss.x1, ss.x3, ss.x4, ProcessFaultValues(phi_rec=0.0))
    leak = m.algebraic(ss.x1, ss.x3, ss.x4, ProcessFaultValues(phi_rec=0.1))
    assert all(np.array_equal(getattr(zero, f), getattr(healthy, f)) for f in vars(healthy))
    assert np.all(leak.h3 < healthy.h3) and np.all(leak.h4 < healthy.h4) and np.all(leak.T_co < healthy.T_co)
    if submodels == "base":
        np.testing.assert_allclose(leak.mdot_g, 0.9 * healthy.mdot_g, rtol=1e-14)
    assert np.array_equal(leak.n, healthy.n) and np.array_equal(leak.p6, healthy.p6)  # Σ2 sees no leak
