"""``marine-fdi report``: Markdown tables and plots from results files."""

from __future__ import annotations

import argparse
import sys
from typing import Sequence

from ..benchmark.report import report_pyplot, write_report
from ..errors import UsageError
from .common import CommandParser, add_force_option
from .failures import fail


def build_report_parser(prog: str = "marine-fdi report") -> argparse.ArgumentParser:
    p = CommandParser(prog=prog, description="Markdown report and plots from results files.")
    p.add_argument(
        "results",
        nargs="+",
        help="results files written by 'marine-fdi evaluate' (.json or .parquet), or sweep folders "
        "('marine-fdi sweep --out DIR') or their episodes.parquet",
    )
    p.add_argument(
        "--out",
        default="report",
        help="output folder (default: ./report; created, and its parent if missing, never more levels)",
    )
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots (no matplotlib needed)")
    add_force_option(p, "overwrite the report in --out (without it: an error when it has one)")
    return p


def report_main(argv: Sequence[str] | None = None) -> int:
    """``marine-fdi report results*.json [--out DIR] [--no-plots]``; returns the exit code."""
    from .common import parse_cli

    args, code = parse_cli(build_report_parser(), argv)
    if args is None:
        return code
    try:
        from ..outputs import prepare_out

        if not args.no_plots:
            report_pyplot()
        out = prepare_out(args.out, "--out", is_dir=True, create=False)  # write_report creates it
        if (out / "report.md").exists() and not args.force:
            raise UsageError(
                f"--out {out} already holds a report (report.md); pass --force to overwrite it, or choose another --out"
            )
        path = write_report(args.results, out, plots=not args.no_plots)
    except (ValueError, OSError) as e:
        return fail("marine-fdi report", e)
    except KeyboardInterrupt:
        print("marine-fdi report: interrupted", file=sys.stderr)
        return 130
    print(f"wrote {path}" + ("" if args.no_plots else " and its plots"))
    return 0
