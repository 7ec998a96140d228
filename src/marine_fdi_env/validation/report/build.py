"""The validation report: what the model gets wrong on a dataset, the named causes, the gain (and plots).

:func:`run_validation` loads the data (and an optional hold-out set), runs :func:`~.select.selection.select_causes`
and assembles a JSON-serialisable report; :func:`~.plots.write_plots` draws model against measurement
before and after the extension (:mod:`.plots`), :func:`~.markdown.markdown_summary` writes it as
Markdown (:mod:`.markdown`); :func:`fitted_engine` turns the result into an engine (parameter set +
submodels) that the simulator, the steady-state solver, the environment and the diagnoser run;
the command line ``marine-fdi validate`` (:mod:`marine_fdi_env.cli.validate`) runs it::

    marine-fdi validate --data FILE [--holdout FILE | --holdout-engine ID] --out report.json
                        [--plots DIR] [--params NAME|FILE.json] [--target auto|power|fuel_flow|speed|fuel_rack]
                        [--max-causes N] [--alpha A] [--alpha-unexplained A] [--save-params ENGINE.json]
                        [--markdown FILE.md]

``--data`` is a CSV or Parquet file (:mod:`.measured.readers`) or the name of a shipped dataset
(``birka_6l46_shop_test``, ``birka_me1_test_protocol``, ``man_12v32_40_fpp_iso``).  ``--holdout-engine ID`` leaves
one engine of ``--data`` out of everything (fit and cross-validation) and reports the fitted model on it.

Report keys, first ``what_the_data_allow`` (:mod:`.conclusion`: how many explanations the data do not decide
between, the first-ranked one, the measurement that decides, where the forward selection's path ends among
them), then ``dataset`` (with ``columns``: what happens to every column, ``boundary_outliers``),
``model``, ``settings``, ``channels`` (per channel: tolerance, the base model's bias / RMSE as it is,
``cv_rmse_base`` of the base calibrated within its uncertainty, ``cv_rmse_extended``, ``cv_gain`` against
the base as it is, and with a hold-out ``holdout_rmse_*``), ``discrepancies`` (the base model's, ranked),
``candidates``, ``steps``, ``selected_causes`` / ``selected_labels`` (the forward selection's path: one
cause added per step until none earns its place; kept under these names for existing readers, it is not a
ranking of what the data allow), ``alternatives``, ``cause_notes``
(per cause: a bound its fit touches without the data wanting more, parameters the data do not determine),
``parameters`` (fitted values with standard errors), ``nuisance`` (the calibration within uncertainty), ``activity``
(per valve-type cause:
the diverted flow fraction at every measured point, file row order, 0 where it does not act),
``openings`` and ``schedules`` of the valves, ``unexplained`` (channel, kind, region), ``calibration_scans``
(per named sensor calibration, the scan of what its gain and offset leave, reported or not: ``p``, shape, region,
departure), ``outliers``,
``explained``, ``cv``, ``holdout`` (the parameter set's conditions where the hold-out recorded none),
``holdout_at_fit_conditions`` (the fitted data's test-bed conditions instead), ``fitted_engine`` (the engine
file's content).
"""

from __future__ import annotations

import math
from datetime import date
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from ...engine.params import EngineParams, engine_file_dict, list_parameter_sets
from ...jsonfile import json_safe
from ..explain.summary import explain
from ..explain.summary import summary_lines as explanation_summary_lines
from ..fit.fitting import FitResult, channel_rmse, predict_setting
from ..fit.mechanisms import PHYSICAL_MECHANISMS, Mechanism, SensorCalibration
from ..fit.problem import FitProblem
from ..measured.dataset import MeasuredDataset
from ..measured.loader import load_data_arg
from ..select.rules import SelectionRules
from ..select.selection import Selection, select_causes
from ..select.unexplained import family_significant
from .conclusion import lead_line, what_the_data_allow
from .markdown import markdown_summary
from .plots import write_plots

__all__ = [
    "run_validation",
    "build_report",
    "write_plots",
    "load_data_arg",
    "split_engine",
    "markdown_summary",
    "holdout_evaluation",
    "fitted_engine",
    "out_path",
    "summary_lines",
]


# --------------------------------------------------------------------------------------- helpers
def split_engine(ds: MeasuredDataset, engine: str) -> tuple[MeasuredDataset, MeasuredDataset]:
    """(the dataset without ``engine``, the dataset of ``engine`` only)."""
    ids = ds.engine_ids()
    if not ids:
        raise ValueError(f"--holdout-engine: {ds.name} has no engine column")
    if engine not in ids:
        raise ValueError(f"--holdout-engine: unknown engine {engine!r}; engines: {', '.join(ids)}")
    if len(ids) < 2:
        raise ValueError("--holdout-engine: the dataset has only one engine")
    e = np.array(ds.engines)
    return ds.subset(e != engine), ds.subset(e == engine)


def _touches(mechs: Sequence[Mechanism], quantity: str, column: str) -> bool:
    return any(quantity in m.touches or column in m.touches for m in mechs)


def fitted_engine(sel: Selection, name: str | None = None) -> EngineParams:
    """The engine the selection describes: the parameter set with the nuisance calibration, the re-matched turbine
    and the selected submodels, valve openings as schedules over the fuel setting (at the parameter set's ambient
    state; sensor calibrations and ambient offsets belong to the measurement, not the engine)."""
    pr = sel.problem
    s = sel.fit.schedule_setting(pr).replace(dT_amb_K=0.0, dp_amb_Pa=0.0, sensors={})
    eng = pr.engine(s)
    label = name or f"{pr.params.name}+fit:{pr.ds.name}"
    return eng.replace(name=label)


def _engine_file(sel: Selection, eng: EngineParams, command: str | None) -> dict[str, Any]:
    pr = sel.problem
    base = pr.params.name if pr.params.name in list_parameter_sets() else pr.ds.params_name
    measurement = {
        "sensor_calibration": {
            m.channel: v for m, v in sel.fit.combination.unpack(sel.fit.x) if isinstance(m, SensorCalibration)
        }
    }
    amb = [v for m, v in sel.fit.combination.unpack(sel.fit.x) if m.id == "ambient_conditions"]
    if amb:
        measurement["ambient_offsets"] = amb[0]
    prov = {
        "dataset": pr.ds.name,
        "data_source": pr.ds.provenance,
        "date": date.today().isoformat(),
        "command": command or "",
        "selected_causes": sel.selected_labels,
        "nuisance": sel.fit.nuisance_values(),
        "cv": {"scheme": sel.cv_scheme, "score_base": sel.base_score, "score_extended": sel.cv_score},
        "measurement": measurement,
        "note": "valve openings are schedules over the fuel setting through the fitted points; sensor "
        "calibrations and ambient offsets describe the measurements and are not part of the engine",
    }
    return json_safe(engine_file_dict(eng, base, prov))


# --------------------------------------------------------------------------------------- report
def build_report(
    sel: Selection, holdout: Mapping[str, Any] | None = None, notes: Sequence[str] = (), command: str | None = None
) -> dict[str, Any]:
    """Assemble the JSON report of a selection (``holdout``: a :func:`holdout_evaluation` of its fitted model)."""
    pr = sel.problem
    ds = pr.ds
    mechs = sel.selected.mechanisms
    ext_in = predict_setting(pr, sel.fit, np.arange(pr.n_points))
    rm_ext_in = channel_rmse(pr, ext_in)
    cv = sel.cv_rmse()
    channels: dict[str, Any] = {}
    for j, c in enumerate(pr.channels):
        cd = sel.base_report.channels.get(c)
        q = ds.column_quantity[c]
        r, b, e = cv[c]["rmse_raw"], cv[c]["cv_rmse_base"], cv[c]["cv_rmse_extended"]
        channels[c] = {
            "quantity": q,
            "unit": ds.spec(c).unit,
            "tolerance": float(pr.tolerance[j]),
            "n": int(pr.measured_mask[:, j].sum()),
            "bias_base": cd.bias if cd else None,
            "rmse_base": r,
            "mean_abs_rel_error_base": cd.mean_abs_rel_error if cd else None,
            "cv_rmse_base": b,
            "cv_rmse_extended": e,
            "rmse_extended_in_sample": rm_ext_in[c],
            "cv_gain": (r - e) / r if r and math.isfinite(r) and r > 0 and math.isfinite(e) else None,
            "cv_gain_vs_calibrated": (b - e) / b if b and math.isfinite(b) and b > 0 and math.isfinite(e) else None,
            "touched_by_selected": _touches(mechs, q, c),
        }
    scheme, folds = pr.folds(sel.settings.get("max_folds"))
    fold_rows = []
    if len(ds.engine_ids()) >= 2:
        for name, rows in folds:
            fb = channel_rmse(pr, sel.raw_pred, rows)
            fe = channel_rmse(pr, sel.cv_pred, rows)
            fold_rows.append(
                {
                    "fold": name,
                    "points": [int(i) + 1 for i in rows],
                    "channels": {c: {"rmse_base": fb[c], "rmse_extended": fe[c]} for c in pr.channels},
                }
            )
    base_family = [
        d
        for d in sel.base_report.discrepancies
        if d["kind"] != "outlier" and family_significant(d, sel.base_report, sel.settings["alpha"])
    ]
    left = {(u["channel"], u["kind"]) for u in sel.unexplained}
    explained = (
        [
            dict(
                {k: d[k] for k in ("channel", "kind", "region", "magnitude", "score")},
                rmse_base=cv[d["channel"]]["rmse_raw"],
                cv_rmse_extended=cv[d["channel"]]["cv_rmse_extended"],
            )
            for d in base_family
            if (d["channel"], d["kind"]) not in left
        ]
        if sel.selected.mechanisms
        else []
    )
    discrepancies = []
    for d in sel.base_report.discrepancies:
        e = {k: d[k] for k in ("rank", "channel", "kind", "region", "magnitude", "score", "p_value", "unit") if k in d}
        if "variable" in d:
            e["variable"] = d["variable"]
        e["family_significant"] = family_significant(d, sel.base_report, sel.settings["alpha"], sel.base_outliers)
        discrepancies.append(e)
    eng = fitted_engine(sel)
    inventory = ds.column_inventory()
    report: dict[str, Any] = {
        "dataset": {
            "name": ds.name,
            "path": ds.path,
            "provenance": ds.provenance,
            "n_points": ds.n_points,
            "engines": ds.engine_ids(),
            "params": pr.params.name,
            "warnings": [str(w) for w in ds.warnings],
            "notes": list(ds.notes),
            "columns": inventory,
            "boundary_outliers": list(ds.boundary_outliers),
            "groups": {
                g: {"columns": v["columns"], "mean_column": v["mean_column"], "spread": v["spread"]}
                for g, v in ds.groups.items()
            },
        },
        "model": {
            "params": pr.params.name,
            "target": pr.target,
            "target_columns": list(pr.target_columns),
            "load_law": pr.law.describe(),
        },
        "settings": sel.settings,
        "channels": channels,
        "not_compared": [r for r in inventory if r["role"] in ("boundary", "not_modelled", "member")],
        "discrepancies": discrepancies,
        "candidates": sel.candidates(),
        "steps": [_step_dict(pr, s) for s in sel.steps],
        "selected_causes": sel.selected_causes,
        "selected_labels": sel.selected_labels,
        "alternatives": sel.alternatives,
        "cause_notes": {k: v for k, v in sel.cause_notes.items() if v},
        "parameters": sel.fit.parameters(),
        "nuisance": {"base_calibrated": sel.base_fit.nuisance_values(), "extended": sel.fit.nuisance_values()},
        "activity": sel.activity(),
        "openings": sel.openings(),
        "schedules": {k: v.as_dict() for k, v in sel.fit.schedules().items()},
        "unexplained": sel.unexplained,
        "calibration_scans": sel.calibration_scans,
        "outliers": sel.outliers,
        "explained": explained,
        "cv": {
            "scheme": scheme,
            "n_folds": len(folds),
            "score_base": sel.base_score,
            "score_extended": sel.cv_score,
            "folds": fold_rows,
        },
        "fitted_engine": _engine_file(sel, eng, command),
        "mechanism_library": [m.describe() for m in PHYSICAL_MECHANISMS],
        "notes": list(notes),
        "seconds": sel.seconds,
    }
    if holdout is not None:
        report["holdout"] = {k: v for k, v in holdout.items() if not k.startswith("_")}
        for c, v in report["holdout"]["channels"].items():
            if c in channels:
                channels[c]["holdout_rmse_base"] = v["holdout_rmse_base"]
                channels[c]["holdout_rmse_extended"] = v["holdout_rmse_extended"]
    return json_safe(report)


def _step_dict(pr: FitProblem, step: Mapping[str, Any]) -> dict[str, Any]:
    """A greedy step without its candidate objects, with the per-channel CV RMSE of its best candidate."""
    d = {k: v for k, v in step.items() if k != "candidates"}
    best = [c for c in step["candidates"] if c.added == step.get("best") and c.cross_validated]
    if best:
        d["best_cv_rmse"] = channel_rmse(pr, best[0].cv_pred)
        d["best_parameters"] = best[0].fit.parameters()
    return d


def holdout_evaluation(
    sel: Selection, holdout: MeasuredDataset, conditions: str = "parameter_set", fit: FitResult | None = None
) -> dict[str, Any]:
    """RMSE per channel of the base model (as it is) and of the fitted engine on data the fit did not see (``fit``:
    another fit of the same data than the selection's, e.g. an explanation of :mod:`.explain.explanations`).

    The fitted engine predicts with its valve schedules (the hold-out's points are not among the fitted ones);
    sensor calibrations apply where the hold-out has the same column.  ``conditions``: where the hold-out did not
    record its ambient pressure, intake temperature or back pressure, take the parameter set's
    (``"parameter_set"``) or the test-bed conditions the fitted data recorded (``"fit"``: their mean ambient
    state, back pressure over load) -- an assumption that the hold-out was run on the same test bed, stated in
    the result's ``conditions``."""
    if conditions not in ("parameter_set", "fit"):
        raise ValueError(f"conditions must be 'parameter_set' or 'fit', not {conditions!r}")
    pr = sel.problem
    ho = FitProblem(holdout, params=pr.params, target=pr.target if pr.target in ("power", "fuel_flow") else "auto")
    cond: dict[str, Any] = {"kind": conditions, "filled": []}
    if conditions == "fit":
        tb = pr.test_bed_conditions()
        if tb is not None:
            cond["filled"] = ho.assume_boundary(tb)
            cond["test_bed"] = tb
        cond["assumption"] = (
            "the hold-out was run on the test bed of the fitted data: what it did not record ("
            + (", ".join(cond["filled"]) or "nothing")
            + ") is taken from the fitted data"
        )
    pb, _, _ = ho.predict()
    fit = sel.fit if fit is None else fit
    s = fit.schedule_setting(pr)
    s = s.replace(sensors={c: v for c, v in s.sensors.items() if c in ho.channels})
    pe, conv, vals = ho.predict(s)
    rb, re_ = channel_rmse(ho, pb), channel_rmse(ho, pe)
    # the same without the readings the loader flags on its own (no model involved)
    pb_c, pe_c = pb.copy(), pe.copy()
    for x in holdout.suspect:
        if x["column"] in ho.channels:
            j = ho.channels.index(x["column"])
            pb_c[x["row"] - 1, j] = pe_c[x["row"] - 1, j] = np.nan
    keep = np.isfinite(pb_c) | ~ho.measured_mask
    rb_c = {c: _rmse_masked(ho, pb_c, keep, j) for j, c in enumerate(ho.channels)}
    re_c = {c: _rmse_masked(ho, pe_c, keep, j) for j, c in enumerate(ho.channels)}
    out = {
        "dataset": holdout.name,
        "engines": holdout.engine_ids(),
        "n_points": holdout.n_points,
        "conditions": cond,
        "not_converged": [int(i) + 1 for i in np.flatnonzero(~conv)],
        "suspect_readings": list(holdout.suspect),
        "channels": {
            c: {
                "holdout_rmse_base": rb[c],
                "holdout_rmse_extended": re_[c],
                "holdout_rmse_base_without_suspect": rb_c[c],
                "holdout_rmse_extended_without_suspect": re_c[c],
                "tolerance": float(ho.tolerance[j]),
                "n": int(ho.measured_mask[:, j].sum()),
                "touched_by_selected": _touches(fit.combination.mechanisms, holdout.column_quantity[c], c),
            }
            for j, c in enumerate(ho.channels)
        },
        "_problem": ho,
        "_pred_base": pb,
        "_pred_extended": pe,
    }
    if holdout.engine_ids():
        e = np.array(holdout.engines)
        out["per_engine"] = {
            x: {
                c: {
                    "holdout_rmse_base": channel_rmse(ho, pb, np.flatnonzero(e == x))[c],
                    "holdout_rmse_extended": channel_rmse(ho, pe, np.flatnonzero(e == x))[c],
                    "holdout_rmse_base_without_suspect": _rmse_masked(ho, pb_c, keep, j, np.flatnonzero(e == x)),
                    "holdout_rmse_extended_without_suspect": _rmse_masked(ho, pe_c, keep, j, np.flatnonzero(e == x)),
                }
                for j, c in enumerate(ho.channels)
            }
            for x in holdout.engine_ids()
        }
    return out


def _rmse_masked(pr: FitProblem, pred: np.ndarray, keep: np.ndarray, j: int, rows=None) -> float | None:
    rows = np.arange(pr.n_points) if rows is None else np.asarray(rows, int)
    e = pred[rows, j] - pr.Y[rows, j]
    m = pr.measured_mask[rows, j] & keep[rows, j]
    return float(np.sqrt(np.mean(e[m] ** 2))) if m.any() else None


def run_validation(
    ds: MeasuredDataset,
    *,
    holdout: MeasuredDataset | None = None,
    target: str = "auto",
    params: str | EngineParams | None = None,
    rules: SelectionRules | None = None,
    progress=None,
    notes: Sequence[str] = (),
    command: str | None = None,
    tolerances: Mapping[str, float] | None = None,
    explanations: bool = True,
) -> tuple[dict[str, Any], Selection, dict | None]:
    """Run the pipeline; returns (JSON report, selection, hold-out evaluation with predictions or None).
    ``rules``: how causes are named (:class:`~.select.rules.SelectionRules`, default its defaults).
    ``explanations``: also every structure the data do not decide against, the measurement that would decide and
    each one's hold-out prediction (:mod:`.explain.summary`; the keys ``explanations``, ``explanations_outside``,
    ``deciding``, ``explanation_rule``).
    ``tolerances``: per channel in its units (default: the sidecar's, else 1 % / 5 K)."""
    rules = rules or SelectionRules()
    pr = FitProblem(ds, target=target, params=params, tolerances=tolerances, held_out_valves=rules.held_out_valves)
    sel = select_causes(pr, rules=rules, progress=progress)
    ho = holdout_evaluation(sel, holdout) if holdout is not None else None
    rep = build_report(sel, ho, notes, command)
    if explanations:

        def each(fit, cond):  # a member's hold-out evaluation, JSON-ready
            r = holdout_evaluation(sel, holdout, conditions=cond, fit=fit)
            return json_safe({k: v for k, v in r.items() if not k.startswith("_")})

        rep.update(json_safe(explain(sel, holdout=each if holdout is not None else None, say=progress)))
    rep = {"what_the_data_allow": json_safe(what_the_data_allow(rep)), **rep}  # the report leads with it
    if ho is not None:
        hf = holdout_evaluation(sel, holdout, conditions="fit")
        if hf["conditions"]["filled"]:
            rep["holdout_at_fit_conditions"] = json_safe({k: v for k, v in hf.items() if not k.startswith("_")})
            ho["_at_fit_conditions"] = hf  # for the plot
    return rep, sel, ho


def summary_lines(rep: Mapping[str, Any]) -> list[str]:
    lines = [
        lead_line(rep),
        f"  the forward selection's path (selected_causes): {', '.join(rep['selected_labels']) or 'none'}",
    ]
    prof = next((e.get("profiles") or {} for e in rep.get("explanations") or () if e["named"]), {})
    for lab, ps in rep["parameters"].items():
        lines.append(
            "  "
            + lab
            + ": "
            + ", ".join(
                f"{k} = {_f(v['value'])} "
                + (_profile(prof[f"{lab}.{k}"]) if f"{lab}.{k}" in prof else f"± {_f(v['stderr'])}")
                for k, v in ps.items()
            )
        )
    for lab, alts in (rep.get("alternatives") or {}).items():
        if alts:
            lines.append(f"  {lab}: hardly told from " + ", ".join(a["mechanism"] for a in alts))
    for notes in (rep.get("cause_notes") or {}).values():
        lines += [f"  {n}" for n in notes]
    for mid, a in (rep.get("activity") or {}).items():
        lines.append(f"  {mid} acts at points " + ", ".join(f"{i + 1} ({x:.3f})" for i, x in enumerate(a) if x))
    lines.append(
        f"  {'channel':40s} {'rmse_base':>11s} {'cv_rmse_ext':>11s}"
        + (f" {'holdout_base':>12s} {'holdout_ext':>12s}" if "holdout" in rep else "")
    )
    for c, v in rep["channels"].items():
        row = f"  {c:40s} {_f(v['rmse_base']):>11s} {_f(v['cv_rmse_extended']):>11s}"
        if "holdout" in rep:
            row += f" {_f(v.get('holdout_rmse_base')):>12s} {_f(v.get('holdout_rmse_extended')):>12s}"
        lines.append(row)
    lines += explanation_summary_lines(rep)
    for u in rep["unexplained"]:
        lines.append("  " + u["text"])
    for o in rep["outliers"]:
        lines.append("  " + o["text"])
    for h in (rep.get("replicas") or {}).get("summary", []):
        lines.append(
            f"  replicas drawn from {h['hypothesis']} ({' + '.join(h['causes']) or 'nothing'}): named "
            f"itself {h['named_itself']}/{h['replicas']}, the data's causes {h['named_data_causes']}/"
            f"{h['replicas']}"
        )
    return lines


def _f(x) -> str:
    return "-" if x is None else f"{x:.4g}"


def _profile(p: Mapping[str, Any]) -> str:
    """A profile interval in words: ``[lo, hi] (95 % profile)``, an end at its bound marked, "not identified"."""
    lo = ("bound " if p["lower_open"] else "") + _f(p["lower"])
    hi = ("bound " if p["upper_open"] else "") + _f(p["upper"])
    return f"[{lo}, {hi}] (95 % profile{'' if p['identified'] else '; not identified'})"


def out_path(text: str, option: str) -> Path:
    p = Path(text)
    if p.parent != Path("") and not p.parent.parent.exists():
        raise ValueError(
            f"{option}: directory {str(p.parent.parent)!r} does not exist (the parent of --out is created, never more)"
        )
    return p
