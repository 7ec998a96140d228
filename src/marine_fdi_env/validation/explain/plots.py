"""The figure of the explanations: each compared explanation's fitted engine over load on the channels that would
decide between them (:mod:`.deciding`), with the measured points."""

from __future__ import annotations

from pathlib import Path

from ...plotting import pyplot
from .deciding import LOADS, deciding_measurements, readings_over_load
from .summary import compared, explanation_name

__all__ = ["plot_explanations"]


def plot_explanations(sel, directory: str | Path, name: str, channels: int = 3) -> list[Path]:
    """``NAME_explanations.png``: the deciding channels (at most ``channels``) over load, each at the ambient
    conditions of its deciding point, one line per compared explanation (the set's best two, or its only member and
    the closest structure outside it, dashed), the measured points and each deciding point; nothing when fewer than
    two explanations."""
    es = sel.explanations
    if es is None:
        return []
    cmp_ = compared(es)
    if len(cmp_) < 2:
        return []
    pr = sel.problem
    labels = [f"#{i + 1} {explanation_name(pr, e)}" for i, e in enumerate(cmp_)]
    dec = deciding_measurements(pr, list(zip(labels, (e.fit for e in cmp_))), per_pair=channels)
    ms = dec[0]["measurements"]
    if not ms:
        return []
    plt = pyplot()
    load = pr.load_axis()
    fig, axes = plt.subplots(1, len(ms), figsize=(4.8 * len(ms), 4.6), squeeze=False)
    for ax, m in zip(axes.flat, ms):
        j = pr.channels.index(m["channel"])
        for k, e in enumerate(cmp_):  # at the ambient conditions of this panel's deciding point
            y = readings_over_load(pr, e.fit, LOADS, m["p_amb_Pa"], m["T_amb_K"])
            ax.plot(
                100 * LOADS,
                y[:, j],
                "-" if e.in_set else "--",
                color=f"C{k}",
                label=labels[k] + ("" if e.in_set else " (outside the set)"),
            )
        ok = pr.measured_mask[:, j]
        ax.errorbar(
            100 * load[ok],
            pr.Y[ok, j],
            yerr=pr.tolerance_cells[ok, j],
            fmt="o",
            color="k",
            ms=4,
            capsize=2,
            label="measured (± tolerance)",
        )
        ax.plot([100 * m["load"]] * 2, [m["a_value"], m["b_value"]], "x-", color="C3", lw=2, label="the deciding point")
        ax.set_xlabel("load [%]")
        ax.set_ylabel(f"[{m['unit']}]")
        ax.set_title(
            f"{m['channel']}: {m['n_tolerances']:.1f} tolerances apart at {100 * m['load']:.0f} %\n"
            f"(intake {m['T_amb_K'] - 273.15:.0f} °C, {m['p_amb_Pa'] / 100:.0f} hPa)",
            fontsize=8,
        )
        ax.grid(alpha=0.3)
    handles, names = axes.flat[0].get_legend_handles_labels()
    fig.legend(handles, names, loc="lower center", ncol=2, fontsize=7, frameon=False)
    fig.suptitle(f"{name}: where the explanations' fitted engines differ most", fontsize=9)
    fig.tight_layout(rect=(0, 0.16, 1, 0.96))
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    out = d / f"{name}_explanations.png"
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return [out]
