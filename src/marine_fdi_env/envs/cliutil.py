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
import sys
from pathlib import Path

__all__ = ["INTERRUPTED", "USAGE_ERROR", "prepare_out", "progress_bar", "add_backend_args", "backend_from_args",
           "require_extra", "EXTRAS", "parse_cli", "interrupted"]

INTERRUPTED = 130  # exit code after Ctrl-C (128 + SIGINT)
USAGE_ERROR = 2    # exit code of an invalid input (argparse's convention)

def parse_cli(ap: argparse.ArgumentParser, argv) -> tuple[argparse.Namespace | None, int | None]:
    """``(args, None)``, or ``(None, exit code)`` where argparse would exit (``--help``: 0, a usage error: 2):
    the commands return their exit code instead of raising ``SystemExit``."""
    try:
        return ap.parse_args(argv), None
    except SystemExit as e:
        return None, (e.code if isinstance(e.code, int) else 0)


def interrupted(prog: str, kept: str = "") -> int:
    """After Ctrl-C: one line saying what is kept and that the same command resumes; the exit code."""
    print(f"{prog}: interrupted; " + (f"{kept}, " if kept else "") + "rerun the same command to resume",
          file=sys.stderr)
    return INTERRUPTED


# optional module -> the extra of pyproject.toml that installs it
EXTRAS: dict[str, str] = {"matplotlib": "plots", "pyarrow": "parquet", "ray": "ray", "torch": "train",
                          "stable_baselines3": "train"}


def require_extra(module: str, what: str) -> None:
    """``ValueError`` "WHAT needs MODULE: pip install 'marine-fdi-env[EXTRA]'" when ``module`` cannot
    be imported; called before a command does any work, so a missing extra costs nothing."""
    import importlib

    try:
        importlib.import_module(module)
    except ImportError:
        extra = EXTRAS.get(module.split(".")[0], "dev")
        raise ValueError(f"{what} needs {module.split('.')[0]}: pip install 'marine-fdi-env[{extra}]'") from None


def prepare_out(path: "str | Path", option: str = "--out", *, is_dir: bool = True, create: bool = True) -> Path:
    """Create the parent of ``path`` if missing (one level only) and, for a folder, ``path`` itself.

    ``create=False`` only checks (``ValueError`` naming ``option``): a command that still has to
    validate other input checks its output path first and creates it when it writes, so a
    failing command leaves no new folder behind."""
    p = Path(path)
    parent = p.parent
    if not parent.exists():
        if not parent.parent.is_dir():
            raise ValueError(f"{option}: folder {str(parent.parent)!r} does not exist (only the parent of "
                             f"{option} is created)")
        if create:
            parent.mkdir()
    elif not parent.is_dir():
        raise ValueError(f"{option}: {str(parent)!r} is not a folder")
    if is_dir:
        if p.exists() and not p.is_dir():
            raise ValueError(f"{option} must be a folder, got the file {str(p)!r}")
        if create:
            p.mkdir(exist_ok=True)
    elif p.is_dir():
        raise ValueError(f"{option} must be a file path, got the folder {str(p)!r}")
    return p


class _Bar:
    """A tqdm bar in (fractional) episodes: it never passes its total, and prints its final state
    exactly once (on :meth:`close`)."""

    def __init__(self, bar) -> None:
        self.bar = bar

    def _set(self, n: float) -> None:
        bar = self.bar
        n = min(max(float(n), 0.0), float(bar.total))
        if n >= bar.total - 1e-6:   # done (up to rounding): the final line is printed once, by close()
            bar.n = bar.total
            return
        bar.n = n
        bar.update(0)  # redraws when tqdm's mininterval has passed

    def advance(self, x: float) -> None:
        if self.bar is not None and x:
            self._set(self.bar.n + x)

    def set_done(self, n: float) -> None:
        if self.bar is not None:
            self._set(n)

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
            self.bar = None


def _isatty(stream) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False


def progress_bar(total: int, done: int, desc: str, enabled: bool = True, unit: str = "episode") -> _Bar:
    """A progress bar on stderr counting episodes, starting at ``done``; says "resuming at
    done/total" when done > 0 (also without a bar).  Off a terminal (a log file) it redraws at
    most every 10 s."""
    if done:
        print(f"{desc}: resuming at {done}/{total}", file=sys.stderr)
    if not enabled:
        return _Bar(None)
    from tqdm import tqdm

    return _Bar(tqdm(total=total, initial=done, desc=desc, unit=unit, file=sys.stderr,
                     mininterval=0.1 if _isatty(sys.stderr) else 10.0,
                     bar_format="{l_bar}{bar}| {n:.1f}/{total_fmt} " + unit + "s [{elapsed}<{remaining}]"))


def add_backend_args(ap: argparse.ArgumentParser, default_batch: int = 32) -> None:
    """``--backend``, ``--workers``, ``--ray-address``, ``--batch-size``."""
    from .backends import BACKENDS

    ap.add_argument("--backend", choices=BACKENDS, default=None,
                    help="where chunks of episodes run: serial (this process), process (a local pool of --workers), "
                         "ray (a local Ray instance with --workers CPUs, or the cluster at --ray-address / "
                         "RAY_ADDRESS). Default: ray with --ray-address, process if --workers > 1, else serial. Results do "
                         "not depend on it.")
    ap.add_argument("--workers", type=int, default=1, metavar="N",
                    help="worker processes / local Ray CPUs (default 1)")
    ap.add_argument("--ray-address", default=None, metavar="ADDR",
                    help="connect to this Ray cluster (e.g. ray://head:10001 or auto); default: $RAY_ADDRESS, "
                         "else a local instance")
    ap.add_argument("--batch-size", type=int, default=default_batch, metavar="N",
                    help=f"episodes advanced together in one task (default {default_batch})")


def backend_from_args(args):
    from .backends import Backend

    if not isinstance(args.batch_size, int) or args.batch_size < 1:
        raise ValueError(f"--batch-size must be a positive integer, got {args.batch_size!r}")
    backend = Backend.make(args.backend, args.workers, args.ray_address)
    if backend.name == "ray":
        require_extra("ray", "--backend ray")
    return backend


def differing_fields(old, new, prefix: str = "") -> str:
    """What differs between two JSON objects, field by field: ``agent: 'random' there, 'reference'
    here; seed_offset: 0 there, 1 here`` (for "this partial file belongs to another run" errors)."""
    if not isinstance(old, dict) or not isinstance(new, dict):
        return f"{prefix or 'header'}: {_short(old)} there, {_short(new)} here"
    parts = []
    for k in list(new) + [k for k in old if k not in new]:
        name = f"{prefix}.{k}" if prefix else str(k)
        if k not in old:
            parts.append(f"{name}: missing there, {_short(new[k])} here")
        elif k not in new:
            parts.append(f"{name}: {_short(old[k])} there, missing here")
        elif old[k] != new[k]:
            parts.append(differing_fields(old[k], new[k], name) if isinstance(old[k], dict) and isinstance(new[k], dict)
                         else f"{name}: {_short(old[k])} there, {_short(new[k])} here")
    return "; ".join(parts) or "no field differs"


def _short(v, width: int = 60) -> str:
    text = repr(v)
    return text if len(text) <= width else text[:width - 3] + "..."
