"""``marine-fdi validate``: compare the engine model with measured data and name the causes of misfit."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Sequence

from ..engine.params import list_parameter_sets, load_params
from ..errors import UsageError
from ..jsonfile import json_safe
from ..plotting import pyplot
from ..validation.fit.problem import FitProblem
from ..validation.measured.loader import list_shipped, load_data_arg
from ..validation.measured.matching import TARGETS
from ..validation.report.build import out_path, run_validation, split_engine, summary_lines
from ..validation.report.data_check import column_registry, describe
from ..validation.report.markdown import markdown_summary
from ..validation.report.plots import write_plots
from ..validation.select.rules import SelectionRules
from .common import CommandParser, run_parsed
from .failures import fail
from .selection_options import add_valve_options, rules_from_args

RULES = SelectionRules()  # the selection's default rules: the options' defaults


def build_parser(prog: str = "marine-fdi validate") -> argparse.ArgumentParser:
    ap = CommandParser(
        prog=prog,
        description="Validate the engine model against measured data: "
        "discrepancies, named causes, cross-validated gain, the fitted engine.",
    )
    ap.add_argument(
        "--data",
        metavar="FILE",
        help="measured data: a CSV or Parquet file (the reader by its ending: .csv, .parquet) with its sidecar "
        f"FILE.meta.json, or a shipped dataset name ({', '.join(list_shipped())})",
    )
    g = ap.add_mutually_exclusive_group()
    g.add_argument("--holdout", metavar="FILE", help="data the fit does not see (as --data); the report gives its RMSE")
    g.add_argument("--holdout-engine", metavar="ID", help="leave this engine of --data out and predict it")
    ap.add_argument("--out", metavar="report.json", help="JSON report (required unless --check)")
    ap.add_argument(
        "--check",
        action="store_true",
        help="only load and check --data: what each column becomes, the assumptions, the readings left "
        "out, the tolerance of every compared channel; no fit (seconds)",
    )
    ap.add_argument("--columns", action="store_true", help="list the column names the loader knows and stop")
    ap.add_argument("--plots", metavar="DIR", help="write model-vs-measurement plots here (needs matplotlib)")
    ap.add_argument(
        "--params",
        metavar="NAME|FILE.json",
        help="parameter set overriding the sidecar's ("
        + ", ".join(list_parameter_sets())
        + ") or a fitted-engine file",
    )
    ap.add_argument(
        "--save-params",
        metavar="ENGINE.json",
        help="write the fitted engine (parameter set + selected submodels) for operating-point, simulate, "
        "the environment and --params",
    )
    ap.add_argument("--target", default="auto", help="what fixes each operating point: " + ", ".join(TARGETS))
    ap.add_argument(
        "--max-causes",
        type=int,
        default=RULES.max_causes,
        help=f"most mechanisms to combine (default {RULES.max_causes})",
    )
    ap.add_argument(
        "--max-folds",
        type=int,
        default=None,
        help="cross-validate single-engine data with at most this many folds (default: leave one out)",
    )
    ap.add_argument(
        "--alpha",
        type=float,
        default=RULES.alpha,
        help=f"significance level of a named cause (default {RULES.alpha:g})",
    )
    ap.add_argument(
        "--alpha-unexplained",
        type=float,
        default=RULES.alpha_unexplained,
        help=f"family-wise level of what is reported as unexplained (default {RULES.alpha_unexplained:g})",
    )
    ap.add_argument(
        "--tolerance",
        action="append",
        default=[],
        metavar="COLUMN=VALUE",
        help="a channel's tolerance (its noise and what is not worth naming), in the column's units or "
        "as P%% of its mean value; repeatable; default: the sidecar's tolerances, else 1 %% and 5 K",
    )
    ap.add_argument("--cv-all", action="store_true", help="cross-validate every candidate (slower)")
    add_valve_options(ap)
    ap.add_argument("--markdown", metavar="FILE.md", help="also write the report's tables as Markdown")
    ap.add_argument(
        "--no-explanations",
        action="store_true",
        help="skip the set of explanations the data do not decide between, their profile intervals and "
        "the deciding measurement (faster)",
    )
    ap.add_argument(
        "--replicas",
        type=int,
        default=0,
        metavar="N",
        help="also ask whether data like these would name the same causes again: N replicas of the data "
        "per hypothesis (the named causes and 4 alternatives), each run through the whole pipeline "
        "(marine-fdi replicas; about 5 x N pipeline runs; default 0: no)",
    )
    ap.add_argument("--workers", type=int, default=1, help="processes for --replicas (default 1)")
    ap.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    return ap


def validate_main(argv: Sequence[str] | None = None, prog: str = "marine-fdi validate") -> int:
    """Command line ``marine-fdi validate``: 0 on success, 2 on bad input (message on stderr), 130 on Ctrl-C."""
    return run_parsed(build_parser, run, argv, prog)


def run(args: argparse.Namespace, argv: Sequence[str], prog: str = "marine-fdi validate") -> int:
    """``marine-fdi validate`` with its parsed options (``argv``: the command line, for the report's command)."""
    if args.columns:
        print(column_registry())
        return 0
    say = None if args.quiet else (lambda s: print(s, file=sys.stderr, flush=True))
    try:
        if args.data is None:
            raise ValueError("--data is required (or --columns to list the known column names)")
        if args.out is None and not args.check:
            raise ValueError("--out is required (or --check to only check the data)")
        rules = rules_from_args(args)
        params = None
        if args.params is not None:
            try:
                params = load_params(args.params)
            except ValueError as e:
                raise ValueError(f"--params: {e}") from None
        if args.target not in TARGETS:
            raise ValueError(f"--target: unknown target {args.target!r}; allowed: {', '.join(TARGETS)}")
        if args.replicas < 0 or args.workers < 1:
            raise ValueError(f"--replicas must be >= 0 and --workers >= 1, got {args.replicas}, {args.workers}")
        out = out_path(args.out, "--out") if args.out else None
        save = out_path(args.save_params, "--save-params") if args.save_params else None
        md = out_path(args.markdown, "--markdown") if args.markdown else None
        if args.plots:
            pyplot()
        try:
            ds = load_data_arg(args.data, args.params if args.params in list_parameter_sets() else None)
        except ValueError as e:
            raise UsageError(f"--data: {e}") from None
        holdout = None
        notes = []
        if args.holdout_engine is not None:
            ds, holdout = split_engine(ds, args.holdout_engine)
            notes.append(
                f"engine {args.holdout_engine} left out of the fit and the cross-validation; it is the hold-out"
            )
        elif args.holdout is not None:
            try:
                holdout = load_data_arg(
                    args.holdout, args.params if args.params in list_parameter_sets() else ds.params_name
                )
            except ValueError as e:
                raise UsageError(f"--holdout: {e}") from None
        problem = FitProblem(ds, target=args.target, params=params) if args.tolerance or args.check else None
        tolerances = problem.stated_tolerances(args.tolerance) if args.tolerance else None
        if args.check:
            print(
                describe(
                    ds,
                    problem,
                    tolerances or dict(zip(problem.channels, problem.tolerance)),
                    args.tolerance,
                    max_folds=args.max_folds,
                )
            )
            if holdout is not None:
                what = f"engine {args.holdout_engine} of {ds.name}" if args.holdout_engine else holdout.name
                print(f"hold-out: {what}, {holdout.n_points} points (predicted, not fitted)")
            print("--check: nothing fitted, nothing written")
            return 0
        rep, sel, ho = run_validation(
            ds,
            holdout=holdout,
            target=args.target,
            params=params,
            rules=rules,
            progress=say,
            notes=notes,
            command="marine-fdi validate " + " ".join(argv),
            tolerances=tolerances,
            explanations=not args.no_explanations,
        )
        if args.replicas:
            from ..validation.select.replicas import replicate

            if say:
                say(f"replicas: {args.replicas} per hypothesis, each through the whole pipeline")
            rep["replicas"] = json_safe(
                replicate(sel, replicas=args.replicas, workers=args.workers, progress=not args.quiet)
            )
    except ValueError as e:
        return fail(prog, e)
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
    for p in (out, save, md):
        if p is not None:
            p.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(rep, indent=1) + "\n")
    if save is not None:
        save.write_text(json.dumps(rep["fitted_engine"], indent=1) + "\n")
    if md is not None:
        title = ds.name + (f" without {args.holdout_engine} (hold-out)" if args.holdout_engine else "")
        md.write_text(markdown_summary(rep, title) + "\n")
    if args.plots:
        prefix = ds.name + (f"_without_{args.holdout_engine}" if args.holdout_engine else "")
        files = write_plots(sel, args.plots, ho, prefix=prefix)
        print("plots: " + ", ".join(str(f) for f in files))
    print("\n".join(summary_lines(rep)))
    print(f"report: {out}" + (f"; fitted engine: {save}" if save is not None else ""))
    return 0
