"""Reference-diagnoser speed: time to diagnose a recorded 300 s run at 100 Hz (target < 1 s).

    python benchmarks/diagnoser.py --json

Prints one JSON object: ``seconds_per_300s_run`` (best of ``--repeats``, one engine, the
thesis-6.4.2 scenario, excluding the one-off compilation), ``samples_per_s`` for one engine,
``engine_samples_per_s_batch`` for a batch of 64 engines in one call, and
``engine_samples_per_s_n1024`` (best of ``--repeats``): :meth:`ReferenceDiagnoser.observe` on
blocks of ``--block`` samples of ``--engines`` (default 1024) engines, the environment's use
(large batches run on two threads), with its CPU time per engine-sample (both threads); and
``kernel_cpu_us_per_engine_sample_one_thread``: the residual kernel alone on 16 engines, one thread
(least sensitive to other load).  ``--inclusion exact`` measures the exact inclusion.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np
from _report import emit  # noqa: E402  (benchmarks/ is the script directory)

from marine_fdi_env.diagnosis.agent import ReferenceDiagnoser
from marine_fdi_env.engine.simulator import Simulator
from marine_fdi_env.scenarios import get_scenario


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--engines", type=int, default=1024)
    ap.add_argument("--block", type=int, default=100)
    ap.add_argument(
        "--inclusion",
        choices=("tabulated", "exact"),
        default="tabulated",
        help="the adaptive thresholds' inclusion (tabulated: the default)",
    )
    args = ap.parse_args(argv)
    inc = {"inclusion": args.inclusion}
    sc = get_scenario("thesis-6.4.2")
    res = Simulator(sc.params, 64, seeds=0, faults=sc.fault_specs(), profiles=sc.profile).run(sc.duration_s)
    Y = res.measurements.transpose(1, 0, 2)
    U = res.truth_of("u").T
    ReferenceDiagnoser(sc.params, 1, **inc).observe(Y[0, :200], U[0, :200])  # compile
    best = np.inf
    for _ in range(args.repeats):
        agent = ReferenceDiagnoser(sc.params, 1, **inc)
        t0 = time.perf_counter()
        agent.observe(Y[0], U[0])
        best = min(best, time.perf_counter() - t0)
    agent = ReferenceDiagnoser(sc.params, 64, **inc)
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
    agent = ReferenceDiagnoser(sc.params, n_big, **inc)
    agent.observe(Yb[:, :10], Ub[:, :10])  # compile, start the observers
    best_big = np.inf
    cpu_big = np.inf
    for _ in range(args.repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        agent.observe(Yb, Ub)
        best_big = min(best_big, time.perf_counter() - t0)
        cpu_big = min(cpu_big, time.process_time() - c0)
    # the residual kernel alone, one thread: CPU time per engine-sample (less load-sensitive)
    from marine_fdi_env.diagnosis import residuals as rs

    n_k = 16
    st = agent.state[:n_k].copy()
    Rk, THk = np.empty((n_k, args.block, 19)), np.empty((n_k, args.block, 19))
    table = agent._table
    args_k = (
        agent.c,
        np.ascontiguousarray(Yb[:n_k]),
        np.ascontiguousarray(Ub[:n_k]),
        agent.dt,
        agent.noise_bounds,
        rs.SIDE_COLS,
        rs.T_OUT_COL,
        Rk,
        THk,
    )
    kernel = np.inf
    for _ in range(max(args.repeats, 5) * 10):
        s0 = st.copy()
        c0 = time.process_time()
        rs._batch_range(*args_k, s0, rs._NO_TABLE if table is None else table, table is not None, 0, n_k)
        kernel = min(kernel, time.process_time() - c0)
    out = {
        "seconds_per_300s_run": round(best, 4),
        "samples_per_s": round(Y.shape[1] / best, 1),
        "engine_samples_per_s_batch": round(Y.shape[0] * Y.shape[1] / batch, 1),
        f"engine_samples_per_s_n{n_big}": round(n_big * args.block / best_big, 1),
        f"cpu_us_per_engine_sample_n{n_big}": round(1e6 * cpu_big / (n_big * args.block), 3),
        "kernel_cpu_us_per_engine_sample_one_thread": round(1e6 * kernel / (n_k * args.block), 3),
        "inclusion": args.inclusion,
        "scenario": sc.name,
        "target_seconds": 1.0,
        "load_average_1min": os.getloadavg()[0] if hasattr(os, "getloadavg") else None,
    }
    emit(out, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
