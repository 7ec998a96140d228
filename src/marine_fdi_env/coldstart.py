"""One line on stderr when numba compiles the model because its on-disk cache is cold.

The physics is compiled with ``numba.njit(cache=True)`` (:mod:`._jit`): the first run after an
install, in a new checkout or after a source change compiles for about a minute; later runs load
the machine code from the cache in a few seconds.  Without a word the first command looks hung.

Detection: numba fires its ``numba:compile`` event only on a cache miss (``Dispatcher.compile``
first looks for the signature in this process, then in the on-disk cache, and only then compiles
inside ``trigger_event("numba:compile")``).  A listener on that event therefore sees exactly the
cold compilations, never a warm start.  It only counts this package's functions compiled with
caching on (a function without ``cache=True`` compiles on every run and says nothing about the
cache).

Quiet by default, so the library never writes to stderr on its own: the ``marine-fdi`` command
(and the benchmarks) call :func:`enable`.  This module imports nothing heavy; the listener is
registered by :mod:`._jit` (which imports numba anyway) or by :func:`enable` once numba is loaded.
"""

from __future__ import annotations

import sys

__all__ = ["COMPILING", "enable", "install", "announced"]

COMPILING = "compiling the model (first run only, about a minute; later runs load it from the cache)"
_STATE: dict = {"prefix": None, "stream": None, "done": False, "installed": False}


def enable(prefix: str = "marine-fdi", stream=None) -> None:
    """Print ``PREFIX: compiling the model ...`` (on ``stream``, default stderr) at the first cold
    compilation in this process (and its forked children)."""
    _STATE["prefix"], _STATE["stream"] = prefix, stream
    if "numba" in sys.modules:
        install()


def announced() -> bool:
    """Whether the line was printed in this process."""
    return bool(_STATE["done"])


def _ours(dispatcher) -> bool:
    from numba.core.caching import NullCache

    module = getattr(getattr(dispatcher, "py_func", None), "__module__", None) or ""
    cache = getattr(dispatcher, "_cache", None)
    return module.split(".")[0] == "marine_fdi_env" and cache is not None and not isinstance(cache, NullCache)


def _notify(dispatcher) -> None:
    if _STATE["done"] or _STATE["prefix"] is None or not _ours(dispatcher):
        return
    _STATE["done"] = True
    msg = f"{_STATE['prefix']}: {COMPILING}"
    stream = _STATE["stream"] or sys.stderr
    try:
        from tqdm import tqdm

        tqdm.write(msg, file=stream)  # above a progress bar that may be on screen
    except ImportError:  # pragma: no cover - tqdm is a core dependency
        print(msg, file=stream, flush=True)


def install() -> None:
    """Register the ``numba:compile`` listener (once per process)."""
    if _STATE["installed"]:
        return
    from numba.core import event

    class _ColdCompile(event.Listener):
        def on_start(self, ev) -> None:
            _notify((ev.data or {}).get("dispatcher"))

        def on_end(self, ev) -> None:
            pass

    event.register("numba:compile", _ColdCompile())
    _STATE["installed"] = True
