"""``marine-fdi diagnose``: run a diagnoser on one engine of a recorded run, report as JSON (and plots)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from ..diagnosis.recorded_run import diagnose_run, plot_residuals
from ..errors import UsageError, require_extra
from ..jsonfile import json_safe
from ..outputs import prepare_out
from ..runio import load_run


def cmd_diagnose(args: argparse.Namespace) -> int:
    if args.plots:  # before any work: a missing extra or a bad folder costs nothing
        require_extra("matplotlib", "--plots")
    if args.thresholds != "local" and args.diagnoser != "reference":
        raise UsageError(
            f"--thresholds {args.thresholds}: only with --diagnoser reference (the sequential tests: local)"
        )
    if Path(args.run).is_dir():
        raise UsageError(f"--run: {args.run!r} is a folder; give a .npz run file written by 'marine-fdi simulate'")
    if not Path(args.run).is_file():
        raise UsageError(f"--run: run file {args.run!r} does not exist")
    # checked here, created when written (a run that fails to load leaves no new folder)
    args.out = str(prepare_out(args.out, "--out", is_dir=False, create=False))
    if args.plots:
        args.plots = str(prepare_out(args.plots, "--plots", is_dir=True, create=False))
    return _diagnose(args)


def _diagnose(args: argparse.Namespace) -> int:
    run = load_run(args.run, allow_nonfinite=True)
    report, block = diagnose_run(
        run,
        engine=args.engine,
        exoneration=args.exoneration,
        diagnoser=args.diagnoser,
        cells=args.cells,
        thresholds=args.thresholds,
    )
    if args.plots:
        report["plots"] = [str(p) for p in plot_residuals(run, block, Path(args.plots), report)]

    text = json.dumps(json_safe(report), indent=2)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(text + "\n")
    first = report["first_detection_time_s"]
    print(f"detected: {report['detected']}" + (f" at {first:.2f} s" if first is not None else ""))
    fired = sorted(((t, m) for m, t in report["module_detection_times_s"].items() if t is not None))
    if fired:
        print(
            "modules fired: "
            + ", ".join(f"{m} at {t:.2f} s" for t, m in fired)
            + (
                f" (M3.1 and M3.2 by the receiver test at {report['receiver_test_time_s']:.2f} s)"
                if report.get("receiver_test_time_s") is not None
                else ""
            )
        )
    print(
        "minimal diagnoses: "
        + (", ".join("{" + ", ".join(d) + "}" for d in report["final_minimal_diagnoses"]) or "none")
    )
    print(f"wrote {args.out}")
    return 0
