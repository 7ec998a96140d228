"""``marine-fdi evaluate``: run an agent on a frozen suite and print its metrics."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..benchmark.evaluate import evaluate
from ..errors import UsageError
from .common import (
    CommandParser,
    add_agent_option,
    add_backend_args,
    add_cache_args,
    add_force_option,
    add_progress_option,
    add_seed_offset_option,
    add_suite_option,
)
from .failures import fail

RESULT_SUFFIXES = (".json", ".parquet")  # the formats a results file is written in


def same_run_results(path: Path, args: argparse.Namespace) -> dict | None:
    """The results in ``path`` if they are those of this command's run (agent, suite and its version,
    seed offset, reward), else None."""
    from ..benchmark.report import load_results
    from ..benchmark.suites import load_suite

    try:
        kept = load_results([path])[0]
    except ValueError:
        return None
    suite = load_suite(args.suite)
    same = (
        kept.get("agent_spec") == str(args.agent)
        and kept.get("suite") == suite.name
        and kept.get("suite_version") == suite["version"]
        and kept.get("seed_offset") == args.seed_offset
    )
    if args.reward is not None:
        from ..envs.fdi_env import env_id_for
        from ..envs.reward import make_reward_config

        same = same and kept.get("env_id") == env_id_for(make_reward_config(args.reward))
    return kept if same else None


def default_results(path: Path, args: argparse.Namespace) -> tuple[Path, dict | None]:
    """Where a run without ``--out`` goes: the first of ``path``, ``STEM-2.SUFFIX``, ``STEM-3.SUFFIX``, ...
    that holds this run's results (returned with them, to show), is being written (a partial file:
    resumed), or is free."""
    k = 1
    while True:
        p = path if k == 1 else path.with_name(f"{path.stem}-{k}{path.suffix}")
        if not p.exists() or p.with_name(p.name + ".partial.jsonl").exists():
            return p, None
        kept = same_run_results(p, args)
        if kept is not None:
            return p, kept
        k += 1


def build_parser() -> argparse.ArgumentParser:
    ap = CommandParser(
        prog="marine-fdi evaluate",
        description="Run an agent on a frozen evaluation suite and print its metrics. With no arguments: the "
        "reference diagnoser on thesis-v1.",
    )
    add_agent_option(ap)
    add_suite_option(ap, default="thesis-v1")
    ap.add_argument(
        "--out",
        type=Path,
        default=None,
        help="results file: .json, or .parquet for the episode records as a table "
        "(default: results/AGENT_SUITE.json; when that holds this run's results they are shown, "
        "when it holds another run's a new file RESULTS-2.json is written beside it)",
    )
    add_seed_offset_option(ap)
    add_force_option(
        ap,
        "recompute and overwrite the results file when it already holds results (without it: an "
        "explicit --out is an error, the default file is shown)",
    )
    add_backend_args(ap)
    add_cache_args(ap)
    ap.add_argument(
        "--reward",
        choices=("v0", "v1"),
        default=None,
        help="reward scored in the results' return (default: the suite's, else v1 = MarineFDI-v1)",
    )
    add_progress_option(ap)
    return ap


def evaluate_main(argv=None) -> int:
    from ..benchmark.report import markdown_table
    from .common import interrupted, parse_cli

    args, code = parse_cli(build_parser(), argv)
    if args is None:
        return code
    try:
        from ..benchmark.agent_api import agent_file_stem
        from ..errors import require_extra
        from ..outputs import check_suffix, prepare_out
        from .common import backend_from_args, cache_from_args

        backend = backend_from_args(args)
        cache, cache_dir = cache_from_args(args)
        out = args.out or Path("results") / f"{agent_file_stem(args.agent)}_{Path(args.suite).stem}.json"
        check_suffix(out, "--out", RESULT_SUFFIXES, "a results file")
        if out.suffix == ".parquet":
            require_extra("pyarrow", "--out *.parquet")
        out = prepare_out(out, "--out", is_dir=False, create=False)  # evaluate() creates it after its checks
        partial = out.with_name(out.name + ".partial.jsonl")
        if out.exists() and not partial.exists() and not args.force:
            if args.out is not None:
                raise UsageError(
                    f"--out {out} already holds results; pass --force to recompute and overwrite them, "
                    "or choose another --out"
                )
            out, kept = default_results(out, args)
            if kept is not None:  # this very run's results: show them
                print(markdown_table([kept]))
                print(f"\nresults: {out} (computed before; --force recomputes them)")
                return 0
        from ..benchmark.suites import load_suite
        from ..costs import CostEstimate, episode_cpu_s, say_cost

        suite = load_suite(args.suite)
        say_cost(
            "marine-fdi evaluate",
            f"{len(suite.scenarios)} episodes of {suite.name}",
            CostEstimate(
                sum(episode_cpu_s(str(args.agent), s.duration_s) for s in suite.scenarios), workers=backend.workers
            ),
        )
        result = evaluate(
            args.agent,
            args.suite,
            out,
            seed_offset=args.seed_offset,
            batch_size=args.batch_size,
            progress=not args.no_progress,
            backend=backend,
            reward=args.reward,
            cache=cache,
            cache_dir=cache_dir,
        )
    except ValueError as e:
        return fail("marine-fdi evaluate", e)
    except KeyboardInterrupt:
        return interrupted("marine-fdi evaluate")
    print(markdown_table([result]))
    cached = result.get("feature_cache")
    print(f"\nresults: {out}" + (f" (scored on the feature cache {', '.join(cached)})" if cached else ""))
    return 0
