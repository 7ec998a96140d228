"""``marine-fdi sweep``: every agent on every suite (and seed offset), on any backend, resumably."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from ..benchmark import sweep
from ..benchmark.suites import SUITE_NAMES
from ..benchmark.sweep import TABLE, run_sweep
from .common import CommandParser
from .failures import fail


def say_sweep_cost(agents: list[str], suites: list[str], n_offsets: int, workers: int) -> None:
    """The grid's expected time, said before it starts (:mod:`marine_fdi_env.costs`)."""
    from ..benchmark.agent_registry import list_agents
    from ..benchmark.suites import load_suite
    from ..costs import CostEstimate, say_cost
    from .common import lockstep_cost

    names = [e.name for e in list_agents() if e.available] if "all" in agents else agents
    try:
        loaded = [load_suite(s) for s in (SUITE_NAMES if "all" in suites else suites)]
    except ValueError:
        return  # run_sweep names the bad suite
    cpu, episodes = lockstep_cost(names, loaded, n_offsets)
    say_cost("marine-fdi sweep", f"{len(names)} agents x {episodes} episodes", CostEstimate(cpu, workers=workers))


def sweep_main(argv=None) -> int:
    from ..benchmark.report import markdown_table
    from ..errors import require_extra
    from ..outputs import prepare_out
    from .common import (
        add_backend_args,
        add_cache_args,
        add_progress_option,
        backend_from_args,
        cache_from_args,
        interrupted,
        parse_cli,
    )

    ap = CommandParser(
        prog="marine-fdi sweep",
        description=sweep.__doc__.splitlines()[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="\n".join(sweep.__doc__.splitlines()[2:]),
    )
    ap.add_argument(
        "--agents",
        nargs="+",
        required=True,
        metavar="AGENT",
        help="agent names (see 'marine-fdi agents'), model folders or file.py:Class; 'all' = every name",
    )
    ap.add_argument(
        "--suites",
        nargs="+",
        required=True,
        metavar="SUITE",
        help=f"suite names or JSON paths; 'all' = {' '.join(SUITE_NAMES)}",
    )
    ap.add_argument(
        "--seed-offsets",
        nargs="+",
        type=int,
        default=[0],
        metavar="K",
        help="noise seed offsets (default 0): each reruns the suite's scenarios with new noise",
    )
    ap.add_argument(
        "--out",
        type=Path,
        default=Path("results") / "sweep",
        help="sweep folder (default results/sweep; its parent is created if missing); a later sweep into the "
        "same folder adds its cells to the table",
    )
    add_backend_args(ap)
    add_cache_args(ap)
    add_progress_option(ap)
    args, code = parse_cli(ap, argv)
    if args is None:
        return code
    try:
        backend = backend_from_args(args)
        cache, cache_dir = cache_from_args(args)
        require_extra("pyarrow", "sweep (its table episodes.parquet)")
        out = prepare_out(args.out, create=False)  # run_sweep creates it after checking agents and suites
        say_sweep_cost(args.agents, args.suites, len(args.seed_offsets), backend.workers)
        res = run_sweep(
            args.agents,
            args.suites,
            args.seed_offsets,
            out,
            backend=backend,
            batch_size=args.batch_size,
            progress=not args.no_progress,
            cache=cache,
            cache_dir=cache_dir,
        )
    except ValueError as e:
        return fail("marine-fdi sweep", e)
    except KeyboardInterrupt:
        out = locals().get("out")
        n = sweep.kept_episodes(out) if out is not None else 0
        kept = (
            f"the {n} episode records of the finished chunks are kept in {out / sweep.PARTIAL}"
            if n
            else "no chunk of episodes had finished, nothing is kept"
        )
        return interrupted("marine-fdi sweep", kept)
    run = res["run"]
    print(markdown_table(res["table"]))
    n = sum(r["n_episodes"] for r in res["results"])
    where = run["backend"]
    if run["backend"] == "ray" and (run["ray_address"] or os.environ.get("RAY_ADDRESS")):
        where += f" (cluster at {run['ray_address'] or os.environ.get('RAY_ADDRESS')})"
    elif run["backend"] != "serial":
        where += f" ({run['workers']} workers)"
    print(
        f"wrote {out / TABLE} ({n} episodes, {len(res['results'])} agent x suite cells) and {out / 'metrics.json'}; "
        f"{run['episodes_run']} episodes run in {run['wall_s']:.1f} s on {where}, load average "
        f"{run['load_average_before'][0]:.2f} before, {run['load_average_after'][0]:.2f} after"
    )
    return 0
