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
time-order check: at small sizes a module that is not sure often fires before the sure ones).

**Validation** (``validate``, ``report``): held-out magnitudes (the geometric midpoints of the
grid), seeds (2e6 + ..., 3 per cell) and profiles (``step`` and ``ramp`` at fuel settings 0.6-1.0,
``random``); the
decision logic is replayed on the measured module firing times with each cell set's sure
cells (the module decisions do not depend on the decision logic), and the runs where the true
fault is ruled out (in no minimal diagnosis) while the diagnoser declares another are counted per
fault.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import zlib
from pathlib import Path

import numpy as np

from marine_fdi_env.diagnosis.agent import ReferenceDiagnoser
from marine_fdi_env.diagnosis.batch import BATCH, DIAGNOSERS, PARAMS
from marine_fdi_env.diagnosis.cell_sets import cell_files, size_blind_cells
from marine_fdi_env.diagnosis.decision import DiagnosisState, declared_faults
from marine_fdi_env.diagnosis.modules import MODULE_IDS
from marine_fdi_env.diagnosis.peak_ratio import PeakRecorder, peak_at
from marine_fdi_env.diagnosis.sequential import SequentialDiagnoser
from marine_fdi_env.diagnosis.sized_cells import SizedCells, load_sized_cells
from marine_fdi_env.diagnosis.sized_decision import SizedDiagnosisState
from marine_fdi_env.diagnosis.structure import fault_signature_matrix
from marine_fdi_env.diagnosis.sure_cells import (
    SURE_CELLS_FILE,
    SureCells,
    grace_times,
    load_sure_cells,
    settle_times,  # noqa: F401
    sure_cells,
)
from marine_fdi_env.diagnosis.thresholds import DEFAULT_THRESHOLDS, THRESHOLD_READINGS, check_thresholds
from marine_fdi_env.engine.fault_registry import check_table_faults, fault_type, measured_table
from marine_fdi_env.engine.faults import FAULT_IDS, PROCESS_FAULT_DEFAULTS, FaultSpec
from marine_fdi_env.engine.simulator import Simulator
from studies.paths import PACKAGE_DATA

from .sized_derivation import derive_sized_cells

__all__ = [
    "grid_magnitudes",
    "measure",
    "derive_sure_cells",
    "replay_declarations",
    "validate",
    "sure_cells",
    "settle_times",
    "grace_times",
    "SENSOR_ONSET_S",
    "N_GRID",
    "SURE_FILES",
]

SENSOR_ONSET_S = 30.0
DURATION_S = 300.0
N_GRID = 5
LOWEST_SCALE = 0.5  # x detectability limit
THIN_GAP = 4.0  # a gap between adjacent grid sizes wider than this gets two more sizes (sized_magnitudes)
GRID_PROFILES = ("constant", "manoeuvring")
HELD_OUT_PROFILES = ("step", "ramp", "random")
SURE_FILES = {"reference": SURE_CELLS_FILE, "sequential": "sequential_sure_cells.json"}
GRID_SEED0 = 1_000_000
HELD_OUT_SEED0 = 2_000_000
_SUPPORT = fault_signature_matrix()[0]


def _onset(fault_id: str) -> float:
    return PROCESS_FAULT_DEFAULTS[fault_id].onset_s if fault_id in PROCESS_FAULT_DEFAULTS else SENSOR_ONSET_S


def _limits() -> dict:
    """(limit, table magnitude) per fault of the detectability table (the package's, or that of the folder
    ``MARINE_FDI_TABLES``)."""
    faults = json.loads(measured_table("env/detectability.json").read_text())["faults"]
    return {f: (float(v["limit"]), float(v["table_magnitude"])) for f, v in faults.items()}


def grid_magnitudes(fault_id: str, held_out: bool = False, sizes: int = N_GRID) -> list[float]:
    """The grid's ``sizes`` magnitudes of a fault (positive; see module docstring), or with ``held_out`` the
    geometric midpoints between them."""
    limits = _limits()
    check_table_faults("env/detectability.json", limits, [fault_id])
    limit, table = limits[fault_id]
    lo = LOWEST_SCALE * limit
    hi = max(table, lo)
    x = np.exp(np.linspace(math.log(lo), math.log(hi), sizes))
    if held_out:
        x = np.sqrt(x[:-1] * x[1:])
    return [float(v) for v in x]


def sized_magnitudes(fault_id: str, sizes: int = N_GRID) -> list[float]:
    """The magnitudes of the size-aware cells: the grid's (:func:`grid_magnitudes`) and, in every
    gap between adjacent grid sizes wider than a factor ``THIN_GAP``, two more at its log-thirds
    (not at the geometric midpoints, which are the held-out sizes); ascending."""
    g = grid_magnitudes(fault_id, sizes=sizes)
    out = [g[0]]
    for a, b in zip(g[:-1], g[1:]):
        if b / a > THIN_GAP:
            out += [a * (b / a) ** (1.0 / 3.0), a * (b / a) ** (2.0 / 3.0)]
        out.append(b)
    return out


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


def _runs(held_out: bool, n_seeds: int, seed0: int | None = None, fault_ids=None, sizes: int = N_GRID) -> list[dict]:
    """The runs of the grid (or the held-out grid).  The grid's own runs come first, in the order
    and with the seeds and profiles they always had (so the grid cells derive from them unchanged);
    the runs at the sizes that :func:`sized_magnitudes` adds follow (``grid_index`` None).  That is the
    group of the suites' faults (``suite_version`` set in the fault registry); every other fault (a
    plugin's) is a group of its own after them, with its own seeds and profiles, so that it changes no run
    of another fault.  ``fault_ids``: the runs of these faults only (the same runs, seeds and profiles as in
    the whole grid; the suites' group needs the detectability limits of all its faults for that)."""
    profiles = HELD_OUT_PROFILES if held_out else GRID_PROFILES
    if seed0 is None:
        seed0 = HELD_OUT_SEED0 if held_out else GRID_SEED0
    runs: list[dict] = []

    def add(group, f, mags, grid_index, size_index):
        signs = (1.0,) if f in PROCESS_FAULT_DEFAULTS else (1.0, -1.0)
        for j, mag in zip(grid_index, mags):
            for sign in signs:
                for prof in profiles:
                    for s in range(n_seeds):
                        group["runs"].append(
                            {
                                "fault": f,
                                "magnitude": sign * mag,
                                "grid_index": j,
                                "size_index": size_index(mag),
                                "profile": _profile(prof, group["rng"]),
                                "family": prof,
                                "seed": group["seed0"] + len(group["runs"]),
                            }
                        )

    keep = None if fault_ids is None else set(fault_ids)
    shipped = [f for f in FAULT_IDS if fault_type(f).suite_version is not None]
    groups = [(shipped, seed0)] + [
        ([f], seed0 + 1_000_000 * (1 + zlib.crc32(f.encode()) % 997)) for f in FAULT_IDS if f not in shipped
    ]
    for faults, first in groups:
        if keep is not None and not keep.intersection(faults):
            continue
        group = {"runs": [], "rng": np.random.default_rng(first), "seed0": first}
        for f in faults:
            g = grid_magnitudes(f, held_out, sizes)
            sized = sized_magnitudes(f, sizes)
            add(group, f, g, range(len(g)), (lambda m: None) if held_out else sized.index)
        if not held_out:
            for f in faults:
                sized = sized_magnitudes(f, sizes)
                extra = [m for m in sized if m not in grid_magnitudes(f, sizes=sizes)]
                add(group, f, extra, [None] * len(extra), sized.index)
        runs += group["runs"]
    return runs if keep is None else [r for r in runs if r["fault"] in keep]


def measure(
    n_seeds: int = 8,
    held_out: bool = False,
    progress: bool = True,
    seed0: int | None = None,
    thresholds: str = DEFAULT_THRESHOLDS,
    fault_ids=None,
    sizes: int = N_GRID,
) -> dict:
    """Module firing times of every run of the grid (or the held-out grid) for both diagnosers at
    once (the sequential diagnoser runs the reference's residual generators and worst-case tests):
    {"reference": (runs, 19), "sequential": (runs, 19)} seconds after the fault's onset (NaN:
    never), with each run's fault, magnitude, profile and seed.  With another reading of the
    observers' ``thresholds`` than ``local``: the reference at that reading only.  ``fault_ids``: the runs
    of these faults only (:func:`_runs`); ``sizes``: magnitudes per fault (default ``N_GRID``)."""
    local = check_thresholds(thresholds) == DEFAULT_THRESHOLDS
    runs = _runs(held_out, n_seeds, seed0, fault_ids, sizes)
    schedules = [
        [
            FaultSpec(
                r["fault"],
                _onset(r["fault"]),
                magnitude=r["magnitude"],
                kind=None if r["fault"] in PROCESS_FAULT_DEFAULTS else "offset",
            )
        ]
        for r in runs
    ]
    seeds = [r["seed"] for r in runs]
    profiles = [r["profile"] for r in runs]
    ref_t = np.full((len(runs), len(MODULE_IDS)), np.nan)
    seq_t = np.full((len(runs), len(MODULE_IDS)), np.nan)
    peaks: list = []
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(runs), desc="held-out" if held_out else "grid", unit="run", file=sys.stderr)
    for a in range(0, len(runs), BATCH):
        b = min(len(runs), a + BATCH)
        sim = Simulator(PARAMS, b - a, seeds=seeds[a:b], faults=schedules[a:b], profiles=profiles[a:b])
        if local:
            agent = SequentialDiagnoser(PARAMS, n_engines=b - a, dt=sim.dt, exoneration="none")
        else:
            agent = ReferenceDiagnoser(PARAMS, n_engines=b - a, dt=sim.dt, exoneration="none", thresholds=thresholds)
        rec = PeakRecorder(b - a)
        on = np.array([_onset(r["fault"]) for r in runs[a:b]])
        out = agent.observe(sim.y[:, None, :], sim.u[:, None])
        rec.update(out.residuals, out.thresholds, -on, sim.dt)
        for k in range(int(round(DURATION_S / sim.dt / 1000))):
            blk = sim.advance(1000)
            out = agent.observe(blk.measurements, blk.u)
            rec.update(out.residuals, out.thresholds, (1 + 1000 * k) * sim.dt - on, sim.dt)
        ref_t[a:b] = agent.ref.first_violation if local else agent.first_violation
        if local:
            seq_t[a:b] = agent.stage.first
        peaks += rec.events
        if bar is not None:
            bar.update(b - a)
    if bar is not None:
        bar.close()
    on = np.array([_onset(r["fault"]) for r in runs])[:, None]
    times = {"reference": (ref_t - on).tolist()}
    if local:
        times["sequential"] = (seq_t - on).tolist()
    return {
        "thresholds": thresholds,
        "held_out": held_out,
        "n_seeds": n_seeds,
        "sizes": sizes,
        "runs": runs,
        "duration_s": DURATION_S,
        "sensor_onset_s": SENSOR_ONSET_S,
        "times_after_onset_s": times,
        "peak_events": peaks,
    }


def derive_sure_cells(grid: dict, diagnoser: str, fault_ids=FAULT_IDS) -> dict:
    """The sure-cell file content of a diagnoser from a measured grid (rule in the module docstring);
    the runs at the sizes only the sized cells use (``grid_index`` None) are left out.  The columns of
    ``fault_ids`` (default every registered fault)."""
    fault_ids = tuple(fault_ids)
    own = [k for k, r in enumerate(grid["runs"]) if r.get("grid_index", 0) is not None]
    runs = [grid["runs"][k] for k in own]
    times = np.asarray(grid["times_after_onset_s"][diagnoser], dtype=float)[own]
    fired = ~np.isnan(times) & (times >= 0.0)
    sure = np.zeros((len(MODULE_IDS), len(fault_ids)), dtype=bool)
    lag = np.zeros(sure.shape)
    spread = np.zeros(len(fault_ids))
    detected_runs = np.zeros(len(fault_ids), dtype=int)
    total_runs = np.zeros(len(fault_ids), dtype=int)
    fault_of = np.array([fault_ids.index(r["fault"]) if r["fault"] in fault_ids else -1 for r in runs])
    for j, f in enumerate(fault_ids):
        sel = fault_of == j
        total_runs[j] = sel.sum()
        sup = _SUPPORT[:, FAULT_IDS.index(f)]
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
        "format": 2,
        "module_ids": list(MODULE_IDS),
        "fault_ids": list(fault_ids),
        "sure": sure.astype(int).tolist(),
        "lag_s": lag.round(3).tolist(),
        "spread_s": spread.round(3).tolist(),
        "detected_runs": detected_runs.tolist(),
        "runs": total_runs.tolist(),
        "settings": {
            "diagnoser": diagnoser,
            "grid": f"{grid.get('sizes', N_GRID)} magnitudes log-spaced from {LOWEST_SCALE}x the "
            "detectability limit (data/env/detectability.json) to the table 6.3/6.4 size; sensor offsets "
            "of both signs",
            "profiles": list(GRID_PROFILES),
            "seeds_per_cell": grid["n_seeds"],
            "first_seed": GRID_SEED0,
            "duration_s": grid["duration_s"],
            "sensor_onset_s": grid["sensor_onset_s"],
            "rule": "sure = fired in every run where the fault was detected (any module of its support "
            "fired at or after the onset), at every magnitude, sign and profile of the grid",
        },
        "command": f"python -m studies.diagnosis.certainty derive --diagnoser {diagnoser}",
    }


def replay_declarations(
    times,
    fault: str,
    sc: "SureCells | SizedCells",
    duration_s: float = DURATION_S,
    onset_s: float = 0.0,
    peak_events=None,
) -> dict:
    """Replay the decision logic on one run's module firing times (19,) [s from the run's start,
    NaN: never]: the events where the fired set changes and the grace expiries, as the streaming
    diagnoser meets them; with sized cells (:class:`SizedCells`) also the run's recorded running
    peaks (``peak_events``: 19 lists of [time from the run's start, peak]) and the band changes.
    Returns whether the true ``fault`` was ever ruled out while another was declared
    (``wrong``), at which time, the final declaration, and since when the diagnoser has declared
    exactly {fault} if it does at the end (``isolated_from_s``)."""
    t = np.asarray(times, dtype=float)
    order = sorted(set(float(x) for x in t[~np.isnan(t)]))
    if isinstance(sc, SizedCells):
        st = SizedDiagnosisState(sc, max_cardinality=2)
        peak_t = sorted({float(e[0]) for ev in peak_events for e in ev})
        order_all = sorted(set(order) | {x for x in peak_t if order and x >= order[0]})
    else:
        st = DiagnosisState(
            exoneration=sc.sure, max_cardinality=2, temporal=True, settle_s=sc.settle_times(), grace_s=sc.grace_times()
        )
        order_all = order

    def peaks_at(now):
        return None if peak_events is None else np.array([peak_at(ev, now) for ev in peak_events])

    out = {
        "wrong": False,
        "wrong_at_s": None,
        "declared_end": [],
        "ruled_out_end": False,
        "detected": bool(order),
        "isolated_from_s": None,
    }
    history = []

    def look(now):
        cand = set().union(*st.diagnoses) if st.detected else set()
        decl = declared_faults(st.diagnoses) if st.detected else []
        if st.detected and fault not in cand and decl and not out["wrong"]:
            out["wrong"], out["wrong_at_s"] = True, now
        history.append((now, decl))

    for ev in order_all:
        # grace periods that end before this event
        while st.temporal and st.fired.any() and st._next_expiry < ev:
            te = st._next_expiry + 1e-9
            st.advance(te)
            look(te)
        if isinstance(st, SizedDiagnosisState):
            st.update(~np.isnan(t) & (t <= ev), ev, peaks_at(ev))
        else:
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


def validate(held: dict, diagnoser: str, cell_sets: dict) -> dict:
    """Wrong isolations (true fault ruled out, another declared) per fault on a measured run set,
    for each of ``cell_sets`` ({name: :class:`SureCells` or :class:`SizedCells`})."""
    runs = held["runs"]
    times = np.asarray(held["times_after_onset_s"][diagnoser], dtype=float)
    peaks = held.get("peak_events")
    res = {}
    for name, sc in cell_sets.items():
        if isinstance(sc, SizedCells) and peaks is None:
            raise ValueError("the held-out runs have no peak records: measure them again with this version")
        per = {
            f: {"runs": 0, "detected": 0, "wrong": 0, "wrong_end": 0, "isolated_end": 0, "wrong_examples": []}
            for f in FAULT_IDS
        }
        for k, (r, tt) in enumerate(zip(runs, times)):
            f = r["fault"]
            on = _onset(f)
            ev = None if peaks is None else [[[e[0] + on, e[1]] for e in m] for m in peaks[k]]
            rep = replay_declarations(tt + on, f, sc, held["duration_s"], on, ev)
            p = per[f]
            p["runs"] += 1
            p["detected"] += int(rep["detected"])
            p["wrong_end"] += int(rep["ruled_out_end"] and bool(rep["declared_end"]))
            p["isolated_end"] += int(rep["declared_end"] == [f])
            if rep["wrong"]:
                p["wrong"] += 1
                if len(p["wrong_examples"]) < 3:
                    p["wrong_examples"].append(
                        {
                            "magnitude": r["magnitude"],
                            "profile": r["profile"],
                            "seed": r["seed"],
                            "at_s": rep["wrong_at_s"],
                            "declared_end": rep["declared_end"],
                        }
                    )
        res[name] = per
    return res


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="Measure, derive and validate the sure cells of the diagnosers.")
    ap.add_argument("what", choices=("measure", "derive", "validate", "report"))
    ap.add_argument("--diagnoser", choices=DIAGNOSERS, default="reference", help="derive / report: which one")
    ap.add_argument("--seeds", type=int, default=None, help="seeds per grid cell (measure 6, validate 3)")
    ap.add_argument(
        "--work-dir",
        type=Path,
        default=None,
        help="default results/certainty (results/certainty/READING for a reading)",
    )
    ap.add_argument(
        "--thresholds",
        choices=THRESHOLD_READINGS,
        default=DEFAULT_THRESHOLDS,
        help="the reading of the observers' thresholds the reference decides with (its cells go to "
        "data/diagnosis/thresholds/READING/; the sequential diagnoser: local only)",
    )
    ap.add_argument(
        "--first-seed",
        type=int,
        default=HELD_OUT_SEED0,
        help=f"validate / report: first seed of the held-out runs (default {HELD_OUT_SEED0}, the "
        "reported ones; another value makes a development set beside them)",
    )
    args = ap.parse_args(argv)
    local = args.thresholds == DEFAULT_THRESHOLDS
    if not local and args.diagnoser != "reference":
        ap.error("--thresholds: the sequential diagnoser decides with the local thresholds only")
    if args.work_dir is None:
        args.work_dir = Path("results/certainty") if local else Path("results/certainty") / args.thresholds
    files = cell_files(args.diagnoser, args.thresholds)
    grid_file = args.work_dir / "grid.json"
    dev = args.first_seed != HELD_OUT_SEED0
    held_file = args.work_dir / ("held_out.json" if not dev else f"held_out_{args.first_seed}.json")
    data_dir = PACKAGE_DATA / "diagnosis"
    if args.what in ("measure", "validate"):
        n = args.seeds or (6 if args.what == "measure" else 3)
        if n < 1:
            ap.error("--seeds must be >= 1")
        data = measure(
            n,
            held_out=args.what == "validate",
            seed0=args.first_seed if args.what == "validate" else None,
            thresholds=args.thresholds,
        )
        args.work_dir.mkdir(parents=True, exist_ok=True)
        out = grid_file if args.what == "measure" else held_file
        out.write_text(json.dumps(data) + "\n")
        print(f"wrote {out} ({len(data['runs'])} runs)")
        return 0
    if args.what == "derive":
        if not grid_file.exists():
            ap.error(f"{grid_file} not found: run 'measure' first")
        grid = json.loads(grid_file.read_text())
        if grid.get("thresholds", DEFAULT_THRESHOLDS) != args.thresholds:
            ap.error(f"{grid_file} was measured at the thresholds {grid.get('thresholds')!r}, not {args.thresholds!r}")
        out = data_dir / files["grid"]
        out.parent.mkdir(parents=True, exist_ok=True)
        data = derive_sure_cells(grid, args.diagnoser)
        if not local:
            data["settings"]["thresholds"] = args.thresholds
            data["command"] += f" --thresholds {args.thresholds}"
        out.write_text(json.dumps(data) + "\n")
        load_sure_cells.cache_clear()
        print(f"wrote {out}: {int(np.sum(data['sure']))} sure cells")
        out = data_dir / files["sized"]
        data = derive_sized_cells(grid, args.diagnoser)
        if not local:
            data["thresholds"] = args.thresholds
            data["command"] = data.get("command", "") + f" --thresholds {args.thresholds}"
        out.write_text(json.dumps(data) + "\n")
        load_sized_cells.cache_clear()
        print(f"wrote {out}: sure cells per band " + ", ".join(str(int(np.sum(b))) for b in data["sure"]))
        return 0
    if not held_file.exists():
        ap.error(f"{held_file} not found: run 'validate' first")
    held = json.loads(held_file.read_text())
    sets = {
        "thesis": size_blind_cells(args.diagnoser, "thesis", args.thresholds),
        "grid": size_blind_cells(args.diagnoser, "grid", args.thresholds),
        "sized": load_sized_cells(files["sized"]),
    }
    seed_opt = f" --first-seed {args.first_seed}" if dev else ""
    if not local:
        seed_opt += f" --thresholds {args.thresholds}"
    res = {
        "diagnoser": args.diagnoser,
        "thresholds": args.thresholds,
        "runs": len(held["runs"]),
        "held_out": {
            "magnitudes": "geometric midpoints of the grid",
            "profiles": list(HELD_OUT_PROFILES),
            "first_seed": args.first_seed,
            "seeds_per_cell": held["n_seeds"],
        },
        "command": f"python -m studies.diagnosis.certainty validate --seeds {held['n_seeds']}{seed_opt} && "
        f"python -m studies.diagnosis.certainty report --diagnoser {args.diagnoser}{seed_opt}",
        "result": validate(held, args.diagnoser, sets),
    }
    stem = f"certainty_{args.diagnoser}" + ("" if local else f"_{args.thresholds}")
    report = (
        Path("docs/data") if not dev else args.work_dir
    ) / f"{stem}{'' if not dev else '_' + str(args.first_seed)}.json"
    report.parent.mkdir(parents=True, exist_ok=True)
    report.write_text(json.dumps(res, indent=1) + "\n")
    for name, per in res["result"].items():
        print(
            name,
            "wrong isolations:",
            sum(p["wrong"] for p in per.values()),
            "of",
            sum(p["detected"] for p in per.values()),
            "detected runs;",
            {f: p["wrong"] for f, p in per.items() if p["wrong"]},
            "at the end:",
            sum(p["wrong_end"] for p in per.values()),
            "isolated at the end:",
            sum(p["isolated_end"] for p in per.values()),
        )
    print(f"wrote {report}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
