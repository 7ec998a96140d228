"""Plots of a validation report (:mod:`.build`, ``marine-fdi validate --plots DIR``): model against measurement
before and after the extension, cross-validated RMSE per channel, and the hold-out engines."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ...plotting import pyplot
from ..fit.fitting import predict_setting
from ..fit.problem import FitProblem
from ..select.selection import Selection

__all__ = ["write_plots"]


def _load_axis(pr: FitProblem) -> tuple[np.ndarray, str]:
    v = pr.ds.values
    if "load_fraction" in v:
        return v["load_fraction"], "load fraction"
    if "power_W" in v:
        return v["power_W"] / pr.ds.rated_power_W, "power / rated power"
    if "engine_speed_rev_s" in v:
        return v["engine_speed_rev_s"] * 60.0, "speed [rpm]"
    return np.arange(pr.n_points, dtype=float), "point"


def write_plots(
    sel: Selection, directory: str | Path, holdout: Mapping[str, Any] | None = None, prefix: str | None = None
) -> list[Path]:
    """Model against measurement per channel (base as it is, calibrated base, fitted extension, cross-validated
    predictions), the valve activity, the cross-validated RMSE per channel, the hold-out if any, and where the
    explanations differ when the selection has them (:mod:`.explain.plots`)."""
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

    def draw(
        ax, x, meas, base, extd, cvp, eng, col, unit, calibrated=None, ext_label="extended (fit on all)", spread=None
    ):
        order = np.argsort(x, kind="stable")
        if eng is None:
            if spread is not None:
                ax.errorbar(
                    x,
                    meas,
                    yerr=spread,
                    fmt="ko",
                    ms=4,
                    capsize=2,
                    elinewidth=0.8,
                    label="measured (± cylinder spread)",
                )
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
        draw(
            ax,
            x,
            pr.Y[:, j],
            sel.raw_pred[:, j],
            ext[:, j] if has else None,
            sel.cv_pred[:, j] if has else None,
            pr.ds.engines,
            c,
            pr.ds.spec(c).unit,
            calib[:, j],
            spread=spreads.get(c),
        )
        ax.set_xlabel(xlabel, fontsize=8)
    if sel.selected.valves:
        ax = axes[len(pr.channels)]
        act = sel.activity()
        w = 0.8 / max(len(act), 1)
        for k, (mid, a) in enumerate(act.items()):
            ax.bar(
                np.asarray(x) + (k - (len(act) - 1) / 2) * w * np.ptp(x) / max(len(x), 1),
                a,
                width=w * np.ptp(x) / max(len(x), 1),
                label=f"{mid}: diverted flow fraction",
                color=f"C{4 + k}",
            )
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
        ho: FitProblem = holdout["_problem"]
        xh, xlh = _load_axis(ho)
        fig, axes = panel_grid(len(ho.channels))
        axes = list(axes)
        for j, (ax, c) in enumerate(zip(axes, ho.channels)):
            draw(
                ax,
                xh,
                ho.Y[:, j],
                holdout["_pred_base"][:, j],
                holdout["_pred_extended"][:, j],
                None,
                ho.ds.engines,
                c,
                ho.ds.spec(c).unit,
                ext_label="fitted engine (fitted without these data)",
            )
            hf = holdout.get("_at_fit_conditions")
            if hf is not None:  # the same at the fitted data's test-bed conditions (what the hold-out did not record)
                o = np.argsort(xh, kind="stable")
                for key, color, lw, alpha, model in (
                    ("_pred_base", "C0", 1.0, 0.7, "base model"),
                    ("_pred_extended", "C3", 1.2, 0.8, "fitted engine"),
                ):
                    label = f"{model}, at the fitted test bed's conditions"
                    ax.plot(xh[o], hf[key][o, j], "-.", color=color, lw=lw, alpha=alpha, label=label)
            ax.set_xlabel(xlh, fontsize=8)
        handles, labels = axes[0].get_legend_handles_labels()
        fig.legend(handles, labels, loc="lower center", ncol=min(4, len(labels)), fontsize=8, frameon=False)
        fig.suptitle(
            f"hold-out {ho.ds.name} {', '.join(ho.ds.engine_ids())}: engine fitted on {pr.ds.name} ({cause})",
            fontsize=10,
        )
        fig.tight_layout(rect=(0, 0.13, 1, 0.95))
        f = d / f"{name}_holdout.png"
        fig.savefig(f, dpi=100)
        plt.close(fig)
        files.append(f)
    if sel.explanations is not None:
        from ..explain.plots import plot_explanations

        files += plot_explanations(sel, d, name)
    return files
