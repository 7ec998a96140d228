"""Global bounds of the observers' forcing terms over the operating envelope: the ``λ_h d̄_χ`` and Λ
of eq. 5.11-5.12 that the ``thesis-lipschitz`` and ``thesis-table-6.1`` threshold readings use
(:mod:`marine_fdi_env.diagnosis.thresholds`).

    python -m studies.diagnosis.threshold_bounds            # -> data/diagnosis/thesis_threshold_bounds.json

The thesis bounds the forcing's uncertainty by a global Lipschitz constant times the noise bound
(eq. 5.11) and gives neither.  We take, per observer (M3.q: h3 of eq. 3.16; M4.q: h4 of eq. 3.31)
and per input, the largest deviation of the forcing at ±d̄ of that input
(:func:`~marine_fdi_env.diagnosis.residuals.model_terms`, the terms of the ``local`` reading)
over the true states of ``--runs`` fault-free 300 s runs of the five profile families at fuel
settings 0.3-1.1 (the profiles the suites and the calibration draw; entropy 6e9 + i, disjoint from
every other set), sampled every ``--every`` seconds.  That is the Lipschitz constant restricted to
the envelope the benchmark visits, times d̄; Λ (eq. 5.12) is the largest slope of the forcing in
the observer's own state, the state's term divided by its noise bound.  The runs have no sensor
noise (the bound is over true states, as a Lipschitz constant is).
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from marine_fdi_env.diagnosis.residuals import model_terms
from marine_fdi_env.diagnosis.thresholds import GLOBAL_BOUNDS_FILE, SENSOR_TERMS, STATE_TERM
from marine_fdi_env.engine.constants import model_constants
from marine_fdi_env.engine.params import load_params
from marine_fdi_env.engine.sensors import NOISE_BOUNDS, sensor_index
from marine_fdi_env.engine.simulator import Simulator
from studies.paths import PACKAGE_DATA

from .sequential_calibration import profile_for

__all__ = ["envelope_bounds", "ENTROPY0"]

ENTROPY0 = 6_000_000_000
DURATION_S = 300.0
OUT = PACKAGE_DATA / "diagnosis" / GLOBAL_BOUNDS_FILE


def envelope_bounds(params: str, runs: int, every_s: float, entropy0: int = ENTROPY0, progress: bool = True) -> dict:
    """{"terms": {input: largest term}, "lambda_state_per_s": ..., "argmax": ...} per observer M3, M4."""
    drawn = [profile_for(entropy0 + i, DURATION_S) for i in range(runs)]
    sim = Simulator(params, runs, seeds=[s for _, s in drawn], profiles=[p for p, _ in drawn], noise_scale=0.0)
    res = sim.run(DURATION_S)
    every = max(1, int(round(every_s / sim.dt)))
    y = res.measurements[::every].reshape(-1, 19)  # noise-free readings = true values
    u = res.truth_of("u")[::every].reshape(-1)
    c = model_constants(load_params(params))
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(y), desc="forcing terms", unit="point", file=sys.stderr)
    terms = np.empty((len(y), 2, 5))
    for a in range(0, len(y), 20000):
        terms[a : a + 20000] = model_terms(c, y[a : a + 20000])[:, :2, :5]
        if bar is not None:
            bar.update(min(20000, len(y) - a))
    if bar is not None:
        bar.close()
    state_bound = {"M3": NOISE_BOUNDS[sensor_index("S3.1")], "M4": NOISE_BOUNDS[sensor_index("S4.1")]}
    chain = [sensor_index(s) for s in ("S1.1", "S3.1", "S4.1", "S4.3", "S3.3")]
    out = {}
    for q, obs in enumerate(("M3", "M4")):
        t = terms[:, q, :]
        k = int(np.argmax(t.sum(axis=1)))
        si = SENSOR_TERMS.index(STATE_TERM[obs])
        out[obs] = {
            "terms": {name: float(t[:, i].max()) for i, name in enumerate(SENSOR_TERMS)},
            "lambda_state_per_s": float(t[:, si].max() / state_bound[obs]),
            "largest_sum_at": {
                "fuel_setting": float(u[k]),
                "state": dict(zip(SENSOR_TERMS, (float(v) for v in y[k, chain]))),
                "sum": float(t[k].sum()),
            },
            "median_sum": float(np.median(t.sum(axis=1))),
        }
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m studies.diagnosis.threshold_bounds", description=__doc__.splitlines()[0]
    )
    ap.add_argument("--runs", type=int, default=100, help="fault-free 300 s runs over the five profile families")
    ap.add_argument("--every", type=float, default=0.1, help="sample spacing [s] of the states taken")
    ap.add_argument("--params", default="thesis-12v28")
    ap.add_argument("--out", default=str(OUT))
    args = ap.parse_args(argv)
    bounds = envelope_bounds(args.params, args.runs, args.every)
    data = {
        "what": "largest deviation of the observers' forcing (h3: M3.q, h4: M4.q) at ±d̄ of each input over the "
        "operating envelope (true states of fault-free runs of the five profile families, fuel settings 0.3-1.1), "
        "without the safety factor; lambda_state_per_s: the largest slope in the observer's own state",
        "command": f"python -m studies.diagnosis.threshold_bounds --runs {args.runs} --every {args.every}",
        "units": {"M3": "Pa/s", "M4": "Pa/s"},
        "noise_bounds": "table 6.3",
        "params": {args.params: bounds},
    }
    path = args.out
    try:
        with open(path) as f:
            old = json.load(f)
        if old.get("command") == data["command"]:
            old["params"].update(data["params"])
            data = old
    except FileNotFoundError:
        pass
    with open(path, "w") as f:
        json.dump(data, f, indent=1)
        f.write("\n")
    for obs, b in bounds.items():
        print(obs, {k: f"{v:.4g}" for k, v in b["terms"].items()}, f"Λ={b['lambda_state_per_s']:.4g}/s")
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
