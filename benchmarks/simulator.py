"""Simulator throughput and accuracy benchmark.

    python benchmarks/simulator.py --json

prints one JSON object:

``engine_samples_per_s_n1``     one engine, sensors and faults on (a sensor offset and a process fault).
                                Both throughputs advance in blocks of 100 samples (``Simulator.advance``),
                                as the environment does once per 1 s decision period.
``engine_samples_per_s_n1_step`` one engine advanced one sample per Python call (``Simulator.step``).
``engine_samples_per_s_n1024``  1024 engines in one batch, each with its own seed, a fuel-setting
                                profile and a random fault schedule (sensor and process faults).
``scipy_engine_samples_per_s``  the reference path (solve_ivp Radau, rtol 1e-10) on one engine.
``speedup_vs_scipy``            batched fixed-step throughput / scipy throughput: wall time of the
                                same simulated work (engine-samples) with each solver.
``speedup_vs_scipy_n1``         the same for one engine alone.
``max_rel_error_vs_scipy``      max over the 19 channels and all samples of the relative error of
                                the noise-free fixed-step run against the reference, on a run with
                                a fuel-setting step and a process fault.

Targets: >= 1e6 engine-samples/s at N=1024 on 2 cores and >= 100x the scipy reference.
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np
from _report import emit  # noqa: E402  (benchmarks/ is the script directory)

from marine_fdi_env.engine.faults import FaultSpec, random_fault_schedule
from marine_fdi_env.engine.integrators import reference_solve
from marine_fdi_env.engine.sensors import VARIABLE_OF_SENSOR
from marine_fdi_env.engine.simulator import Simulator

PARAMS = "thesis-12v28"
PROFILE = "step:u0=0.8,u1=1.0,t=10"
FAULTS = [FaultSpec("compressor_seal_leak", 5.0)]


def throughput(n: int, seconds: float, repeats: int = 3, block: int = 100) -> float:
    rng = np.random.default_rng(12345)
    if n == 1:
        faults = [[FaultSpec("S4.2", 1.0), FaultSpec("bore_damage", 1.0)]]
        profiles = ["constant"]
    else:
        faults = [random_fault_schedule(rng, seconds, 2, onset_range=(0.0, 0.5 * seconds)) for _ in range(n)]
        profiles = [f"random:seed={i},u_min=0.5,u_max=1.05" for i in range(n)]
    best = 0.0
    for _ in range(repeats):
        sim = Simulator(PARAMS, n_engines=n, seeds=0, faults=faults, profiles=profiles)
        steps = int(round(seconds / sim.dt))
        t0 = time.perf_counter()
        done = 0
        while done < steps:  # blocks of one decision period (1 s), as the environment advances
            m = min(block, steps - done)
            sim.advance(m)
            done += m
        best = max(best, n * steps / (time.perf_counter() - t0))
    return best


def accuracy(duration: float) -> tuple[float, float, float]:
    """(max relative error, scipy engine-samples/s, fixed-step single-engine engine-samples/s)."""
    Simulator(PARAMS, 1, 0, [FAULTS], PROFILE, noise_scale=0.0).run(1.0)  # load compiled code first
    reference_solve(PARAMS, PROFILE, FAULTS, 1.0)
    t0 = time.perf_counter()
    t, _, true = reference_solve(PARAMS, PROFILE, FAULTS, duration)
    t_ref = time.perf_counter() - t0
    sim = Simulator(PARAMS, 1, 0, [FAULTS], PROFILE, noise_scale=0.0)
    t0 = time.perf_counter()
    res = sim.run(duration)
    t_fix = time.perf_counter() - t0
    ref = true[:, VARIABLE_OF_SENSOR]
    err = np.abs(res.measurements[:, 0, :] - ref) / np.abs(ref)
    return float(err.max()), len(t) / t_ref, len(t) / t_fix


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--seconds-n1", type=float, default=20.0)
    ap.add_argument("--seconds-n1024", type=float, default=3.0)
    ap.add_argument("--accuracy-duration", type=float, default=30.0, help="simulated seconds of the scipy comparison")
    args = ap.parse_args(argv)
    err, scipy_rate, fixed_n1_acc = accuracy(args.accuracy_duration)
    n1 = throughput(1, args.seconds_n1)
    n1_step = throughput(1, args.seconds_n1, block=1)
    n1024 = throughput(1024, args.seconds_n1024, repeats=5)
    out = {
        "engine_samples_per_s_n1": round(n1, 1),
        "engine_samples_per_s_n1_step": round(n1_step, 1),
        "engine_samples_per_s_n1024": round(n1024, 1),
        "scipy_engine_samples_per_s": round(scipy_rate, 1),
        "speedup_vs_scipy": round(n1024 / scipy_rate, 1),
        "speedup_vs_scipy_n1": round(fixed_n1_acc / scipy_rate, 2),
        "max_rel_error_vs_scipy": err,
        "scenario": {
            "params": PARAMS,
            "profile": PROFILE,
            "faults": [f.to_dict() for f in FAULTS],
            "accuracy_duration_s": args.accuracy_duration,
        },
        "numpy": np.__version__,
        "python": sys.version.split()[0],
    }
    emit(out, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
