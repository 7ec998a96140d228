"""Just-in-time compilation of the physics with numba.

The model is written as scalar functions of one engine (readable, with plain ``if`` branches)
and compiled with numba; batches of engines are explicit loops in compiled code.  This gives the
speed of compiled code for one engine (a Gymnasium env steps one engine at a time) and for many
(training and evaluation batches), from a single source of the physics.

``error_model="numpy"``: a division by zero gives inf/nan instead of raising, so that an engine
leaving its physical range is detected by the failure checks rather than crashing a batch.

Cache: compiled functions are cached on disk (numba's ``cache=True``), keyed on the package's sources.
numba keys a cached function on its own bytecode and invalidates the cache of a source file when that
file changes, but not when a function it calls, inlines or reads constants from in *another* file
changes (e.g. a subsystem equation, or the fault registry's term indices, ``engine.fault_registry``).
So the key of every compiled function here also holds :func:`source_key`: a hash of the sources of its
layer and the layers before it (``engine/`` for the physics, ``+ diagnosis/`` for the diagnosers, ``+ envs/``),
the only places compiled code can call into.  A change of any of them (the fault registry's terms among
them) recompiles its dependants; the same sources load the cache.  Faults declared by plugins do not
enter compiled code (they act through the registry's terms), so they do not change the key.
"""

from __future__ import annotations

import hashlib
from functools import lru_cache
from pathlib import Path

import numba

from . import coldstart

__all__ = ["jit", "jit_inline", "source_key"]

coldstart.install()  # one line on stderr at a cold compilation, when the command asked for it

_ROOT = Path(__file__).resolve().parent
# the folders whose sources a compiled function of each layer may depend on (the one-way layers)
_SOURCE_LAYERS = ("engine", "diagnosis", "envs")


@lru_cache(maxsize=None)
def source_key(module: str) -> str:
    """Hash of the sources the compiled functions of ``module`` (a dotted name) may depend on: this file
    and every ``.py`` file of the layers up to the module's own (all three for a module outside them)."""
    parts = module.split(".")
    layer = parts[1] if len(parts) > 1 and parts[1] in _SOURCE_LAYERS else _SOURCE_LAYERS[-1]
    folders = _SOURCE_LAYERS[: _SOURCE_LAYERS.index(layer) + 1]
    h = hashlib.sha256(Path(__file__).read_bytes())
    for folder in folders:
        for path in sorted((_ROOT / folder).rglob("*.py")):
            h.update(path.relative_to(_ROOT).as_posix().encode())
            h.update(path.read_bytes())
    return h.hexdigest()


try:
    from numba.core.caching import FunctionCache

    class _SourceKeyedCache(FunctionCache):
        """numba's on-disk cache with :func:`source_key` in the index key (module docstring)."""

        def _index_key(self, sig, codegen):
            return super()._index_key(sig, codegen) + (source_key(self._py_func.__module__),)

        def _save_overload(self, sig, data):
            # drop the entries of other sources first, so that the cache does not grow with every edit
            if self._enabled:
                key = source_key(self._py_func.__module__)
                try:
                    index = self._cache_file._load_index()
                    kept = {k: v for k, v in index.items() if k[-1] == key}
                    if len(kept) != len(index):
                        self._cache_file._save_index(kept)
                except Exception:  # pragma: no cover - the cache is an optimisation: never fail on it
                    pass
            super()._save_overload(sig, data)

except ImportError:  # pragma: no cover - a numba without this class: its own per-file invalidation
    _SourceKeyedCache = None


def _njit(**options):
    def decorate(fn):
        if _SourceKeyedCache is None:  # pragma: no cover
            return numba.njit(cache=True, **options)(fn)
        dispatcher = numba.njit(**options)(fn)
        dispatcher._cache = _SourceKeyedCache(fn)  # what cache=True sets (Dispatcher.enable_caching), keyed
        return dispatcher

    return decorate


# nogil: compiled loops release the GIL, so halves of a large batch can run on two threads
jit = _njit(error_model="numpy", nogil=True)

# ``jit`` inlined into the caller by numba (not only by LLVM): an out-of-line call with array arguments
# costs their reference counting at entry and at every exit (an atomic increment and decrement per
# array, which the compiler cannot remove; measured ~0.1 µs per call with the Σ2 table's arrays, and
# most of the simulator's time before the floats-only constants, see ``benchmarks/simulator_cpu.py``)
jit_inline = _njit(error_model="numpy", nogil=True, inline="always")
