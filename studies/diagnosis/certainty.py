"""Which cells of the fault signature matrix *surely* fire, measured over fault sizes: the thesis's
'1' versus '*', made robust to the size of the fault.

The structure (:mod:`marine_fdi_env.diagnosis.structure`) tells which faults *can* violate each
ARR.  Exoneration ("a module that has not fired clears the faults it would surely have seen") also
needs the cells that fire for sure.  The thesis marks them '1' in tables 6.5-6.8 from simulations
at its table 6.3/6.4 magnitudes, and the first version of this module measured them the same
way.  At the suites' sizes (0.5-4x the detectability limit) that misleads: a cell that fires in
every run at the table size stays silent for a smaller fault, the true fault is exonerated, and a
wrong one is declared (single-v1: every detected S3.4 episode declared S3.2).  Sureness is a
property of (module, fault, size); the diagnoser does not know the size, so a cell counts as sure
only if it fires for every size it may meet:

    python -m studies.diagnosis.certainty measure                        # the grid, both diagnosers
    python -m studies.diagnosis.certainty derive --diagnoser reference   # -> data/diagnosis/sure_cells.json
    python -m studies.diagnosis.certainty derive --diagnoser sequential  # -> .../sequential_sure_cells.json
    python -m studies.diagnosis.certainty validate                       # the held-out runs
    python -m studies.diagnosis.certainty report --diagnoser reference   # -> docs/data/certainty_reference.json

**Measurement grid** (``measure``): every fault at 5 magnitudes log-spaced from 0.5x its
detectability limit (``data/env/detectability.json``, the smallest magnitude the reference
detects at nominal load in every seed; the suites go down to 0.5x) to its table 6.3/6.4 size,
sensor offsets of both signs, profiles ``constant`` (fuel setting drawn in [0.6, 1.0]) and
``manoeuvring``, ``--seeds`` (6) noise seeds each (seeds 1e6 + ...); 300 s runs, sensor onsets at
30 s, process faults at their table onsets; the reference's and the sequential diagnoser's module
firing times from the same runs.

**Rule** (``derive``): among the runs where the fault was detected (some module of its support
fired at or after the onset; a run where nothing fired cannot be misdiagnosed), cell (m, f) is sure
when m fired in every one of them, at every magnitude, sign and profile.  ``lag_s`` = the largest
delay of a sure module after the fault's first fired module (any module of its support; the
grace periods); ``spread_s`` = the largest of these lags per fault (the settle time of the
time-order check: at small sizes a module that is not sure often fires before the sure ones).  (The first version required firing in all runs at the
table size and, for sensor faults, within 30 s of the first sure module.)

**Validation** (``validate``, ``report``): held-out magnitudes (the geometric midpoints of the
grid), seeds (2e6 + ..., 3 per cell) and profiles (``step`` and ``ramp`` at fuel settings 0.6-1.0,
``random``); the
decision logic is replayed on the measured module firing times with the old and the new sure
cells (the module decisions do not depend on the decision logic), and the runs where the true
fault is ruled out (in no minimal diagnosis) while the diagnoser declares another are counted per
fault.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from importlib import resources
from pathlib import Path

import numpy as np

from marine_fdi_env.engine.faults import FAULT_IDS, PROCESS_FAULT_DEFAULTS, FaultSpec
from marine_fdi_env.engine.simulator import Simulator
from marine_fdi_env.diagnosis.batch import BATCH, DIAGNOSERS, PARAMS
from marine_fdi_env.diagnosis.sequential import SequentialDiagnoser
from marine_fdi_env.diagnosis.decision import DiagnosisState, declared_faults
from marine_fdi_env.diagnosis.modules import MODULE_IDS
from marine_fdi_env.diagnosis.structure import fault_signature_matrix
from marine_fdi_env.diagnosis.sure_cells import (SURE_CELLS_FILE, SureCells, grace_times, load_sure_cells, settle_times,  # noqa: F401
                         sure_cells)
from studies.paths import PACKAGE_DATA

__all__ = ["grid_magnitudes", "measure", "derive_sure_cells", "replay_declarations", "validate",
           "sure_cells", "settle_times", "grace_times", "SENSOR_ONSET_S", "N_GRID", "SURE_FILES"]

SENSOR_ONSET_S = 30.0
DURATION_S = 300.0
N_GRID = 5
LOWEST_SCALE = 0.5  # x detectability limit
GRID_PROFILES = ("constant", "manoeuvring")
HELD_OUT_PROFILES = ("step", "ramp", "random")
SURE_FILES = {"reference": SURE_CELLS_FILE, "sequential": "sequential_sure_cells.json"}
GRID_SEED0 = 1_000_000
HELD_OUT_SEED0 = 2_000_000
_SUPPORT = fault_signature_matrix()[0]


def _onset(fault_id: str) -> float:
    return PROCESS_FAULT_DEFAULTS[fault_id].onset_s if fault_id in PROCESS_FAULT_DEFAULTS else SENSOR_ONSET_S


def _limits() -> dict:
    path = resources.files("marine_fdi_env") / "data" / "env" / "detectability.json"
    faults = json.loads(path.read_text())["faults"]
    return {f: (float(v["limit"]), float(v["table_magnitude"])) for f, v in faults.items()}


def grid_magnitudes(fault_id: str, held_out: bool = False) -> list[float]:
    """The grid's magnitudes of a fault (positive; see module docstring), or with ``held_out`` the
    geometric midpoints between them."""
    limit, table = _limits()[fault_id]
    lo = LOWEST_SCALE * limit
    hi = max(table, lo)
    x = np.exp(np.linspace(math.log(lo), math.log(hi), N_GRID))
    if held_out:
        x = np.sqrt(x[:-1] * x[1:])
    return [float(v) for v in x]


def _profile(name: str, rng: np.random.Generator) -> str:
    u0, u1 = (round(float(v), 4) for v in rng.uniform(0.6, 1.0, size=2))
    if name == "constant":
        return f"constant:u0={u0}"
    if name == "step":
        return f"step:u0={u0},u1={u1},t={round(float(rng.uniform(40.0, 260.0)), 2)}"
    if name == "ramp":
        a, b = sorted(float(v) for v in rng.uniform(15.0, 285.0, size=2))
        return f"ramp:u0={u0},u1={u1},t0={round(a, 2)},t1={round(max(b, a + 10.0), 2)}"
    if name == "random":
        return f"random:seed={int(rng.integers(0, 2**31))},u_min=0.6,u_max=1.0"
    return name


def _runs(held_out: bool, n_seeds: int) -> list[dict]:
    profiles = HELD_OUT_PROFILES if held_out else GRID_PROFILES
    seed0 = HELD_OUT_SEED0 if held_out else GRID_SEED0
    rng = np.random.default_rng(seed0)
    runs = []
    for f in FAULT_IDS:
        signs = (1.0,) if f in PROCESS_FAULT_DEFAULTS else (1.0, -1.0)
        for j, mag in enumerate(grid_magnitudes(f, held_out)):
            for sign in signs:
                for prof in profiles:
                    for s in range(n_seeds):
                        runs.append({"fault": f, "magnitude": sign * mag, "grid_index": j, "profile": _profile(prof, rng),
                                     "family": prof, "seed": seed0 + len(runs)})
    return runs


def measure(n_seeds: int = 8, held_out: bool = False, progress: bool = True) -> dict:
    """Module firing times of every run of the grid (or the held-out grid) for both diagnosers at
    once (the sequential diagnoser runs the reference's residual generators and worst-case tests):
    {"reference": (runs, 19), "sequential": (runs, 19)} seconds after the fault's onset (NaN:
    never), with each run's fault, magnitude, profile and seed."""
    runs = _runs(held_out, n_seeds)
    schedules = [[FaultSpec(r["fault"], _onset(r["fault"]), magnitude=r["magnitude"],
                            kind=None if r["fault"] in PROCESS_FAULT_DEFAULTS else "offset")] for r in runs]
    seeds = [r["seed"] for r in runs]
    profiles = [r["profile"] for r in runs]
    ref_t = np.full((len(runs), len(MODULE_IDS)), np.nan)
    seq_t = np.full((len(runs), len(MODULE_IDS)), np.nan)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(runs), desc="held-out" if held_out else "grid", unit="run", file=sys.stderr)
    for a in range(0, len(runs), BATCH):
        b = min(len(runs), a + BATCH)
        sim = Simulator(PARAMS, b - a, seeds=seeds[a:b], faults=schedules[a:b], profiles=profiles[a:b])
        agent = SequentialDiagnoser(PARAMS, n_engines=b - a, dt=sim.dt, exoneration="none")
        agent.observe(sim.y[:, None, :], sim.u[:, None])
        for _ in range(int(round(DURATION_S / sim.dt / 1000))):
            blk = sim.advance(1000)
            agent.observe(blk.measurements, blk.u)
        ref_t[a:b] = agent.ref.first_violation
        seq_t[a:b] = agent.stage.first
        if bar is not None:
            bar.update(b - a)
    if bar is not None:
        bar.close()
    on = np.array([_onset(r["fault"]) for r in runs])[:, None]
    return {"held_out": held_out, "n_seeds": n_seeds, "runs": runs, "duration_s": DURATION_S,
            "sensor_onset_s": SENSOR_ONSET_S,
            "times_after_onset_s": {"reference": (ref_t - on).tolist(), "sequential": (seq_t - on).tolist()}}


def derive_sure_cells(grid: dict, diagnoser: str) -> dict:
    """The sure-cell file content of a diagnoser from a measured grid (rule in the module docstring)."""
    runs = grid["runs"]
    times = np.asarray(grid["times_after_onset_s"][diagnoser], dtype=float)
    fired = ~np.isnan(times) & (times >= 0.0)
    sure = np.zeros((len(MODULE_IDS), len(FAULT_IDS)), dtype=bool)
    lag = np.zeros(sure.shape)
    spread = np.zeros(len(FAULT_IDS))
    detected_runs = np.zeros(len(FAULT_IDS), dtype=int)
    total_runs = np.zeros(len(FAULT_IDS), dtype=int)
    fault_of = np.array([FAULT_IDS.index(r["fault"]) for r in runs])
    for j, f in enumerate(FAULT_IDS):
        sel = fault_of == j
        total_runs[j] = sel.sum()
        sup = _SUPPORT[:, j]
        det = sel & (fired[:, sup].any(axis=1))
        detected_runs[j] = det.sum()
        if not det.any():
            continue
        sure[:, j] = sup & fired[det].all(axis=0)
        t = np.where(fired[det][:, sup], times[det][:, sup], np.inf)
        first = t.min(axis=1)
        idx = np.flatnonzero(sure[:, j])
        if len(idx):
            ts = times[det][:, idx]
            lag[idx, j] = (ts - first[:, None]).max(axis=0)
            # the time-order check allows a fault to explain a module only if its sure modules fired
            # by then plus the settle time: at the grid's small sizes another module of the fault
            # often fires first, so the settle time must cover the sure modules' lag behind the
            # fault's first fired module, not only their spread among themselves (the first format)
            spread[j] = float(lag[idx, j].max())
    return {
        "format": 2, "module_ids": list(MODULE_IDS), "fault_ids": list(FAULT_IDS),
        "sure": sure.astype(int).tolist(), "lag_s": lag.round(3).tolist(), "spread_s": spread.round(3).tolist(),
        "detected_runs": detected_runs.tolist(), "runs": total_runs.tolist(),
        "settings": {"diagnoser": diagnoser, "grid": f"{N_GRID} magnitudes log-spaced from {LOWEST_SCALE}x the "
                     "detectability limit (data/env/detectability.json) to the table 6.3/6.4 size; sensor offsets "
                     "of both signs", "profiles": list(GRID_PROFILES), "seeds_per_cell": grid["n_seeds"],
                     "first_seed": GRID_SEED0, "duration_s": grid["duration_s"],
                     "sensor_onset_s": grid["sensor_onset_s"],
                     "rule": "sure = fired in every run where the fault was detected (any module of its support "
                             "fired at or after the onset), at every magnitude, sign and profile of the grid"},
        "command": f"python -m studies.diagnosis.certainty derive --diagnoser {diagnoser}",
    }


def replay_declarations(times, fault: str, sc: SureCells, duration_s: float = DURATION_S,
                        onset_s: float = 0.0) -> dict:
    """Replay the decision logic on one run's module firing times (19,) [s from the run's start,
    NaN: never]: the events where the fired set changes and the grace expiries, as the streaming
    diagnoser meets them.  Returns whether the true ``fault`` was ever ruled out while another was
    declared (``wrong``), at which time, the final declaration, and since when the diagnoser has
    declared exactly {fault} if it does at the end (``isolated_from_s``)."""
    st = DiagnosisState(exoneration=sc.sure, max_cardinality=2, temporal=True, settle_s=sc.settle_times(),
                        grace_s=sc.grace_times())
    t = np.asarray(times, dtype=float)
    order = sorted(set(float(x) for x in t[~np.isnan(t)]))
    out = {"wrong": False, "wrong_at_s": None, "declared_end": [], "ruled_out_end": False, "detected": bool(order),
           "isolated_from_s": None}
    history = []

    def look(now):
        cand = set().union(*st.diagnoses) if st.detected else set()
        decl = declared_faults(st.diagnoses) if st.detected else []
        if st.detected and fault not in cand and decl and not out["wrong"]:
            out["wrong"], out["wrong_at_s"] = True, now
        history.append((now, decl))

    for ev in order:
        # grace periods that end before this event
        while st.temporal and st.fired.any() and st._next_expiry < ev:
            te = st._next_expiry + 1e-9
            st.advance(te)
            look(te)
        st.update(~np.isnan(t) & (t <= ev), ev)
        look(ev)
    while st.fired.any() and st._next_expiry < duration_s:
        te = st._next_expiry + 1e-9
        st.advance(te)
        look(te)
    st.advance(duration_s)
    look(duration_s)
    cand = set().union(*st.diagnoses) if st.detected else set()
    out["declared_end"] = declared_faults(st.diagnoses) if st.detected else []
    out["ruled_out_end"] = bool(st.detected and fault not in cand)
    if out["declared_end"] == [fault]:
        since = duration_s
        for now, decl in reversed(history):
            if decl != [fault]:
                break
            since = now
        out["isolated_from_s"] = since
    return out


def _old_sure_cells() -> SureCells:
    """The sure cells shipped before the grid measurement (table magnitudes only), kept for the
    before/after comparison: ``data/diagnosis/sure_cells_table_magnitudes.json``."""
    return load_sure_cells("sure_cells_table_magnitudes.json")


def validate(held: dict, diagnoser: str, new: SureCells, old: SureCells | None = None) -> dict:
    """Wrong isolations (true fault ruled out, another declared) per fault on a measured run set,
    with the new and (if given) the old sure cells."""
    runs = held["runs"]
    times = np.asarray(held["times_after_onset_s"][diagnoser], dtype=float)
    res = {}
    for name, sc in (("new", new), ("old", old)):
        if sc is None:
            continue
        per = {f: {"runs": 0, "detected": 0, "wrong": 0, "wrong_examples": []} for f in FAULT_IDS}
        for r, tt in zip(runs, times):
            f = r["fault"]
            on = _onset(f)
            rep = replay_declarations(tt + on, f, sc, held["duration_s"], on)
            p = per[f]
            p["runs"] += 1
            p["detected"] += int(rep["detected"])
            if rep["wrong"]:
                p["wrong"] += 1
                if len(p["wrong_examples"]) < 3:
                    p["wrong_examples"].append({"magnitude": r["magnitude"], "profile": r["profile"], "seed": r["seed"],
                                                "at_s": rep["wrong_at_s"], "declared_end": rep["declared_end"]})
        res[name] = per
    return res


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="Measure, derive and validate the sure cells of the diagnosers.")
    ap.add_argument("what", choices=("measure", "derive", "validate", "report"))
    ap.add_argument("--diagnoser", choices=DIAGNOSERS, default="reference", help="derive / report: which one")
    ap.add_argument("--seeds", type=int, default=None, help="seeds per grid cell (measure 6, validate 3)")
    ap.add_argument("--work-dir", type=Path, default=Path("results/certainty"))
    args = ap.parse_args(argv)
    grid_file = args.work_dir / "grid.json"
    held_file = args.work_dir / "held_out.json"
    data_dir = PACKAGE_DATA / "diagnosis"
    if args.what in ("measure", "validate"):
        n = args.seeds or (6 if args.what == "measure" else 3)
        if n < 1:
            ap.error("--seeds must be >= 1")
        data = measure(n, held_out=args.what == "validate")
        args.work_dir.mkdir(parents=True, exist_ok=True)
        out = grid_file if args.what == "measure" else held_file
        out.write_text(json.dumps(data) + "\n")
        print(f"wrote {out} ({len(data['runs'])} runs)")
        return 0
    if args.what == "derive":
        if not grid_file.exists():
            ap.error(f"{grid_file} not found: run 'measure' first")
        out = data_dir / SURE_FILES[args.diagnoser]
        data = derive_sure_cells(json.loads(grid_file.read_text()), args.diagnoser)
        out.write_text(json.dumps(data) + "\n")
        load_sure_cells.cache_clear()
        print(f"wrote {out}: {int(np.sum(data['sure']))} sure cells")
        return 0
    if not held_file.exists():
        ap.error(f"{held_file} not found: run 'validate' first")
    held = json.loads(held_file.read_text())
    new = load_sure_cells(SURE_FILES[args.diagnoser])
    old = _old_sure_cells() if args.diagnoser == "reference" else None
    res = {"diagnoser": args.diagnoser, "runs": len(held["runs"]),
           "held_out": {"magnitudes": "geometric midpoints of the grid", "profiles": list(HELD_OUT_PROFILES),
                        "first_seed": HELD_OUT_SEED0, "seeds_per_cell": held["n_seeds"]},
           "command": f"python -m studies.diagnosis.certainty validate --seeds {held['n_seeds']} && "
                      f"python -m studies.diagnosis.certainty report --diagnoser {args.diagnoser}",
           "result": validate(held, args.diagnoser, new, old)}
    report = Path("docs/data") / f"certainty_{args.diagnoser}.json"
    report.parent.mkdir(parents=True, exist_ok=True)
    report.write_text(json.dumps(res, indent=1) + "\n")
    for name, per in res["result"].items():
        print(name, "wrong isolations:", sum(p["wrong"] for p in per.values()), "of",
              sum(p["detected"] for p in per.values()), "detected runs;",
              {f: p["wrong"] for f, p in per.items() if p["wrong"]})
    print(f"wrote {report}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
