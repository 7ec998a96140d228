"""Would the pipeline name the same causes again on data like these?  A parametric bootstrap at the data's design.

The pipeline (:func:`~.selection.select_causes`) names causes on one dataset; the open-world study
(docs/validation.md) measures how often it is right on data drawn at *its* design (8 stratified loads, the
parameter set's ambient state, noise it chose).  This module asks the question at the design of the data at
hand: the same operating points, per-row boundary conditions, channels, tolerances and per-cylinder spreads.

**Hypotheses.**  The causes named on the data, as fitted there, and each *alternative*: the named set with its
first physical mechanism replaced by another physical mechanism of the library (default: the ``top`` best of the
selection's first step by in-sample score), fitted on the same data (nuisance and any named sensor calibration
refitted with it).  Each is taken in turn as the truth.

**Replicas.**  A hypothesis's fitted readings at the measured cells plus Gaussian noise are new measurements, and
the whole pipeline runs on them unchanged (the settings it ran with on the data).  The noise (``noise``):

* ``residual`` (default): a wild bootstrap of the named model's in-sample residuals.  Each measured cell gets its
  own residual ``e = measured - fitted`` with a random sign, scaled by ``sqrt(M / (M - k))`` (M measured cells, k
  fitted parameters: a fit's residuals are smaller than its errors).  A replica is as far from its truth, cell by
  cell, as the data are from the named model, misfit the library cannot explain included; the signs are random,
  so a replica keeps the size of the data's unexplained structure, not its shape.  (With every sign positive the
  named hypothesis's replica is the data themselves, up to the scale.)
* ``tolerance``: Gaussian noise of each cell's tolerance, the unit the pipeline scores in and what it assumes.

**Read-out** per hypothesis: how often the pipeline names exactly the hypothesis's causes; how often it names the
causes it named on the real data (over the alternatives: the chance of naming them although an alternative is
true); which physical mechanisms it names; for a valve, how often the points where it acts come out as in the
hypothesis.  Replica ``r`` of hypothesis ``h`` draws its noise from ``default_rng([seed, h, r])``, so the numbers
do not depend on the number of workers.

``marine-fdi replicas --data NAME|FILE.csv [--replicas N] [--noise residual|tolerance]
[--alternatives ID,...] [--workers W] [--beside-valve RULE] [--held-out-valves RULE] [--out FILE.json]
[--markdown FILE.md]``: the data's selection and every replica's follow the same rules.
"""

from __future__ import annotations

import dataclasses
import math
import sys
import time
from collections import Counter
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from ..fit.fitting import Combination, fit_combination, predict_setting
from ..fit.mechanisms import PHYSICAL_MECHANISMS, Mechanism, SensorCalibration
from ..fit.problem import FitProblem
from ..measured.dataset import MeasuredDataset
from .binomial import proportion_ci95
from .rules import SelectionRules
from .selection import Selection, select_causes

__all__ = [
    "Hypothesis",
    "NOISE_MODELS",
    "hypotheses",
    "noise_scale",
    "replica_readings",
    "run_replica",
    "replicate",
    "summarise",
    "markdown_table",
]

NOISE_MODELS = ("residual", "tolerance")


@dataclass(frozen=True)
class Hypothesis:
    """One candidate truth: its causes (labels, sorted), fitted readings (points x channels, column units; NaN
    where the model has no steady state) and, per valve, whether it acts at each point."""

    name: str
    causes: tuple[str, ...]
    readings: np.ndarray
    acts: Mapping[str, tuple[bool, ...]]
    in_sample_score: float
    fit_values: Mapping[str, float]


def _physical(m: Mechanism) -> bool:
    return not isinstance(m, SensorCalibration)


def _acts(fit) -> dict[str, tuple[bool, ...]]:
    return {m.id: tuple(bool(math.isfinite(x) and x > 0) for x in fit.openings[m.id]) for m in fit.combination.valves}


def _hypothesis(problem: FitProblem, name: str, fit) -> Hypothesis:
    rows = np.arange(problem.n_points)
    M = int(problem.measured_mask[problem.rows_with_data()].sum())
    return Hypothesis(
        name=name,
        causes=tuple(sorted(fit.combination.labels)),
        readings=predict_setting(problem, fit, rows),
        acts=_acts(fit),
        in_sample_score=2.0 * fit.data_cost / M,
        fit_values=fit.values(),
    )


def hypotheses(sel: Selection, alternatives: Sequence[str] | None = None, top: int = 4) -> list[Hypothesis]:
    """The named causes (first) and the alternatives (see the module docstring), each fitted on the data."""
    problem = sel.problem
    named = sel.selected.mechanisms
    ids = {m.id for m in PHYSICAL_MECHANISMS}
    if alternatives is None:
        first = [c for c in sel.steps[0]["candidates"] if c.members is None] if sel.steps else []
        ranked = sorted((c for c in first if _physical(c.combination.mechanisms[-1])), key=lambda c: c.in_sample_score)
        alternatives = [
            c.combination.mechanisms[-1].id
            for c in ranked
            if c.combination.mechanisms[-1].id not in {m.id for m in named}
        ][:top]
    bad = [a for a in alternatives if a not in ids]
    if bad:
        raise ValueError(
            f"--alternatives: unknown physical mechanism(s) {', '.join(bad)}; known: {', '.join(sorted(ids))}"
        )
    dup = [a for a in alternatives if a in {m.id for m in named}]
    if dup:
        raise ValueError(f"--alternatives: {', '.join(dup)} is among the named causes already")
    out = [_hypothesis(problem, "named", sel.fit)]
    k = next((i for i, m in enumerate(named) if _physical(m)), None)
    for a in alternatives:
        m = next(x for x in PHYSICAL_MECHANISMS if x.id == a)
        mechs = list(named)
        if k is None:
            mechs.insert(0, m)
        else:
            mechs[k] = m
        fit = fit_combination(problem, Combination(tuple(mechs)), start=sel.fit)
        out.append(_hypothesis(problem, f"alternative: {a}", fit))
    return out


def noise_scale(sel: Selection, model: str = "residual") -> np.ndarray:
    """Per cell (points x channels, column units): the standard deviation of the Gaussian noise (``tolerance``) or
    the scaled residual whose sign is drawn (``residual``); see the module docstring."""
    problem = sel.problem
    if model == "tolerance":
        return problem.tolerance_cells.copy()
    if model != "residual":
        raise ValueError(f"--noise must be one of {', '.join(NOISE_MODELS)}, got {model!r}")
    rows = np.arange(problem.n_points)
    e = np.where(problem.measured_mask, problem.Y - predict_setting(problem, sel.fit, rows), np.nan)
    M = int(problem.measured_mask.sum())
    return np.nan_to_num(e) * math.sqrt(M / max(M - sel.fit.k, 1))


def replica_readings(
    problem: FitProblem, hyp: Hypothesis, scale: np.ndarray, seed: int, h: int, r: int, noise: str = "residual"
) -> np.ndarray:
    """Replica ``r`` of hypothesis number ``h``: its readings plus the noise of :func:`noise_scale` (a random sign
    times ``scale`` for ``residual``, N(0, scale²) for ``tolerance``) at the measured cells, NaN elsewhere."""
    rng = np.random.default_rng([int(seed), int(h), int(r)])
    if noise == "residual":
        draw = rng.choice(np.array([-1.0, 1.0]), size=hyp.readings.shape)
    elif noise == "tolerance":
        draw = rng.standard_normal(hyp.readings.shape)
    else:
        raise ValueError(f"--noise must be one of {', '.join(NOISE_MODELS)}, got {noise!r}")
    return np.where(problem.measured_mask, hyp.readings + draw * scale, np.nan)


def run_replica(
    ds: MeasuredDataset,
    params,
    target: str,
    tolerances: Mapping[str, float],
    channels: Sequence[str],
    Y: np.ndarray,
    rules: SelectionRules,
    mechanisms: Sequence[Mechanism] | None = None,
) -> dict[str, Any]:
    """Run the pipeline on ``ds`` with readings ``Y`` of ``channels``: what it names, where valves act, what it
    leaves unexplained.  ``mechanisms``: the candidates (default the library, as on the data); ``rules``: the
    selection's, as on the data."""
    t0 = time.perf_counter()
    rep = ds.with_readings({c: Y[:, j] for j, c in enumerate(channels)})
    pr = FitProblem(rep, params=params, target=target, tolerances=tolerances, held_out_valves=rules.held_out_valves)
    s = select_causes(pr, mechanisms, rules=rules)
    return {
        "named": sorted(s.selected_labels),
        "acts": {k: list(v) for k, v in _acts(s.fit).items()},
        "unexplained": sorted({u["channel"] for u in s.unexplained}),
        "seconds": time.perf_counter() - t0,
    }


def summarise(
    hyps: Sequence[Hypothesis], runs: Mapping[int, Sequence[dict[str, Any]]], data_causes: Sequence[str]
) -> list[dict[str, Any]]:
    """Per hypothesis: rates of naming it, of naming the data's causes, the physical sets named, valve support."""
    data_causes = sorted(data_causes)
    out = []
    for h, hyp in enumerate(hyps):
        rs = runs.get(h, [])
        n = len(rs)
        k_self = sum(r["named"] == list(hyp.causes) for r in rs)
        k_data = sum(r["named"] == data_causes for r in rs)
        phys = Counter(
            " + ".join(x for x in r["named"] if not x.startswith(SensorCalibration.id)) or "(none)" for r in rs
        )
        valves = {}
        for v, acts in hyp.acts.items():
            k = sum(r["acts"].get(v) == list(acts) for r in rs)
            valves[v] = {"acts_in_hypothesis": list(acts), "same_points": k, "rate": k / n if n else math.nan}
        out.append(
            {
                "hypothesis": hyp.name,
                "causes": list(hyp.causes),
                "in_sample_score": hyp.in_sample_score,
                "replicas": n,
                "named_itself": k_self,
                "named_itself_rate": k_self / n if n else math.nan,
                "named_itself_ci95": proportion_ci95(k_self, n),
                "named_data_causes": k_data,
                "named_data_causes_rate": k_data / n if n else math.nan,
                "named_data_causes_ci95": proportion_ci95(k_data, n),
                "physical_named": dict(phys.most_common()),
                "valve_support": valves,
            }
        )
    return out


def replicate(
    sel: Selection,
    *,
    replicas: int = 10,
    noise: str = "residual",
    seed: int = 0,
    alternatives: Sequence[str] | None = None,
    top: int = 4,
    workers: int = 1,
    mechanisms: Sequence[Mechanism] | None = None,
    progress: bool = True,
) -> dict[str, Any]:
    """Fit the hypotheses, run ``replicas`` replicas of each through the pipeline, summarise (module docstring).
    ``mechanisms``: the candidates the selection ``sel`` was run with (default the library)."""
    if int(replicas) != replicas or replicas < 1:
        raise ValueError(f"--replicas must be an integer >= 1, got {replicas!r}")
    if int(workers) != workers or workers < 1:
        raise ValueError(f"--workers must be an integer >= 1, got {workers!r}")
    problem = sel.problem
    scale = noise_scale(sel, noise)
    hyps = hypotheses(sel, alternatives, top)
    rules = sel.rules  # every replica runs under the rules the data were selected with
    tol = dict(zip(problem.channels, map(float, problem.tolerance)))
    jobs = [(h, r) for h in range(len(hyps)) for r in range(int(replicas))]
    args = {
        j: (
            problem.ds,
            problem.params,
            problem.target,
            tol,
            problem.channels,
            replica_readings(problem, hyps[j[0]], scale, seed, *j, noise),
            rules,
            mechanisms,
        )
        for j in jobs
    }
    results: dict[tuple[int, int], dict[str, Any]] = {}
    bar = None
    if progress:
        try:
            from tqdm import tqdm

            bar = tqdm(total=len(jobs), desc="replicas", unit="run", file=sys.stderr)
        except ImportError:  # pragma: no cover
            bar = None
    try:
        if workers > 1:
            from concurrent.futures import ProcessPoolExecutor, as_completed

            with ProcessPoolExecutor(max_workers=int(workers)) as ex:
                futs = {ex.submit(run_replica, *args[j]): j for j in jobs}
                for f in as_completed(futs):
                    results[futs[f]] = f.result()
                    if bar:
                        bar.update(1)
        else:
            for j in jobs:
                results[j] = run_replica(*args[j])
                if bar:
                    bar.update(1)
    finally:
        if bar:
            bar.close()
    runs = {h: [results[(h, r)] for r in range(int(replicas))] for h in range(len(hyps))}
    chans = list(problem.channels)
    return {
        "dataset": problem.ds.name,
        "data_causes": sorted(sel.selected_labels),
        "settings": {
            "replicas": int(replicas),
            "noise": noise,
            "seed": int(seed),
            "selection": dataclasses.asdict(rules),
            "noise_scale": {c: [float(abs(x)) for x in scale[:, j]] for j, c in enumerate(chans)},
        },
        "hypotheses": [
            {
                "name": h.name,
                "causes": list(h.causes),
                "in_sample_score": h.in_sample_score,
                "fit": dict(h.fit_values),
                "acts": {k: list(v) for k, v in h.acts.items()},
                "cells_without_steady_state": int(np.sum(problem.measured_mask & ~np.isfinite(h.readings))),
            }
            for h in hyps
        ],
        "summary": summarise(hyps, runs, sel.selected_labels),
        "runs": {hyps[h].name: runs[h] for h in runs},
    }


def _pct(k: int, n: int, ci: Sequence[float]) -> str:
    return f"{k}/{n} ({100 * ci[0]:.0f}-{100 * ci[1]:.0f} %)" if n else "-"


def markdown_table(rep: Mapping[str, Any]) -> str:
    """The summary as a Markdown table (one row per hypothesis)."""
    lines = [
        "| truth (fitted on the data) | in-sample score | named itself | named the data's causes | "
        "physical causes named | valve acts at the same points |",
        "|---|---|---|---|---|---|",
    ]
    for s in rep["summary"]:
        valves = "; ".join(f"{v}: {d['same_points']}/{s['replicas']}" for v, d in s["valve_support"].items()) or "-"
        phys = ", ".join(f"{k} {v}" for k, v in s["physical_named"].items())
        lines.append(
            f"| {s['hypothesis']} ({' + '.join(s['causes'])}) | {s['in_sample_score']:.3g} | "
            f"{_pct(s['named_itself'], s['replicas'], s['named_itself_ci95'])} | "
            f"{_pct(s['named_data_causes'], s['replicas'], s['named_data_causes_ci95'])} | {phys} | {valves} |"
        )
    return "\n".join(lines)
