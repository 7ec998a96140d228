"""Conventions shared by the long-running ``marine-fdi`` commands (sweep, export-raw, score-raw,
predict-raw, and the backends of evaluate and dataset):

* ``--out`` may name a folder whose parent does not exist yet: the parent is created, never more
  levels (a typo in a long path is an error, not a tree of new folders);
* progress bars count episodes (or scenarios) and advance as each one progresses, not per batch;
  a resumed run says "resuming at k/n";
* Ctrl-C prints "interrupted" and exits with code 130, keeping the finished work, and rerunning
  the same command resumes;
* a command ends with one final line saying what it wrote;
* an option that needs an optional extra (``--plots``: matplotlib, Parquet outputs: pyarrow,
  ``--backend ray``: Ray) is checked before any work starts: one line naming the extra
  (``pip install 'marine-fdi-env[plots]'``), exit code 2;
* on a cold numba cache the first compilation prints one line, "compiling the model (first run
  only, about a minute)" (:mod:`marine_fdi_env.coldstart`), and timings (the ``compute_s`` of
  episodes) start after a warm-up, so compilation never counts.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

from ..errors import UsageError, require_extra
from ..jsonfile import json_safe
from .failures import INTERRUPTED, USAGE_ERROR, fail

__all__ = [
    "PROG",
    "INTERRUPTED",
    "USAGE_ERROR",
    "CommandParser",
    "parse_cli",
    "run_parsed",
    "interrupted",
    "add_agent_option",
    "add_suite_option",
    "add_seed_offset_option",
    "add_json_option",
    "add_force_option",
    "add_progress_option",
    "add_backend_args",
    "backend_from_args",
    "add_cache_args",
    "cache_from_args",
    "lockstep_cost",
    "option_value",
    "positive_seconds",
    "dumps",
]

PROG = "marine-fdi"


class CommandParser(argparse.ArgumentParser):
    """The parser of every ``marine-fdi`` command: a usage error raises :class:`~marine_fdi_env.errors.UsageError`
    (its ``prog`` the command's, subcommands included) instead of printing the usage and exiting, so it ends
    like every other refused input (:mod:`.failures`: one line, exit code 2)."""

    def error(self, message: str):
        exc = UsageError(message)
        exc.prog = self.prog
        raise exc


def parse_cli(ap: argparse.ArgumentParser, argv) -> tuple[argparse.Namespace | None, int | None]:
    """``(args, None)``, or ``(None, exit code)``: ``--help`` and ``--version`` 0; a usage error of a
    :class:`CommandParser` 2, after its one line (:func:`.failures.fail`).  The commands return their
    exit code instead of raising ``SystemExit``."""
    try:
        return ap.parse_args(argv), None
    except SystemExit as e:
        return None, (e.code if isinstance(e.code, int) else 0)
    except UsageError as e:
        return None, fail(getattr(e, "prog", ap.prog), e)


def run_parsed(build_parser, run, argv, prog: str) -> int:
    """A command that parses its options once and hands them to ``run(args, argv, prog)`` (``argv``: the
    command line, for the outputs that record it); ``argv`` None: the process's arguments."""
    argv = list(argv) if argv is not None else sys.argv[1:]
    args, code = parse_cli(build_parser(prog), argv)
    if args is None:
        return code
    return run(args, argv, prog)


def interrupted(prog: str, kept: str = "") -> int:
    """After Ctrl-C: one line saying what is kept and that the same command resumes; the exit code."""
    print(
        f"{prog}: interrupted; " + (f"{kept}, " if kept else "") + "rerun the same command to resume", file=sys.stderr
    )
    return INTERRUPTED


def add_agent_option(ap: argparse.ArgumentParser) -> None:
    """``--agent``: the agent to run, by name, folder or file (default reference)."""
    ap.add_argument(
        "--agent",
        default="reference",
        help="an agent name (see 'marine-fdi agents': null, random, reference, sequential, oracle, "
        "the shipped models), a directory with agent.json, or path/to/file.py:ClassName (default: reference)",
    )


def add_suite_option(ap: argparse.ArgumentParser, default: str | None = None, what: str = "") -> None:
    """``--suite``: a suite by name or JSON path; required unless it has a ``default``; ``what`` ends its help."""
    text = "suite name or JSON path" + (f" {what}" if what else "")
    if default is None:
        ap.add_argument("--suite", required=True, help=text)
    else:
        ap.add_argument("--suite", default=default, help=f"{text} (default: {default})")


def add_seed_offset_option(ap: argparse.ArgumentParser) -> None:
    """``--seed-offset``: new noise on the same scenarios."""
    ap.add_argument("--seed-offset", type=int, default=0, help="shift every noise seed (new noise, same scenarios)")


def add_json_option(ap: argparse.ArgumentParser, text: str = "print JSON") -> None:
    """``--json``: print a command's answer as JSON (``text``: its help)."""
    ap.add_argument("--json", action="store_true", help=text)


def add_force_option(ap: argparse.ArgumentParser, text: str) -> None:
    """``--force``: overwrite what ``--out`` already holds (``text``: what, and what happens without it)."""
    ap.add_argument("--force", action="store_true", help=text)


def add_progress_option(ap: argparse.ArgumentParser) -> None:
    """``--no-progress``: no progress bar."""
    ap.add_argument("--no-progress", action="store_true", help="no progress bar")


def add_backend_args(ap: argparse.ArgumentParser, default_batch: int = 32) -> None:
    """``--backend``, ``--workers``, ``--ray-address``, ``--batch-size``."""
    from ..benchmark.backends import BACKENDS

    ap.add_argument(
        "--backend",
        choices=BACKENDS,
        default=None,
        help="where chunks of episodes run: serial (this process), process (a local pool of --workers), "
        "ray (a local Ray instance with --workers CPUs, or the cluster at --ray-address / "
        "RAY_ADDRESS). Default: ray with --ray-address, process if --workers > 1, else serial. Results do "
        "not depend on it.",
    )
    ap.add_argument("--workers", type=int, default=1, metavar="N", help="worker processes / local Ray CPUs (default 1)")
    ap.add_argument(
        "--ray-address",
        default=None,
        metavar="ADDR",
        help="connect to this Ray cluster (e.g. ray://head:10001 or auto); default: $RAY_ADDRESS, "
        "else a local instance",
    )
    ap.add_argument(
        "--batch-size",
        type=int,
        default=default_batch,
        metavar="N",
        help=f"episodes advanced together in one task (default {default_batch})",
    )


def backend_from_args(args):
    from ..benchmark.backends import Backend

    if not isinstance(args.batch_size, int) or args.batch_size < 1:
        raise UsageError(f"--batch-size must be a positive integer, got {args.batch_size!r}")
    backend = Backend.make(args.backend, args.workers, args.ray_address)
    if backend.name == "ray":
        require_extra("ray", "--backend ray")
    return backend


def add_cache_args(ap: argparse.ArgumentParser) -> None:
    """``--cache`` and ``--cache-dir`` (the feature caches of :mod:`marine_fdi_env.benchmark.feature_cache`)."""
    from ..benchmark.feature_cache import CACHE_MODES, DEFAULT_CACHE_DIR

    ap.add_argument(
        "--cache",
        choices=CACHE_MODES,
        default="use",
        help="feature caches (a suite's observations and infos, so agents are scored without simulating): "
        "use = score on the cache of the suite when --cache-dir has one (default), write = simulate "
        "and write it, off = neither. A cache made by other code or with other parameters is "
        "refused with a message",
    )
    ap.add_argument(
        "--cache-dir",
        type=Path,
        default=DEFAULT_CACHE_DIR,
        metavar="DIR",
        help=f"where feature caches are (default {DEFAULT_CACHE_DIR})",
    )


def cache_from_args(args) -> tuple[str, Path]:
    """(mode, folder) of ``--cache`` and ``--cache-dir``; writing needs pyarrow (checked before any work)."""
    if args.cache == "write":
        require_extra("pyarrow", "--cache write")
    return args.cache, args.cache_dir


def lockstep_cost(agents: list[str], suites: list, n_offsets: int = 1) -> tuple[float, int]:
    """The expected CPU seconds and the number of episodes of scoring ``agents`` (specs) together, in lockstep,
    on the loaded ``suites``, each with ``n_offsets`` seed offsets (:mod:`marine_fdi_env.costs`)."""
    from ..benchmark.agent_api import BUILTIN_AGENTS, load_agent
    from ..benchmark.evaluate import plan_passes
    from ..costs import lockstep_episode_cpu_s

    # the simulation passes: the baselines say which diagnoser they need (cheap to make); a model, the default
    passes = len(plan_passes([load_agent(a) for a in agents if a in BUILTIN_AGENTS], {})) or 1
    episodes = sum(len(s.scenarios) for s in suites) * n_offsets
    cpu = n_offsets * sum(lockstep_episode_cpu_s(agents, passes, sc.duration_s) for s in suites for sc in s.scenarios)
    return cpu, episodes


def option_value(option: str, fn, *args, **kwargs):
    """Call ``fn`` and prefix a ValueError's message with the option it came from."""
    try:
        return fn(*args, **kwargs)
    except ValueError as exc:
        raise UsageError(f"{option}: {exc}") from None


def positive_seconds(option: str, value: float) -> float:
    if not (math.isfinite(value) and value > 0):
        raise UsageError(f"{option} must be a positive finite number of seconds, got {value!r}")
    return float(value)


def dumps(obj) -> str:
    """``obj`` as indented strict JSON (non-finite numbers as null) for a command's listing."""
    return json.dumps(json_safe(obj), indent=2, allow_nan=False)
