"""The open-world hidden-effect study: how often the pipeline names the truth on data it was not fitted to.

``python -m studies.validation.study`` runs conditions (a) closed world,
(b) model error, (c) reading-proportional noise, (d) two mechanisms, (e) out-of-library effects
(:data:`CONDITIONS`), each with its negative control (the same data without the hidden effect), on data drawn by
:func:`~.synthesize.synthesize`, and reports identification rates (:func:`summarise`).  A trial is fixed by its
condition and seed (:func:`trial_draw`, :func:`trial_data`); :func:`trial` runs the whole pipeline on it.
``python -m studies.validation.study pool`` pools study files (:mod:`.study_pool`).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from marine_fdi_env.validation.fit.mechanisms import MECHANISM_IDS, equivalents
from marine_fdi_env.validation.fit.synthesize import (
    DEFAULT_COLUMNS,
    FAMILIES,
    Synthesis,
    draw_effect,
    effect_region,
    synthesize,
)
from marine_fdi_env.validation.select.evidence import BESIDE_VALVE_DEFAULT

from .study_pool import SIZE_BINS

__all__ = [
    "CONDITIONS",
    "SIZE_BINS",
    "TOLERANCE_MODES",
    "effect_size",
    "loaded",
    "noise_tolerances",
    "study",
    "study_main",
    "summarise",
    "trial",
    "trial_data",
    "trial_draw",
]

CONDITIONS = {
    "a": {
        "title": "closed world: base model + one library mechanism, noise 1 % of the typical reading",
        "perturb": 0.0,
        "noise_model": "typical",
        "noise": 0.01,
        "n_mech": 1,
    },
    "b": {
        "title": "model error: the true engine's efficiencies, areas and heat fractions off by N(0, 3 %) each",
        "perturb": 0.03,
        "noise_model": "typical",
        "noise": 0.01,
        "n_mech": 1,
    },
    "c": {
        "title": "noise 1.5 % of each reading (the fit keeps its 1 % / 5 K tolerances)",
        "perturb": 0.0,
        "noise_model": "reading",
        "noise": 0.015,
        "n_mech": 1,
    },
    "d": {
        "title": "two library mechanisms at once (model error 1 %)",
        "perturb": 0.01,
        "noise_model": "typical",
        "noise": 0.01,
        "n_mech": 2,
    },
    "e": {
        "title": "an effect outside the library on one channel (model error 1 %)",
        "perturb": 0.01,
        "noise_model": "typical",
        "noise": 0.01,
        "n_mech": 0,
    },
    "f": {
        "title": "ambiguity by construction: data from one of two structures that fit each other's clean data "
        "within the band (a waste gate / gate and map at other points; a map change / a blade-speed-ratio "
        "loss)",
        "perturb": 0.0,
        "noise_model": "typical",
        "noise": 0.01,
        "n_mech": None,
    },
}


def effect_size(added: Sequence[float], reading: Sequence[float], tol: float) -> dict[str, float]:
    """How large an out-of-library effect is at the measured points, in the pipeline's tolerances: ``rms`` (its
    root-mean-square), ``norm`` (its Euclidean norm: what an oracle that knows the shape tests against noise of one
    tolerance) and ``beyond_calibration`` (the norm of what a gain and an offset of the reading leave of it: the part
    by which any test could tell the effect from a miscalibrated sensor)."""
    e = np.asarray(added, dtype=float)
    A = np.column_stack([np.ones_like(e), np.asarray(reading, dtype=float)])
    left = e - A @ np.linalg.lstsq(A, e, rcond=None)[0]
    return {
        "rms": float(np.sqrt(np.mean(e**2)) / tol),
        "norm": float(np.linalg.norm(e) / tol),
        "beyond_calibration": float(np.linalg.norm(left) / tol),
    }


def _draw_mechanisms(rng: np.random.Generator, n: int) -> list[str]:
    """``n`` distinct mechanism ids (a sensor calibration at most once)."""
    ids = list(MECHANISM_IDS)
    return [str(x) for x in rng.choice(ids, size=n, replace=False)]


#: what the pipeline is told of the noise in a study trial: ``stated`` its own tolerances (1 %, 5 K: what every
#: result of the study uses), ``noise`` each channel's true noise (:func:`noise_tolerances`, an ablation),
#: ``noise2x`` twice each channel's true noise (a loosely stated sensor: what judging at the data's own scatter,
#: :mod:`.data_scale`, must make up for)
TOLERANCE_MODES = ("stated", "noise", "noise2x")


def _trial_settings(
    params: str = "wartsila-6l46",
    points: int = 8,
    max_folds: int | None = None,
    prune: bool = True,
    tolerance: str = "stated",
    exchange: bool = True,
    held_out_valves: str = "schedule",
    beside_valve: str = BESIDE_VALVE_DEFAULT,
    explanations: bool = True,
    **_,
) -> dict[str, Any]:
    """What a trial's outcome depends on besides its condition and seed (a resumed study keeps only trials run with
    the same).  ``tolerance`` is recorded only when it is not the default, ``exchange`` only when it is on (a file
    without the key is a selection without the exchange step: ``--no-exchange``).  ``calibration_scan``: the level
    of the scan of what a named calibration leaves (:func:`~.unexplained.calibration_left`), over the calibrated
    channels; files without the key scan at the level over every channel, and differ from a rerun only in
    unexplained findings on channels with a named calibration.  ``held_out_valves``: how cross-validation predicts a
    valve's opening at a held-out point (:data:`~.problem.HELD_OUT_VALVES`), recorded only when it is not the
    default ``schedule`` (a file without the key follows the schedule).  ``beside_valve``: how a cause joining a
    model with a valve earns its place (:data:`~.evidence.BESIDE_VALVE`), recorded unless it is
    ``cross_validated`` (a file without the key judges it so; the files 340-360 record ``in_sample``, 360-380
    ``in_sample_exchange``, 380-400 ``in_sample_pairs``, the default).  ``explanations``: whether the trial records
    its explanation set (:mod:`.study_sets`), recorded when on (files without it have no set); ``local_scan``: a
    trial with the key judges a channel's window scan at the data's scatter below a loose tolerance
    (:mod:`.data_scale`; files without the key at the tolerance)."""
    out = {
        "params": str(params),
        "points": int(points),
        "max_folds": max_folds,
        "prune": bool(prune),
        "calibration_scan": "per named calibration",
        "local_scan": "data scale below a loose tolerance",
    }
    if explanations:
        out["explanations"] = True
    if tolerance != "stated":
        out["tolerance"] = str(tolerance)
    if exchange:
        out["exchange"] = True
    if held_out_valves != "schedule":
        out["held_out_valves"] = str(held_out_valves)
    if beside_valve != "cross_validated":
        out["beside_valve"] = str(beside_valve)
    return out


def noise_tolerances(syn: Synthesis, channels: Sequence[str]) -> dict[str, float]:
    """Each channel's tolerance set to the noise :func:`synthesize` drew on it: the mean over the points of its
    standard deviation (one number per sensor, as a user states a sensor's accuracy; in condition (c) the noise is
    proportional to the reading, so it is larger at high readings than this).  Used by the study's ``--tolerance
    noise`` ablation, which measures what the pipeline loses because its tolerances misstate the noise; no result
    of the study itself uses it."""
    return {c: float(np.mean(syn.noise_sd(c))) for c in channels}


def trial_draw(
    condition: str, seed: int, *, control: bool = False
) -> tuple[list[str], list[dict[str, Any]], str | None]:
    """What a trial of the study hides: (mechanism ids, out-of-library effects, the control's shadow channel).

    A control drops the draw; in (e) it keeps the channel the paired trial's effect is on (the shadow channel): a
    finding there is the control's false hit."""
    cond = CONDITIONS[condition]
    if condition == "f":  # drawn until two structures fit each other's data (:mod:`.ambiguity`); a control needs none
        from .ambiguity import ambiguous_draw

        d = None if control else ambiguous_draw(int(seed), loaded)
        return (d["specs"] if d else []), [], None
    rng = np.random.default_rng([int(seed), ord(condition), 7919])
    mechs = _draw_mechanisms(rng, cond["n_mech"])
    effects = (
        [draw_effect(rng, DEFAULT_COLUMNS, family=list(FAMILIES)[int(seed) % len(FAMILIES)])]
        if condition == "e"
        else []
    )
    shadow = effects[0]["channel"] if control and effects else None
    if control:
        mechs, effects = [], []
    return mechs, effects, shadow


def loaded(syn: Synthesis, name: str = "trial", workdir: str | Path | None = None):
    """``syn`` written to a temporary CSV and read back with the loader, as a user's file would be (its data
    warnings silenced: the study reports outcomes, not the loader's notes); raises the loader's DatasetError."""
    import tempfile
    import warnings

    from marine_fdi_env.validation.measured.dataset import DataWarning
    from marine_fdi_env.validation.measured.loader import load_measured

    with tempfile.TemporaryDirectory(dir=workdir) as d:
        path = Path(d) / f"{name}.csv"
        syn.write(path)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DataWarning)
            return load_measured(path)


def trial_data(
    condition: str,
    seed: int,
    *,
    control: bool = False,
    params: str = "wartsila-6l46",
    points: int = 8,
    draw: tuple[list[str], list[dict[str, Any]], str | None] | None = None,
) -> Synthesis:
    """The data of one trial of the study (:func:`trial` runs the pipeline on them; ``draw``: its
    :func:`trial_draw`, when already made); raises ValueError when the hidden engine cannot run at the drawn points
    (the trial is then skipped)."""
    cond = CONDITIONS[condition]
    mechs, effects, _ = trial_draw(condition, seed, control=control) if draw is None else draw
    return synthesize(
        params,
        mechs or ["none"],
        points=points,
        noise=cond["noise"],
        seed=int(seed) * 31 + 7,
        noise_model=cond["noise_model"],
        perturb=cond["perturb"],
        effects=effects,
    )


def trial(
    condition: str,
    seed: int,
    *,
    control: bool = False,
    params: str = "wartsila-6l46",
    points: int = 8,
    max_folds: int | None = None,
    prune: bool = True,
    tolerance: str = "stated",
    exchange: bool = True,
    held_out_valves: str = "schedule",
    beside_valve: str = BESIDE_VALVE_DEFAULT,
    explanations: bool = True,
    workdir: str | Path | None = None,
) -> dict[str, Any]:
    """One trial of the study: synthesise with the condition's hidden effects (none when ``control``), write and
    reload the data, run the selection (``prune``: its final removal step, on by default; ``tolerance``: one of
    :data:`TOLERANCE_MODES`; ``exchange``: the selection's exchange step, on by default; ``held_out_valves``: one of
    :data:`~.problem.HELD_OUT_VALVES`; ``beside_valve``: one of :data:`~.evidence.BESIDE_VALVE`; ``explanations``:
    also the explanation set, :mod:`.study_sets`) and compare with the truth."""
    from marine_fdi_env.validation.fit.problem import FitProblem
    from marine_fdi_env.validation.measured.dataset import DatasetError
    from marine_fdi_env.validation.select.rules import SelectionRules
    from marine_fdi_env.validation.select.selection import select_causes

    t0 = time.perf_counter()
    draw = trial_draw(condition, seed, control=control)
    mechs, effects, shadow = draw
    if tolerance not in TOLERANCE_MODES:
        raise ValueError(f"tolerance must be one of {', '.join(TOLERANCE_MODES)}, got {tolerance!r}")
    base = {
        "condition": condition,
        "control": bool(control),
        "seed": int(seed),
        "mechanisms": mechs,
        "effects": effects,
        "trial_settings": _trial_settings(
            params=params,
            points=points,
            max_folds=max_folds,
            prune=prune,
            tolerance=tolerance,
            exchange=exchange,
            held_out_valves=held_out_valves,
            beside_valve=beside_valve,
            explanations=explanations,
        ),
    }
    if condition == "f" and not control and not mechs:
        from .ambiguity import ATTEMPTS

        return {
            **base,
            "outcome": "skipped",
            "why": f"no draw of {ATTEMPTS} within the band",
            "seconds": time.perf_counter() - t0,
        }
    try:
        syn = trial_data(condition, seed, control=control, params=params, points=points, draw=draw)
    except ValueError as e:
        return {**base, "outcome": "skipped", "why": str(e)[:300], "seconds": time.perf_counter() - t0}
    try:
        ds = loaded(syn, f"hidden_{condition}_{seed}", workdir)
    except DatasetError as e:
        return {
            **base,
            "outcome": "skipped",
            "why": "loader: " + " ".join(str(e).split())[:300],
            "seconds": time.perf_counter() - t0,
        }
    rules = SelectionRules(
        max_folds=max_folds, prune=prune, exchange=exchange, beside_valve=beside_valve, held_out_valves=held_out_valves
    )
    problem = FitProblem(ds, held_out_valves=rules.held_out_valves)
    if tolerance in ("noise", "noise2x"):
        factor = 2.0 if tolerance == "noise2x" else 1.0
        problem = FitProblem(
            ds,
            tolerances={c: factor * v for c, v in noise_tolerances(syn, problem.channels).items()},
            held_out_valves=rules.held_out_valves,
        )
    sel = select_causes(problem, rules=rules)
    truth_labels = sorted(t["label"] for t in syn.truth)
    named = sorted(sel.selected_labels)
    res = {
        **base,
        "truth": syn.truth,
        "selected": named,
        "model_error": syn.settings["model_error"],
        "seconds": time.perf_counter() - t0,
        "unexplained": [
            {k: u.get(k) for k in ("channel", "kind", "region", "load_range", "magnitude", "left_by", "scale")}
            for u in sel.unexplained
        ],
    }
    res["calibration_scan"] = sel.calibration_scans
    res["named_any"] = bool(named)
    res["unexplained_local"] = any(u["kind"] == "local" for u in sel.unexplained)
    if shadow is not None:
        res["shadow_channel"] = shadow
        res["unexplained_on_shadow_channel"] = any(u["channel"] == shadow for u in sel.unexplained)
    res["exact"] = named == truth_labels
    if explanations:
        from .study_sets import set_outcome

        alt = None
        if condition == "f" and not control:
            from .ambiguity import ambiguous_draw

            d = ambiguous_draw(int(seed), loaded)
            alt = d["alternative"]
            res["ambiguity"] = {k: d[k] for k in ("alternative", "alternative_support", "misfit", "bound", "attempt")}
        res.update(set_outcome(sel, truth_labels, alt))
    res["alternatives"] = {k: [a["mechanism"] for a in v] for k, v in sel.alternatives.items()}
    res["exact_up_to_equivalence"] = len(named) == len(truth_labels) and all(
        any(t == n or t in equivalents(n) for n in named) for t in truth_labels
    )
    if syn.activity:
        act = sel.activity()
        res["activity_truth"] = syn.activity
        res["activity_found"] = act
        res["activity_support_match"] = {
            k: bool(k in act and [x > 0 for x in act[k]] == [x > 0 for x in v]) for k, v in syn.activity.items()
        }
    if effects:
        e = effects[0]
        lo, hi = effect_region(e)
        found = list(sel.unexplained) + [
            dict(o, load_range=[float(syn.settings["loads"][o["point"] - 1])] * 2, kind="local") for o in sel.outliers
        ]
        hits = [u for u in found if u["channel"] == e["channel"]]
        region_ok = False
        loads_s = np.array(syn.settings["loads"])
        for u in hits:
            if u["kind"] == "local" and u.get("load_range"):
                a, b = u["load_range"]
                region_ok |= (a <= hi + 0.05) and (b >= lo - 0.05)
                # a window at either end of the loads splits them in two: its complement is the same finding
                if a <= loads_s.min() + 1e-9 and b < loads_s.max():
                    nxt = loads_s[loads_s > b + 1e-9].min()
                    region_ok |= hi + 0.05 >= nxt
                elif b >= loads_s.max() - 1e-9 and a > loads_s.min():
                    prv = loads_s[loads_s < a - 1e-9].max()
                    region_ok |= lo - 0.05 <= prv
            elif u["region"].startswith("load >"):
                x0 = float(u["region"].split(">")[1])
                region_ok |= x0 <= hi + 0.05
        res["effect_region"] = [lo, hi]
        j = sel.problem.channels.index(e["channel"])
        add = np.asarray(syn.settings["effects_added"][e["channel"]])
        res["effect_size"] = effect_size(
            add, np.asarray(syn.clean[e["channel"]]) - add, float(sel.problem.tolerance[j])
        )
        res["effect_size_noise"] = effect_size(
            add, np.asarray(syn.clean[e["channel"]]) - add, float(np.mean(syn.noise_sd(e["channel"])))
        )
        res["found_on_channel"] = [{k: u.get(k) for k in ("kind", "region", "load_range")} for u in hits]
        res["unexplained_right_channel"] = bool(hits)
        res["unexplained_right_region"] = bool(region_ok)
        res["named_other"] = bool(named)
    res["outcome"] = (
        "control"
        if control
        else "identified"
        if res["exact"] and not effects
        else "unexplained"
        if effects and res["unexplained_right_channel"]
        else "none"
        if not named
        else "wrong"
    )
    return res


def study(
    conditions: Sequence[str],
    seeds: Sequence[int],
    *,
    controls: bool = True,
    workers: int = 1,
    progress: bool = True,
    checkpoint: str | Path | None = None,
    trials: Sequence[tuple[str, int]] | None = None,
    **kw,
) -> dict[str, Any]:
    """Run :func:`trial` for every condition x seed (and its control) and summarise per condition.

    ``trials``: only these ``(condition, seed)`` (``conditions`` and ``seeds`` are then ignored): a development
    check that reruns the trials a change can touch, e.g. those with a valve in the truth or the selection.

    ``checkpoint`` (a JSON-lines file) keeps every finished trial; a rerun with the same file resumes
    where the last one stopped (trials are deterministic in their seed, so nothing changes); trials it holds that
    ran with other settings (:func:`_trial_settings`: parameter set, points, folds, removal step) are run
    again, not mixed in."""
    pairs = [(c, int(s)) for c, s in trials] if trials is not None else [(c, int(s)) for c in conditions for s in seeds]
    if trials is not None:
        conditions = list(dict.fromkeys(c for c, _ in pairs))
    jobs = [(c, s, False) for c, s in pairs]
    if controls:
        jobs += [(c, s, True) for c, s in pairs]
    results: list[dict[str, Any]] = []
    sink = None
    if checkpoint is not None:
        checkpoint = Path(checkpoint)
        if checkpoint.exists():
            want = set(jobs)
            for line in checkpoint.read_text().splitlines():
                if line.strip():
                    r = json.loads(line)
                    key = (r["condition"], int(r["seed"]), bool(r["control"]))
                    if key in want and r.get("trial_settings") == _trial_settings(**kw):
                        want.discard(key)
                        results.append(r)
            jobs = [j for j in jobs if j in want]
            if results and progress:
                print(
                    f"study: resuming at {len(results)}/{len(results) + len(jobs)} trials ({checkpoint})",
                    file=sys.stderr,
                )
        checkpoint.parent.mkdir(parents=True, exist_ok=True)
        sink = checkpoint.open("a")

    def done(r: dict[str, Any]) -> None:
        results.append(r)
        if sink is not None:
            sink.write(json.dumps(r, default=float) + "\n")
            sink.flush()
        if bar:
            bar.update(1)

    bar = None
    if progress:
        try:
            from tqdm import tqdm

            bar = tqdm(total=len(jobs) + len(results), initial=len(results), desc="study", unit="trial")
        except ImportError:  # pragma: no cover
            bar = None
    try:
        if workers > 1:
            from concurrent.futures import ProcessPoolExecutor, as_completed

            with ProcessPoolExecutor(max_workers=workers) as ex:
                futs = [ex.submit(trial, c, s, control=ctl, **kw) for c, s, ctl in jobs]
                for f in as_completed(futs):
                    done(f.result())
        else:
            for c, s, ctl in jobs:
                done(trial(c, s, control=ctl, **kw))
    finally:
        if sink is not None:
            sink.close()
    if bar:
        bar.close()
    results.sort(key=lambda r: (r["condition"], r["control"], r["seed"]))
    return {
        "conditions": {c: dict(CONDITIONS[c], **summarise(results, c)) for c in conditions},
        "trials": results,
        "settings": {k: (str(v) if isinstance(v, Path) else v) for k, v in kw.items()},
    }


def summarise(results: Sequence[dict[str, Any]], condition: str) -> dict[str, Any]:
    """Rates of one condition: identification (exact set), controls naming a cause, out-of-library detection."""
    tr = [r for r in results if r["condition"] == condition and not r["control"] and r["outcome"] != "skipped"]
    ct = [r for r in results if r["condition"] == condition and r["control"] and r["outcome"] != "skipped"]
    out: dict[str, Any] = {
        "n_trials": len(tr),
        "n_controls": len(ct),
        "skipped": sum(r["outcome"] == "skipped" for r in results if r["condition"] == condition),
        "control_named_rate": (sum(r["named_any"] for r in ct) / len(ct)) if ct else None,
    }
    if ct and all("unexplained_local" in r for r in ct):
        out["control_unexplained_local_rate"] = sum(r["unexplained_local"] for r in ct) / len(ct)
    if ct and all("unexplained_on_shadow_channel" in r for r in ct):
        out["control_unexplained_on_effect_channel_rate"] = sum(r["unexplained_on_shadow_channel"] for r in ct) / len(
            ct
        )
    if condition == "e":
        out["unexplained_right_channel_rate"] = (
            sum(r["unexplained_right_channel"] for r in tr) / len(tr) if tr else None
        )
        if tr and all("effect_size" in r for r in tr):
            edges = (0.0,) + SIZE_BINS + (math.inf,)
            out["unexplained_by_size_beyond_calibration"] = {
                (f"{a:g}-{b:g}" if math.isfinite(b) else f">={a:g}"): "{}/{}".format(
                    sum(r["unexplained_right_channel"] for r in tr if a <= r["effect_size"]["beyond_calibration"] < b),
                    sum(a <= r["effect_size"]["beyond_calibration"] < b for r in tr),
                )
                for a, b in zip(edges[:-1], edges[1:])
            }
        if tr and all("effect_size_noise" in r for r in tr):
            edges = (0.0,) + SIZE_BINS + (math.inf,)
            out["unexplained_by_size_beyond_calibration_in_noise_sd"] = {
                (f"{a:g}-{b:g}" if math.isfinite(b) else f">={a:g}"): "{}/{}".format(
                    sum(
                        r["unexplained_right_channel"]
                        for r in tr
                        if a <= r["effect_size_noise"]["beyond_calibration"] < b
                    ),
                    sum(a <= r["effect_size_noise"]["beyond_calibration"] < b for r in tr),
                )
                for a, b in zip(edges[:-1], edges[1:])
            }
        out["unexplained_right_region_rate"] = sum(r["unexplained_right_region"] for r in tr) / len(tr) if tr else None
        out["named_a_cause_rate"] = sum(r["named_any"] for r in tr) / len(tr) if tr else None
    else:
        out["identification_rate"] = sum(r["exact"] for r in tr) / len(tr) if tr else None
        out["identification_rate_up_to_equivalence"] = (
            sum(r.get("exact_up_to_equivalence", r["exact"]) for r in tr) / len(tr) if tr else None
        )
        out["wrong_rate"] = sum(r["outcome"] == "wrong" for r in tr) / len(tr) if tr else None
        out["none_rate"] = sum(r["outcome"] == "none" for r in tr) / len(tr) if tr else None
        # the calibration scan's price: true sensor calibrations, named, that it reports as leaving structure
        cal = [
            (r, t["channel"])
            for r in tr
            if "calibration_scan" in r
            for t in r.get("truth", [])
            if t["id"] == "sensor_calibration" and t["label"] in r["selected"]
        ]
        if cal:
            out["true_calibration_left_by_it"] = "{}/{}".format(
                sum(
                    any(u["channel"] == ch and u.get("left_by") == "sensor_calibration" for u in r["unexplained"])
                    for r, ch in cal
                ),
                len(cal),
            )
        valves = [r for r in tr if r.get("activity_support_match")]
        if valves:
            out["valve_support_exact"] = (
                f"{sum(all(r['activity_support_match'].values()) for r in valves)}/{len(valves)}"
            )
    by: dict[str, list[int]] = {}
    for r in tr:
        for m in r.get("mechanisms") or [r["effects"][0]["family"] if r.get("effects") else "none"]:
            m = m.split(":")[0]  # a condition-(f) draw is a spec with its values
            b = by.setdefault(m, [0, 0])
            b[0] += 1
            b[1] += bool(r["exact"] if condition != "e" else r.get("unexplained_right_channel"))
    out["by_mechanism"] = {k: f"{v[1]}/{v[0]}" for k, v in sorted(by.items())}
    from .study_sets import set_summary

    out.update(set_summary(results, condition))
    return out


def study_main(argv: Sequence[str] | None = None) -> int:
    """``python -m studies.validation.study [--conditions abcde] [--seeds A:B] [--workers K]
    [--no-prune] [--no-exchange] [--tolerance stated|noise] [--held-out-valves schedule|support|state]
    [--beside-valve in_sample_pairs|in_sample_exchange|in_sample|cross_validated] [--trials d346,...] [--out
    FILE.json]``:
    the open-world hidden-effect study."""
    from marine_fdi_env.cli.selection_options import add_valve_options

    ap = argparse.ArgumentParser(
        prog="python -m studies.validation.study",
        description="Open-world hidden-effect study: "
        + "; ".join(f"({k}) {v['title']}" for k, v in CONDITIONS.items()),
    )
    ap.add_argument("--conditions", default="abcde", help="which conditions (letters), default abcde")
    ap.add_argument("--seeds", default="0:20", help="A:B, the seeds A..B-1 (default 0:20)")
    ap.add_argument(
        "--trials",
        default=None,
        metavar="d346,b12,...",
        help="only these trials (condition letter + seed, comma-separated), instead of --conditions x "
        "--seeds: a development check on the trials a change can touch",
    )
    ap.add_argument("--no-controls", action="store_true", help="skip the negative controls")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--points", type=int, default=8)
    ap.add_argument(
        "--no-prune",
        action="store_true",
        help="without the selection's final removal step (to measure what it changes)",
    )
    ap.add_argument(
        "--no-exchange",
        action="store_true",
        help="without the selection's exchange step (a named physical cause replaced by a sensor "
        "calibration that explains the data better): the selection of the study files 0:20 to 260:280",
    )
    ap.add_argument(
        "--tolerance",
        default="stated",
        choices=TOLERANCE_MODES,
        help="what the pipeline is told of the noise: its own tolerances (default; every result of the "
        "study) or each channel's true noise (an ablation: what misstated tolerances cost)",
    )
    add_valve_options(ap)
    ap.add_argument(
        "--out",
        default=None,
        help="write every trial as JSON here; finished trials are kept in OUT.trials.jsonl and a rerun resumes from it",
    )
    args = ap.parse_args(list(argv) if argv is not None else None)
    bad = set(args.conditions) - set(CONDITIONS)
    if bad:
        print(
            f"study: error: unknown condition(s) {''.join(sorted(bad))}; known: {''.join(CONDITIONS)}", file=sys.stderr
        )
        return 2
    a, _, b = args.seeds.partition(":")
    try:
        seeds = range(int(a), int(b))
    except ValueError:
        print(f"study: error: --seeds must be A:B with integers A < B, got {args.seeds!r}", file=sys.stderr)
        return 2
    if not seeds:
        print(f"study: error: --seeds {args.seeds!r} holds no seed (A:B runs A .. B-1)", file=sys.stderr)
        return 2
    trials = None
    if args.trials is not None:
        trials = []
        for t in (x.strip() for x in args.trials.split(",") if x.strip()):
            if len(t) < 2 or t[0] not in CONDITIONS or not t[1:].isdigit():
                print(
                    f"study: error: --trials wants a condition letter ({''.join(CONDITIONS)}) and a seed, "
                    f"e.g. d346; got {t!r}",
                    file=sys.stderr,
                )
                return 2
            trials.append((t[0], int(t[1:])))
        if not trials:
            print("study: error: --trials names no trial", file=sys.stderr)
            return 2
    try:
        res = study(
            list(args.conditions),
            seeds,
            controls=not args.no_controls,
            workers=args.workers,
            trials=trials,
            points=args.points,
            **({"prune": False} if args.no_prune else {}),
            **({"tolerance": args.tolerance} if args.tolerance != "stated" else {}),
            **({"exchange": False} if args.no_exchange else {}),
            **({"held_out_valves": args.held_out_valves} if args.held_out_valves != "schedule" else {}),
            **({"beside_valve": args.beside_valve} if args.beside_valve != BESIDE_VALVE_DEFAULT else {}),
            checkpoint=(Path(args.out).with_suffix(".trials.jsonl") if args.out else None),
        )
    except KeyboardInterrupt:
        print("study: interrupted", file=sys.stderr)
        return 130
    for c, s in res["conditions"].items():
        print(f"({c}) {s['title']}")
        print(
            "    "
            + ", ".join(
                f"{k} {v}"
                for k, v in s.items()
                if k not in ("title", "by_mechanism", "perturb", "noise_model", "noise", "n_mech")
            )
        )
        print("    by mechanism/family: " + ", ".join(f"{k} {v}" for k, v in s["by_mechanism"].items()))
    if args.out:
        out = Path(args.out)
        out.parent.mkdir(exist_ok=True)
        out.write_text(json.dumps(res, indent=1, default=float) + "\n")
    return 0


if __name__ == "__main__":  # pragma: no cover
    if len(sys.argv) > 1 and sys.argv[1] == "pool":
        from .study_pool import pool_main

        sys.exit(pool_main(sys.argv[2:]))
    sys.exit(study_main())
