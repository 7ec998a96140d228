"""``marine-fdi submit`` and ``marine-fdi verify``: entries with provenance (docs/submitting.md)."""

from __future__ import annotations

import argparse
import shlex
import shutil
import sys
from pathlib import Path

from .failures import fail

__all__ = ["submit_main", "verify_main", "shipped_specs"]

_SUBMIT_HELP = """\
Scores AGENT on the frozen suites (default: all of them) and writes an entry in --out:

  entry.json              the agent (its name and model files, or its files, by sha256), the
                          package and dependency versions, each suite's name, version and content
                          sha256, and the metrics, DX metrics and 95 % intervals computed from the traces
  traces/SUITE.json.gz    the per-episode records (declaration trace, return, ...) of each suite
  agent/                  a copy of a folder or file agent, so that anyone can replay it

'marine-fdi verify DIR' recomputes every metric from the traces and checks every hash; 'marine-fdi
verify --rerun DIR' simulates the suites again and replays the agent.  --shipped writes one entry per
shipped agent and training seed into --out (the repository's leaderboard/entries).  After Ctrl-C
the finished suites are kept in OUT/.work and the same command resumes.
"""


def shipped_specs() -> list[tuple[str, str]]:
    """(entry folder name, agent spec) of every shipped agent and training seed: the baselines by name,
    every model folder, a multi-seed model's seed folders one by one."""
    from ..benchmark.agent_registry import list_agents

    out = []
    for e in list_agents():
        if e.kind == "baseline":
            out.append((e.name, e.name))
            continue
        folder = Path(e.spec)
        seeds = sorted(p for p in folder.iterdir() if p.is_dir() and (p / "agent.json").is_file())
        if seeds:
            out += [(f"{e.name}-{p.name}", str(p)) for p in seeds]
        else:
            out.append((e.name, str(folder)))
    return out


def _clear(out: Path) -> None:
    """Remove an entry (``--force``): its entry.json, traces, agent copy and kept work."""
    from ..benchmark.entries import ENTRY_FILE, TRACES, WORK
    from ..benchmark.provenance import AGENT_FOLDER

    (out / ENTRY_FILE).unlink(missing_ok=True)
    for sub in (TRACES, AGENT_FOLDER, WORK):
        shutil.rmtree(out / sub, ignore_errors=True)


def submit_main(argv=None) -> int:
    from ..benchmark.suites import SUITE_NAMES
    from .common import CommandParser, add_backend_args, add_force_option, add_progress_option, interrupted, parse_cli

    argv = list(sys.argv[1:] if argv is None else argv)
    ap = CommandParser(
        prog="marine-fdi submit",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Score an agent on the frozen suites and write an entry anyone can verify.",
        epilog=_SUBMIT_HELP,
    )
    ap.add_argument(
        "agent",
        nargs="?",
        metavar="AGENT",
        help="an agent name ('marine-fdi agents'), a folder with agent.json, or path/to/file.py:ClassName",
    )
    ap.add_argument(
        "--shipped",
        action="store_true",
        help="every shipped agent and training seed without an entry in --out, one entry each",
    )
    ap.add_argument(
        "--suites", nargs="+", default=["all"], metavar="SUITE", help=f"default all: {' '.join(SUITE_NAMES)}"
    )
    ap.add_argument(
        "--out",
        type=Path,
        required=True,
        metavar="DIR",
        help="the entry folder (with --shipped: the folder of entries)",
    )
    ap.add_argument(
        "--training-data",
        default=None,
        metavar="TEXT",
        help="what the agent was trained on (presets, episodes, seeds; none for a rule): recorded as declared",
    )
    ap.add_argument("--notes", default=None, metavar="TEXT", help="anything else a reader should know")
    ap.add_argument(
        "--needs",
        nargs="+",
        default=[],
        metavar="EXTRA",
        help="optional extras the agent needs (e.g. train), recorded with those of a shipped model",
    )
    add_force_option(ap, "overwrite an entry in --out")
    add_backend_args(ap)
    add_progress_option(ap)
    args, code = parse_cli(ap, argv)
    if args is None:
        return code
    outs: list[Path] = []
    try:
        from ..benchmark.entries import ENTRY_FILE, submit_entries
        from ..errors import UsageError
        from ..outputs import prepare_out
        from .common import backend_from_args

        if bool(args.agent) == bool(args.shipped):
            raise UsageError("submit: give one AGENT, or --shipped (every shipped agent and training seed)")
        backend = backend_from_args(args)
        suites = list(SUITE_NAMES) if "all" in args.suites else list(dict.fromkeys(args.suites))
        unknown = [s for s in suites if s not in SUITE_NAMES]
        if unknown:
            from ..suggest import did_you_mean

            raise UsageError(
                f"--suites: {unknown[0]!r} is not a frozen suite{did_you_mean(unknown[0], SUITE_NAMES)}; "
                f"allowed: all, {', '.join(SUITE_NAMES)}"
            )
        root = prepare_out(args.out, "--out", is_dir=True, create=False)
        if args.shipped:
            pairs = shipped_specs()
            specs, outs = [s for _, s in pairs], [root / n for n, _ in pairs]
        else:
            specs, outs = [args.agent], [root]
        taken = [o for o in outs if (o / ENTRY_FILE).is_file()]
        if args.shipped and taken and not args.force:  # --shipped adds the entries that are missing
            keep = [i for i, o in enumerate(outs) if o not in taken]
            if not keep:
                raise UsageError(f"--out {root}: every shipped agent has an entry; pass --force to score them again")
            print(
                f"marine-fdi submit: {len(taken)} shipped agents have an entry in {root}; scoring the other "
                f"{len(keep)} ({', '.join(outs[i].name for i in keep)})",
                file=sys.stderr,
            )
            specs, outs, taken = [specs[i] for i in keep], [outs[i] for i in keep], []
        if taken and not args.force:
            raise UsageError(
                f"--out {taken[0]} already holds an entry; pass --force to score again and overwrite it, "
                "or choose another --out"
            )
        declared = {k: v for k, v in (("training_data", args.training_data), ("notes", args.notes)) if v}
        if args.needs:
            declared["needs"] = list(args.needs)
        _say_cost(specs, suites, backend.workers)
        prepare_out(args.out, "--out", is_dir=True)
        for o in outs:
            if args.force:
                _clear(o)
            o.mkdir(exist_ok=True)
        command = shlex.join(["marine-fdi", "submit"] + [a for a in argv if a != "--force"])
        submit_entries(
            specs,
            suites,
            outs,
            declared=declared,
            command=command,
            workers=args.workers,
            batch_size=args.batch_size,
            backend=backend,
            progress=not args.no_progress,
        )
    except ValueError as e:
        return fail("marine-fdi submit", e)
    except KeyboardInterrupt:
        return interrupted("marine-fdi submit", "the finished suites are kept in OUT/.work")
    return 0


def _say_cost(specs: list[str], suites: list[str], workers: int) -> None:
    from ..benchmark.suites import load_suite
    from ..costs import CostEstimate, say_cost
    from .common import lockstep_cost

    cpu, n = lockstep_cost([str(s) for s in specs], [load_suite(s) for s in suites])
    say_cost("marine-fdi submit", f"{len(specs)} agent(s) x {n} episodes", CostEstimate(cpu, workers=workers))


def verify_main(argv=None) -> int:
    from .common import CommandParser, add_backend_args, add_progress_option, parse_cli

    ap = CommandParser(
        prog="marine-fdi verify",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Check entries written by 'marine-fdi submit': every hash, and every metric recomputed from "
        "the traces; with --rerun, the suites simulated again and the agents replayed.",
        epilog="What each check catches: the hashes catch corruption and name the provenance (a changed suite "
        "file, trace or model); recomputation catches an edited metric; only --rerun catches an edited trace. "
        "Wall-clock fields are never compared. docs/submitting.md.",
    )
    ap.add_argument("entries", nargs="+", metavar="DIR", help="entry folders, or folders of entry folders")
    ap.add_argument(
        "--rerun",
        action="store_true",
        help="also simulate the suites again and replay the agents (together, in lockstep), comparing every "
        "record field by field (minutes per entry; an interrupted rerun starts over)",
    )
    ap.add_argument(
        "--hashes-only",
        action="store_true",
        help="only the hashes (agent files, suites, traces), without recomputing the metrics: a second for "
        "all the leaderboard's entries; catches corruption, not an edited metric",
    )
    add_backend_args(ap)
    add_progress_option(ap)
    args, code = parse_cli(ap, argv)
    if args is None:
        return code
    try:
        from ..benchmark.entries import rerun_entries, verify_entry
        from ..benchmark.leaderboard import find_entries
        from ..errors import DataFileError, UsageError
        from .common import backend_from_args

        backend = backend_from_args(args)
        dirs = find_entries(args.entries)
        if args.rerun and args.hashes_only:
            raise UsageError("--rerun and --hashes-only: choose one (--rerun checks the hashes too)")
        if args.rerun:
            checks = rerun_entries(
                dirs, workers=args.workers, batch_size=args.batch_size, backend=backend, progress=not args.no_progress
            )
        else:
            checks = [verify_entry(d, recompute=not args.hashes_only) for d in dirs]
        for c in checks:
            if c.ok:
                print(f"verified {c.entry}: " + "; ".join(c.checked[:1] + [f"{len(c.checked)} checks"] + c.notes))
            else:
                print(
                    f"REFUSED {c.entry}: {c.problems[0]}"
                    + (f" (+{len(c.problems) - 1} more)" if c.problems[1:] else "")
                )
        bad = [c for c in checks if not c.ok]
        if bad:
            raise DataFileError(
                f"{len(bad)} of {len(checks)} entries do not verify; {bad[0].entry}: {bad[0].problems[0]}"
            )
    except ValueError as e:
        return fail("marine-fdi verify", e)
    return 0
