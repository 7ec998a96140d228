"""Measured causes of the differences between the thesis's chapter 6 and the reference: what each
module's threshold is made of, how large each fault's effect is against it, and when it crosses.

    python -m studies.diagnosis.reproduction_causes budget      # the observers' and M4.5's threshold terms
    python -m studies.diagnosis.reproduction_causes margins     # sensor offsets: effect against threshold
    python -m studies.diagnosis.reproduction_causes timelines   # |r|/threshold over time, per module
    python -m studies.diagnosis.reproduction_causes one-noisy-sensor   # only the checked sensor noisy

Each writes ``docs/data/reproduction_causes/WHAT.json`` (``timelines`` also one figure per case under
``docs/figures/reproduction/``), which docs/reproduction.md cites.  Seeds 5,000,000 onwards (disjoint
from every other set, :mod:`.reproduction`).

* ``budget``: at a constant fuel setting (1.0 and 0.5), the steady threshold of M3.1 and M4.1 and of
  the algebraic M4.5 split into its terms, for every reading of the observers' thresholds: the
  checked sensor's noise bound d̄; for the observers, the output injection's accumulated noise
  (the exact recursion's gain g_d d̄ with g_d = E L_d / (1 - E (1 - L_d)), or table 6.1's ρ_d d̄/ξ)
  and the forcing's uncertainty per input (g_H · 1.05 · term, g_H = q / (1 - E (1 - L_d)), the
  recursion's steady gain of H̄; the terms of :func:`~marine_fdi_env.diagnosis.residuals.model_terms`
  at the noise-free state; ``forcing_uncertainty_relative``: each term over the forcing itself); for
  M4.5, 1.05 x each input's inclusion term.  Checked against the kernel's own threshold at the same
  point (``kernel_threshold``).
* ``margins``: every sensor offset of table 6.3 against each module that reads the sensor: the
  noise-free residual's largest |r|/threshold over the 30 s after the onset (``effect_ratio``; the
  threshold of the same run with noise) and, over ``--seeds`` noisy runs, the share of runs the
  module fired in and the spread (standard deviation) of its firing time: the KPI 6.5.1 pairs
  explained by the size of the offset against the threshold.
* ``timelines``: per case (a thesis example or a single fault at its table size, constant fuel
  setting 1.0) and reading, the median over ``--seeds`` runs of each module's largest |r|/threshold
  per second, and the first time it exceeds 1: when and why modules fire in the order they do.
* ``one-noisy-sensor``: a module with every sensor noise-free but its checked one, and the diagnoser
  told so (the other noise bounds 0): its threshold is then its own sensor's noise bound (plus, for an
  observer, the injected noise of its output injection), as the thesis's would be if its modules'
  other inputs carried no noise; the same runs with every sensor noisy beside it.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from marine_fdi_env.diagnosis.agent import ReferenceDiagnoser
from marine_fdi_env.diagnosis.modules import MODULE_IDS, MODULES
from marine_fdi_env.diagnosis.residuals import (
    MODEL_MARGIN,
    MODEL_TERM_INPUTS,
    SAFETY,
    model_terms,
    observer_steady_gains,
)
from marine_fdi_env.diagnosis.thresholds import TABLE_6_1, THRESHOLD_READINGS, threshold_array
from marine_fdi_env.engine.constants import model_constants
from marine_fdi_env.engine.faults import PROCESS_FAULT_DEFAULTS, FaultSpec
from marine_fdi_env.engine.params import load_params
from marine_fdi_env.engine.sensors import NOISE_BOUNDS, SENSORS, sensor_index
from marine_fdi_env.engine.simulator import Simulator
from marine_fdi_env.scenarios import get_scenario

__all__ = ["threshold_budget", "offset_margins", "timelines", "main"]

PARAMS = "thesis-12v28"
SEED0 = 5_000_000
OUT = Path("docs/data/reproduction_causes")
FIGURES = Path("docs/figures/reproduction")
SENSOR_ONSET_S = 30.0
DT = 0.01


def _steady_state(u0: float, seconds: float = 120.0) -> np.ndarray:
    """The noise-free readings (19,) of the last sample of a run at constant fuel setting u0."""
    sim = Simulator(PARAMS, 1, seeds=[SEED0], profiles=f"constant:u0={u0}", noise_scale=0.0)
    return sim.run(seconds).measurements[-1, 0]


def _kernel_threshold(u0: float, reading: str, module: str) -> float:
    """The kernel's own threshold of ``module`` at the noise-free steady state of u0 (median of the last 20 s)."""
    sim = Simulator(PARAMS, 1, seeds=[SEED0], profiles=f"constant:u0={u0}", noise_scale=0.0)
    res = sim.run(120.0)
    agent = ReferenceDiagnoser(PARAMS, 1, dt=sim.dt, exoneration="none", thresholds=reading)
    out = agent.observe(res.measurements[:, 0, :], res.truth_of("u")[:, 0])
    return float(np.median(out.thresholds[0, -2000:, MODULE_IDS.index(module)]))


def threshold_budget(loads=(1.0, 0.5)) -> dict:
    """The terms of the steady thresholds of M3.1, M4.1 and M4.5 per reading and load (module docstring)."""
    c = model_constants(load_params(PARAMS))
    gains = observer_steady_gains(c, DT)
    chain = [sensor_index(s) for s in ("S1.1", "S3.1", "S4.1", "S4.3", "S3.3", "S3.5")]
    out = {}
    for u0 in loads:
        y = _steady_state(u0)
        terms = model_terms(c, y[None])[0]  # (3 outputs, 6 inputs)
        per_load = {}
        for obs, module, q, sensor in (("M3", "M3.1", 0, "S3.1"), ("M4", "M4.1", 1, "S4.1")):
            g_d, g_h = gains[obs]
            d = float(NOISE_BOUNDS[sensor_index(sensor)])
            readings = {}
            for reading in THRESHOLD_READINGS:
                a = threshold_array(reading)[1 if obs == "M3" else 2]
                if a[8]:  # closed form: the steady part of eq. 5.10-5.12
                    k = TABLE_6_1[obs]
                    K = (k.rho_d * d + k.rho * a[14]) / k.xi_per_s
                    parts = {
                        "noise_bound": d,
                        "injected_noise": k.rho_d * d / k.xi_per_s,
                        "forcing_all_inputs": k.rho * a[14] / k.xi_per_s,
                        "lipschitz_integral": k.rho * a[13] * K / k.xi_per_s,
                    }
                else:
                    parts = {"noise_bound": d, "injected_noise": g_d * d}
                    for i, name in enumerate(MODEL_TERM_INPUTS[:5]):
                        parts[f"forcing_{name}"] = g_h * SAFETY * a[i] * terms[q, i]
                    if a[7]:
                        parts["forcing_global_interconnection"] = g_h * SAFETY * a[7]
                total = sum(parts.values())
                readings[reading] = {
                    "terms": {k: float(v) for k, v in parts.items()},
                    "total": float(total),
                    "in_noise_bounds": float(total / d),
                    "kernel_threshold": _kernel_threshold(u0, reading, module),
                }
            # at a steady state x' = 0: the forcing equals x/τ (h3 = x3/τ_pd, h4 = x4/τ_TC)
            forcing = float(y[sensor_index(sensor)] / (c.tau_pd_s if obs == "M3" else c.tau_TC_s))
            per_load[module] = {
                "unit": SENSORS[sensor_index(sensor)].unit,
                "forcing_per_s": forcing,
                "forcing_uncertainty_relative": {
                    name: float(terms[q, i] / forcing) for i, name in enumerate(MODEL_TERM_INPUTS[:5])
                },
                "readings": readings,
            }
        d = float(NOISE_BOUNDS[sensor_index("S4.5")])
        parts = {"noise_bound": d}
        for i, name in enumerate(MODEL_TERM_INPUTS):
            parts[f"inclusion_{name}"] = SAFETY * terms[2, i]
        total = sum(parts.values())
        per_load["M4.5"] = {
            "unit": "K",
            "readings": {
                "all": {
                    "terms": {k: float(v) for k, v in parts.items()},
                    "total": float(total),
                    "in_noise_bounds": float(total / d),
                    "kernel_threshold": _kernel_threshold(u0, "local", "M4.5"),
                }
            },
        }
        per_load["state"] = dict(zip(MODEL_TERM_INPUTS, (float(v) for v in y[chain])))
        out[f"u0={u0:g}"] = per_load
    return {"model_margin": MODEL_MARGIN, "safety": SAFETY, "loads": out}


def _module_ratios(schedules, seeds, profile, duration_s, reading, noise_scale=1.0):
    """Per engine, second and module the largest |r|/threshold (N, seconds, 19), and the first
    violation times (N, 19) [s, NaN: never]."""
    n = len(seeds)
    sim = Simulator(PARAMS, n, seeds=seeds, faults=schedules, profiles=profile, noise_scale=noise_scale)
    agent = ReferenceDiagnoser(PARAMS, n, dt=sim.dt, exoneration="none", thresholds=reading)
    agent.observe(sim.y[:, None, :], sim.u[:, None])
    per = int(round(1.0 / sim.dt))
    secs = int(round(duration_s))
    ratio = np.zeros((n, secs, len(MODULE_IDS)))
    for s in range(secs):
        blk = sim.advance(per)
        out = agent.observe(blk.measurements, blk.u)
        with np.errstate(invalid="ignore", divide="ignore"):
            r = np.abs(out.residuals) / out.thresholds
        ratio[:, s, :] = np.nanmax(np.where(np.isfinite(r), r, 1e3), axis=1)
    return ratio, agent.first_violation.copy()


def offset_margins(n_seeds: int = 20) -> dict:
    """Every table 6.3 offset against each module reading its sensor (module docstring)."""
    out = {}
    for j, s in enumerate(SENSORS):
        mods = [m.id for m in MODULES if s.id in m.all_sensors]
        spec = [FaultSpec(s.id, SENSOR_ONSET_S, magnitude=s.fault_magnitude, kind="offset")]
        seeds = [SEED0 + 1000 * j + k for k in range(n_seeds)]
        # the noise-free run's residual against the threshold of the same run with noise
        res0 = Simulator(PARAMS, 1, seeds=[seeds[0]], faults=[spec], profiles="constant", noise_scale=0.0).run(60.0)
        noisy = Simulator(PARAMS, 1, seeds=[seeds[0]], faults=[spec], profiles="constant").run(60.0)
        a0 = ReferenceDiagnoser(PARAMS, 1, dt=DT, exoneration="none")
        a1 = ReferenceDiagnoser(PARAMS, 1, dt=DT, exoneration="none")
        r0 = a0.observe(res0.measurements[:, 0, :], res0.truth_of("u")[:, 0]).residuals[0]
        thr = a1.observe(noisy.measurements[:, 0, :], noisy.truth_of("u")[:, 0]).thresholds[0]
        k0, k1 = int(SENSOR_ONSET_S / DT), int((SENSOR_ONSET_S + 30.0) / DT)
        _, first = _module_ratios([spec] * n_seeds, seeds, "constant", 60.0, "local")
        per = {}
        for m in mods:
            i = MODULE_IDS.index(m)
            t = first[:, i] - SENSOR_ONSET_S
            t = t[np.isfinite(t) & (t >= 0)]
            per[m] = {
                "effect_ratio": float(np.max(np.abs(r0[k0:k1, i]) / thr[k0:k1, i])),
                "effect_at_onset": float(abs(r0[k0 + 1, i])),
                "threshold_at_onset": float(thr[k0 + 1, i]),
                "fired_runs": int(len(t)),
                "runs": n_seeds,
                "median_delay_s": float(np.median(t)) if len(t) else None,
                "spread_s": float(np.std(t)) if len(t) > 1 else None,
                "own": m == next(x.id for x in MODULES if x.checked_sensor == s.id),
            }
        out[s.id] = {"magnitude": s.fault_magnitude, "unit": s.unit, "modules": per}
    return {"seeds": n_seeds, "first_seed": SEED0, "onset_s": SENSOR_ONSET_S, "window_s": 30.0, "offsets": out}


CASES = {
    "thesis-6.4.1": None,
    "thesis-6.4.2": None,
    "thesis-6.4.3": None,
    "thesis-6.4.4": None,
    "intercooler_blockage": "intercooler_blockage",
    "compressor_seal_leak": "compressor_seal_leak",
    "turbine_seal_leak": "turbine_seal_leak",
}


def _case(name: str):
    if name.startswith("thesis-"):
        sc = get_scenario(name)
        return sc.fault_specs(), sc.profile, sc.duration_s
    d = PROCESS_FAULT_DEFAULTS[name]
    return [FaultSpec(name, d.onset_s)], "constant:u0=1.0", 300.0


def timelines(n_seeds: int = 20, readings=("local", "thesis-table-6.1-m4"), figures: Path | None = FIGURES) -> dict:
    """Per case and reading the median |r|/threshold per second and module, and the first crossings."""
    out = {}
    for c, name in enumerate(CASES):
        specs, profile, duration = _case(name)
        seeds = [SEED0 + 200_000 + 1000 * c + k for k in range(n_seeds)]
        per = {}
        for reading in readings:
            ratio, first = _module_ratios([specs] * n_seeds, seeds, profile, duration, reading)
            med = np.median(ratio, axis=0)  # (seconds, 19)
            fired = {
                m: {
                    "runs": int(np.isfinite(first[:, i]).sum()),
                    "median_first_s": float(np.nanmedian(first[:, i])) if np.isfinite(first[:, i]).any() else None,
                }
                for i, m in enumerate(MODULE_IDS)
            }
            per[reading] = {
                "median_ratio_per_s": {m: [round(float(x), 4) for x in med[:, i]] for i, m in enumerate(MODULE_IDS)},
                "fired": fired,
            }
        out[name] = {"faults": [f.to_dict() for f in specs], "profile": profile, "seeds": n_seeds, "readings": per}
        if figures is not None:
            _plot_timeline(name, out[name], figures)
    return out


def _plot_timeline(name: str, case: dict, folder: Path) -> None:
    from marine_fdi_env.plotting import pyplot

    plt = pyplot()
    readings = list(case["readings"])
    fig, axes = plt.subplots(1, len(readings), figsize=(6 * len(readings), 4), sharey=True, squeeze=False)
    for ax, reading in zip(axes[0], readings):
        data = case["readings"][reading]
        for m, series in data["median_ratio_per_s"].items():
            if data["fired"][m]["runs"] * 2 >= case["seeds"]:  # the modules that fire in half the runs or more
                ax.plot(np.arange(1, len(series) + 1), series, label=m, lw=1)
        ax.axhline(1.0, color="k", lw=0.8, ls="--")
        ax.set_yscale("log")
        ax.set_title(f"{name}: {reading}")
        ax.set_xlabel("time [s]")
        if ax.get_legend_handles_labels()[0]:
            ax.legend(fontsize=7, ncol=2, loc="lower right")
    axes[0][0].set_ylabel("median over seeds of max |r|/threshold per second")
    folder.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(folder / f"{name}.png", dpi=90)
    plt.close(fig)


# (case, fault spec, the module and its checked sensor, the readings): what each module does when only
# its checked sensor is noisy
ONE_NOISY_CASES = (
    ("intercooler_blockage", "intercooler_blockage@30", "M4.5", "S4.5", ("local",)),
    ("turbine_seal_leak", "turbine_seal_leak@15", "M3.1", "S3.1", ("local",)),
    ("compressor_seal_leak", "compressor_seal_leak@30", "M4.1", "S4.1", ("local", "thesis-table-6.1-m4")),
    ("S3.1 offset", "S3.1@30", "M3.1", "S3.1", ("local",)),
    ("fault-free", None, "M3.1", "S3.1", ("local",)),
    ("fault-free", None, "M4.1", "S4.1", ("local", "thesis-table-6.1-m4")),
    ("fault-free", None, "M4.5", "S4.5", ("local",)),
)


def one_noisy_sensor(n_seeds: int = 20) -> dict:
    """Each case of :data:`ONE_NOISY_CASES` with every sensor noise-free but the module's checked one
    (and the diagnoser told so: the other sensors' noise bounds 0), constant fuel setting 1.0, 300 s:
    the module's firing time after the onset over ``n_seeds`` runs, and against the same runs with every
    sensor noisy.  What the thesis's thresholds would see if its modules' other inputs carried no noise."""
    from marine_fdi_env.engine.faults import parse_fault_spec

    out = []
    for c, (name, spec, module, sensor, readings) in enumerate(ONE_NOISY_CASES):
        seeds = [SEED0 + 400_000 + 1000 * c + k for k in range(n_seeds)]
        faults = [[parse_fault_spec(spec)] if spec else [] for _ in seeds]
        onset = parse_fault_spec(spec).onset_s if spec else 0.0
        noisy = Simulator(PARAMS, n_seeds, seeds=seeds, faults=faults, profiles="constant:u0=1.0").run(300.0)
        clean = Simulator(PARAMS, n_seeds, seeds=seeds, faults=faults, profiles="constant:u0=1.0", noise_scale=0.0).run(
            300.0
        )
        k = sensor_index(sensor)
        y = clean.measurements.copy()
        y[:, :, k] = noisy.measurements[:, :, k]
        bounds = np.zeros_like(NOISE_BOUNDS)
        bounds[k] = NOISE_BOUNDS[k]
        i = MODULE_IDS.index(module)
        per = {}
        for reading in readings:
            row = {}
            for label, (Y, nb) in {
                "all sensors noisy": (noisy.measurements, None),
                "only the checked sensor noisy": (y, bounds),
            }.items():
                agent = ReferenceDiagnoser(
                    PARAMS, n_seeds, dt=DT, exoneration="none", thresholds=reading, noise_bounds=nb
                )
                agent.observe(np.ascontiguousarray(Y.transpose(1, 0, 2)), np.ascontiguousarray(noisy.truth_of("u").T))
                t = agent.first_violation[:, i] - onset
                fired = t[np.isfinite(t)]
                row[label] = {
                    "fired": int((fired >= 0).sum()),
                    "before_onset": int((fired < 0).sum()),
                    "runs": n_seeds,
                    "median_delay_s": float(np.median(fired[fired >= 0])) if (fired >= 0).any() else None,
                    "spread_s": float(np.std(fired[fired >= 0])) if (fired >= 0).sum() > 1 else None,
                }
            per[reading] = row
        out.append({"case": name, "fault": spec, "module": module, "checked_sensor": sensor, "readings": per})
    return {"seeds": n_seeds, "profile": "constant:u0=1.0", "duration_s": 300.0, "cases": out}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m studies.diagnosis.reproduction_causes", description=__doc__.splitlines()[0]
    )
    ap.add_argument("what", choices=("budget", "margins", "timelines", "one-noisy-sensor"))
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--out-dir", type=Path, default=OUT)
    args = ap.parse_args(argv)
    if args.seeds < 2:
        ap.error("--seeds must be >= 2")
    if args.what == "budget":
        data = threshold_budget()
    elif args.what == "margins":
        data = offset_margins(args.seeds)
    elif args.what == "one-noisy-sensor":
        data = one_noisy_sensor(args.seeds)
    else:
        data = timelines(args.seeds)
    data["command"] = f"python -m studies.diagnosis.reproduction_causes {args.what}" + (
        "" if args.what == "budget" else f" --seeds {args.seeds}"
    )
    args.out_dir.mkdir(parents=True, exist_ok=True)
    path = args.out_dir / f"{args.what}.json"
    path.write_text(json.dumps(data, indent=1) + "\n")
    print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
