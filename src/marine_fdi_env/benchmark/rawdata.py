"""Raw-data suites in the layout of the LiU-ICE / DX'25 diagnosis competition kits.

``marine-fdi export-raw --suite NAME --out DIR`` writes a frozen suite as raw sensor samples for
diagnosers that read one sample at a time (docs/raw_data.md)::

    DIR/manifest.json          suite, sample time, the data and output columns with units, the
                               scenarios (id, data file, output file, number of samples), conventions
    DIR/data/<scenario>.csv    one row per sensor sample (100 Hz), columns: time [s],
                               fuel_setting [-] (the applied fuel setting, a known input), S1.1 ... S4.6
                               (the 19 sensors, SI units), values with 17 significant digits (the
                               simulator's numbers exactly)
    DIR/ground_truth.json      per scenario: the scenario spec, the faults (id, class, onset, magnitude,
                               end), the engine failure if the engine left its range (the data stop there)

A diagnoser answers with one file per scenario, ``output_<data file>`` (the kits' naming), one
row per data row::

    sample_time, computation_time, detection, S1.1_rank, ..., intercooler_blockage_rank, unknown_rank

* ``detection`` (0 or 1): a fault is detected at this sample;
* the 27 ranks: a non-negative ranking over the 26 fault ids and ``unknown`` (the kits' ``f_x``:
  a fault none of the known ones); they sum to 1 when ``detection`` = 1 and to 0 when it is 0;
* ``computation_time`` [s]: the diagnoser's time for this sample;
* the row of sample k may use samples 0 .. k only.

``marine-fdi predict-raw --agent NAME --data DIR --out PRED`` writes any benchmark agent's
diagnoses in that layout: the agent decides every decision period in the environment (on the
same engines, bit for bit), and its declaration holds for the samples until the next decision
(the row at a decision's sample carries that decision).  ``marine-fdi score-raw``
(:mod:`.rawscore`) scores a predictions folder.  From a belief vector ``b`` (:mod:`.hypotheses`):
``detection`` = the alarm; ranks = ``b`` over the faults and ``unknown``, divided by their sum
(all 0 without alarm).
"""

from __future__ import annotations

import hashlib
import json
import re
from pathlib import Path

import numpy as np

from .._version import __version__
from ..engine.faults import FAULT_IDS
from ..engine.sensors import SENSORS
from ..envs.hypotheses import DECLARE_THRESHOLD, N_FAULTS, UNKNOWN
from .suites import load_suite

__all__ = [
    "DATA_COLUMNS",
    "RANK_COLUMNS",
    "OUTPUT_COLUMNS",
    "scenario_stem",
    "export_raw",
    "predict_raw",
    "belief_to_dx",
    "read_manifest",
]

DATA_COLUMNS: tuple[str, ...] = ("time", "fuel_setting") + tuple(s.id for s in SENSORS)
RANK_COLUMNS: tuple[str, ...] = tuple(f"{f}_rank" for f in FAULT_IDS) + ("unknown_rank",)
OUTPUT_COLUMNS: tuple[str, ...] = ("sample_time", "computation_time", "detection") + RANK_COLUMNS
_UNITS = {
    "time": ("s", "time since the start of the scenario"),
    "fuel_setting": ("-", "applied fuel setting (after the charge-air limiter), a known input; 1 = nominal"),
}
_BATCH = 16  # engines simulated together by export-raw
_BLOCK = 1000  # samples per simulator call (progress granularity)


def scenario_stem(scenario_id: str) -> str:
    """A file-name stem for a scenario id (``thesis-6.4.1/seed0`` -> ``thesis-6.4.1__seed0``)."""
    return re.sub(r"[^A-Za-z0-9._+-]", "_", scenario_id.replace("/", "__"))


def _columns_doc() -> list[dict]:
    out = [{"name": c, "unit": _UNITS[c][0], "description": _UNITS[c][1]} for c in ("time", "fuel_setting")]
    out += [{"name": s.id, "unit": s.unit, "description": s.description, "noise_bound": s.noise_bound} for s in SENSORS]
    return out


def _manifest(suite, seed_offset: int, dt: float, entries: list[dict], source: str) -> dict:
    return {
        "format": "marine-fdi raw suite (LiU-ICE / DX'25 kit layout)",
        "package_version": __version__,
        "suite": suite.name,
        "suite_version": suite["version"],
        "seed_offset": int(seed_offset),
        "suite_source": source,
        "env": suite["env"],
        "sample_time_s": dt,
        "data_columns": _columns_doc(),
        "output_columns": list(OUTPUT_COLUMNS),
        "fault_ids": list(FAULT_IDS),
        "conventions": {
            "output_file": "output_<data file name>, one row per data row, same sample_time",
            "detection": "0 or 1 per sample: a fault is detected",
            "ranks": "non-negative ranking over the 26 fault ids and unknown (a fault none of the known ones); "
            "sum 1 when detection = 1, sum 0 when detection = 0",
            "causality": "the row of sample k may use the samples 0..k only",
            "computation_time": "seconds spent on this sample",
        },
        "built_with": f"marine-fdi export-raw --suite {suite.name}"
        + (f" --seed-offset {seed_offset}" if seed_offset else ""),
        "scenarios": entries,
    }


def read_manifest(data_dir: "str | Path") -> dict:
    from ..jsonfile import read_json

    p = Path(data_dir) / "manifest.json"
    if not p.is_file():
        raise ValueError(f"{data_dir}: no manifest.json (not a folder written by 'marine-fdi export-raw')")
    m = read_json(p, "raw-suite manifest")
    if not isinstance(m, dict) or "scenarios" not in m or "suite" not in m:
        raise ValueError(f"{p}: not a raw-suite manifest (no 'suite' or 'scenarios')")
    return m


def _check_names(scenarios) -> None:
    stems = [scenario_stem(s.scenario_id) for s in scenarios]
    if len(set(stems)) != len(stems):
        raise ValueError("two scenario ids map to the same file name; rename the scenarios")


def _write_csv(path: Path, header: tuple[str, ...], arr: np.ndarray, fmt: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    with tmp.open("w") as fh:
        np.savetxt(fh, arr, fmt=fmt, delimiter=",", header=",".join(header), comments="")
    tmp.replace(path)


# ----------------------------------------------------------------------------- export-raw
def export_raw(suite_name: str, out_dir: "str | Path", *, seed_offset: int = 0, progress: bool = True) -> dict:
    """Write a suite's raw samples and ground truth (module docstring); resumable; returns the manifest."""
    from ..engine.simulator import Simulator
    from ..progress import progress_bar
    from .evaluate import offset_scenario

    suite = load_suite(suite_name)
    env = suite["env"]
    scenarios = [offset_scenario(s, seed_offset) for s in suite.scenarios]
    _check_names(scenarios)
    dt = float(env.get("dt", 0.01))
    out = Path(out_dir)
    (out / "data").mkdir(parents=True, exist_ok=True)
    key = hashlib.sha256(json.dumps([s.to_dict() for s in scenarios], sort_keys=True).encode()).hexdigest()
    stamp = out / ".export-raw.json"
    if stamp.is_file():
        old = json.loads(stamp.read_text())
        if old.get("key") != key:
            raise ValueError(
                f"{out} holds an export of another suite or seed offset ({old.get('suite')}); remove it "
                "or choose another --out"
            )
    else:
        stamp.write_text(json.dumps({"suite": suite.name, "seed_offset": seed_offset, "key": key}) + "\n")
    truth_file = out / "ground_truth.partial.json"
    truth: dict[str, dict] = json.loads(truth_file.read_text()) if truth_file.is_file() else {}
    todo = [
        s
        for s in scenarios
        if not (out / "data" / f"{scenario_stem(s.scenario_id)}.csv").is_file() or s.scenario_id not in truth
    ]
    bar = progress_bar(len(scenarios), len(scenarios) - len(todo), f"export-raw {suite.name}", progress, "scenario")
    try:
        for start in range(0, len(todo), _BATCH):
            chunk = todo[start : start + _BATCH]
            sim = Simulator(
                env.get("params", "thesis-12v28"),
                n_engines=len(chunk),
                seeds=[s.noise_seed for s in chunk],
                faults=[list(s.faults) for s in chunk],
                profiles=[s.profile for s in chunk],
                dt=dt,
                noise_scale=chunk[0].noise_scale,
            )
            K = max(int(round(s.duration_s / dt)) for s in chunk)
            Y = np.empty((len(chunk), K + 1, len(SENSORS)))
            U = np.empty((len(chunk), K + 1))
            Y[:, 0], U[:, 0] = sim.y, sim.u
            done = 0
            while done < K:
                m = min(_BLOCK, K - done)
                blk = sim.advance(m)
                Y[:, done + 1 : done + 1 + m] = blk.measurements
                U[:, done + 1 : done + 1 + m] = blk.u
                done += m
                bar.advance(len(chunk) * m / K * 0.8)
            fails = {f.engine: f for f in sim.failures}
            for i, sc in enumerate(chunk):
                n = int(round(sc.duration_s / dt)) + 1
                fail = fails.get(i)
                if fail is not None:  # the data stop at the sample where the engine left its range
                    n = min(n, int(round(fail.time_s / dt)) + 1)
                t = dt * np.arange(n)
                arr = np.column_stack([t, U[i, :n], Y[i, :n]])
                stem = scenario_stem(sc.scenario_id)
                _write_csv(out / "data" / f"{stem}.csv", DATA_COLUMNS, arr, "%.17g")
                truth[sc.scenario_id] = {
                    "scenario_id": sc.scenario_id,
                    "data_file": f"data/{stem}.csv",
                    "output_file": f"output_{stem}.csv",
                    "n_samples": n,
                    "duration_s": float(t[-1]),
                    "profile": sc.profile,
                    "noise_seed": int(sc.noise_seed),
                    "faults": sc.truth(),
                    "scenario": sc.to_dict(),
                    "engine_failure": None if fail is None else {"time_s": fail.time_s, "reason": fail.reason},
                }
                truth_file.write_text(json.dumps(truth))
                bar.advance(0.2)
    finally:
        bar.close()
    entries = [
        {k: truth[s.scenario_id][k] for k in ("scenario_id", "data_file", "output_file", "n_samples")}
        for s in scenarios
    ]
    from .suites import SUITE_NAMES

    source = suite_name if suite_name in SUITE_NAMES else str(Path(suite_name).resolve())
    manifest = _manifest(suite, seed_offset, dt, entries, source)
    (out / "ground_truth.json").write_text(
        json.dumps(
            {"suite": suite.name, "seed_offset": seed_offset, "scenarios": [truth[s.scenario_id] for s in scenarios]},
            indent=1,
        )
        + "\n"
    )
    (out / "manifest.json").write_text(json.dumps(manifest, indent=1) + "\n")
    truth_file.unlink(missing_ok=True)
    return manifest


# ----------------------------------------------------------------------------- predict-raw
def belief_to_dx(beliefs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(detection (n,), ranks (n, 27)) of belief vectors (n, 28): detection = the alarm, ranks =
    the beliefs on the faults and ``unknown`` divided by their sum (0 without alarm)."""
    b = np.asarray(beliefs, dtype=np.float64)
    alarm = (b[:, :N_FAULTS] >= DECLARE_THRESHOLD).any(axis=1) | (b[:, UNKNOWN] >= DECLARE_THRESHOLD)
    r = np.concatenate([b[:, :N_FAULTS], b[:, UNKNOWN : UNKNOWN + 1]], axis=1).clip(0.0, None)
    s = r.sum(axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        ranks = np.where(alarm[:, None] & (s > 0), r / s, 0.0)
    return alarm.astype(np.int64), ranks


def _prediction_rows(n: int, dt: float, decisions: list) -> np.ndarray:
    """The output rows (n, len(OUTPUT_COLUMNS)) of one scenario from its decisions (t, belief, compute_s)."""
    t = dt * np.arange(n)
    rows = np.zeros((n, len(OUTPUT_COLUMNS)))
    rows[:, 0] = t
    if not decisions:
        return rows
    dt_dec = np.array([d[0] for d in decisions])
    det, ranks = belief_to_dx(np.stack([d[1] for d in decisions]))
    comp = np.array([d[2] for d in decisions])
    idx = np.searchsorted(dt_dec, t + 1e-9, side="right") - 1  # the last decision at or before each sample
    ok = idx >= 0
    held = np.bincount(idx[ok], minlength=len(decisions))  # samples each decision's declaration holds for
    rows[ok, 1] = comp[idx[ok]] / np.maximum(held[idx[ok]], 1)
    rows[ok, 2] = det[idx[ok]]
    rows[ok, 3:] = ranks[idx[ok]]
    return rows


def predict_raw(
    agent_spec: str, data_dir: "str | Path", out_dir: "str | Path", *, batch_size: int = 32, progress: bool = True
) -> Path:
    """Write ``agent_spec``'s diagnoses of the raw suite in ``data_dir`` in the output layout; resumable."""
    from ..progress import progress_bar
    from .agent_api import load_agent
    from .evaluate import run_episodes

    man = read_manifest(data_dir)
    suite = load_suite(man.get("suite_source", man["suite"]))
    by_id = {s.scenario_id: s for s in suite.scenarios}
    entries = man["scenarios"]
    missing = [e["scenario_id"] for e in entries if e["scenario_id"] not in by_id]
    if missing:
        raise ValueError(f"{data_dir}/manifest.json: scenarios not in suite {suite.name}: {missing[:5]}")
    dt = float(man["sample_time_s"])
    out = Path(out_dir)
    agent = load_agent(agent_spec)
    out.mkdir(parents=True, exist_ok=True)
    todo = [e for e in entries if not (out / e["output_file"]).is_file()]
    if todo:
        from .evaluate import warm_up

        warm_up(dict(suite["env"]))  # compilation stays out of the computation_time column
    bar = progress_bar(len(entries), len(entries) - len(todo), f"predict-raw {agent.name}", progress, "scenario")
    try:
        for start in range(0, len(todo), batch_size):
            chunk = todo[start : start + batch_size]
            decisions: dict[str, list] = {e["scenario_id"]: [] for e in chunk}

            def on_decision(sid, t, belief, compute_s):
                if sid in decisions:
                    decisions[sid].append((t, np.array(belief, dtype=np.float64), compute_s))

            run_episodes(
                agent,
                [by_id[e["scenario_id"]] for e in chunk],
                dict(suite["env"]),
                suite=suite.name,
                seed_offset=int(man.get("seed_offset", 0)),
                batch_size=len(chunk),
                on_decision=on_decision,
                progress=bar.advance,
            )
            for e in chunk:
                rows = _prediction_rows(int(e["n_samples"]), dt, decisions[e["scenario_id"]])
                _write_csv(
                    out / e["output_file"],
                    OUTPUT_COLUMNS,
                    rows,
                    ",".join(["%.17g", "%.9g", "%d"] + ["%.17g"] * len(RANK_COLUMNS)),
                )
    finally:
        bar.close()
    (out / "predictions.json").write_text(
        json.dumps(
            {
                "agent": agent.name,
                "agent_spec": str(agent_spec),
                "suite": suite.name,
                "seed_offset": int(man.get("seed_offset", 0)),
                "written_by": "marine-fdi predict-raw",
            },
            indent=1,
        )
        + "\n"
    )
    return out
