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
  only, about a minute)" (:mod:`marine_fdi_env._coldstart`), and timings (the ``compute_s`` of
  episodes) start after a warm-up, so compilation never counts.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from ..errors import UsageError, require_extra

__all__ = [
    "PROG",
    "INTERRUPTED",
    "USAGE_ERROR",
    "parse_cli",
    "interrupted",
    "add_backend_args",
    "backend_from_args",
    "add_cache_args",
    "cache_from_args",
    "option_value",
    "positive_seconds",
    "strict_json",
    "dumps",
]

PROG = "marine-fdi"


INTERRUPTED = 130  # exit code after Ctrl-C (128 + SIGINT)
USAGE_ERROR = 2  # exit code of an invalid input (argparse's convention)


def parse_cli(ap: argparse.ArgumentParser, argv) -> tuple[argparse.Namespace | None, int | None]:
    """``(args, None)``, or ``(None, exit code)`` where argparse would exit (``--help``: 0, a usage error: 2):
    the commands return their exit code instead of raising ``SystemExit``."""
    try:
        return ap.parse_args(argv), None
    except SystemExit as e:
        return None, (e.code if isinstance(e.code, int) else 0)


def interrupted(prog: str, kept: str = "") -> int:
    """After Ctrl-C: one line saying what is kept and that the same command resumes; the exit code."""
    print(
        f"{prog}: interrupted; " + (f"{kept}, " if kept else "") + "rerun the same command to resume", file=sys.stderr
    )
    return INTERRUPTED


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


def strict_json(obj):
    """JSON-safe copy: non-finite floats become null."""
    if isinstance(obj, dict):
        return {k: strict_json(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [strict_json(v) for v in obj]
    if isinstance(obj, (float, np.floating)):
        return float(obj) if math.isfinite(obj) else None
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.bool_):
        return bool(obj)
    return obj


def dumps(obj) -> str:
    return json.dumps(strict_json(obj), indent=2, allow_nan=False)
