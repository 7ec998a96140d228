"""Synthetic "measured" data from the engine model with hidden effects, and the open-world study.

:func:`synthesize` draws random operating points (load fractions uniform in a range, sorted), runs the
one engine model (:mod:`marine_fdi_env.engine.operating_point`) with the hidden mechanisms at those powers (the
speed from the propeller law, or from the combinator line when ``cpp_load`` is hidden) and adds
measurement noise.  What makes the data *open world* is optional:

* ``perturb`` (model error): the true engine's efficiencies, areas and heat fractions differ from the
  parameter set by a relative N(0, perturb²) each (clipped at ±2 perturb), and so does one parameter the
  pipeline's nuisance does not cover (the nominal scavenging slip s_sl_nom);
* ``noise_model="reading"``: noise proportional to each reading instead of to the channel's typical value,
  while the pipeline keeps its own tolerances (1 %, 5 K), which then do not equal the noise;
* several hidden mechanisms at once;
* ``effects``: effects outside the library (:data:`EFFECT_KINDS`) on one channel: a bump around a load, a
  step above a load, a bend of the trend, of 4-7 of the pipeline's tolerances (20-35 K; 4-7 % of the
  channel's mean reading); :func:`effect_region` gives the load range where they act.

Load points are stratified (one per equal slice of the load range, uniform inside it), as a test programme
covers its range.  Valve-type mechanisms open at the points above (waste gate) or below (bypass) a drawn
load, with openings growing away from it.  The CSV follows the measured-data conventions of ``shared/data`` with the
protocol's channels (:data:`DEFAULT_COLUMNS`); the sidecar names the parameter set, the seed and the
noise but not the hidden effects.  The truth goes to a separate file only when asked for (``--truth``).

The study (``python -m marine_fdi_env.validation.synthesize study``) runs conditions (a) closed world,
(b) model error, (c) reading-proportional noise, (d) two mechanisms, (e) out-of-library effects, each
with its negative control (the same data without the hidden effect), and reports identification rates.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ..engine.operating_point import MODE_P, solve_points, speed_of_power
from ..engine.params import EngineParams, list_parameter_sets, load_params
from .columns import QUANTITIES, column_problem, lookup_column
from .dataset import write_dataset
from .mechanisms import (MECHANISM_IDS, SensorCalibration, ValveMechanism, equivalents, get_mechanism,
                         parse_mechanism_spec, sensor_reference)
from .problem import BASE_SETTING, Setting, _quantity
from .evidence import BESIDE_VALVE_DEFAULT
from .columns import ModelContext

__all__ = ["DEFAULT_COLUMNS", "SET_POINT_COLUMNS", "EFFECT_KINDS", "PERTURBED_FIELDS", "Synthesis", "synthesize",
           "write_synthesis", "synthesize_main", "trial", "trial_draw", "trial_data", "study", "study_main",
           "CONDITIONS", "effect_region"]

DEFAULT_COLUMNS = (
    "load_fraction", "power_kW", "speed_rpm", "fuel_flow_kg_per_h", "turbocharger_speed_rpm",
    "charge_air_pressure_bar_gauge", "compressor_outlet_temperature_C", "charge_air_cooler_outlet_temperature_C",
    "turbine_inlet_pressure_bar_gauge", "turbine_inlet_temperature_C", "turbine_outlet_temperature_C",
    "cylinder_exhaust_temperature_mean_C", "max_cylinder_pressure_bar_gauge",
)
SET_POINT_COLUMNS = ("load_fraction", "power_kW", "power_W", "power_MW", "load_percent")
LOAD_RANGE = (0.25, 1.1)
# the true engine's model error (condition b): efficiencies, areas and heat fractions, and the scavenging
# slip, which the pipeline's nuisance does not cover
PERTURBED_FIELDS = (("A_eff_m2",), ("a_eta_per_Pa2", "b_eta_per_Pa", "c_eta", "a_turbo", "b_turbo_per_Pa",
                                   "c_turbo_per_Pa2"), ("eta_com",), ("eta_comb",), ("X_cv_nom",), ("X_ct_nom",),
                    ("s_sl_nom",))
EFFECT_KINDS = ("bump", "step", "bend")
FAMILIES = {
    "pressure": ("charge_air_pressure_bar_gauge", "turbine_inlet_pressure_bar_gauge", "max_cylinder_pressure_bar_gauge"),
    "temperature": ("compressor_outlet_temperature_C", "turbine_inlet_temperature_C", "turbine_outlet_temperature_C",
                    "cylinder_exhaust_temperature_mean_C", "charge_air_cooler_outlet_temperature_C"),
    "flow": ("fuel_flow_kg_per_h",),
    "speed": ("turbocharger_speed_rpm",),
}


@dataclass
class Synthesis:
    """Generated data: columns (column units), sidecar, and the hidden truth (not in the sidecar)."""

    columns: dict[str, np.ndarray]
    clean: dict[str, np.ndarray]
    meta: dict[str, Any]
    truth: list[dict[str, Any]]
    engines: list[str] | None = None
    settings: dict[str, Any] = field(default_factory=dict)
    effects: list[dict[str, Any]] = field(default_factory=list)
    activity: dict[str, list[float]] = field(default_factory=dict)

    def write(self, path: str | Path, truth_path: str | Path | None = None) -> Path:
        return write_synthesis(self, path, truth_path)

    def noise_sd(self, column: str) -> np.ndarray:
        """Standard deviation of the noise drawn on each reading of ``column`` (column units; zero on set points),
        as :func:`synthesize` drew it."""
        clean = np.asarray(self.clean[column], dtype=float)
        if column in SET_POINT_COLUMNS:
            return np.zeros_like(clean)
        noise = float(self.settings.get("noise", 0.0))
        if self.settings.get("noise_model", "typical") == "typical":
            return np.full_like(clean, noise * float(np.mean(np.abs(clean))))
        return noise * np.abs(clean)


def _check_columns(columns: Sequence[str]) -> None:
    for c in columns:
        msg = column_problem(c)
        if msg is not None or c == "engine":
            raise ValueError(f"--columns: {msg or 'engine is written with --engines'}")
        q = lookup_column(c).quantity
        if q not in QUANTITIES or QUANTITIES[q].model is None:
            raise ValueError(f"--columns: {c!r} has no model counterpart (quantity {q}); it cannot be synthesised")
    if not any(lookup_column(c).quantity in ("power_W", "load_fraction") for c in columns):
        raise ValueError("--columns: need a power or load_fraction column (the set point of every row)")
    if len(set(columns)) != len(columns):
        raise ValueError("--columns: duplicated column")


def _perturbed(p: EngineParams, rng: np.random.Generator, sigma: float) -> tuple[EngineParams, dict[str, float]]:
    """The parameter set with each group of :data:`PERTURBED_FIELDS` scaled by 1 + N(0, sigma²), clipped at ±2 sigma."""
    if sigma <= 0:
        return p, {}
    ch, scales = {}, {}
    for group in PERTURBED_FIELDS:
        s = 1.0 + float(np.clip(rng.normal(0.0, sigma), -2 * sigma, 2 * sigma))
        scales[group[0]] = s
        for f in group:
            ch[f] = getattr(p, f) * s
    return p.replace(**ch), scales


def effect_region(effect: dict[str, Any], lo: float = LOAD_RANGE[0], hi: float = LOAD_RANGE[1]) -> tuple[float, float]:
    """Load range (within the study's load range) where an out-of-library effect exceeds half its largest magnitude
    there."""
    x = np.linspace(lo, hi, 2001)
    y = np.abs(_effect_shape(effect, x))
    on = x[y >= 0.5 * y.max()] if y.max() > 0 else x[:0]
    return (float(on.min()), float(on.max())) if on.size else (math.nan, math.nan)


def _effect_shape(effect: dict[str, Any], load: np.ndarray) -> np.ndarray:
    k, c, w = effect["kind"], effect["center"], effect["width"]
    if k == "bump":
        return np.exp(-0.5 * ((load - c) / w) ** 2)
    if k == "step":
        return 0.5 * (1.0 + np.tanh((load - c) / (0.25 * w)))
    if k == "bend":  # a kink: zero below the centre, growing linearly above, the amplitude at the top of the range
        return np.maximum(load - c, 0.0) / max(LOAD_RANGE[1] - c, 1e-3)
    raise ValueError(f"unknown effect kind {k!r}; known: {', '.join(EFFECT_KINDS)}")


def _relative_basis(column: str, values: np.ndarray, p_amb_Pa: float) -> float:
    """What a relative effect's amplitude multiplies, in the column's units: the mean absolute reading in SI (the
    absolute pressure for a gauge column), the basis of the pipeline's 1 % tolerance
    (:func:`~.discrepancy.column_tolerance`), so that an amplitude of 4 % is 4 tolerances on every channel.

    Until 2026-11-25 it was the mean *gauge* reading: on charge-air and turbine inlet pressure the "4-7 tolerance"
    effects of condition (e) were about 2.4-4.3 and 1.9-3.4 tolerances (a 5 % step: 3.0 and 2.4)."""
    spec = lookup_column(column)
    return float(np.mean(np.abs(spec.to_si(values, p_amb_Pa)))) / spec.scale


def draw_effect(rng: np.random.Generator, columns: Sequence[str], family: str | None = None) -> dict[str, Any]:
    """An out-of-library effect on one channel: kind, channel, centre load, width, amplitude (column units)."""
    fams = [f for f, cs in FAMILIES.items() if any(c in columns for c in cs)]
    fam = family or str(rng.choice(fams))
    chans = [c for c in FAMILIES[fam] if c in columns]
    col = str(rng.choice(chans))
    kind = str(rng.choice(EFFECT_KINDS))
    center = float(rng.uniform(0.45, 0.85))
    width = float(rng.uniform(0.08, 0.14))
    sign = float(rng.choice([-1.0, 1.0]))
    q = QUANTITIES[lookup_column(col).quantity]
    # 4-7 tolerances of the pipeline (5 K; 1 % of the mean reading, absolute for gauge pressures: _relative_basis)
    if q.kind == "temperature":
        amp = sign * float(rng.uniform(20.0, 35.0))
    else:
        amp = sign * float(rng.uniform(0.04, 0.07))  # times the channel's mean reading
    return {"kind": kind, "family": fam, "channel": col, "center": center, "width": width, "amplitude": amp,
            "relative": q.kind != "temperature"}


def _column_description(column: str) -> str:
    """The sidecar's description of a written column; a gauge column says so (the quantity itself is absolute)."""
    spec = lookup_column(column)
    text = QUANTITIES[spec.quantity].description
    return text.replace(", absolute", "") + ", gauge (above the ambient pressure)" if spec.gauge else text


def synthesize(
    params: str | EngineParams,
    mechanisms: Sequence[str | tuple[str, dict[str, float], str | None]] = ("none",),
    *,
    points: int = 8,
    noise: float = 0.01,
    seed: int = 0,
    columns: Sequence[str] = DEFAULT_COLUMNS,
    load_range: tuple[float, float] = LOAD_RANGE,
    engines: int = 0,
    noise_model: str = "typical",
    full_range: bool = False,
    perturb: float = 0.0,
    effects: Sequence[dict[str, Any]] = (),
) -> Synthesis:
    """Generate a dataset (see the module docstring).

    mechanisms : specs ``ID[:param=value,...]`` (or parsed tuples); ``none`` for the base model.  A valve takes
        ``above=L`` (waste gate) / ``below=L`` (bypass) and ``opening=A`` (default: drawn).
    engines : 0 = no engine column; K >= 1 = K engines E1..EK sharing the same load points.
    noise_model : ``typical`` (standard deviation noise x the channel's mean absolute value) or ``reading``
        (noise x |value|, a relative accuracy of the reading).
    perturb : relative model error of the true engine (condition b of the study).
    effects : out-of-library effects (:func:`draw_effect`) added to the clean readings.
    """
    if noise_model not in ("typical", "reading"):
        raise ValueError(f"noise model must be 'typical' or 'reading', got {noise_model!r}")
    if isinstance(params, str) and params not in list_parameter_sets():
        raise ValueError(f"--params: unknown parameter set {params!r}; allowed: {', '.join(list_parameter_sets())}")
    if int(points) != points or points < 3:
        raise ValueError(f"--points must be an integer >= 3, got {points!r}")
    if not (math.isfinite(noise) and 0.0 <= noise <= 0.5):
        raise ValueError(f"--noise must be a relative noise in [0, 0.5], got {noise!r}")
    lo, hi = load_range
    if not (0.05 <= lo < hi <= 1.15):
        raise ValueError(f"--load-range must satisfy 0.05 <= LO < HI <= 1.15, got {lo}, {hi}")
    if int(engines) != engines or engines < 0:
        raise ValueError(f"--engines must be an integer >= 0, got {engines!r}")
    if not (math.isfinite(perturb) and 0.0 <= perturb <= 0.2):
        raise ValueError(f"--perturb must lie in [0, 0.2], got {perturb!r}")
    columns = tuple(columns)
    _check_columns(columns)
    p0 = load_params(params)
    pname = p0.name
    rng = np.random.default_rng(seed)
    parsed = [parse_mechanism_spec(s) if isinstance(s, str) else s for s in mechanisms]
    ids = [m[0] for m in parsed]
    if "none" in ids and len(ids) > 1:
        raise ValueError("--mechanism none cannot be combined with other mechanisms")
    parsed = [m for m in parsed if m[0] != "none"]
    labels = [m[0] if m[0] != SensorCalibration.id else f"{m[0]}[{m[2]}]" for m in parsed]
    dup = {x for x in labels if labels.count(x) > 1 and not x.endswith("[None]")}
    if dup:
        raise ValueError(f"--mechanism given twice: {', '.join(sorted(dup))}")
    # stratified: one load per equal slice of the range, uniform inside it (a test programme covers the range)
    edges = np.linspace(lo, hi, int(points) + 1)
    loads = np.sort(rng.uniform(edges[:-1], edges[1:]))
    p_true, scales = _perturbed(p0, rng, perturb)

    # physical mechanisms first (the engine), sensor calibrations after the clean readings
    setting: Setting = BASE_SETTING
    truth: list[dict[str, Any]] = []
    sensors: list[tuple[str, dict[str, float], str | None]] = []
    openings: dict[str, np.ndarray] = {}
    for mid, given, channel in parsed:
        if mid == SensorCalibration.id:
            sensors.append((mid, given, channel))
            continue
        m = get_mechanism(mid)
        vals = m.values({k: v for k, v in given.items() if k in m.param_names})
        for prm in m.params:
            if prm.name not in given:
                vals[prm.name] = prm.sample(rng, full_range)
        setting = m.apply(setting, vals, p_true)
        entry = {"id": m.id, "label": m.label, "values": vals}
        if isinstance(m, ValveMechanism):
            o, rule = _valve_openings(m, loads, given, rng)
            openings[m.id] = o
            setting = m.with_openings(setting, o)
            entry["openings"] = o.tolist()
            entry["rule"] = rule
        truth.append(entry)
    eng = _engine(p_true, setting)
    P = loads * p0.P_nom_W
    valves = None
    if openings:
        valves = np.full((loads.size, 2), np.nan)
        for j, name in enumerate(("waste_gate", "bypass_valve")):
            if name in openings:
                valves[:, j] = openings[name]
    op = solve_points(eng, MODE_P, P, speed_of_power(eng, P), valves=valves)
    if not np.all(op.converged):
        bad = ", ".join(f"{x:.3f}" for x in loads[~op.converged])
        raise ValueError(f"the model with these mechanisms has no steady state at load fraction(s) {bad}; "
                         "choose other parameters or another load range")
    ctx = ModelContext(rated_power_W=p0.P_nom_W)
    clean: dict[str, np.ndarray] = {}
    p_amb = p0.p_amb_Pa + setting.dp_amb_Pa  # a gauge reads against the actual ambient
    for c in columns:
        spec = lookup_column(c)
        if c in SET_POINT_COLUMNS:  # the set points as commanded (the model meets them to ~1e-15)
            si = loads if spec.quantity == "load_fraction" else P
        else:
            si = _quantity(spec.quantity, op.values, ctx)
        clean[c] = spec.from_si(si, p_amb)
    activity = {}
    for m_id in openings:
        key = "waste_gate_fraction" if m_id == "waste_gate" else "bypass_fraction"
        activity[m_id] = [float(x) for x in op.values[key]]
    channel_cols = [c for c in columns if c not in SET_POINT_COLUMNS]
    for mid, given, channel in sensors:
        if channel is None:
            channel = str(rng.choice(channel_cols))
        if channel not in channel_cols:
            raise ValueError(f"--mechanism sensor_calibration: channel {channel!r} is not a written measurement "
                             f"column; choose one of {', '.join(channel_cols)}")
        ref = sensor_reference(channel, clean[channel])
        m = SensorCalibration(channel=channel, reference=ref)
        vals = m.values(given)
        drawn = m.sample(rng, full_range)
        for prm in m.params:
            if prm.name not in given:
                vals[prm.name] = drawn[prm.name]
        clean[channel] = vals["gain"] * clean[channel] + vals["offset"]
        truth.append({"id": m.id, "label": m.label, "channel": channel, "reference": ref, "values": vals})
    added: dict[str, list[float]] = {}
    for e in effects:
        if e["channel"] not in clean:
            raise ValueError(f"effect on {e['channel']!r}, which is not a written column")
        shape = _effect_shape(e, loads)
        base = _relative_basis(e["channel"], clean[e["channel"]], p_amb) if e.get("relative") else 1.0
        added[e["channel"]] = (e["amplitude"] * base * shape).tolist()
        clean[e["channel"]] = clean[e["channel"]] + e["amplitude"] * base * shape
    k = max(int(engines), 1)
    out: dict[str, np.ndarray] = {}
    for c in columns:
        v = np.tile(clean[c], k)
        if c not in SET_POINT_COLUMNS and noise > 0:
            scale = float(np.mean(np.abs(clean[c]))) if noise_model == "typical" else np.abs(v)
            v = v + rng.normal(0.0, 1.0, v.size) * noise * scale
        out[c] = v
    eng_ids = [f"E{j + 1}" for j in range(k) for _ in range(int(points))] if engines else None
    meta = {
        "engine_params": pname,
        "kind": "synthetic: generated by marine_fdi_env (synthesize-measurements) from the engine model, possibly "
                "with hidden effects that are not named here",
        "source": f"marine_fdi_env synthesize-measurements --params {pname} --points {int(points)} --noise {noise:g} "
                  f"--seed {seed}" + (f" --engines {engines}" if engines else "") + " (hidden effects not stated)",
        "load_law": "not stated",
        "ambient_pressure_bar": p0.p_amb_Pa / 1e5,
        "ambient_temperature_C": p0.T_amb_K - 273.15,
        "noise": (f"Gaussian noise of standard deviation {noise:g} x the column's mean absolute value" if
                  noise_model == "typical" else f"Gaussian noise of standard deviation {noise:g} x the reading") +
                 " (column units) on every column except the set points",
        "columns": {c: _column_description(c) for c in columns},
    }
    return Synthesis(columns=out, clean={c: np.tile(v, k) for c, v in clean.items()}, meta=meta, truth=truth,
                     engines=eng_ids, effects=list(effects), activity=activity,
                     settings={"params": pname, "points": int(points), "noise": noise, "seed": seed,
                               "load_range": [lo, hi], "engines": int(engines), "noise_model": noise_model,
                               "full_range": full_range, "perturb": perturb, "model_error": scales,
                               "loads": loads.tolist(), "columns": list(columns), "effects_added": added})


def _valve_openings(m: ValveMechanism, loads: np.ndarray, given: dict[str, float], rng
                    ) -> tuple[np.ndarray, dict[str, float]]:
    """Openings per point and the rule: a waste gate opens above a load, a bypass below one, growing away from it."""
    a_max = float(given.get("opening", rng.uniform(*m.draw_range)))
    if m.id == "waste_gate":
        thr = float(given.get("above", rng.uniform(0.6, 0.85)))
        ramp = np.clip((loads - thr) / max(1.1 - thr, 0.05), 0.0, 1.0)
        return np.where(loads > thr, a_max * (0.4 + 0.6 * ramp), 0.0), {"above": thr, "opening": a_max}
    thr = float(given.get("below", rng.uniform(0.45, 0.7)))
    ramp = np.clip((thr - loads) / max(thr - 0.25, 0.05), 0.0, 1.0)
    return np.where(loads < thr, a_max * (0.4 + 0.6 * ramp), 0.0), {"below": thr, "opening": a_max}


def _engine(p: EngineParams, setting: Setting) -> EngineParams:
    """The engine of a setting (scales, area re-match, submodels, ambient offsets) from parameter set ``p``."""
    ch: dict[str, Any] = {k: getattr(p, k) * v for k, v in setting.scales.items() if v != 1.0}
    if setting.area_scale != 1.0:
        ch["A_eff_m2"] = ch.get("A_eff_m2", p.A_eff_m2) * setting.area_scale
    if setting.submodels.any:
        ch["submodels"] = setting.submodels
    if setting.dT_amb_K:
        ch["T_amb_K"] = p.T_amb_K + setting.dT_amb_K
    if setting.dp_amb_Pa:
        ch["p_amb_Pa"] = p.p_amb_Pa + setting.dp_amb_Pa
        ch["p_ex_Pa"] = p.p_ex_Pa + setting.dp_amb_Pa
    return p.replace(**ch) if ch else p


def write_synthesis(syn: Synthesis, path: str | Path, truth_path: str | Path | None = None) -> Path:
    """Write the CSV and its sidecar (and the truth as JSON if ``truth_path``)."""
    path = Path(path)
    write_dataset(path, syn.columns, syn.meta, engines=syn.engines, digits=7)
    if truth_path is not None:
        Path(truth_path).write_text(json.dumps({"mechanisms": syn.truth, "effects": syn.effects,
                                                "activity": syn.activity, "settings": syn.settings},
                                               indent=2, default=float) + "\n")
    return path


# --------------------------------------------------------------------------------------- CLI
def build_parser(prog: str = "marine-fdi synthesize-measurements") -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog=prog, description="Write synthetic measured data from the model with hidden mechanisms.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="mechanisms: none, " + ", ".join(MECHANISM_IDS) + "\n"
               "  e.g. --mechanism turbocharger_map:eta_scale=1.1,curvature=0.1 --mechanism waste_gate:above=0.8\n"
               "  sensor_calibration:channel=turbine_outlet_temperature_C,gain=1.05,offset=-3\n"
               "parameters not given are drawn from the mechanism's range with the seed.")
    ap.add_argument("--params", required=True, help="parameter set (" + ", ".join(list_parameter_sets()) + ")")
    ap.add_argument("--mechanism", action="append", default=None, metavar="ID[:param=value,...]",
                    help="hidden mechanism (repeatable; default none)")
    ap.add_argument("--points", type=int, default=8, help="operating points (per engine), default 8")
    ap.add_argument("--noise", type=float, default=0.01, help="relative measurement noise, default 0.01")
    ap.add_argument("--noise-model", default="typical", choices=("typical", "reading"),
                    help="noise relative to the channel's typical value (default) or to each reading")
    ap.add_argument("--perturb", type=float, default=0.0, help="relative model error of the true engine, default 0")
    ap.add_argument("--seed", type=int, default=0, help="random seed, default 0")
    ap.add_argument("--load-range", default=f"{LOAD_RANGE[0]},{LOAD_RANGE[1]}", metavar="LO,HI",
                    help="load fractions are drawn uniformly in [LO, HI], default %(default)s")
    ap.add_argument("--columns", default=None, metavar="COL,COL,...",
                    help="columns to write (default: " + ",".join(DEFAULT_COLUMNS) + ")")
    ap.add_argument("--engines", type=int, default=0, help="K > 0: K engines E1..EK at the same load points")
    ap.add_argument("--truth", default=None, metavar="FILE.json", help="also write the hidden truth here")
    ap.add_argument("--out", required=True, metavar="FILE.csv", help="output CSV (sidecar FILE.meta.json beside it)")
    return ap


class _ArgError(Exception):
    pass


def _parser_no_exit(prog: str) -> argparse.ArgumentParser:
    ap = build_parser(prog)

    def error(message):
        raise _ArgError(message)

    ap.error = error  # type: ignore[method-assign]
    return ap


def synthesize_main(argv: Sequence[str] | None = None, prog: str = "marine-fdi synthesize-measurements") -> int:
    """Command line: returns 0 on success, 2 on bad input (message on stderr)."""
    try:
        args = _parser_no_exit(prog).parse_args(list(argv) if argv is not None else None)
    except _ArgError as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 2
    except SystemExit as e:  # --help
        return int(e.code or 0)
    try:
        try:
            lo, hi = (float(x) for x in args.load_range.split(","))
        except ValueError:
            raise ValueError(f"--load-range must be LO,HI, got {args.load_range!r}") from None
        columns = DEFAULT_COLUMNS if args.columns is None else \
            tuple(c.strip() for c in args.columns.split(",") if c.strip())
        parsed = []
        for s in args.mechanism or ["none"]:
            try:
                parsed.append(parse_mechanism_spec(s))
            except ValueError as e:
                raise ValueError(f"--mechanism {s!r}: {e}") from None
        out = Path(args.out)
        if not out.name.endswith(".csv"):
            raise ValueError(f"--out must name a .csv file, got {args.out!r}")
        if not out.parent.parent.exists():
            raise ValueError(f"--out: directory {str(out.parent.parent)!r} does not exist")
        syn = synthesize(args.params, parsed, points=args.points, noise=args.noise, seed=args.seed, columns=columns,
                         load_range=(lo, hi), engines=args.engines, noise_model=args.noise_model,
                         perturb=args.perturb)
        out.parent.mkdir(exist_ok=True)
        syn.write(out, args.truth)
    except ValueError as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 2
    n = len(next(iter(syn.columns.values())))
    print(f"wrote {out} ({n} points, {len(syn.columns)} columns) and {out.name[:-4]}.meta.json"
          + (f"; truth in {args.truth}" if args.truth else ""))
    return 0


# --------------------------------------------------------------------------------------- the open-world study
CONDITIONS = {
    "a": {"title": "closed world: base model + one library mechanism, noise 1 % of the typical reading",
          "perturb": 0.0, "noise_model": "typical", "noise": 0.01, "n_mech": 1},
    "b": {"title": "model error: the true engine's efficiencies, areas and heat fractions off by N(0, 3 %) each",
          "perturb": 0.03, "noise_model": "typical", "noise": 0.01, "n_mech": 1},
    "c": {"title": "noise 1.5 % of each reading (the fit keeps its 1 % / 5 K tolerances)",
          "perturb": 0.0, "noise_model": "reading", "noise": 0.015, "n_mech": 1},
    "d": {"title": "two library mechanisms at once (model error 1 %)",
          "perturb": 0.01, "noise_model": "typical", "noise": 0.01, "n_mech": 2},
    "e": {"title": "an effect outside the library on one channel (model error 1 %)",
          "perturb": 0.01, "noise_model": "typical", "noise": 0.01, "n_mech": 0},
}


def effect_size(added: Sequence[float], reading: Sequence[float], tol: float) -> dict[str, float]:
    """How large an out-of-library effect is at the measured points, in the pipeline's tolerances: ``rms`` (its
    root-mean-square), ``norm`` (its Euclidean norm: what an oracle that knows the shape tests against noise of one
    tolerance) and ``beyond_calibration`` (the norm of what a gain and an offset of the reading leave of it: the part
    by which any test could tell the effect from a miscalibrated sensor)."""
    e = np.asarray(added, dtype=float)
    A = np.column_stack([np.ones_like(e), np.asarray(reading, dtype=float)])
    left = e - A @ np.linalg.lstsq(A, e, rcond=None)[0]
    return {"rms": float(np.sqrt(np.mean(e ** 2)) / tol), "norm": float(np.linalg.norm(e) / tol),
            "beyond_calibration": float(np.linalg.norm(left) / tol)}


#: bins of :func:`effect_size`'s ``beyond_calibration`` in the study summary (tolerances)
SIZE_BINS = (3.0, 5.0)


def _draw_mechanisms(rng: np.random.Generator, n: int) -> list[str]:
    """``n`` distinct mechanism ids (a sensor calibration at most once)."""
    ids = list(MECHANISM_IDS)
    return [str(x) for x in rng.choice(ids, size=n, replace=False)]


#: what the pipeline is told of the noise in a study trial: ``stated`` its own tolerances (1 %, 5 K: what every
#: result of the study uses), ``noise`` each channel's true noise (:func:`noise_tolerances`, an ablation)
TOLERANCE_MODES = ("stated", "noise")


def _trial_settings(params: str = "wartsila-6l46", points: int = 8, max_folds: int | None = None, prune: bool = True,
                    tolerance: str = "stated", exchange: bool = True, held_out_valves: str = "schedule",
                    beside_valve: str = BESIDE_VALVE_DEFAULT, **_) -> dict[str, Any]:
    """What a trial's outcome depends on besides its condition and seed (a resumed study keeps only trials run with
    the same).  ``tolerance`` is recorded only when it is not the default, ``exchange`` only when it is on: every
    file written before the exchange step (2026-11-26) was run without it.  ``calibration_scan``: the level of the
    scan of what a named calibration leaves (:func:`~.unexplained.calibration_left`), over the calibrated channels
    since 2026-11-26; files without the key scanned at the level over every channel, and differ from a rerun only
    in unexplained findings on channels with a named calibration.  ``held_out_valves``: how cross-validation
    predicts a valve's opening at a held-out point (:data:`~.problem.HELD_OUT_VALVES`), recorded only when it is
    not the default ``schedule`` (every file before 2026-11-26 followed the schedule).  ``beside_valve``: how a
    cause joining a model with a valve earns its place (:data:`~.evidence.BESIDE_VALVE`), recorded unless it is
    ``cross_validated``: every file before 2026-11-26 (ninth session) judged it so; the files 340-360 record
    ``in_sample``, 360-380 ``in_sample_exchange``, those after it ``in_sample_pairs`` (the default since the twelfth
    session)."""
    out = {"params": str(params), "points": int(points), "max_folds": max_folds, "prune": bool(prune),
           "calibration_scan": "per named calibration"}
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


def trial_draw(condition: str, seed: int, *, control: bool = False
               ) -> tuple[list[str], list[dict[str, Any]], str | None]:
    """What a trial of the study hides: (mechanism ids, out-of-library effects, the control's shadow channel).

    A control drops the draw; in (e) it keeps the channel the paired trial's effect is on (the shadow channel): a
    finding there is the control's false hit."""
    cond = CONDITIONS[condition]
    rng = np.random.default_rng([int(seed), ord(condition), 7919])
    mechs = _draw_mechanisms(rng, cond["n_mech"])
    effects = ([draw_effect(rng, DEFAULT_COLUMNS, family=list(FAMILIES)[int(seed) % len(FAMILIES)])]
               if condition == "e" else [])
    shadow = effects[0]["channel"] if control and effects else None
    if control:
        mechs, effects = [], []
    return mechs, effects, shadow


def loaded(syn: Synthesis, name: str = "trial", workdir: str | Path | None = None):
    """``syn`` written to a temporary CSV and read back with the loader, as a user's file would be (its data
    warnings silenced: the study reports outcomes, not the loader's notes); raises the loader's DatasetError."""
    import tempfile
    import warnings

    from .dataset import DataWarning, load_dataset

    with tempfile.TemporaryDirectory(dir=workdir) as d:
        path = Path(d) / f"{name}.csv"
        syn.write(path)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DataWarning)
            return load_dataset(path)


def trial_data(condition: str, seed: int, *, control: bool = False, params: str = "wartsila-6l46",
               points: int = 8) -> Synthesis:
    """The data of one trial of the study (:func:`trial` runs the pipeline on them); raises ValueError when the
    hidden engine cannot run at the drawn points (the trial is then skipped)."""
    cond = CONDITIONS[condition]
    mechs, effects, _ = trial_draw(condition, seed, control=control)
    return synthesize(params, mechs or ["none"], points=points, noise=cond["noise"], seed=int(seed) * 31 + 7,
                      noise_model=cond["noise_model"], perturb=cond["perturb"], effects=effects)


def trial(condition: str, seed: int, *, control: bool = False, params: str = "wartsila-6l46", points: int = 8,
          max_folds: int | None = None, prune: bool = True, tolerance: str = "stated", exchange: bool = True,
          held_out_valves: str = "schedule", beside_valve: str = BESIDE_VALVE_DEFAULT,
          workdir: str | Path | None = None) -> dict[str, Any]:
    """One trial of the study: synthesise with the condition's hidden effects (none when ``control``), write and
    reload the data, run the selection (``prune``: its final removal step, on by default; ``tolerance``: one of
    :data:`TOLERANCE_MODES`; ``exchange``: the selection's exchange step, on by default; ``held_out_valves``: one of
    :data:`~.problem.HELD_OUT_VALVES`; ``beside_valve``: one of :data:`~.evidence.BESIDE_VALVE`) and compare with the
    truth."""
    from .dataset import DatasetError
    from .problem import Problem
    from .selection import select_causes

    t0 = time.perf_counter()
    mechs, effects, shadow = trial_draw(condition, seed, control=control)
    if tolerance not in TOLERANCE_MODES:
        raise ValueError(f"tolerance must be one of {', '.join(TOLERANCE_MODES)}, got {tolerance!r}")
    base = {"condition": condition, "control": bool(control), "seed": int(seed), "mechanisms": mechs,
            "effects": effects, "trial_settings": _trial_settings(params=params, points=points, max_folds=max_folds,
                                                                  prune=prune, tolerance=tolerance,
                                                                  exchange=exchange,
                                                                  held_out_valves=held_out_valves,
                                                                  beside_valve=beside_valve)}
    try:
        syn = trial_data(condition, seed, control=control, params=params, points=points)
    except ValueError as e:
        return {**base, "outcome": "skipped", "why": str(e)[:300], "seconds": time.perf_counter() - t0}
    try:
        ds = loaded(syn, f"hidden_{condition}_{seed}", workdir)
    except DatasetError as e:
        return {**base, "outcome": "skipped", "why": "loader: " + " ".join(str(e).split())[:300],
                "seconds": time.perf_counter() - t0}
    problem = Problem(ds, held_out_valves=held_out_valves)
    if tolerance == "noise":
        problem = Problem(ds, tolerances=noise_tolerances(syn, problem.channels), held_out_valves=held_out_valves)
    sel = select_causes(problem, max_folds=max_folds, prune=prune, exchange=exchange, beside_valve=beside_valve)
    truth_labels = sorted(t["label"] for t in syn.truth)
    named = sorted(sel.selected_labels)
    res = {**base, "truth": syn.truth, "selected": named, "model_error": syn.settings["model_error"],
           "seconds": time.perf_counter() - t0, "unexplained": [
               {k: u.get(k) for k in ("channel", "kind", "region", "load_range", "magnitude", "left_by")}
               for u in sel.unexplained]}
    res["calibration_scan"] = sel.calibration_scans
    res["named_any"] = bool(named)
    res["unexplained_local"] = any(u["kind"] == "local" for u in sel.unexplained)
    if shadow is not None:
        res["shadow_channel"] = shadow
        res["unexplained_on_shadow_channel"] = any(u["channel"] == shadow for u in sel.unexplained)
    res["exact"] = named == truth_labels
    res["alternatives"] = {k: [a["mechanism"] for a in v] for k, v in sel.alternatives.items()}
    res["exact_up_to_equivalence"] = len(named) == len(truth_labels) and all(
        any(t == n or t in equivalents(n) for n in named) for t in truth_labels)
    if syn.activity:
        act = sel.activity()
        res["activity_truth"] = syn.activity
        res["activity_found"] = act
        res["activity_support_match"] = {
            k: bool(k in act and [x > 0 for x in act[k]] == [x > 0 for x in v]) for k, v in syn.activity.items()}
    if effects:
        e = effects[0]
        lo, hi = effect_region(e)
        found = list(sel.unexplained) + [dict(o, load_range=[float(syn.settings["loads"][o["point"] - 1])] * 2,
                                              kind="local") for o in sel.outliers]
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
        res["effect_size"] = effect_size(add, np.asarray(syn.clean[e["channel"]]) - add,
                                         float(sel.problem.tolerance[j]))
        res["found_on_channel"] = [{k: u.get(k) for k in ("kind", "region", "load_range")} for u in hits]
        res["unexplained_right_channel"] = bool(hits)
        res["unexplained_right_region"] = bool(region_ok)
        res["named_other"] = bool(named)
    res["outcome"] = ("control" if control else
                      "identified" if res["exact"] and not effects else
                      "unexplained" if effects and res["unexplained_right_channel"] else
                      "none" if not named else "wrong")
    return res


def study(conditions: Sequence[str], seeds: Sequence[int], *, controls: bool = True, workers: int = 1,
          progress: bool = True, checkpoint: str | Path | None = None,
          trials: Sequence[tuple[str, int]] | None = None, **kw) -> dict[str, Any]:
    """Run :func:`trial` for every condition x seed (and its control) and summarise per condition.

    ``trials``: only these ``(condition, seed)`` (``conditions`` and ``seeds`` are then ignored): a development
    check that reruns the trials a change can touch, e.g. those with a valve in the truth or the selection.

    ``checkpoint`` (a JSON-lines file) keeps every finished trial; a rerun with the same file resumes
    where the last one stopped (trials are deterministic in their seed, so nothing changes); trials it holds that
    were run with other settings (:func:`_trial_settings`: parameter set, points, folds, removal step) are run
    again, not mixed in."""
    pairs = ([(c, int(s)) for c, s in trials] if trials is not None else
             [(c, int(s)) for c in conditions for s in seeds])
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
                print(f"study: resuming at {len(results)}/{len(results) + len(jobs)} trials ({checkpoint})",
                      file=sys.stderr)
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
    return {"conditions": {c: dict(CONDITIONS[c], **summarise(results, c)) for c in conditions}, "trials": results,
            "settings": {k: (str(v) if isinstance(v, Path) else v) for k, v in kw.items()}}


def summarise(results: Sequence[dict[str, Any]], condition: str) -> dict[str, Any]:
    """Rates of one condition: identification (exact set), controls naming a cause, out-of-library detection."""
    tr = [r for r in results if r["condition"] == condition and not r["control"] and r["outcome"] != "skipped"]
    ct = [r for r in results if r["condition"] == condition and r["control"] and r["outcome"] != "skipped"]
    out: dict[str, Any] = {"n_trials": len(tr), "n_controls": len(ct),
                           "skipped": sum(r["outcome"] == "skipped" for r in results if r["condition"] == condition),
                           "control_named_rate": (sum(r["named_any"] for r in ct) / len(ct)) if ct else None}
    if ct and all("unexplained_local" in r for r in ct):
        out["control_unexplained_local_rate"] = sum(r["unexplained_local"] for r in ct) / len(ct)
    if ct and all("unexplained_on_shadow_channel" in r for r in ct):
        out["control_unexplained_on_effect_channel_rate"] = \
            sum(r["unexplained_on_shadow_channel"] for r in ct) / len(ct)
    if condition == "e":
        out["unexplained_right_channel_rate"] = sum(r["unexplained_right_channel"] for r in tr) / len(tr) if tr else None
        if tr and all("effect_size" in r for r in tr):
            edges = (0.0,) + SIZE_BINS + (math.inf,)
            out["unexplained_by_size_beyond_calibration"] = {
                (f"{a:g}-{b:g}" if math.isfinite(b) else f">={a:g}"): "{}/{}".format(
                    sum(r["unexplained_right_channel"] for r in tr if a <= r["effect_size"]["beyond_calibration"] < b),
                    sum(a <= r["effect_size"]["beyond_calibration"] < b for r in tr))
                for a, b in zip(edges[:-1], edges[1:])}
        out["unexplained_right_region_rate"] = sum(r["unexplained_right_region"] for r in tr) / len(tr) if tr else None
        out["named_a_cause_rate"] = sum(r["named_any"] for r in tr) / len(tr) if tr else None
    else:
        out["identification_rate"] = sum(r["exact"] for r in tr) / len(tr) if tr else None
        out["identification_rate_up_to_equivalence"] = \
            sum(r.get("exact_up_to_equivalence", r["exact"]) for r in tr) / len(tr) if tr else None
        out["wrong_rate"] = sum(r["outcome"] == "wrong" for r in tr) / len(tr) if tr else None
        out["none_rate"] = sum(r["outcome"] == "none" for r in tr) / len(tr) if tr else None
        # the calibration scan's price: true sensor calibrations, named, that it reports as leaving structure
        cal = [(r, t["channel"]) for r in tr if "calibration_scan" in r for t in r.get("truth", [])
               if t["id"] == "sensor_calibration" and t["label"] in r["selected"]]
        if cal:
            out["true_calibration_left_by_it"] = "{}/{}".format(sum(any(
                u["channel"] == ch and u.get("left_by") == "sensor_calibration" for u in r["unexplained"])
                for r, ch in cal), len(cal))
        valves = [r for r in tr if r.get("activity_support_match")]
        if valves:
            out["valve_support_exact"] = f"{sum(all(r['activity_support_match'].values()) for r in valves)}/{len(valves)}"
    by: dict[str, list[int]] = {}
    for r in tr:
        for m in r.get("mechanisms") or [r["effects"][0]["family"] if r.get("effects") else "none"]:
            b = by.setdefault(m, [0, 0])
            b[0] += 1
            b[1] += bool(r["exact"] if condition != "e" else r.get("unexplained_right_channel"))
    out["by_mechanism"] = {k: f"{v[1]}/{v[0]}" for k, v in sorted(by.items())}
    return out


def study_main(argv: Sequence[str] | None = None) -> int:
    """``python -m marine_fdi_env.validation.synthesize study [--conditions abcde] [--seeds A:B] [--workers K]
    [--no-prune] [--no-exchange] [--tolerance stated|noise] [--held-out-valves schedule|support|state]
    [--beside-valve in_sample_pairs|in_sample_exchange|in_sample|cross_validated] [--trials d346,...] [--out FILE.json]``:
    the open-world hidden-effect study."""
    from .evidence import add_valve_options

    ap = argparse.ArgumentParser(prog="python -m marine_fdi_env.validation.synthesize study",
                                 description="Open-world hidden-effect study: " + "; ".join(
                                     f"({k}) {v['title']}" for k, v in CONDITIONS.items()))
    ap.add_argument("--conditions", default="abcde", help="which conditions (letters), default abcde")
    ap.add_argument("--seeds", default="0:20", help="A:B, the seeds A..B-1 (default 0:20)")
    ap.add_argument("--trials", default=None, metavar="d346,b12,...",
                    help="only these trials (condition letter + seed, comma-separated), instead of --conditions x "
                         "--seeds: a development check on the trials a change can touch")
    ap.add_argument("--no-controls", action="store_true", help="skip the negative controls")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--points", type=int, default=8)
    ap.add_argument("--no-prune", action="store_true",
                    help="without the selection's final removal step (to measure what it changes)")
    ap.add_argument("--no-exchange", action="store_true",
                    help="without the selection's exchange step (a named physical cause replaced by a sensor "
                         "calibration that explains the data better): the selection before 2026-11-26")
    ap.add_argument("--tolerance", default="stated", choices=TOLERANCE_MODES,
                    help="what the pipeline is told of the noise: its own tolerances (default; every result of the "
                    "study) or each channel's true noise (an ablation: what misstated tolerances cost)")
    add_valve_options(ap)
    ap.add_argument("--out", default=None, help="write every trial as JSON here; finished trials are kept in "
                    "OUT.trials.jsonl and a rerun resumes from it")
    args = ap.parse_args(list(argv) if argv is not None else None)
    bad = set(args.conditions) - set(CONDITIONS)
    if bad:
        print(f"study: error: unknown condition(s) {''.join(sorted(bad))}; known: {''.join(CONDITIONS)}",
              file=sys.stderr)
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
                print(f"study: error: --trials wants a condition letter ({''.join(CONDITIONS)}) and a seed, "
                      f"e.g. d346; got {t!r}", file=sys.stderr)
                return 2
            trials.append((t[0], int(t[1:])))
        if not trials:
            print("study: error: --trials names no trial", file=sys.stderr)
            return 2
    try:
        res = study(list(args.conditions), seeds, controls=not args.no_controls, workers=args.workers, trials=trials,
                    points=args.points, **({"prune": False} if args.no_prune else {}),
                    **({"tolerance": args.tolerance} if args.tolerance != "stated" else {}),
                    **({"exchange": False} if args.no_exchange else {}),
                    **({"held_out_valves": args.held_out_valves} if args.held_out_valves != "schedule" else {}),
                    **({"beside_valve": args.beside_valve} if args.beside_valve != BESIDE_VALVE_DEFAULT else {}),
                    checkpoint=(Path(args.out).with_suffix(".trials.jsonl") if args.out else None))
    except KeyboardInterrupt:
        print("study: interrupted", file=sys.stderr)
        return 130
    for c, s in res["conditions"].items():
        print(f"({c}) {s['title']}")
        print("    " + ", ".join(f"{k} {v}" for k, v in s.items() if k not in ("title", "by_mechanism", "perturb",
                                                                              "noise_model", "noise", "n_mech")))
        print("    by mechanism/family: " + ", ".join(f"{k} {v}" for k, v in s["by_mechanism"].items()))
    if args.out:
        out = Path(args.out)
        out.parent.mkdir(exist_ok=True)
        out.write_text(json.dumps(res, indent=1, default=float) + "\n")
    return 0


if __name__ == "__main__":  # pragma: no cover
    if len(sys.argv) > 1 and sys.argv[1] == "study":
        sys.exit(study_main(sys.argv[2:]))
    if len(sys.argv) > 1 and sys.argv[1] == "pool":
        from .study_pool import pool_main

        sys.exit(pool_main(sys.argv[2:]))
    sys.exit(synthesize_main())
