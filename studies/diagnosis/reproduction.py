"""The thesis's chapter 6, claim by claim: every checkable claim (:mod:`.thesis_claims`) measured for the
reference, each reading of its observer thresholds and the sequential diagnoser, with a verdict.

    python -m studies.diagnosis.reproduction                         # measure what is missing, write the table
    python -m studies.diagnosis.reproduction --columns local sequential   # some columns only
    python -m studies.diagnosis.reproduction --render-only           # rewrite docs/reproduction.md from results/

Columns (:data:`COLUMNS`): ``local`` (the reference as it ships: `reference`), the readings
``thesis-lipschitz``, ``thesis-no-interconnection``, ``thesis-table-6.1``, ``thesis-table-6.1-m4``
(:mod:`marine_fdi_env.diagnosis.thresholds`, each with the cells measured at its thresholds) and
``sequential``.  What each column measures (:func:`measure_column`), all at constant fuel setting 1.0
(the thesis's runs) unless said, 300 s runs (the thesis's length):

* the 19 sensor offsets (6.1) at the table 6.3 size with ``--kpi-seeds`` noise seeds (100, the thesis's
  K of eq. 6.1-6.2; the KPI 6.5.1 spreads come from these runs) and at the thesis's "X % of the maximum
  measurement" read by its noise rule (noise = 3 % of the maximum, so X % is X/3 noise bounds) with
  ``--seeds`` seeds; onset 30 s;
* the 7 process faults (6.2) at their table 6.4 sizes and onsets, ``--seeds`` seeds;
* the four examples of 6.4, ``--seeds`` seeds, the minimal diagnoses with the column's sized cells at
  the end and at the time of the thesis's interim set;
* table 6.10 (:func:`~.kpis.detectability_limits` of the process faults, ``--limit-seeds`` seeds);
* false alarms: ``--hours`` fault-free engine-hours over the five profile families
  (:func:`~.kpis.false_alarms`);
* the column's agent (``reference``, ``reference-lipschitz``, ..., ``sequential``) on every frozen
  suite (``marine-fdi evaluate``, records in ``results/reproduction/suites/``): what a reading costs
  in isolation and false alarms where the benchmark scores it.

Seeds: ``--first-seed`` (4,000,000) onwards and fault-free entropy 9.5e9 onwards, disjoint from every
seed any setting of the diagnosers or of the readings was chosen on (the certainty grid 1e6-3e6, the
examples 0-49 and 1000-1049, the KPI commands 10,000-80,000, the calibration and false-alarm sets
6e9-9e9 + 2400).  Each column's measurements are kept in ``results/reproduction/COLUMN.json`` (a
column already measured with the same settings is not measured again); the table
(docs/reproduction.md) and its JSON (docs/data/reproduction.json) are written from them.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

from marine_fdi_env.diagnosis.batch import diagnose_batch
from marine_fdi_env.diagnosis.modules import MODULE_IDS, MODULES
from marine_fdi_env.diagnosis.thresholds import DEFAULT_THRESHOLDS, THRESHOLD_READINGS
from marine_fdi_env.engine.faults import PROCESS_FAULT_DEFAULTS, PROCESS_FAULT_IDS, FaultSpec
from marine_fdi_env.engine.sensors import SENSOR_IDS, SENSORS
from marine_fdi_env.scenarios import SCENARIOS, get_scenario

from .kpis import SENSOR_ONSET_S, detectability_limits, false_alarms

__all__ = ["COLUMNS", "measure_column", "sensor_sizes", "main"]

COLUMNS = THRESHOLD_READINGS + ("sequential",)
FIRST_SEED = 4_000_000
FA_ENTROPY0 = 9_500_000_000
WORK = Path("results/reproduction")
NOISE_SHARE_OF_MAX = 0.03  # thesis chapter 6: noise is 3 % of the maximum amplitude of the noiseless measurement


def column_options(column: str) -> dict:
    """The :func:`~marine_fdi_env.diagnosis.batch.diagnose_batch` options of a column."""
    if column == "sequential":
        return {"diagnoser": "sequential"}
    if column not in THRESHOLD_READINGS:
        raise ValueError(f"column must be one of {', '.join(COLUMNS)}, got {column!r}")
    return {} if column == DEFAULT_THRESHOLDS else {"thresholds": column}


def own_module(sensor: str) -> str:
    """The module whose ARR checks ``sensor`` (table 6.2)."""
    return next(m.id for m in MODULES if m.checked_sensor == sensor)


def sensor_sizes(pct_of_max: dict[str, float | None]) -> dict[str, dict[str, float]]:
    """Per sensor the sizes its 6.1 claim is measured at: ``table`` (table 6.3) and, where the thesis
    gives a percentage of the maximum measurement, ``noise-rule`` (that percentage of d̄/0.03)."""
    out = {}
    for s in SENSORS:
        sizes = {"table": float(s.fault_magnitude)}
        pct = pct_of_max.get(s.id)
        if pct is not None:
            sizes["noise-rule"] = float(pct) / 100.0 * float(s.noise_bound) / NOISE_SHARE_OF_MAX
        out[s.id] = sizes
    return out


def _fault_runs(jobs: list[tuple[str, str, float]], n_seeds: int, seed0: int, options: dict) -> dict:
    """Module firing times [s after the onset, None: never] of every (fault, size label, magnitude) job
    over ``n_seeds`` seeds, exoneration none (the firing times do not depend on the decision logic)."""
    schedules, seeds, keys = [], [], []
    for j, (f, label, mag) in enumerate(jobs):
        on = PROCESS_FAULT_DEFAULTS[f].onset_s if f in PROCESS_FAULT_DEFAULTS else SENSOR_ONSET_S
        kind = None if f in PROCESS_FAULT_DEFAULTS else "offset"
        for s in range(n_seeds):
            schedules.append([FaultSpec(f, on, magnitude=mag, kind=kind)])
            seeds.append(seed0 + 1000 * j + s)
            keys.append((f, label, on))
    reps = diagnose_batch(schedules, seeds, "constant", exoneration="none", **options)
    out: dict = {}
    for (f, label, on), r, sd in zip(keys, reps, seeds):
        e = out.setdefault(f, {}).setdefault(label, {"onset_s": on, "seeds": [], "first_s": [], "modules_s": []})
        e["seeds"].append(sd)
        e["first_s"].append(None if not r["detected"] else r["first_detection_time_s"] - on)
        e["modules_s"].append(
            [
                None if r["module_detection_times_s"][m] is None else r["module_detection_times_s"][m] - on
                for m in MODULE_IDS
            ]
        )
    for f, labels in out.items():
        for label, e in labels.items():
            e["magnitude"] = next(m for ff, lab, m in jobs if ff == f and lab == label)
    return out


def _interim_times() -> dict[str, float]:
    """Per example the time its interim diagnosis set is read at: 1 s before the end of the interval
    the thesis states it for (the next event, the time of its final set)."""
    from .thesis_claims import claims

    final = {c.scenario: c.time_s for c in claims("final_set")}
    return {c.scenario: float(math.floor(final[c.scenario]) - 1.0) for c in claims("interim_set")}


def _scenario_runs(n_seeds: int, seed0: int, options: dict) -> dict:
    """The four examples of 6.4 over ``n_seeds`` seeds (``marine-fdi simulate --scenario NAME --seed
    S``), exoneration by the column's sized cells: per run the module firing times [s, absolute], the
    first detection, the minimal diagnoses at the interim time (:func:`_interim_times`) and at the end."""
    interim = _interim_times()
    out = {}
    for k, name in enumerate(SCENARIOS):
        sc = get_scenario(name)
        seeds = [seed0 + 1000 * k + i for i in range(n_seeds)]
        at = interim.get(name)
        seen: list = [None] * n_seeds

        def grab(agent, engines, blk, at=at, seen=seen):
            if at is not None and blk.t[0] <= at + 1e-9 <= blk.t[-1] + 1e-9:
                for j, i in enumerate(range(engines.start, engines.stop)):
                    seen[i] = [sorted(d) for d in agent.diagnoses(j)] if agent.detected[j] else []

        reps = diagnose_batch(
            [sc.fault_specs()] * n_seeds, seeds, sc.profile, sc.duration_s, block_samples=100, on_block=grab, **options
        )
        out[name] = {
            "faults": [f.to_dict() for f in sc.fault_specs()],
            "interim_at_s": at,
            "runs": [
                {
                    "seed": sd,
                    "first_s": r["first_detection_time_s"] if r["detected"] else None,
                    "modules_s": [r["module_detection_times_s"][m] for m in MODULE_IDS],
                    "final": r["final_minimal_diagnoses"],
                    "interim": seen[i],
                }
                for i, (sd, r) in enumerate(zip(seeds, reps))
            ],
        }
    return out


def column_agent(column: str) -> str:
    """The benchmark agent of a column: ``reference``, ``reference-lipschitz``, ..., ``sequential``."""
    if column in ("sequential", DEFAULT_THRESHOLDS):
        return "sequential" if column == "sequential" else "reference"
    return "reference-" + column.removeprefix("thesis-")


def _suite_metrics(column: str, folder: Path) -> dict:
    """The column's agent on every frozen suite (``marine-fdi evaluate``): per suite the episodes,
    faulty episodes, exact isolations, detections and false alarms (the records in ``folder``)."""
    from marine_fdi_env.benchmark.evaluate import evaluate_agents
    from marine_fdi_env.benchmark.suites import SUITE_NAMES

    agent = column_agent(column)
    folder.mkdir(parents=True, exist_ok=True)
    out = {}
    for suite in SUITE_NAMES:
        path = folder / f"{agent}_{suite}.json"
        res = evaluate_agents([agent], suite, [path], progress=False)[0]
        m = res["metrics"]
        out[suite] = {
            "episodes": m["n_episodes"],
            "faulty": m["n_faulty"],
            "isolated": int(round(m["isolation_accuracy"] * m["n_faulty"])) if m["n_faulty"] else 0,
            "detected": int(round(m["detection_rate"] * m["n_faulty"])) if m["n_faulty"] else 0,
            "false_alarms": m["n_false_alarms"],
            "fault_free_hours": m["fault_free_hours"],
            "false_alarm_episodes": int(round(m["false_alarm_episode_rate"] * m["n_episodes"])),
        }
    return out


def measure_column(
    column: str,
    pct_of_max: dict[str, float | None],
    seeds: int,
    kpi_seeds: int,
    limit_seeds: int,
    hours: float,
    first_seed: int = FIRST_SEED,
    suite_dir: Path = WORK / "suites",
    log=print,
) -> dict:
    """Every measurement of one column (module docstring); timings in ``cpu_s``."""
    opts = column_options(column)
    thresholds = opts.get("thresholds", DEFAULT_THRESHOLDS)
    diagnoser = opts.get("diagnoser", "reference")
    out: dict = {"column": column, "options": opts, "cpu_s": {}}
    sizes = sensor_sizes(pct_of_max)

    def timed(name, fn):
        c0 = time.process_time()
        w0 = time.time()
        r = fn()
        out["cpu_s"][name] = round(time.process_time() - c0, 1)
        log(f"{column}: {name} in {time.time() - w0:.0f} s")
        return r

    table_jobs = [(s, "table", sizes[s]["table"]) for s in SENSOR_IDS]
    out["sensor"] = timed("sensor_table", lambda: _fault_runs(table_jobs, kpi_seeds, first_seed, opts))
    rule_jobs = [(s, "noise-rule", v["noise-rule"]) for s, v in sizes.items() if "noise-rule" in v]
    if rule_jobs:
        rule = timed("sensor_noise_rule", lambda: _fault_runs(rule_jobs, seeds, first_seed + 100_000, opts))
        for s, labels in rule.items():
            out["sensor"][s].update(labels)
    proc_jobs = [(f, "table", PROCESS_FAULT_DEFAULTS[f].magnitude) for f in PROCESS_FAULT_IDS]
    out["process"] = timed("process", lambda: _fault_runs(proc_jobs, seeds, first_seed + 200_000, opts))
    out["scenarios"] = timed("scenarios", lambda: _scenario_runs(seeds, first_seed + 300_000, opts))
    out["min_detectable"] = timed(
        "min_detectable",
        lambda: detectability_limits(
            limit_seeds,
            fault_ids=PROCESS_FAULT_IDS,
            first_seed=first_seed + 400_000,
            rtol=1.1,
            diagnoser=diagnoser,
            thresholds=thresholds,
        ),
    )
    fa = timed("false_alarms", lambda: false_alarms(hours, FA_ENTROPY0, thresholds=thresholds))
    out["false_alarms"] = fa["sequential" if column == "sequential" else "reference"]
    out["suites"] = timed("suites", lambda: _suite_metrics(column, suite_dir))
    return out


def _settings(args) -> dict:
    return {
        "seeds": args.seeds,
        "kpi_seeds": args.kpi_seeds,
        "limit_seeds": args.limit_seeds,
        "hours": args.hours,
        "first_seed": args.first_seed,
    }


def main(argv=None) -> int:
    from .thesis_claims import claims

    ap = argparse.ArgumentParser(prog="python -m studies.diagnosis.reproduction", description=__doc__.splitlines()[0])
    ap.add_argument("--columns", nargs="+", choices=COLUMNS, default=list(COLUMNS))
    ap.add_argument("--seeds", type=int, default=50, help="noise seeds per fault, size and example (default 50)")
    ap.add_argument(
        "--kpi-seeds", type=int, default=100, help="noise seeds of the table-size sensor offsets (KPI 6.5.1)"
    )
    ap.add_argument("--limit-seeds", type=int, default=20, help="seeds of the table 6.10 bisection (default 20)")
    ap.add_argument("--hours", type=float, default=200.0, help="fault-free engine-hours per column (default 200)")
    ap.add_argument("--first-seed", type=int, default=FIRST_SEED)
    ap.add_argument("--work-dir", type=Path, default=WORK)
    ap.add_argument("--render-only", action="store_true", help="only write the table from the measured columns")
    ap.add_argument("--force", action="store_true", help="measure the columns again")
    args = ap.parse_args(argv)
    for name in ("seeds", "kpi_seeds", "limit_seeds"):
        if getattr(args, name) < 2:
            ap.error(f"--{name.replace('_', '-')} must be >= 2")
    if not args.hours > 0:
        ap.error("--hours must be > 0")
    settings = _settings(args)
    pct = {c.fault: c.size_pct_of_max for c in claims("sensor_detection")}
    args.work_dir.mkdir(parents=True, exist_ok=True)
    if not args.render_only:
        for col in args.columns:
            path = args.work_dir / f"{col}.json"
            if path.exists() and not args.force:
                old = json.loads(path.read_text())
                if old.get("settings") == settings:
                    print(f"{col}: measured ({path})")
                    continue
            data = measure_column(
                col,
                pct,
                args.seeds,
                args.kpi_seeds,
                args.limit_seeds,
                args.hours,
                args.first_seed,
                suite_dir=args.work_dir / "suites",
            )
            data["settings"] = settings
            path.write_text(json.dumps(data) + "\n")
            print(f"wrote {path}")
    from .reproduction_table import write_table

    return write_table(args.work_dir, settings)


if __name__ == "__main__":
    sys.exit(main())
