"""Reference diagnoser, CPU time per engine-sample on one thread (least sensitive to other load).

    python benchmarks/diagnoser_cpu.py --json                        # the default (tabulated) inclusion
    python benchmarks/diagnoser_cpu.py --json --inclusion exact
    # another version of the package, same measurement (a before/after ratio in one run):
    mkdir -p /tmp/other && git archive COMMIT src | tar -x -C /tmp/other
    PYTHONPATH=/tmp/other/src python benchmarks/diagnoser_cpu.py --json

:meth:`ReferenceDiagnoser.observe` on one block of ``--block`` samples of ``--engines`` engines
(manoeuvring profile, 30 s after the start), the two-thread split switched off; the best of
``--repeats`` process-time measurements divided by the engine-samples.  Works with versions of the
package without the ``inclusion`` argument.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np
from _report import emit  # noqa: E402  (benchmarks/ is the script directory)

from marine_fdi_env.diagnosis import agent as _agent
from marine_fdi_env.diagnosis import residuals as _residuals
from marine_fdi_env.diagnosis.agent import ReferenceDiagnoser
from marine_fdi_env.engine import integrators
from marine_fdi_env.engine.simulator import Simulator


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--engines", type=int, default=1024)
    ap.add_argument("--block", type=int, default=100)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument(
        "--inclusion", choices=("tabulated", "exact"), default=None, help="default: the package's default (tabulated)"
    )
    args = ap.parse_args(argv)
    for mod in (integrators, _agent, _residuals):  # one thread
        mod.THREADED_MIN_ENGINES = 10**9
    kw = {} if args.inclusion is None else {"inclusion": args.inclusion}
    n, block = args.engines, args.block
    sim = Simulator("thesis-12v28", n, seeds=0, profiles="manoeuvring")
    for _ in range(3000):
        sim.step()
    Y, U = np.empty((n, block, 19)), np.empty((n, block))
    for k in range(block):
        Y[:, k] = sim.step()
        U[:, k] = sim.u
    agent = ReferenceDiagnoser("thesis-12v28", n, **kw)
    agent.observe(Y[:, :10], U[:, :10])  # compile, start the observers
    best = np.inf
    for _ in range(args.repeats):
        c0 = time.process_time()
        agent.observe(Y, U)
        best = min(best, time.process_time() - c0)
    emit(
        {
            "cpu_us_per_engine_sample_one_thread": round(1e6 * best / (n * block), 3),
            "inclusion": args.inclusion or "package default",
            "engines": n,
            "block": block,
            "load_average_1min": os.getloadavg()[0] if hasattr(os, "getloadavg") else None,
        },
        args.json,
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
