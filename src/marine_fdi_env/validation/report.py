"""The validation report: what the model gets wrong on a dataset, the named cause, the gain (and plots).

:func:`run_validation` loads the data (and an optional hold-out set), runs :func:`~.selection.select_causes`
and assembles a JSON-serialisable report; :func:`write_plots` draws model against measurement before
and after the extension; :func:`validate_main` is the command line ``marine-fdi validate``::

    marine-fdi validate --data FILE.csv [--holdout FILE.csv | --holdout-engine ID] --out report.json
                        [--plots DIR] [--params NAME] [--target auto|power|fuel_flow|speed|fuel_rack]
                        [--max-causes N] [--alpha A] [--screen] [--markdown FILE.md]

``--data`` also takes the name of a shipped dataset (``birka_6l46_shop_test``, ``man_12v32_40_fpp_iso``).
``--holdout-engine ID`` leaves one engine of ``--data`` out of everything (fit and cross-validation)
and reports the fitted model on it.  Every candidate is cross-validated (``--screen``: only those whose
in-sample score can still win, faster on large datasets; ``--cv-all`` is accepted and is the default).

Report keys: ``dataset``, ``model``, ``settings``, ``channels`` (per channel: tolerance, base bias /
RMSE, ``cv_rmse_base``, ``cv_rmse_extended``, and with a hold-out ``holdout_rmse_base`` /
``holdout_rmse_extended``), ``discrepancies`` (the base model's, ranked), ``candidates`` (each mechanism
with its in-sample and cross-validated score, penalised score, p-value), ``steps`` (the greedy
decisions), ``selected_causes`` (mechanism ids; ``selected_labels`` with the channel of a sensor
calibration), ``parameters`` (fitted values with standard errors per selected cause), ``unexplained``
(family-significant discrepancies left: channel, kind, region), ``outliers`` (single readings),
``explained`` (base discrepancies the extension removed), ``cv`` (scheme, scores, per fold), ``holdout``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import warnings
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from ..params import list_parameter_sets
from .columns import COLUMNS
from .dataset import DatasetError, DataWarning, MeasuredDataset, list_shipped, load_dataset, load_shipped
from .extended_model import NO_HOOKS
from .matching import TARGETS
from .mechanisms import PHYSICAL_MECHANISMS, Mechanism
from .selection import Problem, Selection, channel_rmse, family_significant, select_causes

__all__ = ["run_validation", "build_report", "write_plots", "validate_main", "load_data_arg", "split_engine",
           "markdown_summary", "holdout_evaluation"]


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


def load_data_arg(text: str, params: str | None = None) -> MeasuredDataset:
    """A dataset from a CSV path or the name of a shipped dataset (warnings kept in the dataset)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        p = Path(text)
        if p.exists():
            return load_dataset(p, params=params)
        if text in list_shipped():
            return load_shipped(text, params=params)
        raise ValueError(f"no such file {text!r} (shipped datasets: {', '.join(list_shipped())})")


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


# --------------------------------------------------------------------------------------- report
def build_report(sel: Selection, holdout: Mapping[str, Any] | None = None, notes: Sequence[str] = ()) -> dict[str, Any]:
    """Assemble the JSON report of a selection (``holdout``: a :func:`holdout_evaluation` of its fitted model)."""
    pr = sel.problem
    ds = pr.ds
    hooks = sel.hooks
    mechs = sel.selected.mechanisms
    ext_in, _ = pr.predict(hooks)
    rm_base = channel_rmse(pr, sel.base_pred)
    rm_ext_in = channel_rmse(pr, ext_in)
    cv = sel.cv_rmse()
    channels: dict[str, Any] = {}
    for j, c in enumerate(pr.channels):
        cd = sel.base_report.channels.get(c)
        q = ds.column_quantity[c]
        b, e = cv[c]["cv_rmse_base"], cv[c]["cv_rmse_extended"]
        channels[c] = {
            "quantity": q, "unit": COLUMNS[c].unit, "tolerance": float(pr.tolerance[j]),
            "n": int(pr.measured_mask[:, j].sum()),
            "bias_base": cd.bias if cd else None, "rmse_base": rm_base[c],
            "mean_abs_rel_error_base": cd.mean_abs_rel_error if cd else None,
            "rmse_extended_in_sample": rm_ext_in[c],
            "cv_rmse_base": b, "cv_rmse_extended": e,
            "cv_gain": (b - e) / b if b and math.isfinite(b) and b > 0 else None,
            "touched_by_selected": _touches(mechs, q, c),
        }
    # per fold: the left-out engine(s)/point(s)
    scheme, folds = pr.folds()
    fold_rows = []
    if len(ds.engine_ids()) >= 2:
        for name, rows in folds:
            fb = channel_rmse(pr, sel.base_pred, rows)
            fe = channel_rmse(pr, sel.cv_pred, rows)
            fold_rows.append({"fold": name, "points": [int(i) + 1 for i in rows],
                              "channels": {c: {"rmse_base": fb[c], "rmse_extended": fe[c]} for c in pr.channels}})
    base_family = [d for d in sel.base_report.discrepancies if d["kind"] != "outlier"
                   and family_significant(d, sel.base_report, sel.settings["alpha"])]
    left = {(u["channel"], u["kind"]) for u in sel.unexplained}
    explained = [dict({k: d[k] for k in ("channel", "kind", "region", "magnitude", "score")},
                      cv_rmse_base=cv[d["channel"]]["cv_rmse_base"],
                      cv_rmse_extended=cv[d["channel"]]["cv_rmse_extended"])
                 for d in base_family if (d["channel"], d["kind"]) not in left] if sel.selected.n_params else []
    discrepancies = []
    for d in sel.base_report.discrepancies:
        e = {k: d[k] for k in ("rank", "channel", "kind", "region", "magnitude", "score", "p_value", "unit") if k in d}
        if "variable" in d:
            e["variable"] = d["variable"]
        e["family_significant"] = family_significant(d, sel.base_report, sel.settings["alpha"], sel.base_outliers)
        discrepancies.append(e)
    report: dict[str, Any] = {
        "dataset": {"name": ds.name, "path": ds.path, "provenance": ds.provenance, "n_points": ds.n_points,
                    "engines": ds.engine_ids(), "params": pr.params.name, "warnings": [str(w) for w in ds.warnings],
                    "notes": list(ds.notes)},
        "model": {"params": pr.params.name, "target": pr.target, "target_columns": list(pr.target_columns),
                  "load_law": pr.law.describe()},
        "settings": sel.settings,
        "channels": channels,
        "discrepancies": discrepancies,
        "candidates": sel.candidates(),
        "steps": [_step_dict(pr, s) for s in sel.steps],
        "selected_causes": sel.selected_causes,
        "selected_labels": sel.selected_labels,
        "parameters": sel.fit.parameters(),
        "unexplained": sel.unexplained,
        "outliers": sel.outliers,
        "explained": explained,
        "cv": {"scheme": scheme, "n_folds": len(folds), "score_base": sel.base_score, "score_extended": sel.cv_score,
               "folds": fold_rows},
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


def holdout_evaluation(sel: Selection, holdout: MeasuredDataset) -> dict[str, Any]:
    """RMSE per channel of the base and the fitted extended model on data the fit did not see."""
    pr = sel.problem
    ho = Problem(holdout, params=pr.params, target=pr.target)
    pb, _ = ho.predict(NO_HOOKS)
    pe, conv = ho.predict(sel.hooks)
    rb, re_ = channel_rmse(ho, pb), channel_rmse(ho, pe)
    return {"dataset": holdout.name, "engines": holdout.engine_ids(), "n_points": holdout.n_points,
            "not_converged": [int(i) + 1 for i in np.flatnonzero(~conv)],
            "channels": {c: {"holdout_rmse_base": rb[c], "holdout_rmse_extended": re_[c],
                             "tolerance": float(ho.tolerance[j]), "n": int(ho.measured_mask[:, j].sum()),
                             "touched_by_selected": _touches(sel.selected.mechanisms, holdout.column_quantity[c], c)}
                         for j, c in enumerate(ho.channels)},
            "_problem": ho, "_pred_base": pb, "_pred_extended": pe}


def run_validation(ds: MeasuredDataset, *, holdout: MeasuredDataset | None = None, target: str = "auto",
                   max_causes: int = 2, alpha: float = 0.01, cv_all: bool = False, progress=None,
                   notes: Sequence[str] = ()) -> tuple[dict[str, Any], Selection, dict | None]:
    """Run the pipeline; returns (JSON report, selection, hold-out evaluation with predictions or None)."""
    pr = Problem(ds, target=target)
    sel = select_causes(pr, max_causes=max_causes, alpha=alpha, cv_all=cv_all, progress=progress)
    ho = holdout_evaluation(sel, holdout) if holdout is not None else None
    return build_report(sel, ho, notes), sel, ho


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
    """Model against measurement before (base) and after (fitted extension) per channel, the
    cross-validated RMSE per channel, and the hold-out engine if any.  Returns the files written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    pr = sel.problem
    name = prefix or pr.ds.name
    cause = ", ".join(sel.selected_labels) or "none selected"
    ext, _ = pr.predict(sel.hooks)
    files = []

    def panel_grid(n):
        cols = min(3, n)
        rows = int(math.ceil(n / cols))
        fig, axes = plt.subplots(rows, cols, figsize=(4.6 * cols, 3.4 * rows), squeeze=False)
        for ax in axes.flat[n:]:
            ax.set_visible(False)
        return fig, axes.flat

    # the best candidate of the last step when it was rejected (what the data would have bought)
    rejected = None
    if sel.steps and not sel.steps[-1]["accepted"]:
        best = [c for c in sel.steps[-1]["candidates"] if c.added == sel.steps[-1].get("best") and c.cross_validated]
        if best:
            rejected = (" + ".join(best[0].combination.labels), pr.predict(best[0].fit.hooks(pr.params))[0])

    def draw(ax, x, meas, base, extd, cvp, eng, col, unit, rej=None, ext_label="extended (fit on all)"):
        order = np.argsort(x, kind="stable")
        if eng is None:
            ax.plot(x, meas, "ko", ms=4, label="measured")
        else:
            for k, e in enumerate(dict.fromkeys(eng)):
                m = np.array([z == e for z in eng])
                ax.plot(x[m], meas[m], "o", ms=4, color=f"C{k + 2}", label=f"measured {e}")
        ax.plot(x[order], base[order], "--", color="C0", lw=1.4, label="base model")
        if extd is not None:
            ax.plot(x[order], extd[order], "-", color="C3", lw=1.6, label=ext_label)
        if rej is not None:
            ax.plot(x[order], rej[1][order], ":", color="C7", lw=1.6,
                    label=f"best candidate, rejected: {rej[0]}\n(fit on all)")
        if cvp is not None:
            ax.plot(x, cvp, "x", color="C3", ms=5, label="extended, cross-validated")
        ax.set_title(col, fontsize=9)
        ax.set_ylabel(unit, fontsize=8)
        ax.tick_params(labelsize=8)
        ax.grid(alpha=0.3)

    x, xlabel = _load_axis(pr)
    fig, axes = panel_grid(len(pr.channels))
    for j, (ax, c) in enumerate(zip(axes, pr.channels)):
        draw(ax, x, pr.Y[:, j], sel.base_pred[:, j], ext[:, j] if sel.selected.n_params else None,
             sel.cv_pred[:, j] if sel.selected.n_params else None, pr.ds.engines, c, COLUMNS[c].unit,
             None if rejected is None else (rejected[0], rejected[1][:, j]))
        ax.set_xlabel(xlabel, fontsize=8)
    axes[0].legend(fontsize=7)
    fig.suptitle(f"{pr.ds.name} ({pr.params.name}): model vs measurement, before (base) and after (extension: "
                 f"{cause})", fontsize=10)
    fig.tight_layout()
    f = d / f"{name}_model_vs_measured.png"
    fig.savefig(f, dpi=110)
    plt.close(fig)
    files.append(f)

    # cross-validated RMSE per channel in tolerance units
    cv = sel.cv_rmse()
    fig, ax = plt.subplots(figsize=(max(6.0, 1.1 * len(pr.channels)), 3.8))
    idx = np.arange(len(pr.channels))
    tol = pr.tolerance
    b = np.array([cv[c]["cv_rmse_base"] for c in pr.channels]) / tol
    e = np.array([cv[c]["cv_rmse_extended"] for c in pr.channels]) / tol
    w = 0.38
    ax.bar(idx - w / 2, b, w, label="base model", color="C0")
    ax.bar(idx + w / 2, e, w, label=f"extended ({cause}), {sel.cv_scheme}", color="C3")
    if holdout is not None:
        hb = [holdout["channels"].get(c, {}).get("holdout_rmse_base", np.nan) for c in pr.channels]
        he = [holdout["channels"].get(c, {}).get("holdout_rmse_extended", np.nan) for c in pr.channels]
        ax.plot(idx - w / 2, np.array(hb, float) / tol, "k_", ms=14, mew=2, label="hold-out, base")
        ax.plot(idx + w / 2, np.array(he, float) / tol, "k_", ms=14, mew=2, alpha=0.5, label="hold-out, extended")
    ax.set_xticks(idx)
    ax.set_xticklabels([c.replace("_", " ") for c in pr.channels], rotation=25, ha="right", fontsize=7)
    ax.set_ylabel("RMSE / tolerance")
    ax.set_title(f"{pr.ds.name}: cross-validated error per channel", fontsize=10)
    ax.legend(fontsize=7)
    ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    f = d / f"{name}_cv_rmse.png"
    fig.savefig(f, dpi=110)
    plt.close(fig)
    files.append(f)

    if holdout is not None:
        ho: Problem = holdout["_problem"]
        xh, xlh = _load_axis(ho)
        fig, axes = panel_grid(len(ho.channels))
        for j, (ax, c) in enumerate(zip(axes, ho.channels)):
            draw(ax, xh, ho.Y[:, j], holdout["_pred_base"][:, j], holdout["_pred_extended"][:, j], None, ho.ds.engines,
                 c, COLUMNS[c].unit, ext_label="extended (fitted without these data)")
            ax.set_xlabel(xlh, fontsize=8)
        axes[0].legend(fontsize=7)
        fig.suptitle(f"hold-out {ho.ds.name} {', '.join(ho.ds.engine_ids())}: model fitted on the other data "
                     f"({cause})", fontsize=10)
        fig.tight_layout()
        f = d / f"{name}_holdout.png"
        fig.savefig(f, dpi=110)
        plt.close(fig)
        files.append(f)
    return files


# --------------------------------------------------------------------------------------- markdown
def _g(x, fmt=".4g") -> str:
    return "–" if x is None or (isinstance(x, float) and not math.isfinite(x)) else format(x, fmt)


def markdown_summary(rep: Mapping[str, Any], title: str | None = None) -> str:
    """The report as Markdown tables (what docs/validation.md quotes)."""
    ds, ch = rep["dataset"], rep["channels"]
    L = [f"#### {title or ds['name']}", ""]
    L.append(f"Parameter set `{rep['model']['params']}`, {ds['n_points']} points"
             + (f", engines {', '.join(ds['engines'])}" if ds["engines"] else "")
             + f"; operating points matched on {rep['model']['target']} ({', '.join(rep['model']['target_columns'])}); "
             f"cross-validation: {rep['cv']['scheme']} ({rep['cv']['n_folds']} folds).")
    L.append("")
    L.append("Base model errors (residual = model - measured, in the column's unit; tolerance = the residual "
             "scale of the fit):")
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
                     f"{d.get('unit', '')} "
                     f"| {_g(d['score'], '.1f')} | {_g(d['p_value'], '.2g')} |")
    else:
        L.append("none")
    L.append("")
    L.append("Candidates (S = mean robust loss per measured cell, about the mean squared error in tolerances; "
             "p = F-test of the cross-validated gain, to be compared with alpha / number of candidates):")
    L.append("")
    L.append("| step | mechanism | parameters | S in-sample | S cross-validated | gain vs current | p |")
    L.append("|---|---|---|---|---|---|---|")
    L.append(f"| 0 | base model | 0 | {_g(rep['cv']['score_base'])} | {_g(rep['cv']['score_base'])} | | |")
    for c in sorted(rep["candidates"],
                    key=lambda c: (c["step"], c["cv_score"] if c["cv_score"] is not None else 1e300)):
        L.append(f"| {c['step']} | {' + '.join(f'`{x}`' for x in c['combination'])} | {c['n_params']} | "
                 f"{_g(c['in_sample_score'])} | {_g(c['cv_score'])} | "
                 f"{_g(100 * c['gain_vs_current'] if c['gain_vs_current'] is not None else None, '+.1f')} % | "
                 f"{_g(c['p_value'], '.2g')} |")
    L.append("")
    for s in rep["steps"]:
        L.append(f"* step {s['step']}: best `{s['best']}`, {s['decision']}")
    L.append("")
    rejected = [s for s in rep["steps"] if not s["accepted"] and s.get("best_cv_rmse")]
    for s in rejected:
        ps = "; ".join(f"{k} = {_g(v['value'])} ± {_g(v['stderr'], '.2g')}"
                       for lab, pp in s["best_parameters"].items() for k, v in pp.items())
        L.append(f"The rejected best candidate of step {s['step']}, `{s['best']}` ({ps}), would give these "
                 "cross-validated RMSE (for information; it is not part of the extended model):")
        L.append("")
        L.append("| channel | current model | with `" + s["best"] + "` |")
        L.append("|---|---|---|")
        for c, v in ch.items():
            L.append(f"| `{c}` | {_g(v['cv_rmse_extended'])} | {_g(s['best_cv_rmse'][c])} |")
        L.append("")
    L.append(f"**Selected causes: {', '.join(f'`{x}`' for x in rep['selected_labels']) or 'none'}.**")
    L.append("")
    if rep["parameters"]:
        L.append("| cause | parameter | value | standard error | unit | note |")
        L.append("|---|---|---|---|---|---|")
        for lab, ps in rep["parameters"].items():
            for k, v in ps.items():
                L.append(f"| `{lab}` | `{k}` | {_g(v['value'])} | {_g(v['stderr'], '.2g')} | {v['unit']} | "
                         f"{'at the bound of its plausible range ' + str(v['bounds']) if v['at_bound'] else ''} |")
        L.append("")
    ho = "holdout" in rep
    L.append("Cross-validated RMSE per channel (column units)" + (" and on the hold-out data" if ho else "") + ":")
    L.append("")
    L.append("| channel | touched by the cause | CV RMSE base | CV RMSE extended | gain |"
             + (" hold-out RMSE base | hold-out RMSE extended |" if ho else ""))
    L.append("|---|---|---|---|---|" + ("---|---|" if ho else ""))
    for c, v in ch.items():
        row = (f"| `{c}` | {'yes' if v['touched_by_selected'] else ''} | {_g(v['cv_rmse_base'])} | "
               f"{_g(v['cv_rmse_extended'])} | "
               f"{_g(100 * v['cv_gain'] if v['cv_gain'] is not None else None, '+.0f')} % |")
        if ho:
            row += f" {_g(v.get('holdout_rmse_base'))} | {_g(v.get('holdout_rmse_extended'))} |"
        L.append(row)
    L.append("")
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
        L.append("Unexplained:")
        L.append("")
        for u in rep["unexplained"]:
            L.append(f"* {u['text']}" + (f" — {u['note']}" if u.get("note") else ""))
        L.append("")
    if rep["outliers"]:
        L.append("Single-reading outliers (kept in the data; the robust fit down-weights them):")
        L.append("")
        for o in rep["outliers"]:
            L.append(f"* {o['text']}")
        L.append("")
    return "\n".join(L)


# --------------------------------------------------------------------------------------- CLI
class _ArgError(Exception):
    pass


def build_parser(prog: str = "marine-fdi validate") -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog=prog, description="Validate the engine model against measured data: "
                                 "discrepancies, named cause, cross-validated gain.")
    ap.add_argument("--data", required=True, metavar="FILE.csv",
                    help="measured data (CSV with sidecar FILE.meta.json) or a shipped dataset name "
                         f"({', '.join(list_shipped())})")
    g = ap.add_mutually_exclusive_group()
    g.add_argument("--holdout", metavar="FILE.csv", help="data the fit does not see; the report gives its RMSE")
    g.add_argument("--holdout-engine", metavar="ID", help="leave this engine of --data out and predict it")
    ap.add_argument("--out", required=True, metavar="report.json", help="JSON report")
    ap.add_argument("--plots", metavar="DIR", help="write model-vs-measurement plots here")
    ap.add_argument("--params", metavar="NAME", help="parameter set overriding the sidecar's ("
                    + ", ".join(list_parameter_sets()) + ")")
    ap.add_argument("--target", default="auto", help="what fixes each operating point: " + ", ".join(TARGETS))
    ap.add_argument("--max-causes", type=int, default=2, help="most mechanisms to combine (default 2)")
    ap.add_argument("--alpha", type=float, default=0.01, help="significance level (default 0.01)")
    ap.add_argument("--cv-all", action="store_true", help="cross-validate every candidate (the default)")
    ap.add_argument("--screen", action="store_true",
                    help="faster: cross-validate only candidates whose in-sample score can still win")
    ap.add_argument("--markdown", metavar="FILE.md", help="also write the report's tables as Markdown")
    ap.add_argument("--quiet", action="store_true", help="no progress lines on stderr")
    return ap


def _summary_lines(rep: Mapping[str, Any]) -> list[str]:
    lines = [f"{rep['dataset']['name']} ({rep['model']['params']}, matched on {rep['model']['target']}, "
             f"{rep['cv']['scheme']}): selected causes: {', '.join(rep['selected_labels']) or 'none'}"]
    for lab, ps in rep["parameters"].items():
        lines.append("  " + lab + ": " + ", ".join(f"{k} = {v['value']:.4g} ± {v['stderr']:.2g}"
                                                   for k, v in ps.items()))
    lines.append(f"  {'channel':40s} {'cv_rmse_base':>13s} {'cv_rmse_ext':>13s}"
                 + (f" {'holdout_base':>13s} {'holdout_ext':>13s}" if "holdout" in rep else ""))
    for c, v in rep["channels"].items():
        row = f"  {c:40s} {_f(v['cv_rmse_base']):>13s} {_f(v['cv_rmse_extended']):>13s}"
        if "holdout" in rep:
            row += f" {_f(v.get('holdout_rmse_base')):>13s} {_f(v.get('holdout_rmse_extended')):>13s}"
        lines.append(row)
    for u in rep["unexplained"]:
        lines.append("  " + u["text"])
    for o in rep["outliers"]:
        lines.append("  " + o["text"])
    return lines


def _f(x) -> str:
    return "-" if x is None else f"{x:.4g}"


def validate_main(argv: Sequence[str] | None = None, prog: str = "marine-fdi validate") -> int:
    """Command line ``marine-fdi validate``: 0 on success, 2 on bad input (message on stderr)."""
    ap = build_parser(prog)

    def error(message):
        raise _ArgError(message)

    ap.error = error  # type: ignore[method-assign]
    try:
        args = ap.parse_args(list(argv) if argv is not None else None)
    except _ArgError as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 2
    except SystemExit as e:  # --help
        return int(e.code or 0)
    say = None if args.quiet else (lambda s: print(s, file=sys.stderr))
    try:
        if args.params is not None and args.params not in list_parameter_sets():
            raise ValueError(f"--params: unknown parameter set {args.params!r}; allowed: "
                             f"{', '.join(list_parameter_sets())}")
        if args.target not in TARGETS:
            raise ValueError(f"--target: unknown target {args.target!r}; allowed: {', '.join(TARGETS)}")
        if args.max_causes < 0:
            raise ValueError(f"--max-causes must be >= 0, got {args.max_causes}")
        if not 0.0 < args.alpha < 1.0:
            raise ValueError(f"--alpha must lie in (0, 1), got {args.alpha}")
        out = Path(args.out)
        if not out.parent.exists():
            raise ValueError(f"--out: directory {str(out.parent)!r} does not exist")
        try:
            ds = load_data_arg(args.data, args.params)
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
                holdout = load_data_arg(args.holdout, args.params or ds.params_name)
            except DatasetError as e:
                raise ValueError(f"--holdout: {e}") from None
        rep, sel, ho = run_validation(ds, holdout=holdout, target=args.target, max_causes=args.max_causes,
                                      alpha=args.alpha, cv_all=not args.screen, progress=say, notes=notes)
    except ValueError as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 2
    out.write_text(json.dumps(rep, indent=1) + "\n")
    if args.markdown:
        title = ds.name + (f" without {args.holdout_engine} (hold-out)" if args.holdout_engine else "")
        Path(args.markdown).write_text(markdown_summary(rep, title) + "\n")
    if args.plots:
        prefix = ds.name + (f"_without_{args.holdout_engine}" if args.holdout_engine else "")
        files = write_plots(sel, args.plots, ho, prefix=prefix)
        rep_files = ", ".join(str(f) for f in files)
        print(f"plots: {rep_files}")
    print("\n".join(_summary_lines(rep)))
    print(f"report: {out}")
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(validate_main())
