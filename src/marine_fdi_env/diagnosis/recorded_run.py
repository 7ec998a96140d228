"""``marine-fdi diagnose``: run the reference diagnoser on a recorded run and report as JSON.

Input checks: the run file is validated by :func:`marine_fdi_env.runio.load_run`; non-finite
samples are an error naming the sensor and sample, except a *dropout*: a sensor whose readings
are NaN from some sample to the end of the run.  A dropout is passed to the diagnoser, whose
modules reading that sensor then fire, so it comes out as a sensor fault.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..engine.sensors import SENSOR_IDS
from ..runio import RunData
from .modules import AGENTS, MODULE_IDS

__all__ = ["diagnose_run", "check_dropouts", "plot_residuals"]


def check_dropouts(run: RunData, engine: int) -> dict[str, float]:
    """Sensors that drop out (NaN to the end) with their dropout time; ValueError for any other
    non-finite sample (naming the sensor, engine, sample and time)."""
    Y = run.measurements[:, engine, :]
    out = {}
    for j, sid in enumerate(SENSOR_IDS):
        bad = ~np.isfinite(Y[:, j])
        if not bad.any():
            continue
        first = int(np.argmax(bad))
        if np.isinf(Y[first, j]) or not bad[first:].all():
            k = first if np.isinf(Y[first, j]) else first + int(np.argmax(~bad[first:])) - 1
            raise ValueError(
                f"sensor {sid} of engine {engine} has a non-finite value ({Y[k, j]}) at sample {k} "
                f"(t={run.t[k]:.2f} s) that is not a dropout to the end of the run"
            )
        out[sid] = float(run.t[first])
    return out


def diagnose_run(
    run: RunData,
    engine: int = 0,
    exoneration: str = "sure",
    diagnoser: str = "reference",
    cells: str = "sized",
    thresholds: str = "local",
) -> tuple[dict, object]:
    """Diagnose one engine of a run; returns (JSON-ready report, the residual block output).
    ``diagnoser``: ``reference`` (the thesis's scheme) or ``sequential`` (CUSUM tests on the same
    residuals, :mod:`marine_fdi_env.diagnosis.sequential`); ``cells``: the sure cells
    (:mod:`marine_fdi_env.diagnosis.cell_sets`); ``thresholds``: the reading of the observer modules'
    thresholds (:mod:`marine_fdi_env.diagnosis.thresholds`; the reference only)."""
    from .batch import make_diagnoser

    if not 0 <= engine < run.n_engines:
        raise ValueError(f"--engine must lie in [0, {run.n_engines - 1}], got {engine}")
    dropouts = check_dropouts(run, engine)
    extra = {} if thresholds == "local" else {"thresholds": thresholds}
    if extra and diagnoser != "reference":
        raise ValueError(f"--thresholds {thresholds} needs --diagnoser reference (the sequential tests: local only)")
    agent = make_diagnoser(
        diagnoser, run.params_name or "thesis-12v28", 1, run.dt, exoneration=exoneration, cells=cells, **extra
    )
    u = run.truth_of("u", engine)
    block = agent.observe(run.measurements[:, engine, :], u)
    rep = agent.report(0)
    rep.update(
        {
            "params": run.params_name,
            "engine": engine,
            "diagnoser": {
                "name": agent.name,
                "exoneration": exoneration,
                "cells": cells,
                "thresholds": thresholds,
                "max_cardinality": getattr(agent, "max_cardinality", None) or agent.stage.max_cardinality,
            },
            "sensor_dropouts_s": dropouts,
            "true_faults": [
                {k: f[k] for k in ("id", "class", "kind", "onset_s", "magnitude", "unit", "first_active_s")}
                for f in run.true_faults(engine)
            ],
        }
    )
    truth = frozenset(f["id"] for f in rep["true_faults"] if f["first_active_s"] is not None)
    rep["true_set_in_minimal_diagnoses"] = (sorted(truth) in rep["final_minimal_diagnoses"]) if truth else None
    return rep, block


SUBSYSTEMS = {
    1: "Σ1 fuel pump",
    2: "Σ2 engine block (cylinder)",
    3: "Σ3 exhaust receiver and turbine",
    4: "Σ4 air intake (compressor, intercooler)",
}
# residuals are in the checked sensor's SI unit; plotted in a unit of their size: (factor, unit)
_PLOT_UNITS = {"Pa": (1e-3, "kPa"), "kg": (1e6, "mg"), "N m": (1e-3, "kN m"), "K": (1.0, "K")}


def plot_residuals(run: RunData, block, out_dir: Path, report: dict) -> list[Path]:
    """One figure per subsystem Σ1-Σ4: each monitoring module's residual (its checked sensor
    minus the model's estimate, in the sensor's unit) against its adaptive threshold, with the
    module's detection and the labelled fault onsets (figs. 6.1-6.34).  Files
    ``subsystem_<l>.png``; the thesis calls the four groups of modules "agents" M1-M4, which are
    not the benchmark's agents."""
    from ..engine.sensors import SENSORS
    from ..plotting import pyplot
    from .modules import MODULES

    plt = pyplot()
    from matplotlib.transforms import blended_transform_factory  # after pyplot(): a missing matplotlib is named

    sensor = {s.id: s for s in SENSORS}
    spec = {m.id: m for m in MODULES}
    out_dir.mkdir(parents=True, exist_ok=True)
    t = run.t
    R = block.residuals[0]
    THR = block.thresholds[0]
    onsets = [(f["id"], f["onset_s"]) for f in report["true_faults"] if f["onset_s"] <= t[-1]]
    paths = []
    for sub, modules in AGENTS.items():
        fig, axes = plt.subplots(len(modules), 1, figsize=(10, 1.95 * len(modules) + 0.7), sharex=True, squeeze=False)
        for ax, m in zip(axes[:, 0], modules):
            j = MODULE_IDS.index(m)
            sen = sensor[spec[m].checked_sensor]
            k, unit = _PLOT_UNITS.get(sen.unit, (1.0, sen.unit))
            r = np.where(np.isfinite(R[:, j]), R[:, j], np.nan) * k
            ax.plot(t, r, lw=0.5, color="C0", label="residual")
            ax.plot(t, THR[:, j] * k, lw=1.0, color="C3", label="± adaptive threshold")
            ax.plot(t, -THR[:, j] * k, lw=1.0, color="C3")
            td = report["module_detection_times_s"][m]
            if td is not None:
                ax.axvline(td, color="k", ls="--", lw=0.9, label="detection by the module")
            lo, hi = ax.get_ylim()
            ax.set_ylim(lo, hi + 0.25 * (hi - lo))  # headroom for the onset labels
            tr = blended_transform_factory(ax.transData, ax.transAxes)
            for fid, on in onsets:
                ax.axvline(on, color="C2", ls=":", lw=1.2, label="fault onset")
                ax.text(
                    on,
                    0.96,
                    f" {fid} onset {on:g} s",
                    transform=tr,
                    color="C2",
                    fontsize=7,
                    va="top",
                    ha="left",
                    bbox={"facecolor": "white", "edgecolor": "none", "alpha": 0.85, "pad": 1},
                )
            det = f"detected at {td:.2f} s" if td is not None else "no detection"
            ax.set_title(
                f"module {m} ({SUBSYSTEMS[sub].split(' (')[0]}): {sen.id} {sen.description} - {det}",
                fontsize=8.5,
                loc="left",
            )
            ax.set_ylabel(f"residual [{unit}]", fontsize=8)
            ax.tick_params(labelsize=7)
        axes[-1, 0].set_xlabel("time [s]")
        handles, labels = [], []
        for ax in axes[:, 0]:
            for h, lab in zip(*ax.get_legend_handles_labels()):
                if lab not in labels:
                    handles.append(h)
                    labels.append(lab)
        fig.suptitle(
            f"{SUBSYSTEMS[sub]}: residuals of its monitoring modules (sensor - model) and their adaptive thresholds",
            fontsize=10,
        )
        fig.legend(
            handles,
            labels,
            loc="upper center",
            ncol=len(labels),
            fontsize=8,
            frameon=False,
            bbox_to_anchor=(0.5, 1 - 0.32 / fig.get_figheight()),
        )
        fig.tight_layout(rect=(0, 0, 1, 1 - 0.45 / fig.get_figheight()))
        path = out_dir / f"subsystem_{sub}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths
