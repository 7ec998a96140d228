"""How a ``marine-fdi`` command ends when it fails: the one error convention of the command line.

Every command runs through :func:`run_command` (the dispatcher of :mod:`.main` calls it), and a
command that catches an exception itself hands it to :func:`fail`, so each failure is one line on
stderr, ``marine-fdi COMMAND: error: ...``, and an exit code:

* refused input (a ``ValueError``: the kinds of :mod:`marine_fdi_env.errors` and the library's
  argument checks): its message, naming the option, file or field and what is allowed; exit 2;
* not enough memory (``MemoryError``): what to ask for instead; exit 2;
* an exception raised inside a user's agent (``--agent path/file.py:Class``, also in a worker
  process): ``your agent raised TYPE: MESSAGE at FILE:LINE``, the innermost line of the agent's own
  file; exit 1;
* a file that cannot be read or written (``OSError``): the file and the system's reason; exit 1;
* anything else: ``TYPE: MESSAGE``, said to be unexpected; exit 1;
* Ctrl-C: ``interrupted``; exit 130 (commands that keep finished work say what they keep).

No traceback is printed, except with ``--debug`` anywhere on the command line (or the environment
variable ``MARINE_FDI_DEBUG=1``): then the full traceback follows the line.  The lines of exit
code 1 say so.
"""

from __future__ import annotations

import os
import re
import sys
import traceback
from contextlib import contextmanager
from pathlib import Path
from typing import Callable, Iterator, Sequence

from ..errors import MarineFDIError

__all__ = [
    "DEBUG_FLAG",
    "DEBUG_ENV",
    "FAILURE",
    "USAGE_ERROR",
    "INTERRUPTED",
    "split_debug",
    "debugging",
    "debug_on",
    "fail",
    "run_command",
]

DEBUG_FLAG = "--debug"
DEBUG_ENV = "MARINE_FDI_DEBUG"
FAILURE = 1  # exit code of a failure that is not the input's fault (an agent's exception, a bug)
USAGE_ERROR = 2  # exit code of an invalid input (argparse's convention)
INTERRUPTED = 130  # exit code after Ctrl-C (128 + SIGINT)

_debug = False
_FRAME = re.compile(r'File "([^"]+)", line (\d+)')


def split_debug(argv: Sequence[str]) -> tuple[list[str], bool]:
    """``argv`` without ``--debug`` (accepted anywhere before a ``--``), and whether it was given."""
    argv = list(argv)
    end = argv.index("--") if "--" in argv else len(argv)
    found = DEBUG_FLAG in argv[:end]
    return [a for i, a in enumerate(argv) if not (i < end and a == DEBUG_FLAG)], found


@contextmanager
def debugging(on: bool) -> Iterator[None]:
    """Within the block, :func:`debug_on` is true when ``on`` is (or ``MARINE_FDI_DEBUG=1``)."""
    global _debug
    saved, _debug = _debug, on
    try:
        yield
    finally:
        _debug = saved


def debug_on() -> bool:
    return _debug or os.environ.get(DEBUG_ENV, "").strip().lower() in ("1", "true", "yes", "on")


def _user_agent_frame(exc: BaseException) -> tuple[str, int] | None:
    """The innermost line of a user's agent file (``--agent path/file.py:Class``) in the exception's
    traceback, also in a worker's traceback carried along as text (process pool, Ray), or None."""
    from ..benchmark.agent_api import user_agent_files

    files = user_agent_files()
    if not files:
        return None
    found = None
    for fs in traceback.extract_tb(exc.__traceback__):
        if _resolved(fs.filename) in files:
            found = (fs.filename, int(fs.lineno or 0))
    # a worker's traceback (multiprocessing's RemoteTraceback as the cause, Ray's in the message) is
    # inner to this process's frames
    for text in (str(exc.__cause__) if exc.__cause__ is not None else "", str(exc)):
        for m in _FRAME.finditer(text):
            if _resolved(m.group(1)) in files:
                found = (m.group(1), int(m.group(2)))
    return found


def _resolved(name: str) -> str:
    try:
        return str(Path(name).resolve())
    except (OSError, RuntimeError):
        return name


def _shown(path: str) -> str:
    """``path`` relative to the current folder when it lies inside it, else as it is."""
    try:
        return str(Path(path).resolve().relative_to(Path.cwd().resolve()))
    except (ValueError, OSError):
        return path


def _headline(exc: BaseException) -> str:
    """The exception's message, first line only (Ray and the process pool append tracebacks)."""
    text = str(exc).strip()
    return text.splitlines()[0] if text else ""


def fail(prog: str, exc: BaseException) -> int:
    """Print the one line of ``exc`` for command ``prog`` (module docstring), the traceback too with
    ``--debug``; return the exit code."""
    frame = _user_agent_frame(exc)
    if frame is not None:
        message = _headline(exc)
        line = f"your agent raised {type(exc).__name__}" + (f": {message}" if message else "")
        line += f" at {_shown(frame[0])}:{frame[1]}"
        code = FAILURE
    elif isinstance(exc, MemoryError):
        line = (
            "not enough memory for this request"
            + (f" ({exc})" if str(exc) else "")
            + "; ask for less (fewer engines, episodes or a shorter duration)"
        )
        code = USAGE_ERROR
    elif isinstance(exc, (MarineFDIError, ValueError)):
        line, code = str(exc), USAGE_ERROR
    elif isinstance(exc, OSError):
        where = exc.filename if exc.filename is not None else ""
        reason = exc.strerror or str(exc)
        line = f"{where}: {reason}" if where else reason
        code = FAILURE
    else:
        message = _headline(exc)
        line = f"{type(exc).__name__}" + (f": {message}" if message else "") + " (unexpected: please report it)"
        code = FAILURE
    debug = debug_on()
    if code == FAILURE and not debug:
        line += f"; {DEBUG_FLAG} prints the traceback"
    print(f"{prog}: error: {line}", file=sys.stderr)
    if debug:
        traceback.print_exception(exc, file=sys.stderr)
    return code


def run_command(prog: str, fn: Callable[[], int]) -> int:
    """``fn()``'s exit code, or the exit code of the exception it raised, reported by :func:`fail`."""
    try:
        return fn()
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return INTERRUPTED
    except BrokenPipeError:  # output piped into e.g. head: stop quietly (Python docs' recipe)
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        except (OSError, ValueError, AttributeError):
            pass
        return FAILURE
    except Exception as exc:  # noqa: BLE001 - the convention: one line for any failure
        return fail(prog, exc)
