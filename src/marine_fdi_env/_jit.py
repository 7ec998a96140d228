"""Just-in-time compilation of the physics with numba.

The model is written as scalar functions of one engine (readable, with plain ``if`` branches)
and compiled with numba; batches of engines are explicit loops in compiled code.  This gives the
speed of compiled code for one engine (a Gymnasium env steps one engine at a time) and for many
(training and evaluation batches), from a single source of the physics.

``error_model="numpy"``: a division by zero gives inf/nan instead of raising, so that an engine
leaving its physical range is detected by the failure checks rather than crashing a batch.
"""

from __future__ import annotations

import numba

from . import _coldstart

__all__ = ["jit", "jit_inline"]

_coldstart.install()  # one line on stderr at a cold compilation, when the command asked for it

# nogil: compiled loops release the GIL, so halves of a large batch can run on two threads
jit = numba.njit(cache=True, error_model="numpy", nogil=True)

# ``jit`` inlined into the caller by numba (not only by LLVM): an out-of-line call with array arguments
# costs their reference counting at entry and at every exit (an atomic increment and decrement per
# array, which the compiler cannot remove; measured ~0.1 µs per call with the Σ2 table's arrays, and
# most of the simulator's time before the floats-only constants, see ``benchmarks/simulator_cpu.py``)
jit_inline = numba.njit(cache=True, error_model="numpy", nogil=True, inline="always")
