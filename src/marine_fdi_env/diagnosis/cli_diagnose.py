"""``marine-fdi diagnose``: run the reference diagnoser on a recorded run and report as JSON.

Input checks: the run file is validated by :func:`marine_fdi_env.runio.load_run`; non-finite
samples are an error naming the sensor and sample, except a *dropout*: a sensor whose readings
are NaN from some sample to the end of the run.  A dropout is passed to the diagnoser, whose
modules reading that sensor then fire, so it comes out as a sensor fault.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..runio import RunData, load_run
from ..sensors import SENSOR_IDS
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
                f"(t={run.t[k]:.2f} s) that is not a dropout to the end of the run")
        out[sid] = float(run.t[first])
    return out


def diagnose_run(run: RunData, engine: int = 0, exoneration: str = "sure",
                 diagnoser: str = "reference") -> tuple[dict, object]:
    """Diagnose one engine of a run; returns (JSON-ready report, the residual block output).
    ``diagnoser``: ``reference`` (the thesis's scheme) or ``sequential`` (CUSUM tests on the same
    residuals, :mod:`marine_fdi_env.diagnosis.sequential`)."""
    from .batch import make_diagnoser

    if not 0 <= engine < run.n_engines:
        raise ValueError(f"--engine must lie in [0, {run.n_engines - 1}], got {engine}")
    dropouts = check_dropouts(run, engine)
    agent = make_diagnoser(diagnoser, run.params_name or "thesis-12v28", 1, run.dt, exoneration=exoneration)
    u = run.truth_of("u", engine)
    block = agent.observe(run.measurements[:, engine, :], u)
    rep = agent.report(0)
    rep.update({
        "params": run.params_name,
        "engine": engine,
        "diagnoser": {"name": agent.name, "exoneration": exoneration,
                      "max_cardinality": getattr(agent, "max_cardinality", None) or agent.stage.max_cardinality},
        "sensor_dropouts_s": dropouts,
        "true_faults": [{k: f[k] for k in ("id", "class", "kind", "onset_s", "magnitude", "unit", "first_active_s")}
                        for f in run.true_faults(engine)],
    })
    truth = frozenset(f["id"] for f in rep["true_faults"] if f["first_active_s"] is not None)
    rep["true_set_in_minimal_diagnoses"] = (sorted(truth) in rep["final_minimal_diagnoses"]) if truth else None
    return rep, block


def plot_residuals(run: RunData, block, out_dir: Path, report: dict) -> list[Path]:
    """One figure per monitoring agent: |residual| against its adaptive threshold (figs. 6.1-6.34)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir.mkdir(parents=True, exist_ok=True)
    t = run.t
    R = block.residuals[0]
    THR = block.thresholds[0]
    onsets = [f["onset_s"] for f in report["true_faults"]]
    paths = []
    for agent_no, modules in AGENTS.items():
        fig, axes = plt.subplots(len(modules), 1, figsize=(9, 1.9 * len(modules)), sharex=True, squeeze=False)
        for ax, m in zip(axes[:, 0], modules):
            j = MODULE_IDS.index(m)
            r = np.where(np.isfinite(R[:, j]), R[:, j], np.nan)
            ax.plot(t, r, lw=0.6, color="C0", label="residual")
            ax.plot(t, THR[:, j], lw=0.9, color="C3", label="threshold")
            ax.plot(t, -THR[:, j], lw=0.9, color="C3")
            td = report["module_detection_times_s"][m]
            if td is not None:
                ax.axvline(td, color="k", ls="--", lw=0.8, label=f"detection {td:.2f} s")
            for on in onsets:
                ax.axvline(on, color="C2", ls=":", lw=0.8)
            ax.set_ylabel(m)
            ax.legend(loc="upper left", fontsize=7, ncol=3)
        axes[-1, 0].set_xlabel("time [s]")
        fig.suptitle(f"agent M{agent_no}: residuals and adaptive thresholds (dotted: fault onsets)")
        fig.tight_layout()
        path = out_dir / f"agent_{agent_no}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths


def cmd_diagnose(args) -> int:
    import json

    run = load_run(args.run, allow_nonfinite=True)
    report, block = diagnose_run(run, engine=args.engine, exoneration=args.exoneration,
                                 diagnoser=getattr(args, "diagnoser", "reference"))
    if args.plots:
        report["plots"] = [str(p) for p in plot_residuals(run, block, Path(args.plots), report)]

    def clean(o):
        if isinstance(o, dict):
            return {k: clean(v) for k, v in o.items()}
        if isinstance(o, (list, tuple)):
            return [clean(v) for v in o]
        if isinstance(o, float) and not math.isfinite(o):
            return None
        return o

    text = json.dumps(clean(report), indent=2)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(text + "\n")
    first = report["first_detection_time_s"]
    print(f"detected: {report['detected']}" + (f" at {first:.2f} s" if first is not None else ""))
    print("minimal diagnoses: " + (", ".join("{" + ", ".join(d) + "}" for d in report["final_minimal_diagnoses"])
                                   or "none"))
    print(f"wrote {args.out}")
    return 0
