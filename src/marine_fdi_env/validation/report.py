"""The validation report: what the model gets wrong on a dataset, the named causes, the gain (and plots).

:func:`run_validation` loads the data (and an optional hold-out set), runs :func:`~.selection.select_causes`
and assembles a JSON-serialisable report; :func:`write_plots` draws model against measurement before
and after the extension; :func:`fitted_engine` turns the result into an engine (parameter set +
submodels) that the simulator, the steady-state solver, the environment and the diagnoser run;
:func:`validate_main` is the command line ``marine-fdi validate``::

    marine-fdi validate --data FILE.csv [--holdout FILE.csv | --holdout-engine ID] --out report.json
                        [--plots DIR] [--params NAME|FILE.json] [--target auto|power|fuel_flow|speed|fuel_rack]
                        [--max-causes N] [--alpha A] [--alpha-unexplained A] [--save-params ENGINE.json]
                        [--markdown FILE.md]

``--data`` also takes the name of a shipped dataset (``birka_6l46_shop_test``, ``birka_me1_test_protocol``,
``man_12v32_40_fpp_iso``).  ``--holdout-engine ID`` leaves one engine of ``--data`` out of everything
(fit and cross-validation) and reports the fitted model on it.

Report keys: ``dataset`` (with ``columns``: what happens to every column, ``boundary_outliers``),
``model``, ``settings``, ``channels`` (per channel: tolerance, the base model's bias / RMSE as it is,
``cv_rmse_base`` of the base calibrated within its uncertainty, ``cv_rmse_extended``, ``cv_gain`` against
the base as it is, and with a hold-out ``holdout_rmse_*``), ``discrepancies`` (the base model's, ranked),
``candidates``, ``steps``, ``selected_causes`` / ``selected_labels``, ``alternatives``, ``cause_notes``
(per cause: a bound its fit touches without the data wanting more, parameters the data do not determine),
``parameters`` (fitted values with standard errors), ``nuisance`` (the calibration within uncertainty), ``activity`` (per valve-type cause:
the diverted flow fraction at every measured point, file row order, 0 where it does not act),
``openings`` and ``schedules`` of the valves, ``unexplained`` (channel, kind, region), ``calibration_scans``
(per named sensor calibration, the scan of what its gain and offset leave, reported or not: ``p``, shape, region,
departure), ``outliers``,
``explained``, ``cv``, ``holdout`` (the parameter set's conditions where the hold-out recorded none),
``holdout_at_fit_conditions`` (the fitted data's test-bed conditions instead), ``fitted_engine`` (the engine
file's content).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from datetime import date
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from ..engine.params import EngineParams, engine_file_dict, list_parameter_sets, load_params
from ..plotting import pyplot
from .data_check import column_registry, describe
from .dataset import DatasetError, MeasuredDataset, list_shipped, load_data_arg
from .fitting import channel_rmse, predict_setting
from .matching import TARGETS
from .mechanisms import PHYSICAL_MECHANISMS, Mechanism, SensorCalibration
from .problem import Problem
from .evidence import BESIDE_VALVE_DEFAULT, add_valve_options
from .selection import Selection, select_causes
from .unexplained import ALPHA_UNEXPLAINED, family_significant

__all__ = ["run_validation", "build_report", "write_plots", "validate_main", "load_data_arg", "split_engine",
           "markdown_summary", "holdout_evaluation", "fitted_engine"]


# --------------------------------------------------------------------------------------- helpers
def _clean(x: Any) -> Any:
    """JSON-safe copy: NaN/inf -> None, numpy scalars/arrays -> Python."""
    if isinstance(x, dict):
        return {str(k): _clean(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v) for v in x]
    if isinstance(x, np.ndarray):
        return _clean(x.tolist())
    if isinstance(x, (np.bool_,)):
        return bool(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        x = float(x)
        return x if math.isfinite(x) else None
    return x


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
    measurement = {"sensor_calibration": {m.channel: v for m, v in sel.fit.combination.unpack(sel.fit.x)
                                          if isinstance(m, SensorCalibration)}}
    amb = [v for m, v in sel.fit.combination.unpack(sel.fit.x) if m.id == "ambient_conditions"]
    if amb:
        measurement["ambient_offsets"] = amb[0]
    prov = {"dataset": pr.ds.name, "data_source": pr.ds.provenance, "date": date.today().isoformat(),
            "command": command or "", "selected_causes": sel.selected_labels,
            "nuisance": sel.fit.nuisance_values(), "cv": {"scheme": sel.cv_scheme, "score_base": sel.base_score,
                                                          "score_extended": sel.cv_score},
            "measurement": measurement,
            "note": "valve openings are schedules over the fuel setting through the fitted points; sensor "
                    "calibrations and ambient offsets describe the measurements and are not part of the engine"}
    return _clean(engine_file_dict(eng, base, prov))


# --------------------------------------------------------------------------------------- report
def build_report(sel: Selection, holdout: Mapping[str, Any] | None = None, notes: Sequence[str] = (),
                 command: str | None = None) -> dict[str, Any]:
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
            "quantity": q, "unit": ds.spec(c).unit, "tolerance": float(pr.tolerance[j]),
            "n": int(pr.measured_mask[:, j].sum()),
            "bias_base": cd.bias if cd else None, "rmse_base": r,
            "mean_abs_rel_error_base": cd.mean_abs_rel_error if cd else None,
            "cv_rmse_base": b, "cv_rmse_extended": e, "rmse_extended_in_sample": rm_ext_in[c],
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
            fold_rows.append({"fold": name, "points": [int(i) + 1 for i in rows],
                              "channels": {c: {"rmse_base": fb[c], "rmse_extended": fe[c]} for c in pr.channels}})
    base_family = [d for d in sel.base_report.discrepancies if d["kind"] != "outlier"
                   and family_significant(d, sel.base_report, sel.settings["alpha"])]
    left = {(u["channel"], u["kind"]) for u in sel.unexplained}
    explained = [dict({k: d[k] for k in ("channel", "kind", "region", "magnitude", "score")},
                      rmse_base=cv[d["channel"]]["rmse_raw"], cv_rmse_extended=cv[d["channel"]]["cv_rmse_extended"])
                 for d in base_family if (d["channel"], d["kind"]) not in left] if sel.selected.mechanisms else []
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
        "dataset": {"name": ds.name, "path": ds.path, "provenance": ds.provenance, "n_points": ds.n_points,
                    "engines": ds.engine_ids(), "params": pr.params.name, "warnings": [str(w) for w in ds.warnings],
                    "notes": list(ds.notes), "columns": inventory,
                    "boundary_outliers": list(ds.boundary_outliers),
                    "groups": {g: {"columns": v["columns"], "mean_column": v["mean_column"],
                                   "spread": v["spread"]} for g, v in ds.groups.items()}},
        "model": {"params": pr.params.name, "target": pr.target, "target_columns": list(pr.target_columns),
                  "load_law": pr.law.describe()},
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
        "cv": {"scheme": scheme, "n_folds": len(folds), "score_base": sel.base_score, "score_extended": sel.cv_score,
               "folds": fold_rows},
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
    return _clean(report)


def _step_dict(pr: Problem, step: Mapping[str, Any]) -> dict[str, Any]:
    """A greedy step without its candidate objects, with the per-channel CV RMSE of its best candidate."""
    d = {k: v for k, v in step.items() if k != "candidates"}
    best = [c for c in step["candidates"] if c.added == step.get("best") and c.cross_validated]
    if best:
        d["best_cv_rmse"] = channel_rmse(pr, best[0].cv_pred)
        d["best_parameters"] = best[0].fit.parameters()
    return d


def holdout_evaluation(sel: Selection, holdout: MeasuredDataset, conditions: str = "parameter_set") -> dict[str, Any]:
    """RMSE per channel of the base model (as it is) and of the fitted engine on data the fit did not see.

    The fitted engine predicts with its valve schedules (the hold-out's points are not among the fitted ones);
    sensor calibrations apply where the hold-out has the same column.  ``conditions``: where the hold-out did not
    record its ambient pressure, intake temperature or back pressure, take the parameter set's
    (``"parameter_set"``) or the test-bed conditions the fitted data recorded (``"fit"``: their mean ambient
    state, back pressure over load) -- an assumption that the hold-out was run on the same test bed, stated in
    the result's ``conditions``."""
    if conditions not in ("parameter_set", "fit"):
        raise ValueError(f"conditions must be 'parameter_set' or 'fit', not {conditions!r}")
    pr = sel.problem
    ho = Problem(holdout, params=pr.params, target=pr.target if pr.target in ("power", "fuel_flow") else "auto")
    cond: dict[str, Any] = {"kind": conditions, "filled": []}
    if conditions == "fit":
        tb = pr.test_bed_conditions()
        if tb is not None:
            cond["filled"] = ho.assume_boundary(tb)
            cond["test_bed"] = tb
        cond["assumption"] = ("the hold-out was run on the test bed of the fitted data: what it did not record ("
                              + (", ".join(cond["filled"]) or "nothing") + ") is taken from the fitted data")
    pb, _, _ = ho.predict()
    s = sel.fit.schedule_setting(pr)
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
    out = {"dataset": holdout.name, "engines": holdout.engine_ids(), "n_points": holdout.n_points,
           "conditions": cond, "not_converged": [int(i) + 1 for i in np.flatnonzero(~conv)],
           "suspect_readings": list(holdout.suspect),
           "channels": {c: {"holdout_rmse_base": rb[c], "holdout_rmse_extended": re_[c],
                            "holdout_rmse_base_without_suspect": rb_c[c],
                            "holdout_rmse_extended_without_suspect": re_c[c],
                            "tolerance": float(ho.tolerance[j]), "n": int(ho.measured_mask[:, j].sum()),
                            "touched_by_selected": _touches(sel.selected.mechanisms, holdout.column_quantity[c], c)}
                        for j, c in enumerate(ho.channels)},
           "_problem": ho, "_pred_base": pb, "_pred_extended": pe}
    if holdout.engine_ids():
        e = np.array(holdout.engines)
        out["per_engine"] = {
            x: {c: {"holdout_rmse_base": channel_rmse(ho, pb, np.flatnonzero(e == x))[c],
                    "holdout_rmse_extended": channel_rmse(ho, pe, np.flatnonzero(e == x))[c],
                    "holdout_rmse_base_without_suspect": _rmse_masked(ho, pb_c, keep, j, np.flatnonzero(e == x)),
                    "holdout_rmse_extended_without_suspect": _rmse_masked(ho, pe_c, keep, j, np.flatnonzero(e == x))}
                for j, c in enumerate(ho.channels)}
            for x in holdout.engine_ids()}
    return out


def _rmse_masked(pr: Problem, pred: np.ndarray, keep: np.ndarray, j: int, rows=None) -> float | None:
    rows = np.arange(pr.n_points) if rows is None else np.asarray(rows, int)
    e = pred[rows, j] - pr.Y[rows, j]
    m = pr.measured_mask[rows, j] & keep[rows, j]
    return float(np.sqrt(np.mean(e[m] ** 2))) if m.any() else None


def run_validation(ds: MeasuredDataset, *, holdout: MeasuredDataset | None = None, target: str = "auto",
                   params: str | EngineParams | None = None, max_causes: int = 4, alpha: float = 0.01,
                   alpha_unexplained: float = ALPHA_UNEXPLAINED, cv_all: bool = False, max_folds: int | None = None,
                   progress=None, notes: Sequence[str] = (), command: str | None = None,
                   tolerances: Mapping[str, float] | None = None, held_out_valves: str = "schedule",
                   beside_valve: str = BESIDE_VALVE_DEFAULT) -> tuple[dict[str, Any], Selection, dict | None]:
    """Run the pipeline; returns (JSON report, selection, hold-out evaluation with predictions or None).
    ``tolerances``: per channel in its units (default: the sidecar's, else 1 % / 5 K).  ``held_out_valves``: how
    cross-validation predicts a valve's opening at a held-out point (:data:`~.problem.HELD_OUT_VALVES`).
    ``beside_valve``: how a cause joining a model with a valve earns its place
    (:data:`~.evidence.BESIDE_VALVE`)."""
    pr = Problem(ds, target=target, params=params, tolerances=tolerances, held_out_valves=held_out_valves)
    sel = select_causes(pr, max_causes=max_causes, alpha=alpha, alpha_unexplained=alpha_unexplained, cv_all=cv_all,
                        max_folds=max_folds, progress=progress, beside_valve=beside_valve)
    ho = holdout_evaluation(sel, holdout) if holdout is not None else None
    rep = build_report(sel, ho, notes, command)
    if ho is not None:
        hf = holdout_evaluation(sel, holdout, conditions="fit")
        if hf["conditions"]["filled"]:
            rep["holdout_at_fit_conditions"] = _clean({k: v for k, v in hf.items() if not k.startswith("_")})
            ho["_at_fit_conditions"] = hf  # for the plot
    return rep, sel, ho


# --------------------------------------------------------------------------------------- plots
def _load_axis(pr: Problem) -> tuple[np.ndarray, str]:
    v = pr.ds.values
    if "load_fraction" in v:
        return v["load_fraction"], "load fraction"
    if "power_W" in v:
        return v["power_W"] / pr.ds.rated_power_W, "power / rated power"
    if "engine_speed_rev_s" in v:
        return v["engine_speed_rev_s"] * 60.0, "speed [rpm]"
    return np.arange(pr.n_points, dtype=float), "point"


def write_plots(sel: Selection, directory: str | Path, holdout: Mapping[str, Any] | None = None,
                prefix: str | None = None) -> list[Path]:
    """Model against measurement per channel (base as it is, calibrated base, fitted extension, cross-validated
    predictions), the valve activity, the cross-validated RMSE per channel, and the hold-out if any."""
    plt = pyplot()
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    pr = sel.problem
    name = prefix or pr.ds.name
    cause = ", ".join(sel.selected_labels) or "none selected"
    ext = predict_setting(pr, sel.fit, np.arange(pr.n_points))
    calib = predict_setting(pr, sel.base_fit, np.arange(pr.n_points))
    files = []

    def panel_grid(n, w=4.4, h=3.2):
        cols = min(3, n)
        rows = int(math.ceil(n / cols))
        fig, axes = plt.subplots(rows, cols, figsize=(w * cols, h * rows), squeeze=False)
        for ax in axes.flat[n:]:
            ax.set_visible(False)
        return fig, axes.flat

    def draw(ax, x, meas, base, extd, cvp, eng, col, unit, calibrated=None, ext_label="extended (fit on all)",
             spread=None):
        order = np.argsort(x, kind="stable")
        if eng is None:
            if spread is not None:
                ax.errorbar(x, meas, yerr=spread, fmt="ko", ms=4, capsize=2, elinewidth=0.8,
                            label="measured (± cylinder spread)")
            else:
                ax.plot(x, meas, "ko", ms=4, label="measured")
        else:
            for k, e in enumerate(dict.fromkeys(eng)):
                m = np.array([z == e for z in eng])
                ax.plot(x[m], meas[m], "o", ms=4, color=f"C{k + 2}", label=f"measured {e}")
        ax.plot(x[order], base[order], "--", color="C0", lw=1.3, label="base model")
        if calibrated is not None:
            ax.plot(x[order], calibrated[order], ":", color="C0", lw=1.3, label="base, calibrated within ±6 %")
        if extd is not None:
            ax.plot(x[order], extd[order], "-", color="C3", lw=1.6, label=ext_label)
        if cvp is not None:
            ax.plot(x, cvp, "x", color="C3", ms=6, mew=1.5, label="extended, cross-validated")
        ax.set_title(col.replace("_", " "), fontsize=9)
        ax.set_ylabel(unit, fontsize=8)
        ax.tick_params(labelsize=8)
        ax.grid(alpha=0.3)

    x, xlabel = _load_axis(pr)
    spreads = {g["mean_column"]: g["spread"] for g in pr.ds.groups.values() if g.get("mean_column")}
    n_panels = len(pr.channels) + (1 if sel.selected.valves else 0)
    fig, axes = panel_grid(n_panels)
    axes = list(axes)
    for j, (ax, c) in enumerate(zip(axes, pr.channels)):
        has = bool(sel.selected.mechanisms)
        draw(ax, x, pr.Y[:, j], sel.raw_pred[:, j], ext[:, j] if has else None, sel.cv_pred[:, j] if has else None,
             pr.ds.engines, c, pr.ds.spec(c).unit, calib[:, j], spread=spreads.get(c))
        ax.set_xlabel(xlabel, fontsize=8)
    if sel.selected.valves:
        ax = axes[len(pr.channels)]
        act = sel.activity()
        w = 0.8 / max(len(act), 1)
        for k, (mid, a) in enumerate(act.items()):
            ax.bar(np.asarray(x) + (k - (len(act) - 1) / 2) * w * np.ptp(x) / max(len(x), 1), a,
                   width=w * np.ptp(x) / max(len(x), 1), label=f"{mid}: diverted flow fraction", color=f"C{4 + k}")
        ax.set_title("valve activity per measured point", fontsize=9)
        ax.set_xlabel(xlabel, fontsize=8)
        ax.set_ylabel("fraction of the flow", fontsize=8)
        ax.tick_params(labelsize=8)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    handles, labels = axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=min(5, len(labels)), fontsize=8, frameon=False)
    fig.suptitle(f"{pr.ds.name} ({pr.params.name}): model vs measurement; extension: {cause}", fontsize=10)
    fig.tight_layout(rect=(0, 0.06, 1, 0.97))
    f = d / f"{name}_model_vs_measured.png"
    fig.savefig(f, dpi=100)
    plt.close(fig)
    files.append(f)

    cv = sel.cv_rmse()
    fig, ax = plt.subplots(figsize=(max(7.0, 0.9 * len(pr.channels)), 4.2))
    idx = np.arange(len(pr.channels))
    tol = pr.tolerance
    r = np.array([cv[c]["rmse_raw"] for c in pr.channels]) / tol
    b = np.array([cv[c]["cv_rmse_base"] for c in pr.channels]) / tol
    e = np.array([cv[c]["cv_rmse_extended"] for c in pr.channels]) / tol
    w = 0.27
    ax.bar(idx - w, r, w, label="base model", color="C0")
    ax.bar(idx, b, w, label="base calibrated within ±6 %, cross-validated", color="C9")
    ax.bar(idx + w, e, w, label=f"extended ({cause}), cross-validated", color="C3")
    if holdout is not None:
        hb = [holdout["channels"].get(c, {}).get("holdout_rmse_base", np.nan) for c in pr.channels]
        he = [holdout["channels"].get(c, {}).get("holdout_rmse_extended", np.nan) for c in pr.channels]
        ax.plot(idx - w, np.array(hb, float) / tol, "k_", ms=12, mew=2, label="hold-out, base")
        ax.plot(idx + w, np.array(he, float) / tol, "k_", ms=12, mew=2, alpha=0.5, label="hold-out, extended")
    ax.set_xticks(idx)
    ax.set_xticklabels([c.replace("_", " ") for c in pr.channels], rotation=30, ha="right", fontsize=7)
    ax.set_ylabel("RMSE / tolerance")
    ax.set_title(f"{pr.ds.name}: error per channel ({sel.cv_scheme})", fontsize=10)
    ax.legend(fontsize=7, loc="upper right")
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    f = d / f"{name}_cv_rmse.png"
    fig.savefig(f, dpi=100)
    plt.close(fig)
    files.append(f)

    if holdout is not None:
        ho: Problem = holdout["_problem"]
        xh, xlh = _load_axis(ho)
        fig, axes = panel_grid(len(ho.channels))
        axes = list(axes)
        for j, (ax, c) in enumerate(zip(axes, ho.channels)):
            draw(ax, xh, ho.Y[:, j], holdout["_pred_base"][:, j], holdout["_pred_extended"][:, j], None,
                 ho.ds.engines, c, ho.ds.spec(c).unit, ext_label="fitted engine (fitted without these data)")
            hf = holdout.get("_at_fit_conditions")
            if hf is not None:  # the same at the fitted data's test-bed conditions (what the hold-out did not record)
                o = np.argsort(xh, kind="stable")
                ax.plot(xh[o], hf["_pred_base"][o, j], "-.", color="C0", lw=1.0, alpha=0.7,
                        label="base model, at the fitted test bed's conditions")
                ax.plot(xh[o], hf["_pred_extended"][o, j], "-.", color="C3", lw=1.2, alpha=0.8,
                        label="fitted engine, at the fitted test bed's conditions")
            ax.set_xlabel(xlh, fontsize=8)
        handles, labels = axes[0].get_legend_handles_labels()
        fig.legend(handles, labels, loc="lower center", ncol=min(4, len(labels)), fontsize=8, frameon=False)
        fig.suptitle(f"hold-out {ho.ds.name} {', '.join(ho.ds.engine_ids())}: engine fitted on {pr.ds.name} "
                     f"({cause})", fontsize=10)
        fig.tight_layout(rect=(0, 0.13, 1, 0.95))
        f = d / f"{name}_holdout.png"
        fig.savefig(f, dpi=100)
        plt.close(fig)
        files.append(f)
    return files


# --------------------------------------------------------------------------------------- markdown
def _g(x, fmt=".4g") -> str:
    return "–" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, fmt)


def _holdout_lines(h: Mapping[str, Any], how: str) -> list[str]:
    """Markdown: a hold-out's RMSE base → fitted engine per channel (all points, and without the readings the
    loader flagged), and per engine."""
    pe = h.get("per_engine") or {}
    L = [f"Hold-out `{h['dataset']}` ({how}), RMSE base → fitted engine; in brackets without the "
         f"{len(h.get('suspect_readings') or [])} reading(s) the loader flags as suspect:", "",
         "| engine | " + " | ".join(f"`{c}`" for c in h["channels"]) + " |", "|---|" + "---|" * len(h["channels"])]

    def cell(v):
        b, e = v.get("holdout_rmse_base"), v.get("holdout_rmse_extended")
        bc, ec = v.get("holdout_rmse_base_without_suspect"), v.get("holdout_rmse_extended_without_suspect")
        out = f"{_g(b)} → {_g(e)}"
        if (bc, ec) != (b, e) and bc is not None and ec is not None:
            out += f" ({_g(bc)} → {_g(ec)})"
        return out

    for e, v in pe.items():
        L.append(f"| {e} | " + " | ".join(cell(v[c]) for c in h["channels"]) + " |")
    L.append("| all | " + " | ".join(cell(v) for v in h["channels"].values()) + " |")
    return L + [""]


def markdown_summary(rep: Mapping[str, Any], title: str | None = None) -> str:
    """The report as Markdown tables (what docs/validation.md quotes)."""
    ds, ch = rep["dataset"], rep["channels"]
    L = [f"#### {title or ds['name']}", ""]
    L.append(f"Parameter set `{rep['model']['params']}`, {ds['n_points']} points"
             + (f", engines {', '.join(ds['engines'])}" if ds["engines"] else "")
             + f"; operating points matched on {rep['model']['target']} ({', '.join(rep['model']['target_columns'])}); "
             f"cross-validation: {rep['cv']['scheme']} ({rep['cv']['n_folds']} folds).")
    L.append("")
    nc = rep.get("not_compared") or []
    if nc:
        L.append("Columns not compared (every column of the file is either a channel below or listed here):")
        L.append("")
        L.append("| column | role | why |")
        L.append("|---|---|---|")
        for r in nc:
            L.append(f"| `{r['column']}` | {r['role']} | {r['what']} |")
        L.append("")
    for o in ds.get("boundary_outliers") or []:
        L.append(f"* Recording error left out: `{o['column']}` row {o['row']} reads {_g(o['value'])} (robust z = "
                 f"{_g(o['robust_z'], '.1f')}); the row runs at {_g(o['replacement'])}.")
    if ds.get("boundary_outliers"):
        L.append("")
    L.append("Base model errors (residual = model - measured, column units; tolerance = the residual scale of the "
             "fit):")
    L.append("")
    L.append("| channel | n | tolerance | bias | RMSE | mean rel. error |")
    L.append("|---|---|---|---|---|---|")
    for c, v in ch.items():
        rel = v["mean_abs_rel_error_base"]
        L.append(f"| `{c}` | {v['n']} | {_g(v['tolerance'], '.3g')} | {_g(v['bias_base'], '+.4g')} | "
                 f"{_g(v['rmse_base'])} | {_g(100 * rel if rel is not None else None, '.1f')} % |")
    L.append("")
    fam = [d for d in rep["discrepancies"] if d["family_significant"]]
    L.append(f"Significant discrepancies of the base model ({len(fam)} after the correction for the number of "
             f"channels; {len(rep['discrepancies'])} at p < {rep['settings']['alpha']} per test):")
    L.append("")
    if fam:
        L.append("| channel | kind | region | magnitude | score (x tolerance) | p |")
        L.append("|---|---|---|---|---|---|")
        for d in fam:
            L.append(f"| `{d['channel']}` | {d['kind']} | {d['region']} | {_g(d['magnitude'], '+.4g')} "
                     f"{d.get('unit', '')} | {_g(d['score'], '.1f')} | {_g(d['p_value'], '.2g')} |")
    else:
        L.append("none")
    L.append("")
    L.append("Candidates (S = mean robust loss per measured cell, about the mean squared error in tolerances; p = "
             "F-test of the cross-validated gain, to be compared with alpha / number of candidates; every fit "
             "includes the calibration of the base within ±6 %):")
    L.append("")
    L.append("| step | combination | free parameters | S in-sample | S cross-validated | gain vs current | p | note |")
    L.append("|---|---|---|---|---|---|---|---|")
    L.append(f"| 0 | base model, calibrated | 0 | | {_g(rep['cv']['score_base'])} | | | |")
    for c in sorted(rep["candidates"], key=lambda c: (c["step"], c["cv_score"] if c["cv_score"] is not None else 1e300)):
        if c["cv_score"] is None and not str(c.get("screened", "")).startswith("not eligible"):
            continue
        L.append(f"| {c['step']} | {' + '.join(f'`{x}`' for x in c['combination'])} | {c['n_params']} | "
                 f"{_g(c['in_sample_score'])} | {_g(c['cv_score'])} | "
                 f"{_g(100 * c['gain_vs_current'] if c['gain_vs_current'] is not None else None, '+.1f')} % | "
                 f"{_g(c['p_value'], '.2g')} | {c.get('screened', '')} |")
    L.append("")
    L.append("(Candidates whose in-sample fit could not beat the current model by 10 % were not cross-validated; "
             "all are in the JSON report.)")
    L.append("")
    for s in rep["steps"]:
        best = f"best `{s['best']}`" if s.get("best") else "no eligible candidate"
        L.append(f"* step {s['step']}: {best}, {s['decision']}")
    L.append("")
    L.append(f"**Selected causes: {', '.join(f'`{x}`' for x in rep['selected_labels']) or 'none'}.**")
    L.append("")
    for lab, alts in (rep.get("alternatives") or {}).items():
        if alts:
            L.append(f"* `{lab}`: the data hardly tell it from " + ", ".join(
                f"`{a['mechanism']}` ({a['why']})" for a in alts) + ".")
    for lab, notes in (rep.get("cause_notes") or {}).items():
        for n in notes:
            L.append(f"* `{lab}`: {n}.")
    if any(rep.get("alternatives", {}).values()) or rep.get("cause_notes"):
        L.append("")
    if rep["parameters"]:
        L.append("| cause | parameter | value | standard error | unit |")
        L.append("|---|---|---|---|---|")
        for lab, ps in rep["parameters"].items():
            for k, v in ps.items():
                L.append(f"| `{lab}` | `{k}` | {_g(v['value'])} | {_g(v['stderr'], '.2g')} | {v['unit']} |")
        L.append("")
    if rep.get("activity"):
        L.append("Where the valve-type causes act (diverted flow fraction per measured point, file row order; "
                 "0 = shut):")
        L.append("")
        L.append("| cause | " + " | ".join(f"point {i + 1}" for i in range(ds["n_points"])) + " |")
        L.append("|---|" + "---|" * ds["n_points"])
        for mid, a in rep["activity"].items():
            L.append(f"| `{mid}` | " + " | ".join(_g(x, '.3f') for x in a) + " |")
        L.append("")
    nuis = rep.get("nuisance", {}).get("extended") or {}
    if nuis:
        L.append("Calibration within the base model's uncertainty (multipliers, prior 1 ± 0.03, box ±0.06): "
                 + ", ".join(f"{k} {_g(v, '.3f')}" for k, v in nuis.items()) + ".")
        L.append("")
    ho = "holdout" in rep
    L.append("RMSE per channel (column units): base model as it is; base calibrated within ±6 %, cross-validated; "
             "extended, cross-validated" + ("; and on the hold-out data" if ho else "") + ":")
    L.append("")
    L.append("| channel | touched by a cause | base | base calibrated (CV) | extended (CV) | gain vs base |"
             + (" hold-out base | hold-out extended |" if ho else ""))
    L.append("|---|---|---|---|---|---|" + ("---|---|" if ho else ""))
    for c, v in ch.items():
        row = (f"| `{c}` | {'yes' if v['touched_by_selected'] else ''} | {_g(v['rmse_base'])} | "
               f"{_g(v['cv_rmse_base'])} | {_g(v['cv_rmse_extended'])} | "
               f"{_g(100 * v['cv_gain'] if v['cv_gain'] is not None else None, '+.0f')} % |")
        if ho:
            row += f" {_g(v.get('holdout_rmse_base'))} | {_g(v.get('holdout_rmse_extended'))} |"
        L.append(row)
    L.append("")
    if ho:
        L += _holdout_lines(rep["holdout"], "at the parameter set's conditions where it recorded none")
    if "holdout_at_fit_conditions" in rep:
        h = rep["holdout_at_fit_conditions"]
        L += _holdout_lines(h, "assuming " + h["conditions"]["assumption"] + " (an assumption that favours the "
                            "fitted engine, which was calibrated at those conditions)")
    if rep["cv"]["folds"]:
        cs = [c for c, v in ch.items() if v["touched_by_selected"]] or list(ch)
        L.append("Per left-out engine (model fitted on the other engines), RMSE base → extended:")
        L.append("")
        L.append("| left out | " + " | ".join(f"`{c}`" for c in cs) + " |")
        L.append("|---|" + "---|" * len(cs))
        for f in rep["cv"]["folds"]:
            L.append(f"| {f['fold']} | " + " | ".join(
                f"{_g(f['channels'][c]['rmse_base'])} → {_g(f['channels'][c]['rmse_extended'])}" for c in cs) + " |")
        L.append("")
    if rep["unexplained"]:
        a_u = rep['settings'].get('alpha_unexplained', rep['settings']['alpha'])
        left = (f"; what a named sensor calibration leaves: p < {a_u} over the calibrated channels"
                if any(u.get("left_by") == "sensor_calibration" for u in rep["unexplained"]) else "")
        L.append(f"Unexplained (family-wise p < {a_u} over the channels{left}, judged against the model refitted "
                 "without each channel):")
        L.append("")
        for u in rep["unexplained"]:
            L.append(f"* {u['text']}" + (f" — {u['note']}" if u.get("note") else ""))
        L.append("")
    if rep.get("calibration_scans"):
        L.append("What each named sensor calibration leaves on its channel (the largest step, kink or window beyond its "
                 "gain and offset; reported as unexplained when p < the level and it departs by a tolerance):")
        L.append("")
        for col, sc in rep["calibration_scans"].items():
            lo, hi = sc["load_range"]
            p_txt = f"p < {sc['p']:.2g}" if sc.get("p_at_floor") else f"p = {sc['p']:.2g}"
            verdict = "nothing significant left"
            if sc["p"] < sc.get("level", 0.0) and abs(sc["d"]) >= sc["tolerance"]:
                local = [u for u in rep["unexplained"] if u["channel"] == col and u["kind"] == "local"]
                verdict = ("structure left, reported above" if any(u.get("left_by") for u in local) else
                           "structure left; the channel's local finding above already reports it" if local else
                           "structure left")
            L.append(f"* `{col}`: a {sc['kind']} at load {lo:.3g}-{hi:.3g}, {sc['d']:+.4g} {sc.get('unit', '')} "
                     f"(tolerance {sc['tolerance']:.3g}), {p_txt}, level {sc.get('level', float('nan')):.2g}: {verdict}")
        L.append("")
    if rep["outliers"]:
        L.append("Single-reading outliers (kept in the data; the robust fit down-weights them):")
        L.append("")
        for o in rep["outliers"]:
            L.append(f"* {o['text']}")
        L.append("")
    if rep.get("replicas"):
        from .replicas import markdown_table

        r = rep["replicas"]
        L.append(f"Would data like these name the same causes again? {r['settings']['replicas']} replicas per "
                 f"hypothesis at this dataset's design (noise: {r['settings']['noise']}; each hypothesis fitted on "
                 "the data and taken as the truth, the whole pipeline run on each replica):")
        L.append("")
        L.append(markdown_table(r))
        L.append("")
    return "\n".join(L)


# --------------------------------------------------------------------------------------- CLI
class _ArgError(Exception):
    pass


def build_parser(prog: str = "marine-fdi validate") -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog=prog, description="Validate the engine model against measured data: "
                                 "discrepancies, named causes, cross-validated gain, the fitted engine.")
    ap.add_argument("--data", metavar="FILE.csv",
                    help="measured data (CSV with sidecar FILE.meta.json) or a shipped dataset name "
                         f"({', '.join(list_shipped())})")
    g = ap.add_mutually_exclusive_group()
    g.add_argument("--holdout", metavar="FILE.csv", help="data the fit does not see; the report gives its RMSE")
    g.add_argument("--holdout-engine", metavar="ID", help="leave this engine of --data out and predict it")
    ap.add_argument("--out", metavar="report.json", help="JSON report (required unless --check)")
    ap.add_argument("--check", action="store_true",
                    help="only load and check --data: what each column becomes, the assumptions, the readings left "
                         "out, the tolerance of every compared channel; no fit (seconds)")
    ap.add_argument("--columns", action="store_true", help="list the column names the loader knows and stop")
    ap.add_argument("--plots", metavar="DIR", help="write model-vs-measurement plots here (needs matplotlib)")
    ap.add_argument("--params", metavar="NAME|FILE.json", help="parameter set overriding the sidecar's ("
                    + ", ".join(list_parameter_sets()) + ") or a fitted-engine file")
    ap.add_argument("--save-params", metavar="ENGINE.json",
                    help="write the fitted engine (parameter set + selected submodels) for operating-point, simulate, "
                         "the environment and --params")
    ap.add_argument("--target", default="auto", help="what fixes each operating point: " + ", ".join(TARGETS))
    ap.add_argument("--max-causes", type=int, default=4, help="most mechanisms to combine (default 4)")
    ap.add_argument("--max-folds", type=int, default=None,
                    help="cross-validate single-engine data with at most this many folds (default: leave one out)")
    ap.add_argument("--alpha", type=float, default=0.01, help="significance level of a named cause (default 0.01)")
    ap.add_argument("--alpha-unexplained", type=float, default=ALPHA_UNEXPLAINED,
                    help=f"family-wise level of what is reported as unexplained (default {ALPHA_UNEXPLAINED:g})")
    ap.add_argument("--tolerance", action="append", default=[], metavar="COLUMN=VALUE",
                    help="a channel's tolerance (its noise and what is not worth naming), in the column's units or "
                         "as P%% of its mean value; repeatable; default: the sidecar's tolerances, else 1 %% and 5 K")
    ap.add_argument("--cv-all", action="store_true", help="cross-validate every candidate (slower)")
    add_valve_options(ap)
    ap.add_argument("--markdown", metavar="FILE.md", help="also write the report's tables as Markdown")
    ap.add_argument("--replicas", type=int, default=0, metavar="N",
                    help="also ask whether data like these would name the same causes again: N replicas of the data "
                         "per hypothesis (the named causes and 4 alternatives), each run through the whole pipeline "
                         "(python -m marine_fdi_env.validation.replicas; about 5 x N pipeline runs; default 0: no)")
    ap.add_argument("--workers", type=int, default=1, help="processes for --replicas (default 1)")
    ap.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    return ap


def _summary_lines(rep: Mapping[str, Any]) -> list[str]:
    lines = [f"{rep['dataset']['name']} ({rep['model']['params']}, matched on {rep['model']['target']}, "
             f"{rep['cv']['scheme']}): selected causes: {', '.join(rep['selected_labels']) or 'none'}"]
    for lab, ps in rep["parameters"].items():
        lines.append("  " + lab + ": " + ", ".join(f"{k} = {_f(v['value'])} ± {_f(v['stderr'])}"
                                                   for k, v in ps.items()))
    for lab, alts in (rep.get("alternatives") or {}).items():
        if alts:
            lines.append(f"  {lab}: hardly told from " + ", ".join(a["mechanism"] for a in alts))
    for notes in (rep.get("cause_notes") or {}).values():
        lines += [f"  {n}" for n in notes]
    for mid, a in (rep.get("activity") or {}).items():
        lines.append(f"  {mid} acts at points " + ", ".join(f"{i + 1} ({x:.3f})" for i, x in enumerate(a) if x))
    lines.append(f"  {'channel':40s} {'rmse_base':>11s} {'cv_rmse_ext':>11s}"
                 + (f" {'holdout_base':>12s} {'holdout_ext':>12s}" if "holdout" in rep else ""))
    for c, v in rep["channels"].items():
        row = f"  {c:40s} {_f(v['rmse_base']):>11s} {_f(v['cv_rmse_extended']):>11s}"
        if "holdout" in rep:
            row += f" {_f(v.get('holdout_rmse_base')):>12s} {_f(v.get('holdout_rmse_extended')):>12s}"
        lines.append(row)
    for u in rep["unexplained"]:
        lines.append("  " + u["text"])
    for o in rep["outliers"]:
        lines.append("  " + o["text"])
    for h in (rep.get("replicas") or {}).get("summary", []):
        lines.append(f"  replicas drawn from {h['hypothesis']} ({' + '.join(h['causes']) or 'nothing'}): named "
                     f"itself {h['named_itself']}/{h['replicas']}, the data's causes {h['named_data_causes']}/"
                     f"{h['replicas']}")
    return lines


def _f(x) -> str:
    return "-" if x is None else f"{x:.4g}"


def _out_path(text: str, option: str) -> Path:
    p = Path(text)
    if p.parent != Path("") and not p.parent.parent.exists():
        raise ValueError(f"{option}: directory {str(p.parent.parent)!r} does not exist (the parent of --out is "
                         "created, never more)")
    return p


def validate_main(argv: Sequence[str] | None = None, prog: str = "marine-fdi validate") -> int:
    """Command line ``marine-fdi validate``: 0 on success, 2 on bad input (message on stderr), 130 on Ctrl-C."""
    ap = build_parser(prog)

    def error(message):
        raise _ArgError(message)

    ap.error = error  # type: ignore[method-assign]
    argv = list(argv) if argv is not None else sys.argv[1:]
    try:
        args = ap.parse_args(argv)
    except _ArgError as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 2
    except SystemExit as e:  # --help
        return int(e.code or 0)
    if args.columns:
        print(column_registry())
        return 0
    say = None if args.quiet else (lambda s: print(s, file=sys.stderr, flush=True))
    try:
        if args.data is None:
            raise ValueError("--data is required (or --columns to list the known column names)")
        if args.out is None and not args.check:
            raise ValueError("--out is required (or --check to only check the data)")
        params = None
        if args.params is not None:
            try:
                params = load_params(args.params)
            except ValueError as e:
                raise ValueError(f"--params: {e}") from None
        if args.target not in TARGETS:
            raise ValueError(f"--target: unknown target {args.target!r}; allowed: {', '.join(TARGETS)}")
        if args.max_causes < 0:
            raise ValueError(f"--max-causes must be >= 0, got {args.max_causes}")
        if args.max_folds is not None and args.max_folds < 2:
            raise ValueError(f"--max-folds must be >= 2, got {args.max_folds}")
        if not 0.0 < args.alpha < 1.0:
            raise ValueError(f"--alpha must lie in (0, 1), got {args.alpha}")
        if not 0.0 < args.alpha_unexplained < 1.0:
            raise ValueError(f"--alpha-unexplained must lie in (0, 1), got {args.alpha_unexplained}")
        if args.replicas < 0 or args.workers < 1:
            raise ValueError(f"--replicas must be >= 0 and --workers >= 1, got {args.replicas}, {args.workers}")
        out = _out_path(args.out, "--out") if args.out else None
        save = _out_path(args.save_params, "--save-params") if args.save_params else None
        md = _out_path(args.markdown, "--markdown") if args.markdown else None
        if args.plots:
            pyplot()
        try:
            ds = load_data_arg(args.data, args.params if args.params in list_parameter_sets() else None)
        except DatasetError as e:
            raise ValueError(f"--data: {e}") from None
        holdout = None
        notes = []
        if args.holdout_engine is not None:
            ds, holdout = split_engine(ds, args.holdout_engine)
            notes.append(f"engine {args.holdout_engine} left out of the fit and the cross-validation; "
                         "it is the hold-out")
        elif args.holdout is not None:
            try:
                holdout = load_data_arg(args.holdout, args.params if args.params in list_parameter_sets() else
                                        ds.params_name)
            except DatasetError as e:
                raise ValueError(f"--holdout: {e}") from None
        problem = Problem(ds, target=args.target, params=params) if args.tolerance or args.check else None
        tolerances = problem.stated_tolerances(args.tolerance) if args.tolerance else None
        if args.check:
            print(describe(ds, problem, tolerances or dict(zip(problem.channels, problem.tolerance)), args.tolerance,
                           max_folds=args.max_folds))
            if holdout is not None:
                what = f"engine {args.holdout_engine} of {ds.name}" if args.holdout_engine else holdout.name
                print(f"hold-out: {what}, {holdout.n_points} points (predicted, not fitted)")
            print("--check: nothing fitted, nothing written")
            return 0
        rep, sel, ho = run_validation(ds, holdout=holdout, target=args.target, params=params,
                                      max_causes=args.max_causes, alpha=args.alpha,
                                      alpha_unexplained=args.alpha_unexplained, cv_all=args.cv_all,
                                      max_folds=args.max_folds, progress=say, notes=notes,
                                      command="marine-fdi validate " + " ".join(argv), tolerances=tolerances,
                                      held_out_valves=args.held_out_valves, beside_valve=args.beside_valve)
        if args.replicas:
            from .replicas import replicate

            if say:
                say(f"replicas: {args.replicas} per hypothesis, each through the whole pipeline")
            rep["replicas"] = _clean(replicate(sel, replicas=args.replicas, workers=args.workers,
                                               progress=not args.quiet))
    except RuntimeError as e:  # a missing optional extra
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 2
    except ValueError as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"{prog}: interrupted", file=sys.stderr)
        return 130
    for p in (out, save, md):
        if p is not None:
            p.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(rep, indent=1) + "\n")
    if save is not None:
        save.write_text(json.dumps(rep["fitted_engine"], indent=1) + "\n")
    if md is not None:
        title = ds.name + (f" without {args.holdout_engine} (hold-out)" if args.holdout_engine else "")
        md.write_text(markdown_summary(rep, title) + "\n")
    if args.plots:
        prefix = ds.name + (f"_without_{args.holdout_engine}" if args.holdout_engine else "")
        files = write_plots(sel, args.plots, ho, prefix=prefix)
        print("plots: " + ", ".join(str(f) for f in files))
    print("\n".join(_summary_lines(rep)))
    print(f"report: {out}" + (f"; fitted engine: {save}" if save is not None else ""))
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(validate_main())
