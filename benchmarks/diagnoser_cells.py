"""Reference and sequential diagnoser with each cell set: CPU time per engine-sample of ``observe``
on faulty runs (the decision logic works only on engines where something fired).

    python benchmarks/diagnoser_cells.py --json

The single-v1 suite's scenarios (156 faulty 300 s runs; ``--engines`` of them) are simulated in
blocks of ``--block`` samples (the environment's decision period); every diagnoser with every cell
set observes each block in turn, timed apart; the least process time over ``--repeats`` runs is
divided by the engine-samples.  The residuals and thresholds are the same
for every cell set (one thread, so that the other load matters least).
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from _report import emit  # noqa: E402  (benchmarks/ is the script directory)

from marine_fdi_env.benchmark.suites import load_suite
from marine_fdi_env.diagnosis import agent as _agent
from marine_fdi_env.diagnosis.cell_sets import CELL_SETS
from marine_fdi_env.diagnosis.sequential import SequentialDiagnoser
from marine_fdi_env.engine import integrators
from marine_fdi_env.engine.simulator import Simulator


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--engines", type=int, default=156)
    ap.add_argument("--block", type=int, default=100)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args(argv)
    for mod in (integrators, _agent):  # one thread
        mod.THREADED_MIN_ENGINES = 10**9
    scs = load_suite("single-v1").scenarios[: args.engines]
    best = {}
    for _ in range(args.repeats):
        sim = Simulator(
            "thesis-12v28",
            len(scs),
            seeds=[s.noise_seed for s in scs],
            faults=[list(s.faults) for s in scs],
            profiles=[s.profile for s in scs],
        )
        agents = {
            (d, c): (_agent.ReferenceDiagnoser if d == "reference" else SequentialDiagnoser)(
                "thesis-12v28", n_engines=len(scs), dt=sim.dt, cells=c
            )
            for d in ("reference", "sequential")
            for c in CELL_SETS
        }
        cpu = dict.fromkeys(agents, 0.0)
        samples = 0
        while samples < int(round(300.0 / sim.dt)):
            blk = sim.advance(args.block)
            for key, d in agents.items():  # the same block for every one, timed apart
                t0 = time.process_time()
                d.observe(blk.measurements, blk.u)
                cpu[key] += time.process_time() - t0
            samples += args.block
        for (d, c), t in cpu.items():
            k = f"{d}_{c}_cpu_us_per_engine_sample"
            best[k] = min(best.get(k, np.inf), 1e6 * t / (len(scs) * samples))
    n, T = len(scs), samples
    emit({"engines": n, "samples": T, "block": args.block, **best}, args.json)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
