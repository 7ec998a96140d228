"""Command-line interface ``marine-fdi``.

Subcommands::

    marine-fdi operating-point --params thesis-12v28 --fuel-setting 1.0 [--json]
    marine-fdi simulate --duration 300 --seed 0 --fault S4.2@235:5e4 --out run.npz
    marine-fdi simulate --scenario thesis-6.4.1 --out run.npz
    marine-fdi params [--name thesis-12v28] [--json]
    marine-fdi scenarios [--json]
    marine-fdi info run.npz [--json] [--allow-nonfinite]

Invalid input ends with a one-line message on stderr naming the option and what it allows, and
exit code 2 (never a traceback).  ``main(argv)`` returns the exit code, so it can be called
in-process.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import textwrap
from importlib import resources
from pathlib import Path
from typing import Sequence

import numpy as np

from . import __version__
from .engine.faults import PROCESS_FAULT_IDS, FaultSpec, parse_fault_spec
from .engine.params import list_parameter_sets, load_params, params_provenance
from .engine.profiles import Profile, make_profile
from .scenarios import SCENARIOS, get_scenario
from .engine.steady_state import FUEL_SETTING_RANGE, check_fuel_setting

__all__ = ["main", "build_parser", "LONG_RUN_STEPS"]

PROG = "marine-fdi"
DEFAULT_PARAMS = "thesis-12v28"
# Runs with at least this many samples per engine show a progress bar even when stderr is not a terminal.
LONG_RUN_STEPS = 10_000

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
""".format(process=textwrap.fill(", ".join(PROCESS_FAULT_IDS), width=90, initial_indent=" " * 13,
                                 subsequent_indent=" " * 13))

PROFILE_HELP = """\
profile: a constant fuel setting (e.g. 0.8) or NAME[:key=value,...] with NAME one of
  constant:u0=1.0   step:u0=0.8,u1=1.0,t=100   ramp:u0=0.6,u1=1.0,t0=50,t1=150
  manoeuvring[:scale=1]   random:seed=0,u_min=0.4,u_max=1.05,dwell=40,rate=0.02
  harbour:seed=0,u_min=0.3,u_max=1.0,dwell=30,rate=0.1   seastate:seed=0,u_mean=0.8,amplitude=0.05,period=9
"""


def _scenario_help() -> str:
    lines = ["scenarios (--scenario NAME; --duration, --profile, --params override the scenario's values,",
             "--fault adds faults):"]
    for s in SCENARIOS.values():
        lines.append(f"  {s.name:<14} {' + '.join(s.faults)}, {s.duration_s:g} s, {s.profile}, {s.params}")
    return "\n".join(lines) + "\n"


class CliError(ValueError):
    """A user error; its message names the option and what is allowed."""


def _field(option: str, fn, *args, **kwargs):
    """Call ``fn`` and prefix a ValueError's message with the option it came from."""
    try:
        return fn(*args, **kwargs)
    except ValueError as exc:
        raise CliError(f"{option}: {exc}") from None


def _positive(option: str, value: float) -> float:
    if not (math.isfinite(value) and value > 0):
        raise CliError(f"{option} must be a positive finite number of seconds, got {value!r}")
    return float(value)


def _strict_json(obj):
    """JSON-safe copy: non-finite floats become null."""
    if isinstance(obj, dict):
        return {k: _strict_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_strict_json(v) for v in obj]
    if isinstance(obj, (float, np.floating)):
        return float(obj) if math.isfinite(obj) else None
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj


def _dumps(obj) -> str:
    return json.dumps(_strict_json(obj), indent=2, allow_nan=False)


# ----------------------------------------------------------------------------- operating-point
_UNIT_SUFFIXES = (
    ("_kg_per_J", "kg/J"), ("_rev_s", "rev/s"), ("_kg_s", "kg/s"), ("_Nm", "N m"),
    ("_Pa", "Pa"), ("_kg", "kg"), ("_W", "W"), ("_K", "K"),
)
# a second, conventional unit for the human table: (factor, offset, unit)
_PRACTICAL = {
    "rev/s": (60.0, 0.0, "rpm"), "W": (1e-3, 0.0, "kW"), "Pa": (1e-5, 0.0, "bar"),
    "K": (1.0, -273.15, "degC"), "kg/J": (3.6e9, 0.0, "g/kWh"), "N m": (1e-3, 0.0, "kN m"),
    "kg": (1e3, 0.0, "g"),
}


def _split_unit(key: str) -> tuple[str, str]:
    for suffix, unit in _UNIT_SUFFIXES:
        if key.endswith(suffix):
            return key[: -len(suffix)], unit
    return key, "-"


def cmd_operating_point(args: argparse.Namespace) -> int:
    params = _field("--params", load_params, args.params)
    u = float(check_fuel_setting(args.fuel_setting, "--fuel-setting"))
    from .engine.model import EngineModel
    from .engine.steady_state import steady_state

    with np.errstate(all="ignore"):
        ss = steady_state(EngineModel(params), u)
        summary = ss.summary(params)
    summary.pop("fuel_setting", None)
    out = {"params": params.name, "fuel_setting": u, **summary, "converged": bool(ss.converged[0])}
    if not out["converged"]:
        print(f"{PROG}: warning: the steady-state solver did not converge at fuel setting {u:g}", file=sys.stderr)
    if not out["engine_speed_rev_s"] > 0:
        print(f"{PROG}: warning: the engine does not run at fuel setting {u:g} (speed 0)", file=sys.stderr)
    if args.json:
        print(_dumps(out))
        return 0
    print(f"Steady state of {params.name} at fuel setting {u:g}"
          f"{'' if out['converged'] else ' (NOT converged)'}")
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
        return _field("--profile", make_profile, text, duration_s=duration_s)
    return _field("--profile", make_profile, value)


def _describe_fault(spec: FaultSpec) -> str:
    d = spec.to_dict()
    mag = d["magnitude"]
    parts = [f"{spec.fault_id}@{spec.onset_s:g}"] + ([d["kind"]] if d["class"] == "sensor" else [])
    if not (isinstance(mag, float) and math.isnan(mag)):
        from .runio import fault_unit

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
    from .runio import save_run
    from .engine.simulator import Simulator

    scen = _field("--scenario", get_scenario, args.scenario) if args.scenario is not None else None
    params = _field("--params", load_params, args.params or (scen.params if scen else DEFAULT_PARAMS))
    if args.duration is None and scen is None:
        raise CliError("--duration is required: the simulated time in seconds (> 0), unless --scenario gives one")
    duration = _positive("--duration", args.duration if args.duration is not None else scen.duration_s)
    dt = _positive("--dt", args.dt)
    if duration < dt:
        raise CliError(f"--duration ({duration:g} s) must be at least one sample time --dt ({dt:g} s)")
    if args.engines < 1:
        raise CliError(f"--engines must be a positive integer, got {args.engines}")
    if args.seed < 0:
        raise CliError(f"--seed must be a non-negative integer, got {args.seed}")
    if not (math.isfinite(args.noise_scale) and args.noise_scale >= 0):
        raise CliError(f"--noise-scale must be a finite number >= 0 (1 = table 6.3 noise, 0 = noise-free), "
                       f"got {args.noise_scale!r}")

    specs: list[FaultSpec] = scen.fault_specs() if scen else []
    for text in args.fault or []:
        spec = _field(f"--fault {text}", parse_fault_spec, text)
        clash = [s for s in specs if s.fault_id == spec.fault_id]
        if clash:
            origin = f"the scenario {scen.name} already schedules it" if scen and clash[0] in scen.fault_specs() \
                else "it is given twice"
            raise CliError(f"--fault: fault {spec.fault_id} may be scheduled once per engine; {origin}")
        specs.append(spec)
    for s in specs:
        if s.onset_s >= duration:
            print(f"{PROG}: warning: fault {s.fault_id} starts at {s.onset_s:g} s, at or after the end of the "
                  f"run ({duration:g} s); it will not be active", file=sys.stderr)

    profile = _make_profile(args.profile if args.profile is not None else (scen.profile if scen else "constant"),
                            duration)

    from .envs.cliutil import prepare_out

    out = prepare_out(args.out, "--out", is_dir=False)

    sim = Simulator(params, n_engines=args.engines, seeds=args.seed, faults=specs, profiles=profile,
                    dt=dt, noise_scale=args.noise_scale)
    steps = int(round(duration / dt))
    with np.errstate(all="ignore"):
        result = sim.run(duration, progress=_want_progress(args.progress, steps))
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
            print(_dumps([{"name": n, "description": _description(n)} for n in names]))
            return 0
        w = max(len(n) for n in names)
        for n in names:
            print(f"{n:<{w}}  {_description(n)}")
        return 0
    p = _field("--name", load_params, args.name)
    if args.name not in list_parameter_sets():  # a fitted-engine file: its base, overrides and submodels
        d = json.loads(Path(args.name).read_text())
        if args.json:
            print(_dumps(d))
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
        print(_dumps({"name": args.name, "description": _description(args.name), "parameters": prov}))
        return 0
    print(f"{args.name}: {_description(args.name)}")
    rows = [(k, f"{v['value']:.6g}" if isinstance(v["value"], float) else str(v["value"]), v.get("unit", ""),
             v.get("source", "")) for k, v in prov.items()]
    w0, w1, w2 = (max(len(r[i]) for r in rows) for i in range(3))
    print(f"  {'parameter':<{w0}}  {'value':>{w1}}  {'unit':<{w2}}  source")
    for k, v, u, s in rows:
        print(f"  {k:<{w0}}  {v:>{w1}}  {u:<{w2}}  {s}")
    return 0


# ----------------------------------------------------------------------------- scenarios, info
def cmd_scenarios(args: argparse.Namespace) -> int:
    if args.json:
        print(_dumps([s.to_dict() for s in SCENARIOS.values()]))
        return 0
    for s in SCENARIOS.values():
        print(f"{s.name}: {' + '.join(s.faults)}  ({s.duration_s:g} s, {s.profile}, {s.params})")
        print(f"    {s.description}")
    return 0


def cmd_info(args: argparse.Namespace) -> int:
    from .runio import load_run

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
        print(_dumps(info))
        return 0
    for key in ("file", "params", "scenario", "n_samples", "n_engines", "dt_s", "t_end_s", "seeds", "noise_scale",
                "nonfinite_measurements", "package_version", "command_line"):
        print(f"{key:<23} {info[key]}")
    print("true faults:" if info["true_faults"] else "true faults:            none")
    for f in info["true_faults"]:
        first = "not active in run" if f["first_active_s"] is None else f"first active at {f['first_active_s']:g} s"
        mag = "-" if f["magnitude"] is None else f"{f['magnitude']:g}{'' if f['unit'] == '-' else ' ' + f['unit']}"
        what = f"sensor {f['kind']}" if f["class"] == "sensor" else "process"
        print(f"  engine {f['engine']}: {f['id']} ({what}) onset {f['onset_s']:g} s, "
              f"magnitude {mag}, {first}")
    print("failures:" if info["failures"] else "failures:               none")
    for f in info["failures"]:
        print(f"  engine {f['engine']} at {f['time_s']:g} s: {f['reason']}")
    return 0


def _cmd_diagnose(args: argparse.Namespace) -> int:
    from .envs.cliutil import prepare_out, require_extra

    if args.plots:  # before any work: a missing extra or a bad folder costs nothing
        require_extra("matplotlib", "--plots")
    if not Path(args.run).is_file():
        raise CliError(f"--run: run file {args.run!r} does not exist")
    # checked here, created when written (a run that fails to load leaves no new folder)
    args.out = str(prepare_out(args.out, "--out", is_dir=False, create=False))
    if args.plots:
        args.plots = str(prepare_out(args.plots, "--plots", is_dir=True, create=False))
    from .diagnosis.cli_diagnose import cmd_diagnose

    return cmd_diagnose(args)


# ----------------------------------------------------------------------------- parser
def build_parser() -> argparse.ArgumentParser:
    fmt = argparse.RawDescriptionHelpFormatter
    parser = argparse.ArgumentParser(
        prog=PROG,
        description=textwrap.fill(
            "Marine diesel engine fault detection and isolation benchmark: steady states, "
            "simulated sensor data with injected faults, parameter sets.", width=90),
        epilog="Run 'marine-fdi COMMAND --help' for the options of a command.",
        formatter_class=fmt,
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    p = sub.add_parser("operating-point", help="steady state of an engine at a fuel setting",
                       description="Steady state (equilibrium) of the engine model at a constant fuel setting; "
                                   "all quantities in SI units (JSON keys end in their unit).")
    p.add_argument("--params", default=DEFAULT_PARAMS, metavar="NAME|FILE.json",
                   help=f"parameter set (default {DEFAULT_PARAMS}; see 'marine-fdi params') or a fitted-engine file "
                        "written by 'marine-fdi validate --save-params'")
    p.add_argument("--fuel-setting", type=float, required=True, metavar="U",
                   help=f"fuel setting in [{FUEL_SETTING_RANGE[0]:g}, {FUEL_SETTING_RANGE[1]:g}], 1.0 = nominal")
    p.add_argument("--json", action="store_true", help="print JSON instead of a table")
    p.set_defaults(func=cmd_operating_point)

    p = sub.add_parser(
        "simulate", help="simulate engines with faults and write a .npz run file",
        description=textwrap.fill(
            "Simulate N engines sampled at --dt with sensor noise and injected faults, and write "
            "measurements, ground truth and metadata to a .npz run file (read it with "
            "marine_fdi_env.runio.load_run or 'marine-fdi info').", width=90),
        epilog=FAULT_SPEC_HELP + "\n" + PROFILE_HELP + "\n" + _scenario_help(),
        formatter_class=fmt,
    )
    p.add_argument("--params", default=None, metavar="NAME|FILE.json",
                   help=f"parameter set (default: the scenario's, else {DEFAULT_PARAMS}) or a fitted-engine file "
                        "('marine-fdi validate --save-params')")
    p.add_argument("--duration", type=float, default=None, metavar="S",
                   help="simulated time [s] (required unless --scenario is given)")
    p.add_argument("--seed", type=int, default=0, metavar="N",
                   help="noise seed; engine i uses N + i (default 0)")
    p.add_argument("--fault", action="extend", nargs="+", metavar="SPEC",
                   help="fault(s) on every engine, e.g. S4.2@235:5e4 (syntax below); repeatable")
    p.add_argument("--profile", default=None, metavar="NAME|SPEC",
                   help="fuel profile (default: the scenario's, else constant 1.0; syntax below)")
    p.add_argument("--noise-scale", type=float, default=1.0, metavar="X",
                   help="multiplier of the table 6.3 noise bounds (default 1, 0 = noise-free)")
    p.add_argument("--dt", type=float, default=0.01, metavar="DT", help="sample time [s] (default 0.01)")
    p.add_argument("--engines", type=int, default=1, metavar="N", help="number of engines (default 1)")
    p.add_argument("--scenario", default=None, metavar="NAME",
                   help=f"thesis scenario: {', '.join(SCENARIOS)} (its faults are added to --fault)")
    p.add_argument("--out", required=True, metavar="FILE.npz", help="output run file (its folder is created if missing, never more levels)")
    p.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                   help=f"progress bar on stderr (default: when stderr is a terminal or the run has "
                        f">= {LONG_RUN_STEPS} samples)")
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser("params", help="list parameter sets or show one",
                       description="List the shipped parameter sets, or print one set's parameters with "
                                   "value, unit and source.")
    p.add_argument("--name", default=None, metavar="NAME|FILE.json", help="parameter set or fitted-engine file to show")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=cmd_params)

    p = sub.add_parser("scenarios", help="list the thesis fault scenarios",
                       description="The named scenarios usable with 'simulate --scenario'.")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=cmd_scenarios)

    p = sub.add_parser(
        "diagnose", help="run the reference diagnoser on a run file",
        description="Run the thesis's reference diagnoser (19 monitoring modules, adaptive thresholds, "
                    "minimal diagnoses) on one engine of a run written by 'marine-fdi simulate'.")
    p.add_argument("--run", required=True, metavar="FILE", help="run file (.npz)")
    p.add_argument("--out", required=True, metavar="FILE.json",
                   help="JSON report (its folder is created if missing, never more levels)")
    p.add_argument("--plots", default=None, metavar="DIR",
                   help="write one figure per subsystem Σ1-Σ4: each monitoring module's residual against its adaptive "
                        "threshold, detections and fault onsets (needs matplotlib)")
    p.add_argument("--engine", type=int, default=0, metavar="I", help="engine of the run (default 0)")
    p.add_argument("--exoneration", choices=("sure", "none", "all"), default="sure",
                   help="sure (default): a silent module clears the faults it surely sees; none: plain "
                        "consistency-based diagnosis; all: every structural sensitivity counts as sure")
    p.add_argument("--diagnoser", choices=("reference", "sequential"), default="reference",
                   help="reference (the thesis's scheme, default) or sequential (CUSUM tests on its residuals)")
    p.add_argument("--cells", choices=("thesis", "grid", "sized"), default="sized",
                   help="which measured sure cells exonerate (with --exoneration sure): sized (default: those of the "
                        "size the evidence bounds each candidate fault to), grid (sure at every size from 0.5x the "
                        "detectability limit to the table size) or thesis (the table sizes only)")
    p.set_defaults(func=_cmd_diagnose)

    # implemented in marine_fdi_env.validation (own argument parsers; see main())
    sub.add_parser("validate", add_help=False,
                   help="compare the model with measured data, name the causes of misfit (see --help)")
    sub.add_parser("evaluate", add_help=False, help="run an agent on a frozen evaluation suite (see evaluate --help)")
    sub.add_parser("report", add_help=False, help="Markdown table and plots from results files (see report --help)")
    sub.add_parser("dataset", add_help=False, help="export features and labels for offline learning (see dataset --help)")
    sub.add_parser("synthesize-measurements", add_help=False,
                   help="write 'measured' data from the model with hidden mechanisms (see --help)")
    sub.add_parser("agents", add_help=False, help="list the agents known by name (see agents --help)")
    sub.add_parser("sweep", add_help=False,
                   help="agents x suites x seed offsets on a backend, resumably, into one Parquet table (see --help)")
    sub.add_parser("export-raw", add_help=False,
                   help="write a suite's 100 Hz sensor samples and ground truth in the DX competition layout")
    sub.add_parser("predict-raw", add_help=False,
                   help="write an agent's per-sample diagnoses of a suite in the DX layout (see --help)")
    sub.add_parser("score-raw", add_help=False,
                   help="score per-sample diagnoses in the DX layout with the benchmark's and DX metrics")

    p = sub.add_parser("info", help="validate and summarise a run file",
                       description="Load a .npz run file (validating it) and print its metadata and ground truth.")
    p.add_argument("file", metavar="FILE", help="run file written by 'marine-fdi simulate'")
    p.add_argument("--allow-nonfinite", action="store_true", help="accept NaN/inf measurements (dropouts)")
    p.add_argument("--json", action="store_true", help="print JSON")
    p.set_defaults(func=cmd_info)
    return parser


_ENV_COMMANDS = {
    "evaluate": ("marine_fdi_env.envs.evaluate", "evaluate_main"),
    "report": ("marine_fdi_env.envs.report", "report_main"),
    "dataset": ("marine_fdi_env.envs.dataset", "dataset_main"),
    "agents": ("marine_fdi_env.envs.agents_cli", "agents_main"),
    "sweep": ("marine_fdi_env.envs.sweep", "sweep_main"),
    "export-raw": ("marine_fdi_env.envs.rawdata", "export_raw_main"),
    "predict-raw": ("marine_fdi_env.envs.rawdata", "predict_raw_main"),
    "score-raw": ("marine_fdi_env.envs.rawscore", "score_raw_main"),
}


_OWN_PARSER_COMMANDS = {
    **_ENV_COMMANDS,
    "validate": ("marine_fdi_env.validation.report", "validate_main"),
    "synthesize-measurements": ("marine_fdi_env.validation.synthesize", "synthesize_main"),
}

# the output options of the validation commands: option -> (argparse dest, is a folder)
_VALIDATION_OUTPUTS = {
    "validate": {"--out": ("out", False), "--markdown": ("markdown", False), "--plots": ("plots", True)},
    "synthesize-measurements": {"--out": ("out", False), "--truth": ("truth", False)},
}


def _run_validation_command(command: str, argv: list[str]) -> int:
    """``validate`` and ``synthesize-measurements`` under the conventions of the other commands
    (:mod:`.envs.cliutil`): ``--plots`` without matplotlib is one line before any work; the parent
    of each output path is created when missing (one level, never more) and removed again when
    the command fails, so a failing command leaves no new folder."""
    import importlib

    from .envs.cliutil import USAGE_ERROR, prepare_out, require_extra

    mod_name, fn = _OWN_PARSER_COMMANDS[command]
    mod = importlib.import_module(mod_name)
    run = getattr(mod, fn)
    if any(a in ("-h", "--help") for a in argv):
        return run(argv)
    parser = mod.build_parser(f"{PROG} {command}")

    def error(message):
        raise ValueError(message)

    parser.error = error  # type: ignore[method-assign]
    try:
        args = parser.parse_args(argv)
    except ValueError:
        return run(argv)  # the command prints its own usage error
    created: list[Path] = []
    try:
        if getattr(args, "plots", None):
            require_extra("matplotlib", "--plots")
        for option, (dest, is_dir) in _VALIDATION_OUTPUTS[command].items():
            value = getattr(args, dest, None)
            if value:
                prepare_out(value, option, is_dir=is_dir, create=False)
        for option, (dest, _) in _VALIDATION_OUTPUTS[command].items():
            value = getattr(args, dest, None)
            parent = Path(value).parent if value else None
            if parent is not None and not parent.exists():
                parent.mkdir()
                created.append(parent)
    except ValueError as e:
        print(f"{PROG} {command}: error: {e}", file=sys.stderr)
        return USAGE_ERROR
    rc = 1
    try:
        rc = run(argv)
        return rc
    finally:
        if rc != 0:
            for folder in reversed(created):
                try:
                    folder.rmdir()  # only if still empty
                except OSError:
                    pass


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; returns the exit code (0 ok, 2 invalid input, 1 I/O error, 130 interrupted).

    Every command: Ctrl-C prints "interrupted" and returns 130 (commands that write
    incrementally keep their finished work and resume when rerun); a cold numba cache prints one
    line before the first compilation (:mod:`._coldstart`).
    """
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        from . import _coldstart

        _coldstart.enable(PROG)
        if argv and argv[0] in _VALIDATION_OUTPUTS:
            return _run_validation_command(argv[0], argv[1:])
        if argv and argv[0] in _OWN_PARSER_COMMANDS:
            import importlib

            mod, fn = _OWN_PARSER_COMMANDS[argv[0]]
            return getattr(importlib.import_module(mod), fn)(argv[1:])
        return _main(argv)
    except KeyboardInterrupt:  # a command without its own handler, or Ctrl-C while importing
        print(f"{PROG}{' ' + argv[0] if argv and not argv[0].startswith('-') else ''}: interrupted",
              file=sys.stderr)
        return 130


def _main(argv: list[str]) -> int:
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # --help, --version, argparse usage errors (exit code 2)
        return exc.code if isinstance(exc.code, int) else (0 if exc.code is None else 2)
    if args.command is None:
        parser.print_help(sys.stderr)
        return 2
    try:
        if args.command == "simulate":
            return cmd_simulate(args, argv)
        return args.func(args)
    except ValueError as exc:
        print(f"{PROG} {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # output piped into e.g. head: stop quietly (Python docs' recipe)
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        except (OSError, ValueError, AttributeError):
            pass
        return 1
    except OSError as exc:
        print(f"{PROG} {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"{PROG} {args.command}: interrupted", file=sys.stderr)
        return 130


def console_main() -> None:
    """The ``marine-fdi`` script: :func:`main`, then exit with its code.

    After Ctrl-C in a run that used Ray, the process leaves at once (``os._exit``, after
    flushing stdout and stderr): the finished work is on disk and Ray was shut down, but Ray's
    C++ core worker can crash while the interpreter tears down after an interrupted
    ``ray.wait`` (a segfault instead of exit code 130)."""
    code = main()
    if code == 130 and "ray" in sys.modules:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (OSError, ValueError):
                pass
        os._exit(code)
    sys.exit(code)


if __name__ == "__main__":
    console_main()
