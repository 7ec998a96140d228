"""Conventions shared by the long-running ``marine-fdi`` commands (sweep, export-raw, score-raw,
predict-raw, and the backends of evaluate and dataset):

* ``--out`` may name a folder whose parent does not exist yet: the parent is created, never more
  levels (a typo in a long path is an error, not a tree of new folders);
* progress bars count episodes (or scenarios) and advance as each one progresses, not per batch;
  a resumed run says "resuming at k/n";
* Ctrl-C prints "interrupted" and exits with code 130, keeping the finished work, and rerunning
  the same command resumes;
* a command ends with one final line saying what it wrote.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

__all__ = ["INTERRUPTED", "prepare_out", "progress_bar", "add_backend_args", "backend_from_args"]

INTERRUPTED = 130  # exit code after Ctrl-C (128 + SIGINT)


def prepare_out(path: "str | Path", option: str = "--out", *, is_dir: bool = True) -> Path:
    """Create the parent of ``path`` if missing (one level only) and, for a folder, ``path`` itself."""
    p = Path(path)
    parent = p.parent
    if not parent.exists():
        if not parent.parent.exists():
            raise ValueError(f"{option}: folder {str(parent.parent)!r} does not exist (only the parent of "
                             f"{option} is created)")
        parent.mkdir()
    elif not parent.is_dir():
        raise ValueError(f"{option}: {str(parent)!r} is not a folder")
    if is_dir:
        if p.exists() and not p.is_dir():
            raise ValueError(f"{option} must be a folder, got the file {str(p)!r}")
        p.mkdir(exist_ok=True)
    elif p.is_dir():
        raise ValueError(f"{option} must be a file path, got the folder {str(p)!r}")
    return p


class _Bar:
    """A tqdm bar in (fractional) units that ends exactly on whole units."""

    def __init__(self, bar) -> None:
        self.bar = bar

    def advance(self, x: float) -> None:
        if self.bar is not None and x:
            self.bar.update(x)

    def set_done(self, n: float) -> None:
        if self.bar is not None:
            self.bar.n = n
            self.bar.refresh()

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()


def progress_bar(total: int, done: int, desc: str, enabled: bool = True, unit: str = "episode") -> _Bar:
    """A progress bar on stderr, starting at ``done``; says "resuming at done/total" when done > 0."""
    if done and enabled:
        print(f"{desc}: resuming at {done}/{total}", file=sys.stderr)
    if not enabled:
        return _Bar(None)
    from tqdm import tqdm

    return _Bar(tqdm(total=total, initial=done, desc=desc, unit=unit, file=sys.stderr,
                     bar_format="{l_bar}{bar}| {n:.1f}/{total_fmt} [{elapsed}<{remaining}]"))


def add_backend_args(ap: argparse.ArgumentParser, default_batch: int = 32) -> None:
    """``--backend``, ``--workers``, ``--ray-address``, ``--batch-size``."""
    from .backends import BACKENDS

    ap.add_argument("--backend", choices=BACKENDS, default=None,
                    help="where chunks of episodes run: serial (this process), process (a local pool of --workers), "
                         "ray (a local Ray instance with --workers CPUs, or the cluster at --ray-address / "
                         "RAY_ADDRESS). Default: ray with --ray-address, process if --workers > 1, else serial. Results do "
                         "not depend on it.")
    ap.add_argument("--workers", type=int, default=1, help="worker processes / local Ray CPUs (default 1)")
    ap.add_argument("--ray-address", default=None, metavar="ADDR",
                    help="connect to this Ray cluster (e.g. ray://head:10001 or auto); default: $RAY_ADDRESS, "
                         "else a local instance")
    ap.add_argument("--batch-size", type=int, default=default_batch,
                    help=f"episodes advanced together in one task (default {default_batch})")


def backend_from_args(args):
    from .backends import Backend

    if not isinstance(args.batch_size, int) or args.batch_size < 1:
        raise ValueError(f"--batch-size must be a positive integer, got {args.batch_size!r}")
    return Backend.make(args.backend, args.workers, args.ray_address)
