"""How often could *any* test tell the open-world study's out-of-library effects from a sensor calibration?

Condition (e) of the study (:mod:`.study`) adds a bump, a step or a bend to one channel, and the pipeline
should report it as unexplained on that channel.  A gain and an offset of that channel's reading (a sensor
calibration: in the library, and conditions (a)-(d) ask the pipeline to name it when it is the truth) reproduce
part of every such effect.  Only the part they cannot reproduce tells the effect from a miscalibrated sensor.

**The bound.**  An oracle knows the channel, the effect's exact shape, the true readings and the noise's standard
deviation σ_i at each point, and sees no model error.  It tests "gain and offset" (H0, a miscalibrated sensor)
against "gain and offset plus θ times the shape" (H1).  Whitened by the noise, the generalised likelihood-ratio
statistic is normal with unit variance and mean

    z = || P⊥ (e / σ) ||,    P⊥: the projection orthogonal to the whitened columns [1, reading],

(e: the effect added at the measured points): the gain and the offset are projected out exactly, and for a known
shape no test of the same level is more powerful (Neyman-Pearson).  At level α it reports the effect with
probability Φ(z - z_(1-α)).  α is the rate at which the same test would call a truly miscalibrated sensor
unexplained; two levels are reported:

* **5 % on the one channel**: the calibration being judged names its channel, and a 95 % identification target
  for true calibrations leaves 5 % to lose;
* **5 % family-wise over the compared channels** (Bonferroni), the level at which the pipeline reports
  unexplained findings (:data:`~.unexplained.ALPHA_UNEXPLAINED`).

Everything favours the oracle (the shape, the channel, the noise, no model error: the study's (e) engine is 1 % off),
so its mean rate over the trials bounds what any pipeline can reach on them while naming true calibrations at the
stated rate.  The pipeline need not respect that rate for this one decision, so its own hit rate is compared, not
ordered.  :func:`scale_for` gives the factor on the effects' amplitudes at which the oracle would reach a target.

**A scan that knows the family, not the effect** (:func:`family_scan_rate`).  The oracle knows the one shape;
a test in practice does not.  The generalised likelihood-ratio scan over the study's own family of shapes (bumps,
steps and bends on a grid of centres and widths covering the generator's ranges, each made orthogonal to the
whitened [1, reading]) takes the largest normalised projection; its threshold is simulated under H0 at the
trial's points and noise.  It still knows more than any pipeline (the family the effects are drawn from, the
channel, the noise, no model error), so it is a second, tighter reference, not a bound in the strict sense.
It is also run with the noise floored at the pipeline's tolerance (σ_i = max(noise, tolerance), ``at the
tolerance``): the pipeline takes a channel's noise to be at least its tolerance (1 %, 5 K), and where the study's
noise is smaller (a 45 °C reading: 0.45 K) the first two references exploit what the pipeline by design does not.

``python -m studies.validation.effect_bound --study FILE.json [FILE.json ...] [--out OUT.json]
[--plot OUT.png]`` re-draws each (e) trial's data from its seed (no pipeline run; seconds) and prints the table of
docs/validation.md: per file, pooled, and pooled by the study's size bins (how much of the effect a sensor's gain and
offset leave, :data:`~.study_pool.SIZE_BINS`; ``pooled_by_size`` in the JSON).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np
from scipy import optimize, stats

from marine_fdi_env.validation.select.binomial import proportion_ci95
from marine_fdi_env.validation.select.calibration_scan import orthonormal_directions

from .study_pool import SIZE_BINS, size_bin

__all__ = [
    "separation",
    "oracle_rate",
    "family_scan_rate",
    "shape_family",
    "trial_bound",
    "bound",
    "summarise",
    "scale_for",
    "plot",
    "LEVELS",
    "main",
]

#: (name, family-wise level, spread over the compared channels?)
LEVELS = (("one channel, 5 %", 0.05, False), ("family-wise 5 % over the channels", 0.05, True))


def separation(added: Sequence[float], reading: Sequence[float], noise_sd: Sequence[float] | float) -> float:
    """z: the norm of the whitened effect's part that no gain and offset of ``reading`` reproduce (see the module
    docstring).  ``added``: the effect at the measured points; ``reading``: the true readings without it;
    ``noise_sd``: the noise's standard deviation per point (or one for all), in the same units."""
    e = np.asarray(added, dtype=float)
    x = np.asarray(reading, dtype=float)
    s = np.broadcast_to(np.asarray(noise_sd, dtype=float), e.shape)
    if e.shape != x.shape or e.ndim != 1:
        raise ValueError(f"added and reading must be 1-D of the same length, got {e.shape} and {x.shape}")
    if not np.all(np.isfinite(s)) or np.any(s <= 0):
        raise ValueError("noise_sd must be finite and positive at every point")
    A = np.column_stack([np.ones_like(x), x]) / s[:, None]
    ew = e / s
    left = ew - A @ np.linalg.lstsq(A, ew, rcond=None)[0]
    return float(np.linalg.norm(left))


def oracle_rate(z: float | np.ndarray, alpha: float) -> float | np.ndarray:
    """Probability that the one-sided test at level ``alpha`` reports a statistic N(z, 1): Φ(z - z_(1-α))."""
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"alpha must be in (0, 1), got {alpha}")
    return stats.norm.cdf(np.asarray(z, dtype=float) - stats.norm.isf(alpha))


#: the scan's family: the generator's kinds (``synthesize.EFFECT_KINDS``) with centres and widths on a grid over
#: its draw ranges (``synthesize.draw_effect``: centre 0.45-0.85, width 0.08-0.14)
SCAN_CENTRES = tuple(np.round(np.linspace(0.45, 0.85, 17), 4))
SCAN_WIDTHS = (0.08, 0.10, 0.12, 0.14)
#: Monte Carlo draws for the scan's threshold (under H0) and its rate (under H1)
SCAN_NULL_DRAWS = 20000
SCAN_ALT_DRAWS = 4000


def shape_family(loads: Sequence[float]) -> np.ndarray:
    """The scan's shapes at ``loads`` (rows; unit amplitude): every kind of the study's effects at every grid
    centre and width (a bend does not depend on the width: once)."""
    from marine_fdi_env.validation.fit.synthesize import EFFECT_KINDS, effect_shape

    x = np.asarray(loads, dtype=float)
    rows = []
    for kind in EFFECT_KINDS:
        for c in SCAN_CENTRES:
            for w in SCAN_WIDTHS if kind != "bend" else SCAN_WIDTHS[:1]:
                rows.append(effect_shape({"kind": kind, "center": float(c), "width": float(w)}, x))
    return np.asarray(rows)


def family_scan_rate(
    added: Sequence[float],
    reading: Sequence[float],
    noise_sd: Sequence[float] | float,
    loads: Sequence[float],
    alpha: float,
    rng: np.random.Generator,
) -> float:
    """Rate at which the scan over :func:`shape_family` (two-sided, see the module docstring), at level ``alpha``
    (threshold simulated with :data:`SCAN_NULL_DRAWS` draws), reports the effect ``added`` (Monte Carlo over
    :data:`SCAN_ALT_DRAWS` noise draws)."""
    e = np.asarray(added, dtype=float)
    x = np.asarray(reading, dtype=float)
    sd = np.broadcast_to(np.asarray(noise_sd, dtype=float), e.shape).astype(float)
    if not 0.0 < alpha < 1.0:
        raise ValueError(f"alpha must be in (0, 1), got {alpha}")
    U, _ = orthonormal_directions(shape_family(loads), x, sd)
    null = np.max(np.abs(rng.standard_normal((SCAN_NULL_DRAWS, e.size)) @ U), axis=1)
    thr = float(np.quantile(null, 1.0 - alpha))
    alt = np.max(np.abs((e / sd)[None, :] @ U + rng.standard_normal((SCAN_ALT_DRAWS, e.size)) @ U), axis=1)
    return float(np.mean(alt > thr))


def _alpha(level: float, spread: bool, n_channels: int) -> float:
    return level / n_channels if spread else level


def trial_bound(result: Mapping[str, Any]) -> dict[str, Any]:
    """The oracle's z and rates for one (e) trial of a study file (its data re-drawn from the seed).

    Raises ValueError when the result is not an (e) trial with an effect, or when the re-drawn effect differs from
    the one the file records (the file was written by another version of the study)."""
    from marine_fdi_env.validation.fit.synthesize import SET_POINT_COLUMNS

    from .study import trial_data

    if result.get("condition") != "e" or result.get("control") or not result.get("effects"):
        raise ValueError("not an (e) trial with an out-of-library effect")
    ts = result.get("trial_settings") or {}
    syn = trial_data(
        "e", int(result["seed"]), params=str(ts.get("params", "wartsila-6l46")), points=int(ts.get("points", 8))
    )
    eff = syn.effects[0]
    rec = result["effects"][0]
    if eff["channel"] != rec["channel"] or not math.isclose(eff["amplitude"], rec["amplitude"], rel_tol=1e-9):
        raise ValueError(
            f"seed {result['seed']}: the re-drawn effect ({eff['channel']}, {eff['amplitude']:.6g}) is "
            f"not the file's ({rec['channel']}, {rec['amplitude']:.6g}): another version of the study"
        )
    c = eff["channel"]
    added = np.asarray(syn.settings["effects_added"][c], dtype=float)
    reading = np.asarray(syn.clean[c], dtype=float) - added
    z = separation(added, reading, syn.noise_sd(c))
    n_ch = sum(1 for k in syn.columns if k not in SET_POINT_COLUMNS)
    tol = _tolerance(syn, c)
    out = {
        "seed": int(result["seed"]),
        "channel": c,
        "kind": eff["kind"],
        "z": z,
        "n_channels": n_ch,
        "tolerance": tol,
        "pipeline_hit": bool(result.get("unexplained_right_channel")),
    }
    if "effect_size" in result:  # the study's own size: what a gain and an offset leave, in tolerances
        out["beyond_calibration"] = float(result["effect_size"]["beyond_calibration"])
        out["size_bin"] = size_bin(out["beyond_calibration"])
    rng = np.random.default_rng([int(result["seed"]), 7919, 5])
    loads = syn.settings["loads"]
    sd = syn.noise_sd(c)
    for name, level, spread in LEVELS:
        a = _alpha(level, spread, n_ch)
        out[name] = float(oracle_rate(z, a))
        out["scan: " + name] = family_scan_rate(added, reading, sd, loads, a, rng)
        out["scan at the tolerance: " + name] = family_scan_rate(added, reading, np.maximum(sd, tol), loads, a, rng)
    return out


def _tolerance(syn, column: str) -> float:
    """The pipeline's tolerance of ``column`` on the trial's data (written and loaded as the study does)."""
    from marine_fdi_env.validation.measured.discrepancy import column_tolerance

    from .study import loaded

    return float(column_tolerance(loaded(syn), column))


def scale_for(z: Sequence[float], alpha: float, target: float) -> float:
    """The factor k on every effect's amplitude at which the oracle's mean rate reaches ``target`` (z scales with
    the amplitude)."""
    zz = np.asarray(z, dtype=float)
    if not 0.0 < target < 1.0:
        raise ValueError(f"target must be in (0, 1), got {target}")
    if zz.size == 0 or np.any(zz <= 0):
        raise ValueError("need at least one trial, with z > 0 in every trial")

    def f(k: float) -> float:
        return float(np.mean(oracle_rate(k * zz, alpha))) - target

    hi = 1.0
    while f(hi) < 0:
        hi *= 2.0
    lo = hi / 2.0
    while f(lo) > 0 and lo > 1e-6:
        lo /= 2.0
    return float(optimize.brentq(f, lo, hi, xtol=1e-6))


def bound(results: Sequence[Mapping[str, Any]], target: float = 0.9) -> dict[str, Any]:
    """Per (e) trial of ``results`` (skipped trials and controls left out) and in summary: the oracle's rates at
    :data:`LEVELS`, the pipeline's hit rate on the same trials, and the amplitude factor for ``target``."""
    trials = [
        trial_bound(r)
        for r in results
        if r.get("condition") == "e" and not r.get("control") and r.get("outcome") != "skipped" and r.get("effects")
    ]
    if not trials:
        raise ValueError("no (e) trial in the results")
    return {"summary": summarise(trials, target), "trials": trials}


def summarise(trials: Sequence[Mapping[str, Any]], target: float = 0.9) -> dict[str, Any]:
    """Mean oracle rates at :data:`LEVELS`, the pipeline's hit rate and the amplitude factors over the per-trial
    values of :func:`trial_bound`."""
    z = [t["z"] for t in trials]
    n_ch = trials[0]["n_channels"]
    out: dict[str, Any] = {
        "n_trials": len(trials),
        "pipeline_rate": sum(t["pipeline_hit"] for t in trials) / len(trials),
        "z_median": float(np.median(z)),
        "target": target,
    }
    for name, level, spread in LEVELS:
        a = _alpha(level, spread, n_ch)
        out[name] = {
            "alpha": a,
            "oracle_rate": float(np.mean([t[name] for t in trials])),
            "family_scan_rate": float(np.mean([t["scan: " + name] for t in trials])),
            "family_scan_rate_at_tolerance": float(np.mean([t["scan at the tolerance: " + name] for t in trials])),
            "amplitude_factor_for_target": scale_for(z, a, target),
        }
    return out


def _table(rows: Sequence[tuple[str, dict[str, Any]]]) -> str:
    lines = [
        "| trials | n | level | pipeline: unexplained on the right channel | oracle (knows the shape) | "
        "scan over the family | scan over the family, noise floored at the tolerance | amplitude factor for the "
        "oracle to reach 90 % |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for label, s in rows:
        for name, _, _ in LEVELS:
            v = s[name]
            lines.append(
                f"| {label} | {s['n_trials']} | {name} | {s['pipeline_rate']:.0%} | {v['oracle_rate']:.0%} | "
                f"{v['family_scan_rate']:.0%} | {v['family_scan_rate_at_tolerance']:.0%} | "
                f"{v['amplitude_factor_for_target']:.2f}x |"
            )
    return "\n".join(lines)


def plot(out: Mapping[str, Any], path: str | Path, n_bins: int = 8) -> Path:
    """The pipeline's rate of reported effects against their size z, in ``n_bins`` bins of equal count with exact 95 %
    intervals, over what the references reach: the oracle's rate Φ(z - z_(1-α)) at :data:`LEVELS` (curves) and the
    family scan's mean rate in the same bins at the family-wise level, with the true noise and with the noise floored
    at the tolerance.  Each effect is a tick at 1 (reported) or 0 (not)."""
    from marine_fdi_env.plotting import pyplot

    plt = pyplot()
    trials = [t for b in out.values() if "trials" in b for t in b["trials"]]
    z = np.array([t["z"] for t in trials])
    hit = np.array([t["pipeline_hit"] for t in trials], dtype=bool)
    fw = LEVELS[1][0]
    grid = np.geomspace(max(0.3, float(z.min()) * 0.8), float(z.max()) * 1.2, 200)
    fig, ax = plt.subplots(figsize=(8.5, 5.2))
    n_ch = trials[0]["n_channels"]
    for (name, level, spread), style in zip(LEVELS, ("-", "--")):
        ax.plot(
            grid,
            oracle_rate(grid, _alpha(level, spread, n_ch)),
            "k" + style,
            lw=1.2,
            label=f"oracle (knows the shape), {name.replace(' over the channels', '')}",
        )
    rng = np.random.default_rng(0)  # fixed: the same file draws the same figure
    ax.scatter(
        z,
        hit + rng.uniform(-0.03, 0.03, z.size),
        marker="|",
        s=30,
        color="0.55",
        alpha=0.6,
        label=f"one effect, reported (1) or not (0): {int(hit.sum())}/{hit.size} reported",
    )
    order = np.argsort(z, kind="stable")
    bins = [b for b in np.array_split(order, min(n_bins, z.size)) if b.size]
    centre = np.array([float(np.exp(np.mean(np.log(z[b])))) for b in bins])
    for key, style, label in (
        ("scan: " + fw, "s:", "true noise"),
        ("scan at the tolerance: " + fw, "o:", "noise floored at the tolerance"),
    ):
        ax.plot(
            centre,
            [np.mean([trials[i][key] for i in b]) for b in bins],
            style,
            color="tab:blue",
            ms=4,
            lw=1,
            mfc="white" if style[0] == "o" else "tab:blue",
            label=f"scan over the family ({label}), family-wise 5 %",
        )
    k = np.array([int(hit[b].sum()) for b in bins])
    n = np.array([b.size for b in bins])
    ci = np.array([proportion_ci95(int(ki), int(ni)) for ki, ni in zip(k, n)])
    rate = k / n
    ax.errorbar(
        centre,
        rate,
        yerr=[rate - ci[:, 0], ci[:, 1] - rate],
        fmt="D",
        color="tab:red",
        mec="k",
        ms=6,
        capsize=3,
        lw=1.5,
        label=f"pipeline: {len(bins)} bins of {int(np.median(n))} effects, exact 95 % interval",
    )
    ax.set_xscale("log")
    ax.set_xlabel("z: the effect beyond a gain and offset, in noise units (log)")
    ax.set_ylabel("reported unexplained on the right channel")
    ax.set_ylim(-0.08, 1.08)
    ax.set_yticks([0, 0.25, 0.5, 0.75, 1])
    ax.set_title(
        f"Out-of-library effects (study condition e, {z.size} effects): the pipeline against what a test could report",
        fontsize=9,
    )
    ax.grid(alpha=0.3)
    fig.legend(*ax.get_legend_handles_labels(), loc="lower center", ncol=2, fontsize=7, frameon=False)
    fig.tight_layout(rect=(0, 0.15, 1, 1))
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m studies.validation.effect_bound",
        description="How often could any test tell the open-world study's (e) effects "
        "from a sensor calibration? (an oracle bound, see the module docstring)",
    )
    ap.add_argument(
        "--study",
        nargs="+",
        required=True,
        metavar="FILE.json",
        help="study files written by `python -m studies.validation.study --out`",
    )
    ap.add_argument("--target", type=float, default=0.9, help="rate for the amplitude factor (default 0.9)")
    ap.add_argument("--out", default=None, help="write the per-trial values and summaries as JSON here")
    ap.add_argument(
        "--plot",
        default=None,
        metavar="FILE.png",
        help="plot z against the pipeline's hits over the oracle's rate curves (needs matplotlib)",
    )
    args = ap.parse_args(list(argv) if argv is not None else None)
    rows, out = [], {}
    for f in args.study:
        try:
            results = json.loads(Path(f).read_text())["trials"]
        except (OSError, ValueError, KeyError, TypeError) as e:
            print(f"effect_bound: error: {f}: not a study file ({e})", file=sys.stderr)
            return 2
        try:
            b = bound(results, target=args.target)
        except ValueError as e:
            print(f"effect_bound: error: {f}: {e}", file=sys.stderr)
            return 2
        seeds = [t["seed"] for t in b["trials"]]
        label = f"seeds {min(seeds)}-{max(seeds)}"
        rows.append((label, b["summary"]))
        out[str(f)] = b
    if len(rows) > 1:
        every = [t for b in out.values() for t in b["trials"]]
        pooled = summarise(every, args.target)
        rows.append(("pooled", pooled))
        out["pooled"] = {"summary": pooled}
        by_size = {
            lab: summarise(mine, args.target)
            for lab in (size_bin(x) for x in (0.0,) + SIZE_BINS)
            if (mine := [t for t in every if t.get("size_bin") == lab])
        }
        rows += [(f"pooled, {lab} tolerances beyond a calibration", v) for lab, v in by_size.items()]
        out["pooled_by_size"] = by_size
    print(_table(rows))
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(json.dumps(out, indent=1) + "\n")
    if args.plot:
        try:
            plot(out, args.plot)
        except RuntimeError as e:
            print(f"effect_bound: error: {e}", file=sys.stderr)
            return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
