"""``marine-fdi export-raw``, ``predict-raw`` and ``score-raw``: raw-data suites in the LiU-ICE / DX'25 layout."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from ..benchmark import rawdata, rawscore
from ..benchmark.rawdata import export_raw, predict_raw, read_manifest
from ..benchmark.rawscore import dx_table, score_raw
from .common import (
    CommandParser,
    add_agent_option,
    add_progress_option,
    add_seed_offset_option,
    add_suite_option,
)
from .failures import fail


# ----------------------------------------------------------------------------- commands
def say_export_cost(suite_name: str) -> None:
    """The export's expected time and disk use, said before it starts (:mod:`marine_fdi_env.costs`)."""
    from ..benchmark.suites import load_suite
    from ..costs import RAW_BYTES_PER_SAMPLE, RAW_CPU_S_PER_SAMPLE, CostEstimate, say_cost

    try:
        suite = load_suite(suite_name)
    except ValueError:
        return  # export_raw names the bad suite
    samples = sum(s.duration_s / float(suite["env"].get("dt", 0.01)) for s in suite.scenarios)
    say_cost(
        "marine-fdi export-raw",
        f"{len(suite.scenarios)} scenarios of {suite.name}",
        CostEstimate(samples * RAW_CPU_S_PER_SAMPLE, samples * RAW_BYTES_PER_SAMPLE),
    )


def export_raw_main(argv=None) -> int:
    from ..outputs import prepare_out
    from .common import interrupted, parse_cli

    ap = CommandParser(
        prog="marine-fdi export-raw",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Write a suite's 100 Hz sensor samples (named columns, SI units) and "
        "ground truth in the LiU-ICE / DX'25 kit layout.",
        epilog=rawdata.__doc__,
    )
    add_suite_option(ap)
    ap.add_argument("--out", type=Path, required=True, help="output folder (its parent is created if missing)")
    add_seed_offset_option(ap)
    add_progress_option(ap)
    args, code = parse_cli(ap, argv)
    if args is None:
        return code
    t0 = time.perf_counter()
    try:
        out = prepare_out(args.out, create=False)  # export_raw creates it after checking the suite
        say_export_cost(args.suite)
        man = export_raw(args.suite, out, seed_offset=args.seed_offset, progress=not args.no_progress)
    except ValueError as e:
        return fail("marine-fdi export-raw", e)
    except KeyboardInterrupt:
        return interrupted("marine-fdi export-raw", "written scenarios are kept")
    n = sum(e["n_samples"] for e in man["scenarios"])
    print(
        f"wrote {len(man['scenarios'])} scenarios of {man['suite']} ({n} samples at {1 / man['sample_time_s']:g} Hz) "
        f"to {out}/data, ground truth and manifest.json in {time.perf_counter() - t0:.1f} s"
    )
    return 0


def predict_raw_main(argv=None) -> int:
    from ..outputs import prepare_out
    from .common import interrupted, parse_cli

    ap = CommandParser(
        prog="marine-fdi predict-raw",
        description="Write a benchmark agent's per-sample diagnoses of a raw suite (written by export-raw) in the "
        "LiU-ICE / DX'25 output layout: one output_<data file> per scenario. The reference's outputs "
        "written this way are the baseline a DX participant compares with.",
    )
    add_agent_option(ap)
    ap.add_argument("--data", type=Path, required=True, help="raw suite folder (marine-fdi export-raw --out)")
    ap.add_argument("--out", type=Path, required=True, help="predictions folder (its parent is created if missing)")
    ap.add_argument("--batch-size", type=int, default=32, help="episodes advanced together (default 32)")
    add_progress_option(ap)
    args, code = parse_cli(ap, argv)
    if args is None:
        return code
    try:
        if args.batch_size < 1:
            raise ValueError(f"--batch-size must be a positive integer, got {args.batch_size}")
        out = prepare_out(args.out, create=False)  # predict_raw creates it after checking data and agent
        predict_raw(args.agent, args.data, out, batch_size=args.batch_size, progress=not args.no_progress)
    except ValueError as e:
        return fail("marine-fdi predict-raw", e)
    except KeyboardInterrupt:
        return interrupted("marine-fdi predict-raw", "written files are kept")
    n = len(read_manifest(args.data)["scenarios"])
    print(f"wrote {n} prediction files of agent {args.agent} to {out}")
    return 0


def score_raw_main(argv=None) -> int:
    from ..benchmark.report import markdown_table
    from ..errors import require_extra
    from ..outputs import prepare_out
    from .common import INTERRUPTED, parse_cli

    ap = CommandParser(
        prog="marine-fdi score-raw",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Score per-sample diagnoses in the LiU-ICE / DX'25 layout with the "
        "benchmark's metrics and the DX per-sample ones.",
        epilog=rawscore.__doc__,
    )
    add_suite_option(ap, what="the predictions are for")
    ap.add_argument("--predictions", type=Path, required=True, help="folder of output_<scenario>.csv files")
    ap.add_argument(
        "--data",
        type=Path,
        default=None,
        help="the raw suite folder (export-raw --out): sample counts, engine failures, seed offset",
    )
    ap.add_argument(
        "--name", default=None, help="agent name in the results (default: predictions.json's, else the folder name)"
    )
    ap.add_argument(
        "--out", type=Path, default=None, help="write the results (.json or .parquet; readable by 'marine-fdi report')"
    )
    add_progress_option(ap)
    args, code = parse_cli(ap, argv)
    if args is None:
        return code
    try:
        if args.out is not None:
            from ..outputs import check_suffix
            from .evaluate import RESULT_SUFFIXES

            check_suffix(args.out, "--out", RESULT_SUFFIXES, "a results file")
            if args.out.suffix == ".parquet":
                require_extra("pyarrow", "--out *.parquet")
            prepare_out(args.out, is_dir=False, create=False)
        res = score_raw(
            args.suite, args.predictions, data_dir=args.data, agent=args.name, progress=not args.no_progress
        )
        if args.out is not None:
            prepare_out(args.out, is_dir=False)
            if args.out.suffix == ".parquet":
                from ..benchmark.records import write_results_parquet

                write_results_parquet(args.out, res)
            else:
                args.out.write_text(json.dumps(res, separators=(",", ":")) + "\n")
    except ValueError as e:
        return fail("marine-fdi score-raw", e)
    except KeyboardInterrupt:
        print("marine-fdi score-raw: interrupted (nothing written)", file=sys.stderr)
        return INTERRUPTED
    print(markdown_table([res]))
    print(dx_table([res]))
    m = res["dx_metrics"]
    f = lambda v: "–" if v is None else f"{100 * v:.1f} %"  # noqa: E731
    print(
        f"scored {res['n_scenarios']} scenarios of {res['suite']} from {args.predictions}: TDR "
        f"{f(m['true_detection_rate'])}, FAR {f(m['false_alarm_rate'])}, FIA {f(m['fault_isolation_accuracy'])}"
        + (f"; results: {args.out}" if args.out else "")
    )
    return 0
