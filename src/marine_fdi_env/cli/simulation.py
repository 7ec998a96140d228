"""``marine-fdi operating-point``, ``simulate``, ``params``, ``scenarios`` and ``info``: the engine model and its
run files.

marine-fdi operating-point --params thesis-12v28 --fuel-setting 1.0 [--json]
marine-fdi simulate --duration 300 --seed 0 --fault S4.2@235:5e4 --out run.npz
marine-fdi simulate --scenario thesis-6.4.1 --out run.npz
marine-fdi params [--name thesis-12v28] [--json]
marine-fdi scenarios [--json]
marine-fdi info run.npz [--json] [--allow-nonfinite]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import textwrap
from importlib import resources
from pathlib import Path
from typing import Sequence

import numpy as np

from ..engine.faults import PROCESS_FAULT_IDS, FaultSpec, parse_fault_spec
from ..engine.params import list_parameter_sets, load_params, params_provenance
from ..engine.profiles import Profile, make_profile
from ..engine.steady_state import check_fuel_setting
from ..errors import UsageError
from ..scenarios import SCENARIOS, get_scenario
from .common import PROG, dumps, option_value, positive_seconds

DEFAULT_PARAMS = "thesis-12v28"


# Runs with at least this many samples per engine show a progress bar even when stderr is not a terminal.
LONG_RUN_STEPS = 10_000
# what a run costs (benchmarks/costs.py): simulated engine-samples per CPU second of a whole `simulate` (the
# batched simulator, recording and saving) and bytes of the compressed run file per engine-sample
SIMULATED_SAMPLES_PER_CPU_S = 1.25e5
RUN_FILE_BYTES_PER_ENGINE_SAMPLE = 143


FAULT_SPEC_HELP = """\
fault SPEC syntax:  ID@ONSET[:MAGNITUDE][,kind=K,end=T,period=P,duty=D,kappa=R]
  ID         a sensor id (S1.1 ... S4.6) or a process fault id:
{process}
  ONSET      start of the fault [s]
  MAGNITUDE  fault function parameter in SI units (default: thesis tables 6.3/6.4)
  kind=      sensor faults: offset (default), drift, stuck, gain, precision
  end=       end of the fault [s] (default: permanent)
  period=, duty=   intermittent fault: active duty*period seconds every period seconds
  kappa=     evolution rate [1/s] of beta(s) = 1 - exp(-kappa s) (default: abrupt for sensors,
             table 6.4 for process faults)
examples:  S4.2@235:5e4   S3.4@175   bore_damage@5   S2.1@20:3e4,kind=drift
           S1.1@50,kind=offset,end=80   S3.3@10,period=20,duty=0.25   valve_seizing@20:0.1,kappa=0.05
""".format(
    process=textwrap.fill(", ".join(PROCESS_FAULT_IDS), width=90, initial_indent=" " * 13, subsequent_indent=" " * 13)
)


PROFILE_HELP = """\
profile: a constant fuel setting (e.g. 0.8) or NAME[:key=value,...] with NAME one of
  constant:u0=1.0   step:u0=0.8,u1=1.0,t=100   ramp:u0=0.6,u1=1.0,t0=50,t1=150
  manoeuvring[:scale=1]   random:seed=0,u_min=0.4,u_max=1.05,dwell=40,rate=0.02
  harbour:seed=0,u_min=0.3,u_max=1.0,dwell=30,rate=0.1   seastate:seed=0,u_mean=0.8,amplitude=0.05,period=9
"""


def scenario_help() -> str:
    lines = [
        "scenarios (--scenario NAME; --duration, --profile, --params override the scenario's values,",
        "--fault adds faults):",
    ]
    for s in SCENARIOS.values():
        lines.append(f"  {s.name:<14} {' + '.join(s.faults)}, {s.duration_s:g} s, {s.profile}, {s.params}")
    return "\n".join(lines) + "\n"


# ----------------------------------------------------------------------------- operating-point
_UNIT_SUFFIXES = (
    ("_kg_per_J", "kg/J"),
    ("_rev_s", "rev/s"),
    ("_kg_s", "kg/s"),
    ("_Nm", "N m"),
    ("_Pa", "Pa"),
    ("_kg", "kg"),
    ("_W", "W"),
    ("_K", "K"),
)


# a second, conventional unit for the human table: (factor, offset, unit)
_PRACTICAL = {
    "rev/s": (60.0, 0.0, "rpm"),
    "W": (1e-3, 0.0, "kW"),
    "Pa": (1e-5, 0.0, "bar"),
    "K": (1.0, -273.15, "degC"),
    "kg/J": (3.6e9, 0.0, "g/kWh"),
    "N m": (1e-3, 0.0, "kN m"),
    "kg": (1e3, 0.0, "g"),
}


def _split_unit(key: str) -> tuple[str, str]:
    for suffix, unit in _UNIT_SUFFIXES:
        if key.endswith(suffix):
            return key[: -len(suffix)], unit
    return key, "-"


def cmd_operating_point(args: argparse.Namespace) -> int:
    params = option_value("--params", load_params, args.params)
    u = float(check_fuel_setting(args.fuel_setting, "--fuel-setting"))
    from ..engine.model import EngineModel
    from ..engine.steady_state import steady_state

    with np.errstate(all="ignore"):
        ss = steady_state(EngineModel(params), u)
        summary = ss.summary(params)
    summary.pop("fuel_setting", None)
    out = {"params": params.name, "fuel_setting": u, **summary, "converged": bool(ss.converged[0])}
    if not out["converged"]:
        print(f"{PROG}: warning: the steady-state solver did not converge at fuel setting {u:g}", file=sys.stderr)
    if not out["engine_speed_rev_s"] > 0:
        print(f"{PROG}: warning: the engine does not run at fuel setting {u:g} (speed 0)", file=sys.stderr)
    else:
        from ..engine.envelope import envelope_warnings

        for text in envelope_warnings(out["engine_speed_rev_s"], out["sfc_kg_per_J"], params.n_nom_rev_s):
            print(
                f"{PROG}: warning: fuel setting {u:g} is outside {params.name}'s operating envelope: {text}",
                file=sys.stderr,
            )
    if args.json:
        print(dumps(out))
        return 0
    print(f"Steady state of {params.name} at fuel setting {u:g}{'' if out['converged'] else ' (NOT converged)'}")
    rows = []
    for key, value in out.items():
        if key in ("params", "fuel_setting", "converged"):
            continue
        label, unit = _split_unit(key)
        practical = ""
        if unit in _PRACTICAL and math.isfinite(value):
            f, off, pu = _PRACTICAL[unit]
            practical = f"{value * f + off:.6g} {pu}"
        rows.append((label.replace("_", " "), f"{value:.6g}", unit, practical))
    w0 = max(len(r[0]) for r in rows)
    w1 = max(len(r[1]) for r in rows)
    w2 = max(len(r[2]) for r in rows)
    for label, value, unit, practical in rows:
        line = f"  {label:<{w0}}  {value:>{w1}}  {unit:<{w2}}"
        print(f"{line}  ({practical})" if practical else line.rstrip())
    return 0


# ----------------------------------------------------------------------------- simulate
def _make_profile(text: str, duration_s: float) -> Profile:
    try:
        value = float(text)
    except ValueError:
        return option_value("--profile", make_profile, text, duration_s=duration_s)
    return option_value("--profile", make_profile, value)


def _describe_fault(spec: FaultSpec) -> str:
    d = spec.to_dict()
    mag = d["magnitude"]
    parts = [f"{spec.fault_id}@{spec.onset_s:g}"] + ([d["kind"]] if d["class"] == "sensor" else [])
    if not (isinstance(mag, float) and math.isnan(mag)):
        from ..runio import fault_unit

        unit = fault_unit(spec)
        parts.append(f"magnitude {mag:g}{'' if unit == '-' else ' ' + unit}")
    if d["end_s"] is not None:
        parts.append(f"end {d['end_s']:g} s")
    if d["period_s"] is not None:
        parts.append(f"period {d['period_s']:g} s duty {d['duty']:g}")
    return " ".join(parts)


def _want_progress(flag: bool | None, steps: int) -> bool:
    if flag is not None:
        return flag
    try:
        tty = sys.stderr.isatty()
    except (AttributeError, ValueError):
        tty = False
    return tty or steps >= LONG_RUN_STEPS


def cmd_simulate(args: argparse.Namespace, argv: Sequence[str]) -> int:
    from ..engine.simulator import Simulator
    from ..runio import save_run

    scen = option_value("--scenario", get_scenario, args.scenario) if args.scenario is not None else None
    params = option_value("--params", load_params, args.params or (scen.params if scen else DEFAULT_PARAMS))
    if args.duration is None and scen is None:
        raise UsageError("--duration is required: the simulated time in seconds (> 0), unless --scenario gives one")
    duration = positive_seconds("--duration", args.duration if args.duration is not None else scen.duration_s)
    dt = positive_seconds("--dt", args.dt)
    if duration < dt:
        raise UsageError(f"--duration ({duration:g} s) must be at least one sample time --dt ({dt:g} s)")
    if args.engines < 1:
        raise UsageError(f"--engines must be a positive integer, got {args.engines}")
    from ..costs import check_memory
    from ..engine.simulator import RESULT_BYTES_PER_ENGINE_SAMPLE

    samples = (int(round(duration / dt)) + 1) * args.engines
    check_memory(
        samples * RESULT_BYTES_PER_ENGINE_SAMPLE * 1.1,
        f"{args.engines} engines x {duration:g} s at --dt {dt:g} s",
        "--engines",
    )
    if args.seed < 0:
        raise UsageError(f"--seed must be a non-negative integer, got {args.seed}")
    if not (math.isfinite(args.noise_scale) and args.noise_scale >= 0):
        raise UsageError(
            f"--noise-scale must be a finite number >= 0 (1 = table 6.3 noise, 0 = noise-free), "
            f"got {args.noise_scale!r}"
        )

    specs: list[FaultSpec] = scen.fault_specs() if scen else []
    for text in args.fault or []:
        spec = option_value(f"--fault {text}", parse_fault_spec, text)
        clash = [s for s in specs if s.fault_id == spec.fault_id]
        if clash:
            origin = (
                f"the scenario {scen.name} already schedules it"
                if scen and clash[0] in scen.fault_specs()
                else "it is given twice"
            )
            raise UsageError(f"--fault: fault {spec.fault_id} may be scheduled once per engine; {origin}")
        specs.append(spec)
    for s in specs:
        if s.onset_s >= duration:
            print(
                f"{PROG}: warning: fault {s.fault_id} starts at {s.onset_s:g} s, at or after the end of the "
                f"run ({duration:g} s); it will not be active",
                file=sys.stderr,
            )

    profile = _make_profile(
        args.profile if args.profile is not None else (scen.profile if scen else "constant"), duration
    )

    from ..outputs import check_suffix, prepare_out

    out = check_suffix(args.out, "--out", (".npz",), "a run file")
    out = prepare_out(out, "--out", is_dir=False, create=False)
    if out.exists() and not args.force:
        raise UsageError(f"--out {out} already exists; pass --force to overwrite it, or choose another --out")

    from ..costs import CostEstimate, say_cost

    say_cost(
        PROG + " simulate",
        f"{samples:,} engine-samples",
        CostEstimate(samples / SIMULATED_SAMPLES_PER_CPU_S, samples * RUN_FILE_BYTES_PER_ENGINE_SAMPLE),
    )
    sim = Simulator(
        params,
        n_engines=args.engines,
        seeds=args.seed,
        faults=specs,
        profiles=profile,
        dt=dt,
        noise_scale=args.noise_scale,
    )
    steps = int(round(duration / dt))
    with np.errstate(all="ignore"):
        result = sim.run(duration, progress=_want_progress(args.progress, steps))
    prepare_out(out, "--out", is_dir=False)
    save_run(result, out, command_line=[PROG, *argv], extra={"scenario": scen.name if scen else None})

    T, N = result.measurements.shape[:2]
    print(f"wrote {out}")
    print(f"  params    {params.name}{f'  (scenario {scen.name})' if scen else ''}")
    print(f"  samples   {T} per engine, t = {result.t[0]:g} ... {result.t[-1]:g} s, dt = {dt:g} s")
    seeds = ", ".join(str(s) for s in result.seeds[:8]) + (", ..." if N > 8 else "")
    print(f"  engines   {N}  (seeds {seeds}), noise scale {args.noise_scale:g}")
    print(f"  profile   {profile.name}: u(0) = {float(profile(0.0)):g}")
    if specs:
        print(f"  faults    {'; '.join(_describe_fault(s) for s in specs)}  (every engine)")
    else:
        print("  faults    none")
    if result.failures:
        for f in result.failures:
            print(f"  FAILURE   engine {f.engine} at t = {f.time_s:g} s: {f.reason}")
    else:
        print("  failures  none")
    return 0


# ----------------------------------------------------------------------------- params
def _description(name: str) -> str:
    try:
        with (resources.files("marine_fdi_env") / "data" / "params" / f"{name}.json").open() as fh:
            return str(json.load(fh).get("description", ""))
    except (OSError, ValueError):
        return ""


def cmd_params(args: argparse.Namespace) -> int:
    if args.name is None:
        names = list_parameter_sets()
        if args.json:
            print(dumps([{"name": n, "description": _description(n)} for n in names]))
            return 0
        w = max(len(n) for n in names)
        for n in names:
            print(f"{n:<{w}}  {_description(n)}")
        return 0
    p = option_value("--name", load_params, args.name)
    if args.name not in list_parameter_sets():  # a fitted-engine file: its base, overrides and submodels
        d = json.loads(Path(args.name).read_text())
        if args.json:
            print(dumps(d))
            return 0
        print(f"{p.name}: fitted engine on {d['base']} ({args.name})")
        for k, v in (d.get("overrides") or {}).items():
            print(f"  {k:<22} {v:.6g}  (base {getattr(load_params(d['base']), k):.6g})")
        for k, v in (d.get("submodels") or {}).items():
            print(f"  submodel {k}: {json.dumps(v)}")
        prov = d.get("provenance") or {}
        if prov:
            print(f"  fitted on {prov.get('dataset', '?')} ({prov.get('date', '')}): {prov.get('command', '')}")
        return 0
    prov = params_provenance(args.name)
    if args.json:
        print(dumps({"name": args.name, "description": _description(args.name), "parameters": prov}))
        return 0
    print(f"{args.name}: {_description(args.name)}")
    rows = [
        (
            k,
            f"{v['value']:.6g}" if isinstance(v["value"], float) else str(v["value"]),
            v.get("unit", ""),
            v.get("source", ""),
        )
        for k, v in prov.items()
    ]
    w0, w1, w2 = (max(len(r[i]) for r in rows) for i in range(3))
    print(f"  {'parameter':<{w0}}  {'value':>{w1}}  {'unit':<{w2}}  source")
    for k, v, u, s in rows:
        print(f"  {k:<{w0}}  {v:>{w1}}  {u:<{w2}}  {s}")
    return 0


# ----------------------------------------------------------------------------- scenarios, info
def cmd_scenarios(args: argparse.Namespace) -> int:
    if args.json:
        print(dumps([s.to_dict() for s in SCENARIOS.values()]))
        return 0
    for s in SCENARIOS.values():
        print(f"{s.name}: {' + '.join(s.faults)}  ({s.duration_s:g} s, {s.profile}, {s.params})")
        print(f"    {s.description}")
    return 0


def cmd_info(args: argparse.Namespace) -> int:
    from ..runio import load_run

    run = load_run(args.file, allow_nonfinite=args.allow_nonfinite)
    meta = run.metadata
    info = {
        "file": str(args.file),
        "params": run.params_name,
        "scenario": meta.get("scenario"),
        "n_samples": run.n_samples,
        "n_engines": run.n_engines,
        "dt_s": run.dt,
        "t_end_s": float(run.t[-1]),
        "seeds": run.seeds,
        "noise_scale": run.noise_scale,
        "nonfinite_measurements": int(np.count_nonzero(~np.isfinite(run.measurements))),
        "true_faults": run.true_faults(),
        "failures": run.failures,
        "package_version": meta.get("package_version"),
        "command_line": meta.get("command_line"),
    }
    if args.json:
        print(dumps(info))
        return 0
    for key in (
        "file",
        "params",
        "scenario",
        "n_samples",
        "n_engines",
        "dt_s",
        "t_end_s",
        "seeds",
        "noise_scale",
        "nonfinite_measurements",
        "package_version",
        "command_line",
    ):
        print(f"{key:<23} {info[key]}")
    print("true faults:" if info["true_faults"] else "true faults:            none")
    for f in info["true_faults"]:
        first = "not active in run" if f["first_active_s"] is None else f"first active at {f['first_active_s']:g} s"
        mag = "-" if f["magnitude"] is None else f"{f['magnitude']:g}{'' if f['unit'] == '-' else ' ' + f['unit']}"
        what = f"sensor {f['kind']}" if f["class"] == "sensor" else "process"
        print(f"  engine {f['engine']}: {f['id']} ({what}) onset {f['onset_s']:g} s, magnitude {mag}, {first}")
    print("failures:" if info["failures"] else "failures:               none")
    for f in info["failures"]:
        print(f"  engine {f['engine']} at {f['time_s']:g} s: {f['reason']}")
    return 0
