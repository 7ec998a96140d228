"""Validation pipeline: CPU time of the fit's inner call, a model evaluation, and of whole fits.

    python benchmarks/validation.py --json
    python benchmarks/validation.py --json --trial c381      # also one open-world study trial (about 15 s)
    # another version of the code, same measurement:
    mkdir -p /tmp/before && git archive HEAD src | tar -x -C /tmp/before
    PYTHONPATH=/tmp/before/src python benchmarks/validation.py --json

Every fit of ``marine-fdi validate`` and of the open-world study spends its time in one call, repeated for each
residual and finite-difference Jacobian column: the model readings of a parameter vector at the measured points
(:meth:`~marine_fdi_env.validation.fit.fitting._Objective.data_residuals`: the setting of the vector, the steady states
of the points, the readings in the columns' units, the normalised residuals).  On the Birka ME1 shop-test protocol
(6 points, 11 channels, each row at its own boundary conditions) with a waste gate open at the four highest loads:

``evaluation_us``         process time per call of the whole inner call (best of ``--repeats``).
``kernel_us``             of that, the compiled steady-state solve of the points (``operating_point._solve_batch``).
``overhead_us``           the rest: Python and numpy around the kernel (building the setting and the engine, the
                          readings, the residuals).
``fit_waste_gate_s``      process time of fitting the waste gate from the calibrated base (``fit_combination``).
``trial_<id>_s``          with ``--trial``: process time of one study trial (data, selection, findings).

The numbers are the same to the last bit whatever the speed: a faster version must leave every fit identical
(the study trials and the real datasets' reports are compared before a speed change lands).
"""

from __future__ import annotations

import argparse
import os
import time
import warnings

import numpy as np
from _report import emit  # noqa: E402  (benchmarks/ is the script directory)

from marine_fdi_env.engine import operating_point
from marine_fdi_env.validation import load_shipped
from marine_fdi_env.validation.fit.fitting import Combination, _Objective, fit_combination
from marine_fdi_env.validation.fit.mechanisms import WasteGateM
from marine_fdi_env.validation.fit.problem import FitProblem


def _best(fn, zs, repeats: int) -> float:
    """Best of ``repeats`` process-time measurements of ``fn`` over the vectors ``zs``, per call [s]."""
    best = float("inf")
    for _ in range(repeats):
        t0 = time.process_time()
        for z in zs:
            fn(z)
        best = min(best, (time.process_time() - t0) / len(zs))
    return best


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--number", type=int, default=400, help="inner calls per timed repeat")
    ap.add_argument("--trial", default=None, metavar="ID", help="also time one study trial, e.g. c381 or d386")
    args = ap.parse_args(argv)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ds = load_shipped("birka_me1_test_protocol")
    problem = FitProblem(ds)
    rows = problem.rows_with_data()
    gate = Combination((WasteGateM(),))
    fit = fit_combination(problem, gate)  # a realistic point: the gate open where the data want it
    obj = _Objective(problem, gate, rows, {m.id: np.asarray(fit.support[m.id], int) for m in gate.valves}, 0.0)
    z = np.concatenate([fit.nuisance, fit.x] + [np.sqrt(fit.openings[m.id][fit.support[m.id]]) for m in gate.valves])
    obj.data_residuals(z)  # compiled and warm
    # as in a fit, every call sees another parameter vector (a new engine: nothing is reused from the call before)
    steps = np.random.default_rng(0).normal(0.0, 1e-4, (args.number, z.size))
    zs = [z * (1.0 + d) for d in steps]

    kernel = operating_point._solve_batch
    spent = [0.0]

    def timed_kernel(*a, **k):
        t0 = time.process_time()
        out = kernel(*a, **k)
        spent[0] += time.process_time() - t0
        return out

    evaluation = _best(obj.data_residuals, zs, args.repeats)
    operating_point._solve_batch = timed_kernel
    try:
        kernel_s = float("inf")
        for _ in range(args.repeats):
            spent[0] = 0.0
            for zi in zs:
                obj.data_residuals(zi)
            kernel_s = min(kernel_s, spent[0] / len(zs))
    finally:
        operating_point._solve_batch = kernel
    t0 = time.process_time()
    fit_combination(problem, gate)
    out = {
        "evaluation_us": round(evaluation * 1e6, 1),
        "kernel_us": round(kernel_s * 1e6, 1),
        "overhead_us": round((evaluation - kernel_s) * 1e6, 1),
        "fit_waste_gate_s": round(time.process_time() - t0, 2),
    }
    if args.trial:
        import sys
        from pathlib import Path

        sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the repository root, home of studies/
        from studies.validation import study

        t0 = time.process_time()
        study.trial(args.trial[0], int(args.trial[1:]))
        out[f"trial_{args.trial}_s"] = round(time.process_time() - t0, 2)
    out["load_average_1min"] = round(os.getloadavg()[0], 2)
    emit(out, args.json)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
