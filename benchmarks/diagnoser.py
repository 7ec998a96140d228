"""Reference-diagnoser speed: time to diagnose a recorded 300 s run at 100 Hz (target < 1 s).

    python benchmarks/diagnoser.py --json

Prints one JSON object: ``seconds_per_300s_run`` (best of ``--repeats``, one engine, the
thesis-6.4.2 scenario, excluding the one-off compilation), ``samples_per_s`` for one engine,
``engine_samples_per_s_batch`` for a batch of 64 engines in one call, and
``engine_samples_per_s_n1024`` (best of ``--repeats``): :meth:`ReferenceDiagnoser.observe` on
blocks of ``--block`` samples of ``--engines`` (default 1024) engines, the environment's use
(large batches run on two threads).
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

from marine_fdi_env.diagnosis.agent import ReferenceDiagnoser
from marine_fdi_env.scenarios import get_scenario
from marine_fdi_env.simulator import Simulator
from _report import emit  # noqa: E402  (benchmarks/ is the script directory)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--engines", type=int, default=1024)
    ap.add_argument("--block", type=int, default=100)
    args = ap.parse_args(argv)
    sc = get_scenario("thesis-6.4.2")
    res = Simulator(sc.params, 64, seeds=0, faults=sc.fault_specs(), profiles=sc.profile).run(sc.duration_s)
    Y = res.measurements.transpose(1, 0, 2)
    U = res.truth_of("u").T
    ReferenceDiagnoser(sc.params, 1).observe(Y[0, :200], U[0, :200])  # compile
    best = np.inf
    for _ in range(args.repeats):
        agent = ReferenceDiagnoser(sc.params, 1)
        t0 = time.perf_counter()
        agent.observe(Y[0], U[0])
        best = min(best, time.perf_counter() - t0)
    agent = ReferenceDiagnoser(sc.params, 64)
    t0 = time.perf_counter()
    agent.observe(Y, U)
    batch = time.perf_counter() - t0
    n_big = args.engines
    sim = Simulator(sc.params, n_big, seeds=0)
    Yb = np.empty((n_big, args.block, 19))
    Ub = np.empty((n_big, args.block))
    for k in range(args.block):
        Yb[:, k] = sim.step()
        Ub[:, k] = sim.u
    agent = ReferenceDiagnoser(sc.params, n_big)
    agent.observe(Yb[:, :10], Ub[:, :10])  # compile, start the observers
    best_big = np.inf
    for _ in range(args.repeats):
        t0 = time.perf_counter()
        agent.observe(Yb, Ub)
        best_big = min(best_big, time.perf_counter() - t0)
    out = {
        "seconds_per_300s_run": round(best, 4),
        "samples_per_s": round(Y.shape[1] / best, 1),
        "engine_samples_per_s_batch": round(Y.shape[0] * Y.shape[1] / batch, 1),
        f"engine_samples_per_s_n{n_big}": round(n_big * args.block / best_big, 1),
        "scenario": sc.name,
        "target_seconds": 1.0,
    }
    emit(out, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
