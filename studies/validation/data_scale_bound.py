"""What judging residual structure at the data's own scatter can and cannot do: false findings on pure noise and
the power on a bump, for three ways of estimating the scatter (validation/select/data_scale.py's module docstring
quotes these numbers).

Each draw is a dataset of ``n`` points (load order) on 13 channels of Gaussian noise, every channel's tolerance 1;
the scan is :func:`~marine_fdi_env.validation.select.window_scan.window_excess`'s (windows up to ``n/2``),
Bonferroni over the channels (``alpha = 0.05 / 13``), and a finding must also depart by a tolerance, as in the
pipeline.  Rules:

* ``own``: each channel judged at its own robust scatter (``median |Δr| / (0.6745 sqrt 2)``) with a null that
  simulates that estimate (studentised), where it is below the tolerance;
* ``median``: judged at the larger of the median over channels and the channel's own scatter, the null taking
  that scale as known;
* ``largest``: judged at the largest channel scatter when it is below the tolerance (the package's rule);
* ``known``: judged at each channel's true noise (an oracle no data set offers: the bound).

Scenarios: pure noise with every channel at its tolerance, with a mix like the study's condition (a) (1 % noise
against 1 % / 5 K tolerances: pressures and speeds at their tolerance, temperatures 0.1-0.8 of it), and every channel
at half its tolerance (a loosely stated dataset) with a Gaussian bump (width 0.1 of the load range) or a step of 5
and 8 noise levels on one channel.

    python -m studies.validation.data_scale_bound --draws 2000 --out docs/figures/validation/data_scale_bound.json
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from marine_fdi_env.validation.select.window_scan import _scan, scan_null

CHANNELS = 13
ALPHA = 0.05 / CHANNELS
#: noise in tolerances per channel, like condition (a): 1 % of the typical reading against 1 % / 5 K tolerances
MIXED = np.array([1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.8, 0.36, 0.09, 0.5, 1.0, 1.0, 0.7])
RULES = ("own", "median", "largest", "known")


def robust_scatter(Y: np.ndarray) -> np.ndarray:
    """``median |Δr| / (0.6745 sqrt 2)`` along the last axis (validation.data_scale.channel_noise)."""
    return np.median(np.abs(np.diff(Y, axis=-1)), axis=-1) / (0.6745 * math.sqrt(2.0))


def studentised_null(n: int, draws: int = 40_000) -> np.ndarray:
    """Sorted scan statistics of unit noise judged at each draw's own robust scatter."""
    X = np.random.default_rng([n, 20261127]).normal(0.0, 1.0, (draws, n))
    return np.sort(_scan(X / robust_scatter(X)[:, None], 1.0, n // 2)[0])


def findings(Y: np.ndarray, rule: str, crit_known: float, crit_own: float, sd: np.ndarray) -> np.ndarray:
    """Which channels (rows of ``Y``, tolerance 1, true noise ``sd``) show a local finding under ``rule``."""
    own = robust_scatter(Y)
    if rule == "known":
        scale, crit = sd, np.full(own.size, crit_known)
    elif rule == "own":
        scale, crit = np.where(own < 1.0, own, 1.0), np.where(own < 1.0, crit_own, crit_known)
    elif rule == "median":
        s = np.maximum(np.median(own), own)
        scale, crit = np.where(s < 1.0, s, 1.0), np.full(own.size, crit_known)
    else:
        top = own.max()
        scale, crit = np.full(own.size, top if top < 1.0 else 1.0), np.full(own.size, crit_known)
    z, _, _, (d, _) = _scan(Y / scale[:, None], 1.0, Y.shape[1] // 2)
    return (z > crit) & (np.abs(d * scale) >= 1.0)


def run(points: int, draws: int, seed: int = 0) -> list[dict]:
    """Every (rule, scenario): the share of datasets with a finding on a noise-only channel and, with an effect, the
    share with a finding on the effect's channel; each with its Wilson 95 % interval."""
    from scipy.stats import binomtest

    known = scan_null(points, points // 2, 1.0)
    crit_known = known[int((1 - ALPHA) * known.size)]
    own_null = studentised_null(points)
    crit_own = own_null[int((1 - ALPHA) * own_null.size)]
    x = np.linspace(0.0, 1.0, points)
    scenarios = [
        ("noise at the tolerance", np.ones(CHANNELS), None, 0.0),
        ("mixed noise (condition (a))", MIXED, None, 0.0),
        ("half the tolerance", np.full(CHANNELS, 0.5), None, 0.0),
        ("half, bump 5 noise levels", np.full(CHANNELS, 0.5), "bump", 5.0),
        ("half, bump 8 noise levels", np.full(CHANNELS, 0.5), "bump", 8.0),
        ("half, step 5 noise levels", np.full(CHANNELS, 0.5), "step", 5.0),
    ]
    out = []
    for name, sd, kind, amp in scenarios:
        for rule in RULES:
            rng = np.random.default_rng([seed, points, RULES.index(rule)])
            false, hit = 0, 0
            for _ in range(draws):
                Y = rng.normal(0.0, 1.0, (CHANNELS, points)) * sd[:, None]
                if kind is not None:
                    c = rng.uniform(0.3, 0.7)
                    shape = (x > c).astype(float) if kind == "step" else np.exp(-0.5 * ((x - c) / 0.1) ** 2)
                    Y[0] += amp * sd[0] * shape
                f = findings(Y, rule, crit_known, crit_own, sd)
                false += bool(f[1:].any() if kind else f.any())
                hit += bool(f[0]) if kind else 0
            row = {"points": points, "scenario": name, "rule": rule, "draws": draws}
            row["critical_z"] = float(crit_own if rule == "own" else crit_known)
            for key, k in (("false_finding", false), ("found", hit)) if kind else (("false_finding", false),):
                ci = binomtest(k, draws).proportion_ci(method="wilson")
                row[key] = {"rate": k / draws, "ci95": [ci.low, ci.high]}
            out.append(row)
    return out


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--draws", type=int, default=2000, help="datasets per rule and scenario")
    ap.add_argument("--points", type=int, nargs="+", default=[8, 14], help="points per dataset")
    ap.add_argument("--out", type=Path, default=None, help="JSON output (default: print only)")
    a = ap.parse_args(argv)
    rows = [r for n in a.points for r in run(n, a.draws)]
    for r in rows:
        ff = r["false_finding"]
        found = r.get("found")
        print(
            f"{r['points']:>3} {r['scenario']:<30} {r['rule']:<8} false {100 * ff['rate']:5.1f} %"
            + (f"  found {100 * found['rate']:5.1f} %" if found else "")
        )
    if a.out:
        a.out.parent.mkdir(parents=True, exist_ok=True)
        a.out.write_text(json.dumps({"alpha_per_channel": ALPHA, "rows": rows}, indent=1) + "\n")


if __name__ == "__main__":
    main()
