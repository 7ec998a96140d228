"""Could the data of a missed study trial have told the hidden causes from the ones the pipeline named?

Conditions (a)-(d) of the open-world study (:mod:`.study`) hide one or two library mechanisms and score the
selection (:mod:`.selection`) on naming exactly them.  A miss has two possible reasons:

* **the data cannot tell**: the named set fits the trial's data as well as the truth does.  With eight points and
  the model-error nuisance free, a flexible mechanism (a waste gate opening freely at each point) can absorb a
  second one (a turbine efficiency over blade-speed ratio); no selection that judges fits can then prefer the
  truth;
* **the data prefer the named set**: it fits clearly better than the truth (usually the truth plus a sensor
  calibration that absorbs the model error of condition (b) or the noise of (c));
* **the selection missed what the data say**: the truth fits clearly better, and the selection's path (the
  greedy order, the supports a step keeps, the cross-validated gain a partner must add) did not get there.

The check fits both sets to the trial's full data, with the selection's own loss, nuisance and valve-support rules
(:func:`~.fitting.fit_combination`), each the better of two fits: from the mechanisms' default starts, and from the
true values of the mechanisms it shares with the truth (the oracle knows them). A set is *preferred by the data*
over the other when it passes the selection's own bar for accepting a model over another, in sample: its mean robust
loss per cell is at least ``min_gain`` (10 %) lower and, when it has more free parameters than the other, the F-test
of the drop gives ``p < alpha`` (0.01; the selection's threshold is this over the number of candidates of a step, so
this is the lenient side). An in-sample fit favours the larger model (it is scored on the data it saw; the selection
scores cross-validated losses), so a miss where even the in-sample comparison does not prefer the truth is one no
selection of this kind could avoid (when the named set is the larger one, its being preferred in sample is the
weaker statement): ``identifiable`` = hits + misses the data prefer bounds, from above, what such a selection can
reach on the trials. It is a bound in that sense only: a different kind of evidence (more points, other channels)
could tell more.

``python -m studies.validation.identification_bound --study FILE.json [FILE.json ...] [--out OUT.json]``
re-draws each missed trial's data from its seed (no selection run: two fits per miss, seconds each) and prints
the table of docs/validation.md.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any, Mapping, Sequence

from scipy import stats

from .study_pool import load_trials

__all__ = ["passes_bar", "trial_check", "check", "summarise", "CONDITIONS", "main"]

#: the conditions whose trials hide library mechanisms (scored on naming exactly them)
CONDITIONS = ("a", "b", "c", "d")


def passes_bar(
    S_a: float, k_a: int, S_b: float, k_b: int, M: int, *, min_gain: float = 0.10, alpha: float = 0.01
) -> tuple[bool, float]:
    """Whether model ``a`` passes the selection's bar against model ``b``, in sample: ``(verdict, p)``.

    ``S``: mean robust loss per measured cell (1 = errors at the tolerance), ``k``: free parameters, ``M``: measured
    cells.  ``a`` must lower ``S`` by ``min_gain`` (relative); with more parameters, the one-sided F-test of the
    drop per added parameter against its loss per residual degree of freedom must also give ``p < alpha``
    (``p`` is NaN when it has no more parameters)."""
    if not (math.isfinite(S_a) and math.isfinite(S_b)) or M <= 0:
        raise ValueError(f"need finite scores and M > 0, got S_a={S_a}, S_b={S_b}, M={M}")
    gain_ok = S_a <= (1.0 - min_gain) * S_b
    if k_a <= k_b:
        return bool(gain_ok), math.nan
    dk, dof = k_a - k_b, max(M - k_a, 1)
    if S_a <= 0:
        p = 0.0 if S_b > 0 else 1.0
    else:
        F = ((S_b - S_a) * M / dk) / (S_a * M / dof)
        p = float(stats.f.sf(F, dk, dof)) if F > 0 else 1.0
    return bool(gain_ok and p < alpha), p


def _problem(condition: str, seed: int, params: str, points: int):
    """The trial's data and :class:`~.problem.FitProblem`, written and loaded as the study does."""
    from marine_fdi_env.validation.fit.problem import FitProblem

    from .study import loaded, trial_data

    syn = trial_data(condition, seed, params=params, points=points)
    return syn, FitProblem(loaded(syn, f"hidden_{condition}_{seed}"))


def trial_check(result: Mapping[str, Any], *, min_gain: float = 0.10, alpha: float = 0.01) -> dict[str, Any]:
    """Fit the truth and the named set of one missed (a)-(d) trial of a study file (its data re-drawn from the seed).

    Raises ValueError when the result is not a scored miss of (a)-(d), or when the re-drawn truth is not the one the
    file records (the file was written by another version of the study)."""
    from marine_fdi_env.validation.fit.fitting import Combination, fit_combination
    from marine_fdi_env.validation.fit.mechanisms import library, sensor_reference
    from marine_fdi_env.validation.measured.columns import QUANTITIES

    cond = result.get("condition")
    if cond not in CONDITIONS or result.get("control") or result.get("outcome") in (None, "skipped", "control"):
        raise ValueError("not a scored trial of conditions (a)-(d)")
    if result.get("exact"):
        raise ValueError(f"seed {result.get('seed')}: not a miss")
    ts = result.get("trial_settings") or {}
    seed = int(result["seed"])
    syn, problem = _problem(cond, seed, str(ts.get("params", "wartsila-6l46")), int(ts.get("points", 8)))
    truth = sorted(t["label"] for t in syn.truth)
    recorded = sorted(t["label"] for t in result.get("truth", []))
    if truth != recorded:
        raise ValueError(
            f"({cond}) seed {seed}: the re-drawn truth {truth} is not the file's {recorded}: another "
            "version of the study"
        )
    refs = {
        c: sensor_reference(c, problem.Y[:, j], QUANTITIES[problem.ds.column_quantity[c]].kind)
        for j, c in enumerate(problem.channels)
    }
    lib = {m.label: m for m in library(problem.channels, refs)}
    named = list(result.get("selected", []))
    unknown = [x for x in truth + named if x not in lib]
    if unknown:
        raise ValueError(f"({cond}) seed {seed}: not in the library: {', '.join(unknown)}")
    known = {f"{t['label']}.{k}": float(v) for t in syn.truth for k, v in t.get("values", {}).items()}

    def best_fit(labels):
        comb = Combination(tuple(lib[x] for x in labels))
        fits = [fit_combination(problem, comb), fit_combination(problem, comb, known=known)]
        return min(fits, key=lambda f: f.data_cost)

    f_truth, f_named = best_fit(truth), best_fit(named)
    M = f_truth.n_cells
    S_t, S_n = 2.0 * f_truth.data_cost / M, 2.0 * f_named.data_cost / M
    truth_wins, p = passes_bar(S_t, f_truth.k, S_n, f_named.k, M, min_gain=min_gain, alpha=alpha)
    named_wins, p_named = passes_bar(S_n, f_named.k, S_t, f_truth.k, M, min_gain=min_gain, alpha=alpha)
    return {
        "condition": cond,
        "seed": seed,
        "truth": truth,
        "named": sorted(named),
        "M": int(M),
        "S_truth": S_t,
        "k_truth": int(f_truth.k),
        "S_named": S_n,
        "k_named": int(f_named.k),
        "p": None if math.isnan(p) else p,
        "p_named": None if math.isnan(p_named) else p_named,
        "data_prefer": "truth" if truth_wins else "named" if named_wins else "neither",
    }


def check(results: Sequence[Mapping[str, Any]], *, progress: bool = True, **kw) -> dict[str, Any]:
    """Per condition of (a)-(d): the scored trials, the hits, and :func:`trial_check` of every miss."""
    scored = [
        r
        for r in results
        if r.get("condition") in CONDITIONS
        and not r.get("control")
        and r.get("outcome") not in (None, "skipped", "control")
    ]
    if not scored:
        raise ValueError("no scored trial of conditions (a)-(d) in the results")
    misses = [r for r in scored if not r.get("exact")]
    bar = None
    if progress and misses:
        try:
            from tqdm import tqdm

            bar = tqdm(total=len(misses), unit="miss", desc="identification bound", file=sys.stderr)
        except ImportError:  # pragma: no cover - tqdm is a core dependency
            bar = None
    checked = []
    for r in misses:
        checked.append(trial_check(r, **kw))
        if bar is not None:
            bar.update(1)
    if bar is not None:
        bar.close()
    counts = {
        c: {
            "n": sum(r["condition"] == c for r in scored),
            "hits": sum(r["condition"] == c and bool(r.get("exact")) for r in scored),
        }
        for c in CONDITIONS
    }
    return {"summary": summarise(counts, checked), "counts": counts, "misses": checked}


def summarise(counts: Mapping[str, Mapping[str, int]], checked: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """Per condition: n, hits, misses, the misses the data prefer the truth in (``selection_missed``), the named set
    in (``data_prefer_named``) or neither in (``data_cannot_tell``), and ``identifiable_rate`` = (hits +
    selection_missed) / n."""
    out = {}
    for c, k in counts.items():
        if not k["n"]:
            continue
        mine = [m for m in checked if m["condition"] == c]
        sel = sum(m["data_prefer"] == "truth" for m in mine)
        out[c] = {
            "n": int(k["n"]),
            "hits": int(k["hits"]),
            "misses": len(mine),
            "selection_missed": sel,
            "data_prefer_named": sum(m["data_prefer"] == "named" for m in mine),
            "data_cannot_tell": sum(m["data_prefer"] == "neither" for m in mine),
            "identification_rate": k["hits"] / k["n"],
            "identifiable_rate": (k["hits"] + sel) / k["n"],
        }
    return out


def _table(rows: Sequence[tuple[str, Mapping[str, Any]]]) -> str:
    lines = [
        "| trials | condition | n | named exactly | misses | the data prefer the truth (selection missed) | "
        "the data prefer the named set | neither fits clearly better (data cannot tell) | "
        "at most identifiable |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for label, s in rows:
        for c, v in s.items():
            lines.append(
                f"| {label} | ({c}) | {v['n']} | {v['hits']} = {v['identification_rate']:.1%} | "
                f"{v['misses']} | {v['selection_missed']} | {v['data_prefer_named']} | "
                f"{v['data_cannot_tell']} | "
                f"{v['hits'] + v['selection_missed']} = {v['identifiable_rate']:.1%} |"
            )
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m studies.validation.identification_bound",
        description="Could the data of the study's missed (a)-(d) trials tell the truth "
        "from the named causes? (see the module docstring)",
    )
    ap.add_argument(
        "--study",
        nargs="+",
        required=True,
        metavar="FILE.json",
        help="study files written by `python -m studies.validation.study --out`",
    )
    ap.add_argument("--out", default=None, help="write the per-miss fits and summaries as JSON here")
    ap.add_argument("--no-progress", action="store_true", help="no progress bar")
    args = ap.parse_args(list(argv) if argv is not None else None)
    try:
        files = load_trials(args.study)  # refuses an unreadable file and a trial counted twice
    except ValueError as e:
        print(f"identification_bound: error: not a study file ({e})", file=sys.stderr)
        return 2
    rows, out = [], {}
    for f, (label, results) in zip(args.study, files):
        try:
            b = check(results, progress=not args.no_progress)
        except ValueError as e:
            print(f"identification_bound: error: {f}: {e}", file=sys.stderr)
            return 2
        rows.append((f"seeds {label}", b["summary"]))
        out[str(f)] = b
    if len(out) > 1:
        counts = {c: {k: sum(b["counts"][c][k] for b in out.values()) for k in ("n", "hits")} for c in CONDITIONS}
        pooled = summarise(counts, [m for b in out.values() for m in b["misses"]])
        rows.append(("pooled", pooled))
        out["pooled"] = {"summary": pooled}
    print(_table(rows))
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
