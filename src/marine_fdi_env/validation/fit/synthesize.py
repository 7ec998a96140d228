"""Synthetic "measured" data from the engine model with hidden effects.

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
The open-world study of docs/validation.md runs the pipeline on such data.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from ...engine.operating_point import MODE_P, solve_points, speed_of_power
from ...engine.params import EngineParams, list_parameter_sets, load_params
from ..measured.columns import QUANTITIES, ModelContext, column_problem, lookup_column
from ..measured.loader import write_measured
from .mechanisms import SensorCalibration, ValveMechanism, get_mechanism, parse_mechanism_spec, sensor_reference
from .problem import BASE_SETTING, Setting, quantity_values

__all__ = [
    "DEFAULT_COLUMNS",
    "SET_POINT_COLUMNS",
    "EFFECT_KINDS",
    "PERTURBED_FIELDS",
    "FAMILIES",
    "Synthesis",
    "synthesize",
    "write_synthesis",
    "draw_effect",
    "effect_region",
]

DEFAULT_COLUMNS = (
    "load_fraction",
    "power_kW",
    "speed_rpm",
    "fuel_flow_kg_per_h",
    "turbocharger_speed_rpm",
    "charge_air_pressure_bar_gauge",
    "compressor_outlet_temperature_C",
    "charge_air_cooler_outlet_temperature_C",
    "turbine_inlet_pressure_bar_gauge",
    "turbine_inlet_temperature_C",
    "turbine_outlet_temperature_C",
    "cylinder_exhaust_temperature_mean_C",
    "max_cylinder_pressure_bar_gauge",
)
SET_POINT_COLUMNS = ("load_fraction", "power_kW", "power_W", "power_MW", "load_percent")
LOAD_RANGE = (0.25, 1.1)
# the true engine's model error (``perturb``): efficiencies, areas and heat fractions, and the scavenging
# slip, which the pipeline's nuisance does not cover
PERTURBED_FIELDS = (
    ("A_eff_m2",),
    ("a_eta_per_Pa2", "b_eta_per_Pa", "c_eta", "a_turbo", "b_turbo_per_Pa", "c_turbo_per_Pa2"),
    ("eta_com",),
    ("eta_comb",),
    ("X_cv_nom",),
    ("X_ct_nom",),
    ("s_sl_nom",),
)
EFFECT_KINDS = ("bump", "step", "bend")
FAMILIES = {
    "pressure": (
        "charge_air_pressure_bar_gauge",
        "turbine_inlet_pressure_bar_gauge",
        "max_cylinder_pressure_bar_gauge",
    ),
    "temperature": (
        "compressor_outlet_temperature_C",
        "turbine_inlet_temperature_C",
        "turbine_outlet_temperature_C",
        "cylinder_exhaust_temperature_mean_C",
        "charge_air_cooler_outlet_temperature_C",
    ),
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
    """Load range (within the synthetic data's load range) where an out-of-library effect exceeds half its largest
    magnitude there."""
    x = np.linspace(lo, hi, 2001)
    y = np.abs(effect_shape(effect, x))
    on = x[y >= 0.5 * y.max()] if y.max() > 0 else x[:0]
    return (float(on.min()), float(on.max())) if on.size else (math.nan, math.nan)


def effect_shape(effect: dict[str, Any], load: np.ndarray) -> np.ndarray:
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
    (:func:`~.measured.discrepancy.column_tolerance`), so that an amplitude of 4 % is 4 tolerances on every channel.

    Not the mean *gauge* reading: on charge-air and turbine inlet pressure effects of 4-7 tolerances would then be
    about 2.4-4.3 and 1.9-3.4 tolerances (a 5 % step: 3.0 and 2.4)."""
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
    return {
        "kind": kind,
        "family": fam,
        "channel": col,
        "center": center,
        "width": width,
        "amplitude": amp,
        "relative": q.kind != "temperature",
    }


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
    perturb : relative model error of the true engine.
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
        raise ValueError(
            f"the model with these mechanisms has no steady state at load fraction(s) {bad}; "
            "choose other parameters or another load range"
        )
    ctx = ModelContext(rated_power_W=p0.P_nom_W)
    clean: dict[str, np.ndarray] = {}
    p_amb = p0.p_amb_Pa + setting.dp_amb_Pa  # a gauge reads against the actual ambient
    for c in columns:
        spec = lookup_column(c)
        if c in SET_POINT_COLUMNS:  # the set points as commanded (the model meets them to ~1e-15)
            si = loads if spec.quantity == "load_fraction" else P
        else:
            si = quantity_values(spec.quantity, op.values, ctx)
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
            raise ValueError(
                f"--mechanism sensor_calibration: channel {channel!r} is not a written measurement "
                f"column; choose one of {', '.join(channel_cols)}"
            )
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
        shape = effect_shape(e, loads)
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
        "noise": (
            f"Gaussian noise of standard deviation {noise:g} x the column's mean absolute value"
            if noise_model == "typical"
            else f"Gaussian noise of standard deviation {noise:g} x the reading"
        )
        + " (column units) on every column except the set points",
        "columns": {c: _column_description(c) for c in columns},
    }
    return Synthesis(
        columns=out,
        clean={c: np.tile(v, k) for c, v in clean.items()},
        meta=meta,
        truth=truth,
        engines=eng_ids,
        effects=list(effects),
        activity=activity,
        settings={
            "params": pname,
            "points": int(points),
            "noise": noise,
            "seed": seed,
            "load_range": [lo, hi],
            "engines": int(engines),
            "noise_model": noise_model,
            "full_range": full_range,
            "perturb": perturb,
            "model_error": scales,
            "loads": loads.tolist(),
            "columns": list(columns),
            "effects_added": added,
        },
    )


def _valve_openings(
    m: ValveMechanism, loads: np.ndarray, given: dict[str, float], rng
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
    write_measured(path, syn.columns, syn.meta, engines=syn.engines, digits=7)
    if truth_path is not None:
        Path(truth_path).write_text(
            json.dumps(
                {"mechanisms": syn.truth, "effects": syn.effects, "activity": syn.activity, "settings": syn.settings},
                indent=2,
                default=float,
            )
            + "\n"
        )
    return path
