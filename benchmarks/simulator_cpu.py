"""Engine simulator, CPU time per engine-sample on one thread (least sensitive to other load).

    python benchmarks/simulator_cpu.py --json
    python benchmarks/simulator_cpu.py --json --params wartsila-6l46 --faults none
    # another version of the code, same measurement:
    mkdir -p /tmp/before && git archive HEAD src | tar -x -C /tmp/before
    PYTHONPATH=/tmp/before/src python benchmarks/simulator_cpu.py --json

:meth:`Simulator.advance` on blocks of ``--block`` samples of ``--engines`` engines (as the
environment advances once per 1 s decision), the two-thread split switched off, ``--profile``
fuel-setting profile (per engine seeded where the profile takes a seed) and a random fault schedule
per engine (sensor and process faults with onsets in the first half of the timed run;
``--faults none`` for healthy engines).  Reports the best of ``--repeats`` process-time
measurements divided by the engine-samples:

``cpu_us_per_engine_sample_one_thread``  the whole ``advance`` (compiled kernel, noise, sensor faults).
``kernel_cpu_us_per_engine_sample``      the compiled ``integrators.advance_batch`` call alone (same runs).
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np
from _report import emit  # noqa: E402  (benchmarks/ is the script directory)

from marine_fdi_env.engine import integrators
from marine_fdi_env.engine import simulator as _simulator
from marine_fdi_env.engine.faults import random_fault_schedule
from marine_fdi_env.engine.simulator import Simulator


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--engines", type=int, default=1024)
    ap.add_argument("--block", type=int, default=100)
    ap.add_argument("--blocks", type=int, default=3, help="blocks per timed run")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--params", default="thesis-12v28")
    ap.add_argument("--profile", default="random", help="a profile spec; 'random': random:seed=i per engine")
    ap.add_argument("--faults", choices=("random", "none"), default="random")
    args = ap.parse_args(argv)
    integrators.THREADED_MIN_ENGINES = 10**9  # one thread
    n, block = args.engines, args.block
    seconds = args.blocks * block * 0.01
    rng = np.random.default_rng(12345)
    faults = (
        [random_fault_schedule(rng, seconds, 2, onset_range=(0.0, 0.5 * seconds)) for _ in range(n)]
        if args.faults == "random"
        else None
    )
    profiles = [f"random:seed={i},u_min=0.5,u_max=1.05" for i in range(n)] if args.profile == "random" else args.profile
    kernel = [0.0]
    inner = integrators.advance_batch

    def timed(*a, **kw):
        c0 = time.process_time()
        inner(*a, **kw)
        kernel[0] += time.process_time() - c0

    _simulator.advance_batch = timed
    Simulator(
        args.params,
        4,
        seeds=0,
        faults=None if faults is None else faults[:4],
        profiles=profiles if isinstance(profiles, str) else profiles[:4],
    ).advance(2)  # compile
    best, best_kernel = np.inf, np.inf
    for _ in range(args.repeats):
        sim = Simulator(args.params, n, seeds=0, faults=faults, profiles=profiles)
        kernel[0] = 0.0
        c0 = time.process_time()
        for _ in range(args.blocks):
            sim.advance(block)
        best = min(best, time.process_time() - c0)
        best_kernel = min(best_kernel, kernel[0])
    samples = n * block * args.blocks
    emit(
        {
            "cpu_us_per_engine_sample_one_thread": round(1e6 * best / samples, 3),
            "kernel_cpu_us_per_engine_sample": round(1e6 * best_kernel / samples, 3),
            "params": args.params,
            "profile": args.profile,
            "faults": args.faults,
            "engines": n,
            "block": block,
            "blocks": args.blocks,
            "load_average_1min": os.getloadavg()[0] if hasattr(os, "getloadavg") else None,
        },
        args.json,
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
