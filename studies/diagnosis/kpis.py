"""Key performance indicators of the diagnosers (thesis section 6.5) and their checks.

    python -m studies.diagnosis.kpis false-alarms --hours 200        # fault-free, all families, both
    python -m studies.diagnosis.kpis delays --seeds 100              # single faults, delays
    python -m studies.diagnosis.kpis scenarios --seeds 50 --first-seed 1000  # the 4 examples of 6.4
    python -m studies.diagnosis.kpis cell-sets --results FILE ...    # the cell sets on the suites
    python -m studies.diagnosis.kpis min-detectable --seeds 20       # KPI 6.5.2, bisection
    python -m studies.diagnosis.kpis min-detectable --all --seeds 4  # all 26 faults -> env table
    python -m studies.diagnosis.kpis seal-leak-snr --seeds 16        # why turbine_seal_leak is missed
    python -m studies.diagnosis.detection_bound --seeds 50           # how fast any test could see it
    python -m studies.diagnosis.kpis render                          # docs/diagnosis_results.md

``--diagnoser sequential`` measures the ``sequential`` diagnoser instead of the reference.  Each
writes a JSON file under ``docs/data/`` (``diagnoser_*.json`` for the reference, ``sequential_*.json``;
``--out`` to change) and prints where.  Engines are simulated in batches and diagnosed as they
run (:func:`marine_fdi_env.diagnosis.batch.diagnose_batch`).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from marine_fdi_env.diagnosis.agent import ReferenceDiagnoser
from marine_fdi_env.diagnosis.batch import BATCH, DIAGNOSERS, diagnose_batch  # noqa: F401
from marine_fdi_env.diagnosis.batch import PARAMS as _PARAMS  # noqa: F401
from marine_fdi_env.diagnosis.cell_sets import CELL_SETS, DEFAULT_CELLS
from marine_fdi_env.diagnosis.decision import declared_faults
from marine_fdi_env.diagnosis.modules import MODULE_IDS
from marine_fdi_env.diagnosis.residuals import residuals_for_run
from marine_fdi_env.diagnosis.thresholds import DEFAULT_THRESHOLDS
from marine_fdi_env.engine.faults import FAULT_IDS, PROCESS_FAULT_DEFAULTS, PROCESS_FAULT_IDS, FaultSpec
from marine_fdi_env.engine.sensors import SENSORS, sensor_index
from marine_fdi_env.engine.simulator import Simulator
from marine_fdi_env.scenarios import SCENARIOS, get_scenario
from studies.paths import PACKAGE_DATA

from .cell_set_table import cell_set_table, proportion_ci95, summarize_results, wrong_isolations  # noqa: F401

__all__ = [
    "diagnose_batch",
    "seal_leak_snr",
    "false_alarms",
    "single_fault_delays",
    "scenario_checks",
    "min_detectable",
    "detectability_limits",
    "THESIS_DELAYS_S",
    "THESIS_MIN_DETECTABLE",
]

PARAMS = "thesis-12v28"
DURATION_S = 300.0
SENSOR_ONSET_S = 30.0
EXTENDED_S = 3600.0  # horizon of the second pass for faults missed within DURATION_S
LIMIT_SENSOR_ONSET_S = 50.0  # onset of the sensor offsets in the detectability-limit bisection
ENV_TABLE = PACKAGE_DATA / "env" / "detectability.json"
# Detection times the thesis states for its examples (section 6.4) and KPI table 6.10.
THESIS_DELAYS_S = {
    "thesis-6.4.2": {"bore_damage (M2.3, M2.4)": 146.1, "bore_damage (M2.1, M2.2)": 201.6, "valve_seizing (M1)": 207.1},
    "thesis-6.4.3": {"S2.2": 20.0, "compressor_seal_leak": 156.8},
    "thesis-6.4.4": {"turbine_lubrication_loss": 104.6},
}
THESIS_MIN_DETECTABLE = {
    "turbine_seal_leak": 5e-5,
    "turbine_lubrication_loss": 0.3,
    "compressor_seal_leak": 78e-4,
    "intercooler_blockage": 3.75e-2,
    "compressor_lubrication_loss": 0.165,
    "bore_damage": 1.5e-3,
    "valve_seizing": 1.85e-2,
}


FA_ENTROPY0 = 9_000_000_000  # fault-free runs of the false-alarm KPI (disjoint from the calibration sets)


def false_alarms(
    hours: float, entropy0: int = FA_ENTROPY0, progress: bool = True, thresholds: str = DEFAULT_THRESHOLDS
) -> dict:
    """Fault-free 300 s runs over all profile families (fuel settings 0.3-1.1, as
    :func:`~studies.diagnosis.sequential_calibration.profile_for` draws them; seeds disjoint
    from the sequential diagnoser's calibration and validation sets): the runs where a module of
    each diagnoser fired, {"reference": ..., "sequential": ...} (one simulation for both: the
    sequential diagnoser runs the reference's residual generators and worst-case tests).  With
    another reading of the observers' ``thresholds`` than ``local``: {"reference": ...} at that
    reading only."""
    from marine_fdi_env.diagnosis.sequential import SequentialDiagnoser

    from .sequential_calibration import FAMILIES, profile_for

    n = int(math.ceil(hours * 3600.0 / DURATION_S))
    drawn = [profile_for(entropy0 + i) for i in range(n)]
    profiles = [p for p, _ in drawn]
    seeds = [sd for _, sd in drawn]
    local = thresholds == DEFAULT_THRESHOLDS
    first = {"reference": np.full((n, len(MODULE_IDS)), np.nan)}
    if local:
        first["sequential"] = np.full((n, len(MODULE_IDS)), np.nan)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=n, desc="false alarms", unit="run", file=sys.stderr)
    for a in range(0, n, BATCH):
        b = min(n, a + BATCH)
        sim = Simulator(PARAMS, b - a, seeds=seeds[a:b], profiles=profiles[a:b])
        if local:
            agent = SequentialDiagnoser(PARAMS, n_engines=b - a, dt=sim.dt, exoneration="none")
        else:
            agent = ReferenceDiagnoser(PARAMS, n_engines=b - a, dt=sim.dt, exoneration="none", thresholds=thresholds)
        agent.observe(sim.y[:, None, :], sim.u[:, None])
        for _ in range(int(round(DURATION_S / sim.dt / 1000))):
            blk = sim.advance(1000)
            agent.observe(blk.measurements, blk.u)
        first["reference"][a:b] = agent.ref.first_violation if local else agent.first_violation
        if local:
            first["sequential"][a:b] = agent.stage.first
        if bar is not None:
            bar.update(b - a)
    if bar is not None:
        bar.close()
    out = {}
    for name, t in first.items():
        alarms = [
            {
                "run": i,
                "profile": profiles[i],
                "seed": seeds[i],
                "first_detection_s": float(np.nanmin(t[i])),
                "modules": [m for m, x in zip(MODULE_IDS, t[i]) if not np.isnan(x)],
            }
            for i in range(n)
            if not np.isnan(t[i]).all()
        ]
        out[name] = {
            "runs": n,
            "duration_s": DURATION_S,
            "engine_hours": n * DURATION_S / 3600.0,
            "entropy0": entropy0,
            "runs_with_false_alarm": len(alarms),
            "per_family": {
                f: {
                    "runs": sum(p.startswith(f) for p in profiles),
                    "runs_with_false_alarm": sum(x["profile"].startswith(f) for x in alarms),
                }
                for f in FAMILIES
            },
            "alarms": alarms,
        }
    return out


def _onset(f: str) -> float:
    return PROCESS_FAULT_DEFAULTS[f].onset_s if f in PROCESS_FAULT_DEFAULTS else SENSOR_ONSET_S


class IsolationClock:
    """``diagnose_batch`` block callback: per run, since when the diagnoser has declared exactly the
    run's own fault (``declared_faults`` of its minimal diagnoses, the agents' rule), None while it
    does not; checked at the end of every block (the decision period of the blocks fed)."""

    def __init__(self, faults: list[str]) -> None:
        self.faults = faults
        self.since: list[float | None] = [None] * len(faults)

    def __call__(self, agent, engines: slice, blk) -> None:
        t = float(blk.t[-1])
        for k, i in enumerate(range(engines.start, engines.stop)):
            decl = declared_faults(agent.diagnoses(k)) if agent.detected[k] else []
            if decl != [self.faults[i]]:
                self.since[i] = None
            elif self.since[i] is None:
                self.since[i] = t


def _delay_stats(rs: list[dict], f: str, on: float, isolated_since: list | None = None) -> dict:
    delays = [r["first_detection_time_s"] - on for r in rs if r["detected"]]
    contains = [any(d == [f] or f in d for d in r["final_minimal_diagnoses"]) for r in rs]
    single = [[f] in r["final_minimal_diagnoses"] for r in rs]
    out = {
        "runs": len(rs),
        "detected": sum(r["detected"] for r in rs),
        "early_alarms": sum(1 for r in rs if r["detected"] and r["first_detection_time_s"] < on),
        "contains_fault": int(sum(contains)),
        "single_fault_diagnosis": int(sum(single)),
        "median_delay_s": float(np.median(delays)) if delays else None,
        "p10_delay_s": float(np.percentile(delays, 10)) if delays else None,
        "p90_delay_s": float(np.percentile(delays, 90)) if delays else None,
        "std_delay_s": float(np.std(delays)) if delays else None,
    }
    if isolated_since is not None:
        iso = [x - on for x in isolated_since if x is not None]
        out.update(
            {
                "isolated": len(iso),
                "median_isolation_delay_s": float(np.median(iso)) if iso else None,
                "p90_isolation_delay_s": float(np.percentile(iso, 90)) if iso else None,
            }
        )
    return out


# samples per block of the isolation clock: the environment's decision period of 1 s
ISOLATION_BLOCK = 100


def single_fault_delays(
    n_seeds: int,
    first_seed: int = 10_000,
    fault_ids=FAULT_IDS,
    extended_s: float = EXTENDED_S,
    diagnoser: str = "reference",
) -> dict:
    """Every single fault at its default magnitude, n_seeds noise seeds, constant fuel setting:
    detection delays, isolation delays (the diagnoser declares exactly the fault, from the end of
    the 1 s block in which it does so to the end of the run: :class:`IsolationClock`) and diagnoses.

    A fault missed in some seed within the 300 s runs is run again, same seeds, for ``extended_s``
    (with the same seeds fault-free as the false-alarm check of that horizon): ``extended``
    says whether and when it is detected once the runs are long enough.
    """
    schedules, seeds, labels = [], [], []
    for j, f in enumerate(fault_ids):
        for s in range(n_seeds):
            schedules.append([FaultSpec(f, _onset(f))])
            seeds.append(first_seed + 1000 * j + s)
            labels.append(f)
    clock = IsolationClock(labels)
    reps = diagnose_batch(schedules, seeds, diagnoser=diagnoser, block_samples=ISOLATION_BLOCK, on_block=clock)
    out = {}
    for f in fault_ids:
        rs = [r for r, lab in zip(reps, labels) if lab == f]
        since = [x for x, lab in zip(clock.since, labels) if lab == f]
        on = _onset(f)
        per_module = {}
        for m in MODULE_IDS:
            t = [r["module_detection_times_s"][m] - on for r in rs if r["module_detection_times_s"][m] is not None]
            if t:
                per_module[m] = {"n": len(t), "median_s": float(np.median(t)), "std_s": float(np.std(t))}
        out[f] = {
            "onset_s": on,
            **_delay_stats(rs, f, on, since),
            "n_diagnoses_median": float(np.median([len(r["final_minimal_diagnoses"]) for r in rs])),
            "modules": per_module,
        }
        if extended_s > DURATION_S and out[f]["detected"] < len(rs):
            f_seeds = [s for s, lab in zip(seeds, labels) if lab == f]
            long = diagnose_batch(
                [[FaultSpec(f, on)] for _ in f_seeds], f_seeds, duration_s=extended_s, diagnoser=diagnoser
            )
            healthy = diagnose_batch([[] for _ in f_seeds], f_seeds, duration_s=extended_s, diagnoser=diagnoser)
            within = sum(1 for r in long if r["detected"] and 0.0 <= r["first_detection_time_s"] - on <= 300.0)
            out[f]["extended"] = {
                "duration_s": extended_s,
                **_delay_stats(long, f, on),
                "within_300_s_of_onset": within,
                "healthy_runs_with_alarm": sum(r["detected"] for r in healthy),
            }
    return out


def scenario_checks(
    n_seeds: int,
    first_seed: int = 20_000,
    diagnoser: str = "reference",
    cells: str = "sized",
    thresholds: str = DEFAULT_THRESHOLDS,
) -> dict:
    """The four thesis examples (section 6.4) over n_seeds noise seeds (``marine-fdi simulate --scenario
    NAME --seed S`` for S = first_seed, ...), with the cell set ``cells`` (and the reading of the
    reference's observer ``thresholds``)."""
    extra = {} if thresholds == DEFAULT_THRESHOLDS else {"thresholds": thresholds}
    thesis_counts = {"thesis-6.4.1": 4, "thesis-6.4.2": 1, "thesis-6.4.3": 1, "thesis-6.4.4": 9}
    out = {}
    for name in SCENARIOS:
        sc = get_scenario(name)
        specs = sc.fault_specs()
        seeds = [first_seed + i for i in range(n_seeds)]
        reps = diagnose_batch(
            [specs] * n_seeds, seeds, sc.profile, sc.duration_s, diagnoser=diagnoser, cells=cells, **extra
        )
        injected = sorted(f.fault_id for f in specs)
        first_onset = min(f.onset_s for f in specs)
        rows = []
        for s, r in zip(seeds, reps):
            diag = r["final_minimal_diagnoses"]
            key = sorted(injected, key=FAULT_IDS.index)
            rows.append(
                {
                    "seed": s,
                    "first_detection_s": r["first_detection_time_s"],
                    "early": bool(r["detected"] and r["first_detection_time_s"] < first_onset),
                    "injected_in_diagnoses": key in diag,
                    "n_diagnoses": len(diag),
                    "unique": diag == [key],
                    "diagnoses": diag,
                    "module_detection_times_s": {
                        m: t for m, t in r["module_detection_times_s"].items() if t is not None
                    },
                }
            )
        limit = thesis_counts.get(name)
        out[name] = {
            "injected": injected,
            "thesis_final_candidates": limit,
            "seeds": n_seeds,
            "first_seed": first_seed,
            "cells": cells,
            "early_runs": sum(x["early"] for x in rows),
            "injected_in_diagnoses_runs": sum(x["injected_in_diagnoses"] for x in rows),
            "unique_runs": sum(x["unique"] for x in rows),
            "within_thesis_count_runs": sum(limit is None or x["n_diagnoses"] <= limit for x in rows),
            "no_early_detection": all(not x["early"] for x in rows),
            "injected_always_in_diagnoses": all(x["injected_in_diagnoses"] for x in rows),
            "max_candidates": max(x["n_diagnoses"] for x in rows),
            "always_unique": all(x["unique"] for x in rows),
            "runs": rows,
        }
    return out


def min_detectable(
    n_seeds: int, first_seed: int = 30_000, fault_ids=PROCESS_FAULT_IDS, diagnoser: str = "reference", rtol: float = 1.1
) -> dict:
    """KPI 6.5.2: smallest magnitude of each process fault detected within 300 s (at or after
    the onset) in every one of ``n_seeds`` seeds, constant fuel setting 1.0: the bracketing
    log-space bisection of :func:`detectability_limits` (from the table 6.4 value, halving or
    doubling up to 16x, then bisecting to ``rtol``)."""
    lim = detectability_limits(n_seeds, fault_ids=fault_ids, first_seed=first_seed, rtol=rtol, diagnoser=diagnoser)
    out = {}
    for f, v in lim.items():
        d = {
            "min_detectable": v["limit"],
            "bracket": v["bracket"],
            "unit": PROCESS_FAULT_DEFAULTS[f].unit,
            "thesis_table_6_10": THESIS_MIN_DETECTABLE[f],
            "seeds": n_seeds,
            "evaluations": v["evaluations"],
        }
        if v.get("note"):
            d["note"] = v["note"]
        out[f] = d
    return out


def _fault_unit(f: str) -> str:
    return PROCESS_FAULT_DEFAULTS[f].unit if f in PROCESS_FAULT_DEFAULTS else SENSORS[sensor_index(f)].unit


def _limit_spec(f: str, magnitude: float, sensor_onset_s: float) -> FaultSpec:
    if f in PROCESS_FAULT_DEFAULTS:
        return FaultSpec(f, PROCESS_FAULT_DEFAULTS[f].onset_s, magnitude=magnitude)
    return FaultSpec(f, sensor_onset_s, magnitude=magnitude, kind="offset")


def detectability_limits(
    n_seeds: int,
    fault_ids=FAULT_IDS,
    first_seed: int = 30_000,
    factor: float = 2.0,
    rtol: float = 1.05,
    max_up: int = 4,
    max_down: int = 20,
    sensor_onset_s: float = LIMIT_SENSOR_ONSET_S,
    duration_s: float = DURATION_S,
    log=None,
    diagnoser: str = "reference",
    thresholds: str = DEFAULT_THRESHOLDS,
    exoneration: str = "sure",
) -> dict:
    """Smallest magnitude of every fault detected (any module violated, first at or after the onset)
    before ``duration_s`` in each of ``n_seeds`` noise seeds, at constant fuel setting 1.0.  Detection does
    not depend on the diagnoser's cells: ``exoneration="none"`` measures a fault that has none yet.

    Sensor faults: abrupt positive offsets with onset ``sensor_onset_s``; process faults: their
    table 6.4 fault functions with their default onsets and κ (as in :func:`min_detectable`).
    Bracketing from the table magnitude m0: a magnitude detected in every seed becomes the upper
    bound and the next try is divided by ``factor``; otherwise it becomes the lower bound and the
    next try is multiplied by ``factor`` (at most m0·factor**max_up; down to m0/factor**max_down).
    Once both bounds exist, log-space bisection until hi/lo <= ``rtol``.  All faults still searching
    are simulated in one batch per iteration (all seeds of every magnitude together).

    Returns ``{fault_id: {"limit", "detected", "bracket", "unit", "table_magnitude", "onset_s",
    "evaluations": [[magnitude, n_detected, median_delay_s or None, n_early, n_failures], ...],
    "note"?}}``; a fault not detected in every seed even at the largest magnitude tried gets
    ``limit = None, detected = False``.
    """
    if factor <= 1 or rtol <= 1:
        raise ValueError("factor and rtol must be > 1")
    seeds = [first_seed + i for i in range(n_seeds)]
    state = {}
    for f in fault_ids:
        m0 = FaultSpec(f, 0.0, kind=None if f in PROCESS_FAULT_DEFAULTS else "offset").resolved_magnitude
        state[f] = {"table": m0, "lo": None, "hi": None, "next": m0, "evals": [], "note": None}
    it = 0
    while True:
        todo = [(f, st["next"]) for f, st in state.items() if st["next"] is not None]
        if not todo:
            break
        it += 1
        schedules = [[_limit_spec(f, m, sensor_onset_s)] for f, m in todo for _ in seeds]
        extra = {} if diagnoser == "reference" else {"diagnoser": diagnoser}
        if thresholds != DEFAULT_THRESHOLDS:
            extra["thresholds"] = thresholds
        if exoneration != "sure":
            extra["exoneration"] = exoneration
        reps = diagnose_batch(schedules, seeds * len(todo), duration_s=duration_s, **extra)
        for k, (f, m) in enumerate(todo):
            st = state[f]
            onset = schedules[k * n_seeds][0].onset_s
            rs = reps[k * n_seeds : (k + 1) * n_seeds]
            ok = [bool(r["detected"]) and r["first_detection_time_s"] >= onset for r in rs]
            early = sum(1 for r in rs if r["detected"] and r["first_detection_time_s"] < onset)
            delays = [r["first_detection_time_s"] - onset for r, o in zip(rs, ok) if o]
            st["evals"].append(
                [
                    m,
                    int(sum(ok)),
                    float(np.median(delays)) if delays else None,
                    early,
                    sum(1 for r in rs if r["failures"]),
                ]
            )
            if all(ok):
                st["hi"] = m
            else:
                st["lo"] = m
            lo, hi, m0 = st["lo"], st["hi"], st["table"]
            if lo is None:
                nxt = m / factor
                if nxt < m0 / factor**max_down * (1 - 1e-9):
                    nxt, st["note"] = None, f"detected in every seed at every magnitude tried, down to {m:g}"
            elif hi is None:
                nxt = m * factor
                if nxt > m0 * factor**max_up * (1 + 1e-9):
                    nxt, st["note"] = None, f"not detected in every seed even at {m:g} ({m / m0:g} x table)"
            else:
                nxt = math.sqrt(lo * hi) if hi / lo > rtol else None
            st["next"] = nxt
        if log is not None:
            log(
                f"iteration {it}: {len(todo)} faults x {n_seeds} seeds; "
                + ", ".join(f"{f} {m:.3g}:{state[f]['evals'][-1][1]}/{n_seeds}" for f, m in todo)
            )
    out = {}
    for f, st in state.items():
        det = st["hi"] is not None
        d = {
            "limit": st["hi"],
            "detected": det,
            "bracket": [st["lo"], st["hi"]],
            "unit": _fault_unit(f),
            "table_magnitude": st["table"],
            "onset_s": _limit_spec(f, None, sensor_onset_s).onset_s,
            "seeds": n_seeds,
            "evaluations": st["evals"],
        }
        if st["note"]:
            d["note"] = st["note"]
        out[f] = d
    return out


def env_table(limits: dict, command: str, n_seeds: int) -> dict:
    """The environment's detectability table (``marine_fdi_env/data/env/detectability.json``) from
    :func:`detectability_limits`; an undetected fault gets its table magnitude as limit."""
    faults = {}
    for f, v in limits.items():
        e = {
            "limit": v["limit"],
            "unit": v["unit"],
            "source": f"bisection, {n_seeds} seeds, command {command}",
            "table_magnitude": v["table_magnitude"],
            "detected": v["detected"],
            "onset_s": v["onset_s"],
            "bracket": v["bracket"],
            "ratio_to_table": None,
            "evaluations": v["evaluations"],
        }
        if not v["detected"]:
            e["limit"] = v["table_magnitude"]
            e["note"] = (
                f"{v.get('note', 'never detected')}; the limit is the table magnitude, so scenarios "
                "are sampled relative to it"
            )
        elif v.get("note"):
            e["note"] = v["note"]
        e["ratio_to_table"] = e["limit"] / v["table_magnitude"]
        faults[f] = e
    return {
        "description": "Detectability limit of every fault: the smallest magnitude detected by the reference "
        "diagnoser (any module, at or after the onset) before the end of a 300 s run in every "
        "seed, at constant fuel setting 1.0. Sensor faults: abrupt positive offsets with onset "
        f"{LIMIT_SENSOR_ONSET_S:g} s; process faults: table 6.4 fault functions with their default "
        "onsets and kappa. evaluations: [magnitude, seeds detected, median delay s, early alarms, "
        "runs with engine failure].",
        "params": PARAMS,
        "seeds": n_seeds,
        "duration_s": DURATION_S,
        "command": command,
        "faults": faults,
    }


SNR_MULTIPLES = (1.0, 4.0, 16.0)
SNR_WINDOW_S = 60.0


def seal_leak_snr(
    n_seeds: int,
    fault: str = "turbine_seal_leak",
    multiples=SNR_MULTIPLES,
    profiles=("constant", "manoeuvring"),
    window_s: float = SNR_WINDOW_S,
    first_seed: int = 70_000,
) -> dict:
    """How visible a seal leak is to the receiver observers M3.1/M3.2 (or M4.1/M4.2) in the last
    ``window_s`` of a 300 s run, at multiples of the table 6.4 magnitude, same noise seeds with and
    without the fault.

    Per profile and multiple: the fault's effect on the true state (x3 or x4) and on the mean of
    the two modules' residuals over the window, the fault-free spread (std over seeds) of that window
    mean, their ratio (the z-score of the best averaging test on one window), and the mean worst-case
    threshold the thesis's scheme compares single samples with.
    """
    sys_ = "x3" if fault == "turbine_seal_leak" else "x4"
    mods = [MODULE_IDS.index(m) for m in (("M3.1", "M3.2") if sys_ == "x3" else ("M4.1", "M4.2"))]
    c = ReferenceDiagnoser(PARAMS).c
    seeds = [first_seed + i for i in range(n_seeds)]
    table = PROCESS_FAULT_DEFAULTS[fault].magnitude
    out = {}
    for prof in profiles:
        runs = {}
        for mult in (0.0,) + tuple(multiples):
            faults = [
                [] if mult == 0 else [FaultSpec(fault, PROCESS_FAULT_DEFAULTS[fault].onset_s, table * mult)]
                for _ in seeds
            ]
            sim = Simulator(PARAMS, len(seeds), seeds=seeds, faults=faults, profiles=prof)
            res = sim.run(DURATION_S)
            w = int(round(window_s / sim.dt))
            state = res.truth_of(sys_)[-w:].mean(axis=0)  # (N,)
            r_mean, thr = [], []
            for i in range(len(seeds)):
                tr = residuals_for_run(c, res.measurements[:, i], res.truth_of("u")[:, i], sim.dt)
                r_mean.append(tr.residuals[-w:, mods].mean())
                thr.append(tr.thresholds[-w:, mods].mean())
            runs[mult] = (state, np.array(r_mean), float(np.mean(thr)))
        state0, r0, thr0 = runs[0.0]
        sigma = float(np.std(r0, ddof=1)) if len(seeds) > 1 else math.nan
        rows = {
            "fault_free": {
                "residual_window_mean_Pa": float(r0.mean()),
                "residual_window_mean_std_Pa": sigma,
                "threshold_mean_Pa": thr0,
            }
        }
        for mult in multiples:
            state, r, thr = runs[mult]
            shift = float((r - r0).mean())
            rows[f"{mult:g}x"] = {
                "magnitude": table * mult,
                "state_change_Pa": float((state - state0).mean()),
                "state_change_relative": float(((state - state0) / state0).mean()),
                "residual_shift_Pa": shift,
                "z_score": shift / sigma if sigma > 0 else math.nan,
                "threshold_mean_Pa": thr,
            }
        out[prof] = rows
    return {
        "fault": fault,
        "state": sys_,
        "modules": [MODULE_IDS[m] for m in mods],
        "window_s": window_s,
        "result": out,
    }


_THESIS_NOTES = {
    "valve_seizing": "almost 10 s with noise (fig. 6.22); 6.4.2: M1.1/M1.2 at +7.1 s",
    "bore_damage": "6.4.2: 141.1 s after onset (146.1 s)",
    "turbine_seal_leak": "'relatively short time' (fig. 6.26)",
    "turbine_lubrication_loss": "6.4.4: 74.6 s after onset (104.6 s)",
    "compressor_seal_leak": "6.4.3: 126.8 s after onset (156.8 s)",
    "compressor_lubrication_loss": "'shortly after' (fig. 6.32)",
    "intercooler_blockage": "about 15 s (fig. 6.34)",
}


def _count(k: int, n: int) -> str:
    lo, hi = proportion_ci95(k, n)
    return f"{k}/{n} ({100 * lo:.0f}-{100 * hi:.0f} %)"


def _fmt(x, spec=".2f", none="-"):
    return none if x is None else format(x, spec)


def render(data_dir: Path = Path("docs/data")) -> str:
    """Markdown tables of the KPI JSON files (written by the other subcommands), the reference
    diagnoser and the sequential one side by side."""
    lines = []

    def load(name, prefix="diagnoser"):
        p = data_dir / f"{prefix}_{name}.json"
        return json.loads(p.read_text()) if p.exists() else None

    agents = [a for a in ("diagnoser", "sequential")]
    label = {"diagnoser": "reference", "sequential": "sequential"}

    fas = {a: load("false-alarms", a) for a in agents}
    if any(fas.values()):
        lines += [
            "### False alarms",
            "",
            "Fault-free 300 s runs over all profile families (constant, step, ramp, "
            "random, manoeuvring; fuel settings 0.3-1.1), seeds disjoint from the sequential diagnoser's "
            "calibration and validation runs.",
            "",
            "| diagnoser | command | runs | engine-hours | runs with a false alarm | per family (runs with an "
            "alarm / runs) |",
            "|---|---|---|---|---|---|",
        ]
        for a, fa in fas.items():
            if not fa:
                continue
            v = fa["result"]
            fam = ", ".join(f"{k} {x['runs_with_false_alarm']}/{x['runs']}" for k, x in v["per_family"].items())
            lines.append(
                f"| {label[a]} | `{fa['command']}` | {v['runs']} | {v['engine_hours']:.0f} | "
                f"{v['runs_with_false_alarm']} | {fam} |"
            )
        lines.append("")
    sfa = data_dir / "sequential_calibration_check.json"
    if sfa.exists():
        v = json.loads(sfa.read_text())
        lines += [
            f"The sequential tests' own check on the validation runs (`python -m "
            f"studies.diagnosis.sequential_calibration record --set validation --hours {v['hours']:g}`, "
            f"then `{v['command']}`; {v['runs']} runs, "
            f"{v['hours']:.0f} engine-hours, disjoint from the {v.get('calibration_hours', 100):.0f} h of "
            f"calibration runs): {v['runs_with_alarm']} runs with an alarm ({v['runs_with_cusum_alarm']} by a "
            f"CUSUM test, {v['runs_with_worst_case_alarm']} by a worst-case threshold).",
            "",
        ]
    des = {a: load("delays", a) for a in agents}
    if any(des.values()):
        cmd = "; ".join(f"`{d['command']}`" for d in des.values() if d)
        lines += [
            f"### Single faults at their default magnitudes ({cmd})",
            "",
            "Constant fuel setting 1.0, table 6.3/6.4 magnitudes, 300 s.  Detection delay = first firing of "
            "any module minus onset; isolation delay = from when the diagnoser declares exactly the fault (to "
            "the end of the run; checked at the end of every 1 s block, the environment's decision period) "
            "minus onset, over the runs isolated at the end; 'alone': runs where {fault} itself is a final "
            "minimal diagnosis.  Default cell set (sized).",
            "",
            "| fault | thesis | reference: detected | alone | median det. delay [s] | median iso. delay [s] "
            "| sequential: detected | alone | median det. delay [s] | median iso. delay [s] |",
            "|---|---|---|---|---|---|---|---|---|---|",
        ]
        ref = des.get("diagnoser")
        seq = des.get("sequential")
        for f in FAULT_IDS:
            row = [f, _THESIS_NOTES.get(f, "immediate (figs. 6.2-6.20)")]
            for d in (ref, seq):
                if d is None or f not in d["result"]:
                    row += ["-"] * 4
                    continue
                v = d["result"][f]
                row += [
                    f"{v['detected']}/{v['runs']}",
                    str(v["single_fault_diagnosis"]),
                    _fmt(v["median_delay_s"]),
                    _fmt(v.get("median_isolation_delay_s")),
                ]
            lines.append("| " + " | ".join(row) + " |")
        for a, d in des.items():
            ext = {f: v["extended"] for f, v in (d or {"result": {}})["result"].items() if "extended" in v}
            if ext:
                lines += [
                    "",
                    f"{label[a].capitalize()}: faults missed within 300 s, run again with the same seeds "
                    "for longer (and the same seeds fault-free over that horizon, for false alarms):",
                    "",
                    "| fault | run length [s] | detected | within 300 s of the onset | in diagnoses | alone | "
                    "median delay [s] | 10-90 % [s] | fault-free runs with an alarm |",
                    "|---|---|---|---|---|---|---|---|---|",
                ]
                for f, v in ext.items():
                    rng = "-" if v["p10_delay_s"] is None else f"{v['p10_delay_s']:.0f}-{v['p90_delay_s']:.0f}"
                    w = v.get("within_300_s_of_onset")
                    within = "-" if w is None else f"{w}/{v['runs']}"
                    lines.append(
                        f"| {f} | {v['duration_s']:.0f} | {v['detected']}/{v['runs']} | {within} | "
                        f"{v['contains_fault']} | "
                        f"{v['single_fault_diagnosis']} | {_fmt(v['median_delay_s'], '.0f')} | {rng} | "
                        f"{v['healthy_runs_with_alarm']}/{v['runs']} |"
                    )
        if ref:
            lines += [
                "",
                "KPI 6.5.1, spread of the detection time per module for the sensor offsets, reference "
                "(std over runs, thesis: below 0.003 s):",
                "",
                "| fault | module: std [s] |",
                "|---|---|",
            ]
            for f, v in ref["result"].items():
                if f.startswith("S"):
                    lines.append(
                        f"| {f} | " + ", ".join(f"{m}: {x['std_s']:.3f}" for m, x in v["modules"].items()) + " |"
                    )
        lines.append("")
    scs = {a: load("scenarios", a) for a in agents}
    if any(scs.values()):
        cmd = "; ".join(f"`{d['command']}`" for d in scs.values() if d)
        first = next(d for d in scs.values() if d)["result"]["thesis-6.4.1"]
        lines += [
            f"### The thesis's multiple-fault examples ({cmd})",
            "",
            f"Seeds {first['first_seed']}-{first['first_seed'] + first['seeds'] - 1} (`marine-fdi simulate "
            f"--scenario NAME --seed S`), which no design choice looked at (the development seeds are "
            "0-49); the default cell set (sized; the others in the table of the cell sets below).  Counts of "
            "runs with the exact 95 % interval of the rate.",
            "",
            "| example | injected | diagnoser | detection before the first onset | injected set among the final "
            "minimal diagnoses | unique | at most the thesis's candidate count | most candidates (thesis) |",
            "|---|---|---|---|---|---|---|---|",
        ]
        names = next(d for d in scs.values() if d)["result"]
        for name in names:
            for a, d in scs.items():
                if not d:
                    continue
                v = d["result"][name]
                n = v["seeds"]
                lines.append(
                    f"| {name} | {', '.join(v['injected'])} | {label[a]} | {v['early_runs']}/{n} | "
                    f"{_count(v['injected_in_diagnoses_runs'], n)} | {_count(v['unique_runs'], n)} | "
                    f"{_count(v['within_thesis_count_runs'], n)} | {v['max_candidates']} "
                    f"({v['thesis_final_candidates']}) |"
                )
        sc = scs.get("diagnoser")
        if sc:
            lines += ["", "Module detection times of the first seed (reference), beside the thesis's:", ""]
            for name, v in sc["result"].items():
                r = v["runs"][0]
                lines.append(
                    f"* {name}: "
                    + ", ".join(
                        f"{m} {t:.2f} s" for m, t in sorted(r["module_detection_times_s"].items(), key=lambda kv: kv[1])
                    )
                    + (f" — thesis: {THESIS_DELAYS_S[name]}" if name in THESIS_DELAYS_S else "")
                )
        lines.append("")
    sn = load("seal-leak-snr")
    if sn:
        lines += [
            f"### Why the reference misses turbine_seal_leak (`{sn['command']}`)",
            "",
            f"Last {sn['result']['window_s']:g} s of 300 s runs, same noise seeds with and without the fault; "
            f"residual = mean of {' and '.join(sn['result']['modules'])}; z = residual shift / fault-free "
            "spread (std over seeds) of that window mean, i.e. what the best averaging test over the window "
            "could see; threshold = the worst-case bound a single sample is compared with.",
            "",
            "| profile | magnitude | change of x3 [Pa] | residual shift [Pa] | z | threshold [Pa] |",
            "|---|---|---|---|---|---|",
        ]
        for prof, rows in sn["result"]["result"].items():
            for k, v in rows.items():
                if k == "fault_free":
                    continue
                lines.append(
                    f"| {prof} | {k} ({v['magnitude']:.3g}) | {v['state_change_Pa']:.0f} "
                    f"({100 * v['state_change_relative']:.3f} %) | {v['residual_shift_Pa']:.0f} | "
                    f"{v['z_score']:.1f} | {v['threshold_mean_Pa']:.0f} |"
                )
        lines.append("")
    bound = load("seal-leak-bound")
    if bound:
        from .detection_bound import render as render_bound

        lines += render_bound(bound)
    mds = {a: load("min-detectable", a) for a in agents}
    if any(mds.values()):
        cmd = "; ".join(f"`{d['command']}`" for d in mds.values() if d)
        lines += [
            f"### Smallest detectable process faults, KPI 6.5.2 ({cmd})",
            "",
            "Smallest magnitude detected within 300 s (at or after the onset) in every seed, constant fuel "
            "setting 1.0; bracketing log-space bisection to 10 %.  Ratio = thesis / ours (> 1: smaller than "
            "the thesis's).",
            "",
            "| fault | thesis table 6.10 | reference | ratio | sequential | ratio | unit |",
            "|---|---|---|---|---|---|---|",
        ]
        for f in PROCESS_FAULT_IDS:
            row = [f, f"{THESIS_MIN_DETECTABLE[f]:g}"]
            for a in agents:
                d = mds.get(a)
                v = d["result"].get(f) if d else None
                m = None if v is None else v.get("min_detectable")
                row += [
                    "-" if d is None else ("not detected" if m is None else f"{m:.3g}"),
                    "-" if m is None else f"{THESIS_MIN_DETECTABLE[f] / m:.2g}",
                ]
            row.append(PROCESS_FAULT_DEFAULTS[f].unit)
            lines.append("| " + " | ".join(row) + " |")
        lines.append("")
    return "\n".join(lines)


def render_robustness(data_dir: Path = Path("docs/data")) -> str:
    """Wrong isolations with each cell set: held-out grid (certainty validate) and single-v1 (the
    results files), and the cell sets side by side on everything (:mod:`.cell_set_table`)."""
    lines = []
    for a in ("reference", "sequential"):
        p = data_dir / f"certainty_{a}.json"
        if not p.exists():
            continue
        v = json.loads(p.read_text())
        res = v["result"]
        cols = [k for k in CELL_SETS if k in res]
        lines += [
            f"### Wrong isolations of the {a} diagnoser on held-out sizes, seeds and profiles (`{v['command']}`)",
            "",
            f"{v['runs']} runs: {v['held_out']['magnitudes']} (sensor offsets of both signs), profiles "
            f"{', '.join(v['held_out']['profiles'])}, {v['held_out']['seeds_per_cell']} seeds each from "
            f"{v['held_out']['first_seed']}.  Wrong: at some time the true fault is in no minimal diagnosis "
            "while the diagnoser declares a fault (at the end: so at the end of the run); isolated: the "
            "diagnoser declares exactly the true fault at the end.  Cell sets: thesis (the table sizes), grid "
            "(sure at every size), sized (the size band the evidence bounds each candidate to).",
            "",
            "| fault | detected runs | " + " | ".join(f"{c}: wrong (at the end) / isolated" for c in cols) + " |",
            "|---|---|" + "---|" * len(cols),
        ]
        tot = {c: [0, 0, 0] for c in cols}
        for f in FAULT_IDS:
            vals = [(res[c][f]["wrong"], res[c][f]["wrong_end"], res[c][f]["isolated_end"]) for c in cols]
            for c, x in zip(cols, vals):
                tot[c] = [t + y for t, y in zip(tot[c], x)]
            d0 = res[cols[0]][f]
            lines.append(
                f"| {f} | {d0['detected']}/{d0['runs']} | "
                + " | ".join(f"{x[0]} ({x[1]}) / {x[2]}" for x in vals)
                + " |"
            )
        lines.append("| all | | " + " | ".join(f"{t[0]} ({t[1]}) / {t[2]}" for t in tot.values()) + " |")
        lines.append("")
    p = data_dir / "wrong_isolations_single-v1.json"
    if p.exists():
        v = json.loads(p.read_text())
        keys = list(v["agents"])
        lines += ["### Wrong isolations on single-v1", "", v["description"]]
        lines += [
            "",
            "| fault | episodes | " + " | ".join(f"{k}: ever / at the end" for k in keys) + " |",
            "|---|---|" + "---|" * len(keys),
        ]
        tot = {k: [0, 0] for k in keys}
        for f in FAULT_IDS:
            cells = []
            n = None
            for k in keys:
                x = v["agents"][k].get(f)
                if x is None:
                    cells.append("-")
                    continue
                n = x["episodes"]
                tot[k][0] += x["anytime"]
                tot[k][1] += x["end"]
                cells.append(f"{x['anytime']} / {x['end']}")
            lines.append(f"| {f} | {n} | " + " | ".join(cells) + " |")
        lines.append("| all | | " + " | ".join(f"{tot[k][0]} / {tot[k][1]}" for k in keys) + " |")
        lines.append("")
    table = cell_set_table(data_dir)
    if table:
        lines += (
            [
                "### The three cell sets side by side",
                "",
                "Each diagnoser with each cell set (`--cells` / the agents `reference`, `reference-grid`, "
                "`reference-thesis`, `sequential`, ...): the thesis's examples on the reported seeds (counts of 50; "
                "the scenario commands above with `--cells`), the held-out certainty grid (the tables above) and "
                "every frozen suite (isolation accuracy with its exact 95 % interval; suites: "
                "`for a in reference reference-grid reference-thesis sequential sequential-grid sequential-thesis; "
                "do for s in thesis-v1 single-v1 multi-v1 incipient-v1 transfer-v1 nominal-v1 transfer-v2; do "
                "marine-fdi evaluate --agent $a --suite $s --out results/cell_sets/${a}_$s.json; done; done`, then "
                "`python -m studies.diagnosis.kpis cell-sets --results results/cell_sets/*.json`).",
                "",
            ]
            + table
            + [""]
        )
    return "\n".join(lines)


_PREFIX = {"reference": "diagnoser", "sequential": "sequential"}


def _wrong_isolations_main(args) -> int:
    """``wrong-isolations --results before=old.json after=new.json ...`` -> docs/data/wrong_isolations_single-v1.json"""
    pairs = [str(x) for x in (args.results or [])]
    if not pairs or any("=" not in p for p in pairs):
        print("wrong-isolations needs --results NAME=FILE ...", file=sys.stderr)
        return 2
    agents = {}
    for p in pairs:
        name, _, path = p.partition("=")
        agents[name] = wrong_isolations(json.loads(Path(path).read_text()))
    out = args.out or Path("docs/data/wrong_isolations_single-v1.json")
    data = {
        "description": "Single-fault episodes of single-v1 where the agent ever declared (belief >= 0.5) a set "
        "without the true fault, and where its last declaration lacks it (command: `python -m "
        "studies.diagnosis.kpis wrong-isolations --results " + " ".join(pairs) + "`).",
        "agents": agents,
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(data, indent=1) + "\n")
    print(f"wrote {out}")
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "what",
        choices=(
            "false-alarms",
            "delays",
            "scenarios",
            "min-detectable",
            "seal-leak-snr",
            "wrong-isolations",
            "cell-sets",
            "render",
        ),
    )
    ap.add_argument(
        "--results",
        nargs="*",
        type=Path,
        default=None,
        help="wrong-isolations: NAME=results.json pairs (evaluate results on single-v1); cell-sets: "
        "evaluate results files of the agents with each cell set",
    )
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument(
        "--first-seed",
        type=int,
        default=None,
        help="scenarios: first noise seed (default 20000; the reported runs use 1000, the development "
        "ones 0: docs/diagnosis.md)",
    )
    ap.add_argument(
        "--cells",
        choices=CELL_SETS,
        default=DEFAULT_CELLS,
        help="scenarios: the diagnoser's sure cells (default sized; results of the others are written "
        "beside, *_scenarios_CELLS.json)",
    )
    ap.add_argument("--hours", type=float, default=200.0, help="false-alarms: fault-free engine-hours (default 200)")
    ap.add_argument(
        "--diagnoser",
        choices=DIAGNOSERS,
        default="reference",
        help="reference (the thesis scheme, default) or sequential (CUSUM tests on its residuals)",
    )
    ap.add_argument("--out", type=Path, default=None)
    ap.add_argument(
        "--all",
        action="store_true",
        help="min-detectable: all 26 faults (sensor offsets too) with a bracketing log-space "
        "bisection; writes the environment's table (default "
        "src/marine_fdi_env/data/env/detectability.json)",
    )
    args = ap.parse_args(argv)
    if args.seeds < 1:
        ap.error("--seeds must be >= 1")
    if args.what == "render":
        text = (
            "# Diagnosers: measured results\n\nGenerated by `python -m studies.diagnosis.kpis render` "
            "from `docs/data/diagnoser_*.json` (the reference diagnoser), `docs/data/sequential_*.json` (the "
            "sequential one), `docs/data/certainty_*.json`, `docs/data/wrong_isolations_single-v1.json` and "
            "`docs/data/cell_sets.json`; "
            "the commands that wrote them are named with each table.\n\n" + render() + "\n" + render_robustness()
        )
        out = args.out or Path("docs/diagnosis_results.md")
        out.write_text(text.rstrip() + "\n")
        print(f"wrote {out}")
        return 0
    if args.what == "wrong-isolations":
        return _wrong_isolations_main(args)
    if args.what == "cell-sets":
        files = [Path(x) for x in (args.results or [])]
        if not files:
            ap.error("cell-sets needs --results FILE ... (marine-fdi evaluate results)")
        out = args.out or Path("docs/data/cell_sets.json")
        data = {
            "command": "python -m studies.diagnosis.kpis cell-sets --results " + " ".join(str(f) for f in files),
            "agents": summarize_results([json.loads(f.read_text()) for f in files]),
        }
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(data, indent=1) + "\n")
        print(f"wrote {out}")
        return 0
    if args.all:
        if args.what != "min-detectable":
            ap.error("--all only applies to min-detectable")
        command = f"python -m studies.diagnosis.kpis min-detectable --all --seeds {args.seeds}"
        limits = detectability_limits(args.seeds, log=lambda msg: print(msg, flush=True))
        table = env_table(limits, command, args.seeds)
        out = args.out or ENV_TABLE
        out.parent.mkdir(parents=True, exist_ok=True)
        out.write_text(json.dumps(table, indent=1) + "\n")
        print("| fault | limit | unit | table | limit/table |\n|---|---|---|---|---|")
        for f, v in table["faults"].items():
            lim = f"{v['limit']:.3g}" + ("" if v["detected"] else " (not detected)")
            print(f"| {f} | {lim} | {v['unit']} | {v['table_magnitude']:g} | {v['ratio_to_table']:.3g} |")
        print(f"wrote {out}")
        return 0
    if args.what == "seal-leak-snr" and args.diagnoser != "reference":
        ap.error("seal-leak-snr looks at the reference's residuals and thresholds: no --diagnoser")
    extra = "" if args.diagnoser == "reference" else f" --diagnoser {args.diagnoser}"
    if args.what == "false-alarms":  # both diagnosers from one simulation
        if not args.hours > 0:
            ap.error("--hours must be > 0")
        both = false_alarms(args.hours)
        for name, result in both.items():
            data = {
                "what": args.what,
                "diagnoser": name,
                "hours": args.hours,
                "params": PARAMS,
                "command": f"python -m studies.diagnosis.kpis false-alarms --hours {args.hours:g}",
                "result": result,
            }
            out = Path("docs/data") / f"{_PREFIX[name]}_{args.what}.json"
            out.parent.mkdir(parents=True, exist_ok=True)
            out.write_text(json.dumps(data, indent=1) + "\n")
            print(f"{name}: {result['runs_with_false_alarm']} of {result['runs']} runs with an alarm; wrote {out}")
        return 0
    else:
        size = f"--seeds {args.seeds}"
        fn = {
            "delays": single_fault_delays,
            "scenarios": scenario_checks,
            "min-detectable": min_detectable,
            "seal-leak-snr": seal_leak_snr,
        }[args.what]
        if args.what == "scenarios":
            first = 20_000 if args.first_seed is None else args.first_seed
            size += f" --first-seed {first}" + ("" if args.cells == DEFAULT_CELLS else f" --cells {args.cells}")
            result = scenario_checks(args.seeds, first, diagnoser=args.diagnoser, cells=args.cells)
        elif args.first_seed is not None or args.cells != DEFAULT_CELLS:
            ap.error("--first-seed and --cells apply to scenarios only")
        else:
            result = fn(args.seeds) if args.what == "seal-leak-snr" else fn(args.seeds, diagnoser=args.diagnoser)
    data = {
        "what": args.what,
        "diagnoser": args.diagnoser,
        "seeds": args.seeds,
        "params": PARAMS,
        "command": f"python -m studies.diagnosis.kpis {args.what} {size}{extra}",
        "result": result,
    }
    tail = "" if args.what != "scenarios" or args.cells == DEFAULT_CELLS else f"_{args.cells}"
    out = args.out or Path("docs/data") / f"{_PREFIX[args.diagnoser]}_{args.what}{tail}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(data, indent=1, default=lambda o: None if isinstance(o, float) else str(o)) + "\n")
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
