"""``marine-fdi evaluate``: run an agent on a frozen suite and print its metrics."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ..benchmark.evaluate import evaluate


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="marine-fdi evaluate",
        description="Run an agent on a frozen evaluation suite and print its metrics. With no arguments: the "
                    "reference diagnoser on thesis-v1.")
    ap.add_argument("--agent", default="reference",
                    help="an agent name (see 'marine-fdi agents': null, random, reference, sequential, oracle, "
                         "the shipped models), a directory with agent.json, or path/to/file.py:ClassName (default: reference)")
    ap.add_argument("--suite", default="thesis-v1", help="suite name or JSON path (default: thesis-v1)")
    ap.add_argument("--out", type=Path, default=None,
                    help="results file: .json, or .parquet for the episode records as a table "
                         "(default: results/AGENT_SUITE.json)")
    ap.add_argument("--seed-offset", type=int, default=0, help="shift every noise seed (new noise, same scenarios)")
    ap.add_argument("--force", action="store_true",
                    help="recompute and overwrite --out when it already holds results (without it: an error)")
    from .common import add_backend_args, add_cache_args

    add_backend_args(ap)
    add_cache_args(ap)
    ap.add_argument("--reward", choices=("v0", "v1"), default=None,
                    help="reward scored in the results' return (default: the suite's, else v1 = MarineFDI-v1)")
    ap.add_argument("--no-progress", action="store_true", help="no progress bar")
    return ap


def evaluate_main(argv=None) -> int:
    from .common import interrupted, parse_cli
    from ..benchmark.report import markdown_table

    args, code = parse_cli(build_parser(), argv)
    if args is None:
        return code
    try:
        from ..benchmark.agent_api import agent_file_stem
        from .common import backend_from_args, cache_from_args
        from ..outputs import prepare_out
        from ..errors import require_extra

        backend = backend_from_args(args)
        cache, cache_dir = cache_from_args(args)
        out = args.out or Path("results") / f"{agent_file_stem(args.agent)}_{Path(args.suite).stem}.json"
        if out.suffix == ".parquet":
            require_extra("pyarrow", "--out *.parquet")
        out = prepare_out(out, "--out", is_dir=False, create=False)  # evaluate() creates it after its checks
        partial = out.with_name(out.name + ".partial.jsonl")
        if out.exists() and not partial.exists() and not args.force:
            raise ValueError(f"--out {out} already holds results; pass --force to recompute and overwrite them, "
                             "or choose another --out")
        result = evaluate(args.agent, args.suite, out, seed_offset=args.seed_offset, batch_size=args.batch_size,
                          progress=not args.no_progress, backend=backend,
                          reward=args.reward, cache=cache, cache_dir=cache_dir)
    except ValueError as e:
        print(f"marine-fdi evaluate: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return interrupted("marine-fdi evaluate")
    print(markdown_table([result]))
    cached = result.get("feature_cache")
    print(f"\nresults: {out}" + (f" (scored on the feature cache {', '.join(cached)})" if cached else ""))
    return 0
