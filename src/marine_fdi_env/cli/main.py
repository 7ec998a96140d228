"""The ``marine-fdi`` command: one parser with a subcommand per job, each in its own module of this package.

The engine's commands (:mod:`.simulation`) and ``diagnose`` (:mod:`.diagnose`) are subparsers here; the
others (:data:`OWN_PARSER_COMMANDS`) parse their own arguments.  Every command runs through
:func:`.failures.run_command`: invalid input ends with a one-line message on stderr naming the
option and what it allows, and exit code 2 (a traceback only with ``--debug``).  ``main(argv)``
returns the exit code, so it can be called in-process.
"""

from __future__ import annotations

import argparse
import os
import sys
import textwrap
from pathlib import Path
from typing import Sequence

from .._version import __version__
from ..diagnosis.thresholds import THRESHOLD_READINGS
from ..engine.steady_state import FUEL_SETTING_RANGE
from ..errors import require_extra
from ..outputs import prepare_out
from ..scenarios import SCENARIOS
from .common import PROG, CommandParser, add_force_option, add_json_option, parse_cli
from .diagnose import cmd_diagnose
from .failures import DEBUG_ENV, DEBUG_FLAG, debugging, fail, run_command, split_debug
from .simulation import (
    DEFAULT_PARAMS,
    FAULT_SPEC_HELP,
    LONG_RUN_STEPS,
    PROFILE_HELP,
    cmd_info,
    cmd_operating_point,
    cmd_params,
    cmd_scenarios,
    cmd_simulate,
    scenario_help,
)

__all__ = ["main", "console_main", "build_parser", "OWN_PARSER_COMMANDS"]


# ----------------------------------------------------------------------------- parser
def build_parser() -> argparse.ArgumentParser:
    fmt = argparse.RawDescriptionHelpFormatter
    parser = CommandParser(
        prog=PROG,
        description=textwrap.fill(
            "Marine diesel engine fault detection and isolation benchmark: steady states, "
            "simulated sensor data with injected faults, parameter sets.",
            width=90,
        ),
        epilog="Run 'marine-fdi COMMAND --help' for the options of a command.",
        formatter_class=fmt,
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    parser.add_argument(
        DEBUG_FLAG,
        action="store_true",
        help=f"on any command, anywhere on its line (or {DEBUG_ENV}=1): print the full traceback "
        "under an error's one-line message",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")

    p = sub.add_parser(
        "operating-point",
        help="steady state of an engine at a fuel setting",
        description="Steady state (equilibrium) of the engine model at a constant fuel setting; "
        "all quantities in SI units (JSON keys end in their unit).",
    )
    p.add_argument(
        "--params",
        default=DEFAULT_PARAMS,
        metavar="NAME|FILE.json",
        help=f"parameter set (default {DEFAULT_PARAMS}; see 'marine-fdi params') or a fitted-engine file "
        "written by 'marine-fdi validate --save-params'",
    )
    p.add_argument(
        "--fuel-setting",
        type=float,
        required=True,
        metavar="U",
        help=f"fuel setting in [{FUEL_SETTING_RANGE[0]:g}, {FUEL_SETTING_RANGE[1]:g}], 1.0 = nominal",
    )
    add_json_option(p, "print JSON instead of a table")
    p.set_defaults(func=cmd_operating_point)

    p = sub.add_parser(
        "simulate",
        help="simulate engines with faults and write a .npz run file",
        description=textwrap.fill(
            "Simulate N engines sampled at --dt with sensor noise and injected faults, and write "
            "measurements, ground truth and metadata to a .npz run file (read it with "
            "marine_fdi_env.runio.load_run or 'marine-fdi info').",
            width=90,
        ),
        epilog=FAULT_SPEC_HELP + "\n" + PROFILE_HELP + "\n" + scenario_help(),
        formatter_class=fmt,
    )
    p.add_argument(
        "--params",
        default=None,
        metavar="NAME|FILE.json",
        help=f"parameter set (default: the scenario's, else {DEFAULT_PARAMS}) or a fitted-engine file "
        "('marine-fdi validate --save-params')",
    )
    p.add_argument(
        "--duration",
        type=float,
        default=None,
        metavar="S",
        help="simulated time [s] (required unless --scenario is given)",
    )
    p.add_argument("--seed", type=int, default=0, metavar="N", help="noise seed; engine i uses N + i (default 0)")
    p.add_argument(
        "--fault",
        action="extend",
        nargs="+",
        metavar="SPEC",
        help="fault(s) on every engine, e.g. S4.2@235:5e4 (syntax below); repeatable",
    )
    p.add_argument(
        "--profile",
        default=None,
        metavar="NAME|SPEC",
        help="fuel profile (default: the scenario's, else constant 1.0; syntax below)",
    )
    p.add_argument(
        "--noise-scale",
        type=float,
        default=1.0,
        metavar="X",
        help="multiplier of the table 6.3 noise bounds (default 1, 0 = noise-free)",
    )
    p.add_argument("--dt", type=float, default=0.01, metavar="DT", help="sample time [s] (default 0.01)")
    p.add_argument("--engines", type=int, default=1, metavar="N", help="number of engines (default 1)")
    p.add_argument(
        "--scenario",
        default=None,
        metavar="NAME",
        help=f"thesis scenario: {', '.join(SCENARIOS)} (its faults are added to --fault)",
    )
    p.add_argument(
        "--out",
        required=True,
        metavar="FILE.npz",
        help="output run file (its folder is created if missing, never more levels)",
    )
    add_force_option(p, "overwrite --out if it exists (without it: an error)")
    p.add_argument(
        "--progress",
        action=argparse.BooleanOptionalAction,
        default=None,
        help=f"progress bar on stderr (default: when stderr is a terminal or the run has >= {LONG_RUN_STEPS} samples)",
    )
    p.set_defaults(func=cmd_simulate)

    p = sub.add_parser(
        "params",
        help="list parameter sets or show one",
        description="List the shipped parameter sets, or print one set's parameters with value, unit and source.",
    )
    p.add_argument("--name", default=None, metavar="NAME|FILE.json", help="parameter set or fitted-engine file to show")
    add_json_option(p)
    p.set_defaults(func=cmd_params)

    p = sub.add_parser(
        "scenarios",
        help="list the thesis fault scenarios",
        description="The named scenarios usable with 'simulate --scenario'.",
    )
    add_json_option(p)
    p.set_defaults(func=cmd_scenarios)

    p = sub.add_parser(
        "diagnose",
        help="run the reference diagnoser on a run file",
        description="Run the thesis's reference diagnoser (19 monitoring modules, adaptive thresholds, "
        "minimal diagnoses) on one engine of a run written by 'marine-fdi simulate'.",
    )
    p.add_argument("--run", required=True, metavar="FILE", help="run file (.npz)")
    p.add_argument(
        "--out",
        required=True,
        metavar="FILE.json",
        help="JSON report (its folder is created if missing, never more levels)",
    )
    p.add_argument(
        "--plots",
        default=None,
        metavar="DIR",
        help="write one figure per subsystem Σ1-Σ4: each monitoring module's residual against its adaptive "
        "threshold, detections and fault onsets (needs matplotlib)",
    )
    p.add_argument("--engine", type=int, default=0, metavar="I", help="engine of the run (default 0)")
    p.add_argument(
        "--exoneration",
        choices=("sure", "none", "all"),
        default="sure",
        help="sure (default): a silent module clears the faults it surely sees; none: plain "
        "consistency-based diagnosis; all: every structural sensitivity counts as sure",
    )
    p.add_argument(
        "--diagnoser",
        choices=("reference", "sequential"),
        default="reference",
        help="reference (the thesis's scheme, default) or sequential (CUSUM tests on its residuals)",
    )
    p.add_argument(
        "--cells",
        choices=("thesis", "grid", "sized"),
        default="sized",
        help="which measured sure cells exonerate (with --exoneration sure): sized (default: those of the "
        "size the evidence bounds each candidate fault to), grid (sure at every size from 0.5x the "
        "detectability limit to the table size) or thesis (the table sizes only)",
    )
    p.add_argument(
        "--thresholds",
        choices=THRESHOLD_READINGS,
        default="local",
        help="the reading of the observer modules' adaptive thresholds (reference only): local (default: the "
        "local inclusion of the forcing over every input's noise box), thesis-lipschitz (eq. 5.11 with a "
        "global Lipschitz bound on the interconnection term), thesis-no-interconnection, thesis-table-6.1 "
        "(eq. 5.10-5.12 with table 6.1's constants) or thesis-table-6.1-m4 (those constants in M4.1/M4.2 only); "
        "each with its own measured cells (docs/diagnosis.md)",
    )
    p.set_defaults(func=cmd_diagnose)

    for name, (_, _, summary) in OWN_PARSER_COMMANDS.items():  # they parse their own arguments (see main())
        sub.add_parser(name, add_help=False, help=summary)

    p = sub.add_parser(
        "info",
        help="validate and summarise a run file",
        description="Load a .npz run file (validating it) and print its metadata and ground truth.",
    )
    p.add_argument("file", metavar="FILE", help="run file written by 'marine-fdi simulate'")
    p.add_argument("--allow-nonfinite", action="store_true", help="accept NaN/inf measurements (dropouts)")
    add_json_option(p)
    p.set_defaults(func=cmd_info)
    return parser


# command -> (module of this package, function, its line in --help): the commands that parse their own arguments,
# imported only when run (a command's import cost is paid by that command alone), in the order --help lists them
OWN_PARSER_COMMANDS = {
    "validate": (
        "marine_fdi_env.cli.validate",
        "validate_main",
        "compare the model with measured data, name the causes of misfit (see --help)",
    ),
    "evaluate": (
        "marine_fdi_env.cli.evaluate",
        "evaluate_main",
        "run an agent on a frozen evaluation suite (see evaluate --help)",
    ),
    "report": (
        "marine_fdi_env.cli.report",
        "report_main",
        "Markdown table and plots from results files (see report --help)",
    ),
    "dataset": (
        "marine_fdi_env.cli.dataset",
        "dataset_main",
        "export features and labels for offline learning (see dataset --help)",
    ),
    "synthesize-measurements": (
        "marine_fdi_env.cli.synthesize",
        "synthesize_main",
        "write 'measured' data from the model with hidden mechanisms (see --help)",
    ),
    "agents": ("marine_fdi_env.cli.agents", "agents_main", "list the agents known by name (see agents --help)"),
    "sweep": (
        "marine_fdi_env.cli.sweep",
        "sweep_main",
        "agents x suites x seed offsets on a backend, resumably, into one Parquet table (see --help)",
    ),
    "export-raw": (
        "marine_fdi_env.cli.raw",
        "export_raw_main",
        "write a suite's 100 Hz sensor samples and ground truth in the DX competition layout",
    ),
    "predict-raw": (
        "marine_fdi_env.cli.raw",
        "predict_raw_main",
        "write an agent's per-sample diagnoses of a suite in the DX layout (see --help)",
    ),
    "score-raw": (
        "marine_fdi_env.cli.raw",
        "score_raw_main",
        "score per-sample diagnoses in the DX layout with the benchmark's and DX metrics",
    ),
    "replicas": (
        "marine_fdi_env.cli.replicas",
        "replicas_main",
        "would validate name the same causes again on data like these? (a bootstrap; see --help)",
    ),
    "suites": ("marine_fdi_env.cli.suites", "suites_main", "list the frozen evaluation suites (see suites --help)"),
    "train": (
        "marine_fdi_env.cli.train",
        "train_main",
        "train a learned agent: PPO or the GRU classifier (needs [train])",
    ),
    "submit": (
        "marine_fdi_env.cli.submit",
        "submit_main",
        "score an agent on the frozen suites into an entry anyone can verify",
    ),
    "verify": (
        "marine_fdi_env.cli.submit",
        "verify_main",
        "check entries: hashes, metrics recomputed, --rerun replays them",
    ),
    "leaderboard": (
        "marine_fdi_env.cli.leaderboard",
        "leaderboard_main",
        "build the leaderboard's table from its entries",
    ),
}

# the output options of the validation commands: option -> (argparse dest, is a folder)
_VALIDATION_OUTPUTS = {
    "validate": {"--out": ("out", False), "--markdown": ("markdown", False), "--plots": ("plots", True)},
    "synthesize-measurements": {"--out": ("out", False), "--truth": ("truth", False)},
}


def _run_validation_command(command: str, argv: list[str]) -> int:
    """``validate`` and ``synthesize-measurements`` under the conventions of the other commands
    (:mod:`.common`): their options parsed once (the command's parser, then its ``run``); ``--plots``
    without matplotlib is one line before any work; the parent of each output path is created when missing
    (one level, never more) and removed again when the command fails, so a failing command leaves no new
    folder."""
    import importlib

    mod = importlib.import_module(OWN_PARSER_COMMANDS[command][0])
    prog = f"{PROG} {command}"
    args, code = parse_cli(mod.build_parser(prog), argv)
    if args is None:
        return code
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
        return fail(prog, e)
    rc = 1
    try:
        rc = mod.run(args, argv, prog)
        return rc
    finally:
        if rc != 0:
            for folder in reversed(created):
                try:
                    folder.rmdir()  # only if still empty
                except OSError:
                    pass


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; returns the exit code (0 ok, 2 invalid input, 1 a failure that is not the input's
    fault, 130 interrupted).

    Every command ends a failure the same way (:mod:`.failures`: one line, the traceback with
    ``--debug`` anywhere on the command line); Ctrl-C prints "interrupted" and returns 130 (commands
    that write incrementally keep their finished work and resume when rerun); a cold numba cache
    prints one line before the first compilation (:mod:`marine_fdi_env.coldstart`).
    """
    argv, debug = split_debug(sys.argv[1:] if argv is None else argv)
    prog = PROG + (f" {argv[0]}" if argv and not argv[0].startswith("-") else "")
    with debugging(debug):
        return run_command(prog, lambda: _dispatch(argv))


def _dispatch(argv: list[str]) -> int:
    from .. import coldstart

    coldstart.enable(PROG)
    if argv and argv[0] in _VALIDATION_OUTPUTS:
        return _run_validation_command(argv[0], argv[1:])
    if argv and argv[0] in OWN_PARSER_COMMANDS:
        import importlib

        mod, fn, _ = OWN_PARSER_COMMANDS[argv[0]]
        return getattr(importlib.import_module(mod), fn)(argv[1:])
    return _main(argv)


def _main(argv: list[str]) -> int:
    parser = build_parser()
    args, code = parse_cli(parser, argv)
    if args is None:  # --help, --version, a usage error (its line printed)
        return code
    if args.command is None:
        parser.print_help(sys.stderr)
        return 2
    if args.command == "simulate":
        return cmd_simulate(args, argv)
    return args.func(args)


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
