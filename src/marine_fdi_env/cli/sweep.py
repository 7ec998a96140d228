"""``marine-fdi sweep``: every agent on every suite (and seed offset), on any backend, resumably."""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from ..benchmark import sweep
from ..benchmark.suites import SUITE_NAMES
from ..benchmark.sweep import TABLE, run_sweep


def sweep_main(argv=None) -> int:
    from .common import add_backend_args, add_cache_args, backend_from_args, cache_from_args, interrupted, parse_cli
    from ..outputs import prepare_out
    from ..errors import require_extra
    from ..benchmark.report import markdown_table

    ap = argparse.ArgumentParser(prog="marine-fdi sweep", description=sweep.__doc__.splitlines()[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter,
                                 epilog="\n".join(sweep.__doc__.splitlines()[2:]))
    ap.add_argument("--agents", nargs="+", required=True, metavar="AGENT",
                    help="agent names (see 'marine-fdi agents'), model folders or file.py:Class; 'all' = every name")
    ap.add_argument("--suites", nargs="+", required=True, metavar="SUITE",
                    help=f"suite names or JSON paths; 'all' = {' '.join(SUITE_NAMES)}")
    ap.add_argument("--seed-offsets", nargs="+", type=int, default=[0], metavar="K",
                    help="noise seed offsets (default 0): each reruns the suite's scenarios with new noise")
    ap.add_argument("--out", type=Path, required=True, help="sweep folder (its parent is created if missing)")
    add_backend_args(ap)
    add_cache_args(ap)
    ap.add_argument("--no-progress", action="store_true", help="no progress bar")
    args, code = parse_cli(ap, argv)
    if args is None:
        return code
    try:
        backend = backend_from_args(args)
        cache, cache_dir = cache_from_args(args)
        require_extra("pyarrow", "sweep (its table episodes.parquet)")
        out = prepare_out(args.out, create=False)  # run_sweep creates it after checking agents and suites
        res = run_sweep(args.agents, args.suites, args.seed_offsets, out, backend=backend,
                        batch_size=args.batch_size, progress=not args.no_progress, cache=cache, cache_dir=cache_dir)
    except ValueError as e:
        print(f"marine-fdi sweep: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        return interrupted("marine-fdi sweep", "finished chunks are kept")
    run = res["run"]
    print(markdown_table(res["table"]))
    n = sum(r["n_episodes"] for r in res["results"])
    where = run["backend"]
    if run["backend"] == "ray" and (run["ray_address"] or os.environ.get("RAY_ADDRESS")):
        where += f" (cluster at {run['ray_address'] or os.environ.get('RAY_ADDRESS')})"
    elif run["backend"] != "serial":
        where += f" ({run['workers']} workers)"
    print(f"wrote {out / TABLE} ({n} episodes, {len(res['results'])} agent x suite cells) and {out / 'metrics.json'}; "
          f"{run['episodes_run']} episodes run in {run['wall_s']:.1f} s on {where}, load average "
          f"{run['load_average_before'][0]:.2f} before, {run['load_average_after'][0]:.2f} after")
    return 0
