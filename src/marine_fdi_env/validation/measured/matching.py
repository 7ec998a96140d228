"""Operating-point matching: run the model at each measured point.

A measured point fixes the operating point through some of its columns; which ones depends on the
load law of the installation:

* ``propeller`` (fixed-pitch propeller, P = c n^3): one quantity fixes the point - power (or the load
  fraction times rated power), fuel flow, or speed;
* ``constant_speed`` (generator) and ``independent`` (controllable-pitch propeller, combinator): speed and
  power are set separately.  The base model ties speed to power by the propeller law (eq. 3.11), so
  it cannot honour both: it is matched on power (or fuel) and its speed residual measures the load-law
  mismatch (the ``cpp_load`` mechanism, a combinator speed line in :mod:`.fit.mechanisms`, removes it).

For each point the fuel setting ``u`` is the root of ``model(u)[target] = measured target`` on
``[0.05, 1.2]`` (:func:`scipy.optimize.brentq` on the steady state).  When the sidecar says nothing
about the load law, :func:`infer_load_law` infers it from speed against power.

The model is reached through a *steady-state function* ``steady(u, point) -> summary`` (the SI dict of
:meth:`marine_fdi_env.engine.steady_state.SteadyState.summary`); ``point`` is the measured point (SI quantities)
so that an extended model can use e.g. the measured speed.  :func:`base_steady` wraps the base model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping, Sequence

import numpy as np
from scipy import stats
from scipy.optimize import brentq

from ...engine.model import EngineModel
from ...engine.params import EngineParams
from ...engine.steady_state import steady_state
from .columns import QUANTITIES, ModelContext, lookup_column
from .dataset import MeasuredDataset

__all__ = [
    "LoadLaw",
    "MatchResult",
    "SteadyFunction",
    "base_steady",
    "infer_load_law",
    "load_law_of",
    "match_operating_points",
    "predict_columns",
    "TARGETS",
    "U_BOUNDS",
    "rack_settings",
    "resolve_target",
    "target_values",
]

U_BOUNDS = (0.05, 1.2)
TARGETS = ("auto", "power", "fuel_flow", "speed", "fuel_rack")
SteadyFunction = Callable[[float, Mapping[str, float]], Mapping[str, float]]

# thresholds of the load-law inference
CONSTANT_SPEED_CV = 0.02  # speed coefficient of variation below which speed is constant
PROPELLER_R2 = 0.95  # R^2 of n = k P^(1/3) above which the propeller law fits
PROPELLER_EXPONENT_TOL = 0.1  # |fitted exponent of n ~ P^b - 1/3| allowed for the propeller law


def base_steady(model: EngineModel) -> SteadyFunction:
    """Steady-state function of the base model: ignores the measured point except for ``u``."""
    p = model.params

    def steady(u: float, point: Mapping[str, float]) -> dict[str, float]:
        return steady_state(model, float(u)).summary(p)

    return steady


# --------------------------------------------------------------------------------------- load law
@dataclass(frozen=True)
class LoadLaw:
    """The load law used for a dataset and the evidence for it.

    law : ``propeller`` | ``constant_speed`` | ``independent`` | ``None`` (unknown).
    source : ``given`` (by the caller), ``metadata`` (the sidecar states it), ``inferred`` (from the data)
        or ``none``.  evidence : the inference statistics (always computed when speed and power exist,
        also when the sidecar states the law, so that a stated law can be checked against the data).
    """

    law: str | None
    source: str
    stated: str | None = None
    evidence: dict[str, Any] = field(default_factory=dict)

    def describe(self) -> str:
        ev = self.evidence
        bits = [f"load law {self.law or 'unknown'} ({self.source})"]
        if ev.get("n_points"):
            bits.append(
                f"n ~ P^(1/3): R^2 = {ev['r2_propeller']:.4f}; free exponent {ev['exponent']:.3f}; "
                f"speed CV {ev['speed_cv']:.3f} over {ev['n_points']} points ({ev['power_source']})"
            )
        if ev.get("verdict"):
            bits.append(ev["verdict"])
        return "; ".join(bits)


def infer_load_law(speed, power, *, power_source: str = "power", c_load_W_s3: float | None = None) -> LoadLaw:
    """Infer the load law from speed [rev/s] against power [W] (or a proxy proportional to it).

    Propeller law: fit ``n = k P^(1/3)`` through the origin (R^2 about the mean speed, the fitted
    ``c = k^-3`` in W s^3) and the free power law ``log n = a + b log P`` (b = 1/3 for a propeller).
    Constant speed: coefficient of variation of the speed below 2 %.  Otherwise speed and power are
    set independently (CPP / combinator).
    """
    n = np.asarray(speed, dtype=float)
    P = np.asarray(power, dtype=float)
    ok = np.isfinite(n) & np.isfinite(P) & (n > 0) & (P > 0)
    n, P = n[ok], P[ok]
    ev: dict[str, Any] = {"n_points": int(n.size), "power_source": power_source}
    if n.size < 3:
        ev["verdict"] = "fewer than 3 points with speed and power: cannot infer"
        return LoadLaw(None, "none", None, ev)
    cv = float(np.std(n) / np.mean(n))
    x = np.cbrt(P)
    k = float(np.sum(n * x) / np.sum(x * x))
    sse = float(np.sum((n - k * x) ** 2))
    sst = float(np.sum((n - n.mean()) ** 2))
    r2p = 1.0 - sse / sst if sst > 0 else (1.0 if sse == 0 else -math.inf)
    ev.update(
        speed_cv=cv,
        speed_min=float(n.min()),
        speed_max=float(n.max()),
        r2_propeller=r2p,
        rmse_propeller_rel=float(math.sqrt(sse / n.size) / np.mean(n)),
    )
    if power_source == "power":
        ev["c_fit_W_s3"] = k**-3.0
        if c_load_W_s3 is not None:
            ev["c_fit_over_params"] = k**-3.0 / c_load_W_s3
    if np.ptp(np.log(P)) > 0:
        lr = stats.linregress(np.log(P), np.log(n))
        ev.update(exponent=float(lr.slope), exponent_stderr=float(lr.stderr), r2_power_law=float(lr.rvalue**2))
    else:
        ev.update(exponent=math.nan, exponent_stderr=math.nan, r2_power_law=math.nan)
    if cv < CONSTANT_SPEED_CV:
        law = "constant_speed"
        ev["verdict"] = f"speed constant within {cv:.1%} (CV) while power varies: generator / constant-speed law"
    elif r2p >= PROPELLER_R2 and abs(ev["exponent"] - 1.0 / 3.0) <= PROPELLER_EXPONENT_TOL:
        law = "propeller"
        ev["verdict"] = f"speed follows P^(1/3) (R^2 = {r2p:.3f}, exponent {ev['exponent']:.3f} vs 1/3): propeller law"
    else:
        law = "independent"
        ev["verdict"] = (
            f"speed varies but not as P^(1/3) (R^2 = {r2p:.3f}, exponent {ev['exponent']:.3f}): "
            "speed and power set independently (CPP / combinator)"
        )
    return LoadLaw(law, "inferred", None, ev)


def _power_for_law(ds: MeasuredDataset) -> tuple[np.ndarray | None, str]:
    v = ds.values
    if "power_W" in v:
        return v["power_W"], "power"
    if "load_fraction" in v:
        return v["load_fraction"] * ds.rated_power_W, "power"
    if "fuel_mass_flow_kg_s" in v:
        return v["fuel_mass_flow_kg_s"], "fuel flow as a proxy of power"
    return None, "none"


def load_law_of(ds: MeasuredDataset) -> LoadLaw:
    """The stated load law of the sidecar, else the one inferred from the data (with evidence in both)."""
    P, src = _power_for_law(ds)
    if P is not None and "engine_speed_rev_s" in ds.values:
        inferred = infer_load_law(
            ds.values["engine_speed_rev_s"], P, power_source=src, c_load_W_s3=ds.params.c_load_W_s3
        )
    else:
        inferred = LoadLaw(None, "none", None, {"n_points": 0, "verdict": "no speed or no power: cannot infer"})
    if ds.load_law is not None:
        ev = dict(inferred.evidence)
        ev["inferred_law"] = inferred.law
        if inferred.law is not None and inferred.law != ds.load_law:
            ev["verdict"] = f"the data suggest {inferred.law} where the sidecar states {ds.load_law}: " + str(
                inferred.evidence.get("verdict", "")
            )
        return LoadLaw(ds.load_law, "metadata", ds.load_law_text, ev)
    return LoadLaw(inferred.law, inferred.source, ds.load_law_text, inferred.evidence)


# --------------------------------------------------------------------------------------- predictions
def _context(params: EngineParams, rated_power_W: float | None) -> ModelContext:
    return ModelContext(rated_power_W=rated_power_W or params.P_nom_W)


def predict_columns(
    summaries: Sequence[Mapping[str, float] | None],
    columns: Sequence[str],
    params: EngineParams,
    *,
    rated_power_W: float | None = None,
    p_amb_Pa: float | None = None,
    column_quantity: Mapping[str, str] | None = None,
) -> dict[str, np.ndarray]:
    """Model values of measured-data ``columns`` (in the columns' units) from steady-state summaries.

    Columns without a model counterpart (``fuel_rack``) are left out; a ``None`` summary gives NaN.
    ``column_quantity`` overrides the registry's quantity of a column (resolved ambiguous columns).
    """
    ctx = _context(params, rated_power_W)
    p_amb = params.p_amb_Pa if p_amb_Pa is None else p_amb_Pa
    out = {}
    for col in columns:
        spec = lookup_column(col)
        if spec is None or spec.effective_role == "member":
            continue
        q = QUANTITIES.get((column_quantity or {}).get(col, spec.quantity))
        if q is None or q.model is None:
            continue
        si = np.array([q.model(s, ctx) if s is not None else math.nan for s in summaries], dtype=float)
        out[col] = spec.from_si(si, p_amb)
    return out


# --------------------------------------------------------------------------------------- matching
@dataclass(frozen=True)
class MatchResult:
    """Model predictions at every measured point.

    target : what the fuel setting was matched on (``power``, ``fuel_flow``, ``speed``, ``fuel_rack``);
    target_columns : the data columns that fixed the point (not channels: their residual is zero by
    construction).  u : fuel setting per point (NaN where no match).  status : ``ok`` or why not.
    predicted / measured : per column, in the column's units.  model_si : per summary key, SI arrays.
    channels : columns the model predicts and the match did not use, i.e. the comparison channels.
    """

    dataset: MeasuredDataset
    params: EngineParams
    law: LoadLaw
    target: str
    target_columns: tuple[str, ...]
    u: np.ndarray
    status: tuple[str, ...]
    predicted: dict[str, np.ndarray]
    measured: dict[str, np.ndarray]
    model_si: dict[str, np.ndarray]
    channels: tuple[str, ...]
    notes: tuple[str, ...] = ()

    @property
    def ok(self) -> np.ndarray:
        return np.array([s == "ok" for s in self.status])

    def residual(self, column: str) -> np.ndarray:
        """Model minus measurement in the column's units (NaN where either is missing)."""
        return self.predicted[column] - self.measured[column]

    def residual_si(self, column: str) -> np.ndarray:
        ds = self.dataset
        return ds.to_si(column, self.predicted[column]) - ds.to_si(column, self.measured[column])

    def table(self) -> list[dict[str, Any]]:
        """One row per point: engine, u, status and ``COLUMN``/``COLUMN_model`` for every predicted column."""
        ds = self.dataset
        rows = []
        for i in range(ds.n_points):
            r: dict[str, Any] = {}
            if ds.engines is not None:
                r["engine"] = ds.engines[i]
            r["u"] = float(self.u[i])
            r["status"] = self.status[i]
            for c in ds.columns:
                r[c] = float(self.measured[c][i])
                if c in self.predicted:
                    r[c + "_model"] = float(self.predicted[c][i])
            rows.append(r)
        return rows

    def format_table(self) -> str:
        """The table as aligned text (measured / model per column)."""
        ds = self.dataset
        cols = [c for c in ds.columns if c in self.predicted or c in self.target_columns]
        head = (["engine"] if ds.engines is not None else []) + ["u"] + [c for c in cols]
        lines = ["  ".join(f"{h:>18s}" for h in head)]
        for i in range(ds.n_points):
            cells = ([f"{ds.engines[i]:>18s}"] if ds.engines is not None else []) + [f"{self.u[i]:18.4f}"]
            for c in cols:
                m = self.measured[c][i]
                p = self.predicted.get(c, np.full(ds.n_points, np.nan))[i]
                cells.append(f"{m:8.4g} / {p:<8.4g}".rjust(18))
            lines.append("  ".join(cells))
        return "\n".join(lines)


def _point(ds: MeasuredDataset, i: int) -> dict[str, float]:
    return {q: float(v[i]) for q, v in ds.values.items()}


def resolve_target(ds: MeasuredDataset, target: str) -> str:
    """The matching target ``target`` names, with ``auto`` resolved to the one the dataset's columns allow."""
    v = ds.values
    if target not in TARGETS:
        raise ValueError(f"unknown matching target {target!r}; allowed: {', '.join(TARGETS)}")
    if target != "auto":
        return target
    if "power_W" in v or "load_fraction" in v:
        return "power"
    if "fuel_mass_flow_kg_s" in v or ("sfc_kg_per_J" in v and "power_W" in v):
        return "fuel_flow"
    if "engine_speed_rev_s" in v:
        return "speed"
    if "fuel_rack" in v:
        return "fuel_rack"
    raise ValueError(
        f"{ds.name}: no column fixes the operating point (power, load fraction, fuel flow, speed or fuel rack)"
    )


def target_values(ds: MeasuredDataset, target: str) -> tuple[str, np.ndarray, tuple[str, ...]]:
    """(summary key, SI target per point, data columns used) of a matching target."""
    v = ds.values
    col = ds.column_of
    if target == "power":
        if "power_W" not in v and "load_fraction" not in v:
            raise ValueError(f"{ds.name}: matching on power needs a power or load_fraction column")
        P = v["power_W"].copy() if "power_W" in v else np.full(ds.n_points, np.nan)
        used = tuple(c for c in (col("power_W"), col("load_fraction")) if c is not None)
        if "load_fraction" in v:
            fill = ~np.isfinite(P)
            P[fill] = v["load_fraction"][fill] * ds.rated_power_W
        return "power_W", P, used
    if target == "fuel_flow":
        if "fuel_mass_flow_kg_s" in v:
            return "fuel_mass_flow_kg_s", v["fuel_mass_flow_kg_s"], (col("fuel_mass_flow_kg_s"),)
        if "sfc_kg_per_J" in v and ("power_W" in v or "load_fraction" in v):
            P = v["power_W"] if "power_W" in v else v["load_fraction"] * ds.rated_power_W
            return "fuel_mass_flow_kg_s", v["sfc_kg_per_J"] * P, (col("sfc_kg_per_J"),)
        raise ValueError(f"{ds.name}: matching on fuel flow needs a fuel flow column (or SFC and power)")
    if target == "speed":
        if "engine_speed_rev_s" not in v:
            raise ValueError(f"{ds.name}: matching on speed needs a speed column")
        return "engine_speed_rev_s", v["engine_speed_rev_s"], (col("engine_speed_rev_s"),)
    raise AssertionError(target)


def rack_settings(ds: MeasuredDataset) -> tuple[np.ndarray, str]:
    """u = rack / rack at nominal fuel (sidecar ``fuel_rack_at_nominal``, else per engine at load fraction 1)."""
    rack = ds.values.get("fuel_rack")
    if rack is None:
        raise ValueError(f"{ds.name}: matching on the fuel rack needs a fuel_rack column")
    ref = np.full(ds.n_points, np.nan)
    if "fuel_rack_at_nominal" in ds.meta:
        ref[:] = float(ds.meta["fuel_rack_at_nominal"])
        how = "sidecar fuel_rack_at_nominal"
    elif "load_fraction" in ds.values:
        lf = ds.values["load_fraction"]
        eng = ds.engines or ("",) * ds.n_points
        for e in set(eng):
            idx = [i for i in range(ds.n_points) if eng[i] == e]
            at_nom = [i for i in idx if abs(lf[i] - 1.0) < 0.01 and math.isfinite(rack[i])]
            if at_nom:
                ref[idx] = rack[at_nom[0]]
        how = "rack at load fraction 1 of the same engine"
    else:
        raise ValueError(
            f"{ds.name}: matching on the fuel rack needs fuel_rack_at_nominal in the sidecar or a "
            "point at load fraction 1"
        )
    return rack / ref, how


def match_operating_points(
    ds: MeasuredDataset,
    model: EngineModel | None = None,
    *,
    target: str = "auto",
    law: str | LoadLaw | None = None,
    steady: SteadyFunction | None = None,
    u_bounds: tuple[float, float] = U_BOUNDS,
    rtol: float = 1e-10,
) -> MatchResult:
    """Run the model at every measured point of ``ds``.

    target : ``auto`` (power if the data have power or load fraction, else fuel flow, else speed),
        ``power`` (power column, else load fraction x rated power), ``fuel_flow`` (fuel flow column,
        else SFC x power), ``speed`` or ``fuel_rack`` (u = rack / rack at nominal, no root finding).
    law : load law to use (default: the sidecar's, else inferred, see :func:`load_law_of`).
    steady : steady-state function (default: :func:`base_steady` of ``model``, itself default
        ``EngineModel(ds.params)``).
    The fuel setting of each point is the root of ``steady(u)[key] - target`` in ``u_bounds``
    (brentq, relative tolerance ``rtol`` on u); points whose target lies outside the model's range over
    ``u_bounds`` or whose target is missing get NaN predictions and a status saying why.
    """
    model = model if model is not None else EngineModel(ds.params)
    params = model.params
    steady = steady if steady is not None else base_steady(model)
    if isinstance(law, LoadLaw):
        load_law = law
    elif law is not None:
        load_law = LoadLaw(law, "given", None, load_law_of(ds).evidence)
    else:
        load_law = load_law_of(ds)
    tgt = resolve_target(ds, target)
    notes: list[str] = list(ds.notes)
    n = ds.n_points
    u = np.full(n, np.nan)
    status = ["ok"] * n
    summaries: list[Mapping[str, float] | None] = [None] * n
    lo, hi = u_bounds

    if tgt == "fuel_rack":
        u_rack, how = rack_settings(ds)
        notes.append(
            f"fuel setting = fuel rack / rack at nominal fuel ({how}); assumes fuel per cycle "
            "proportional to the rack (no offset)"
        )
        used = (ds.column_of("fuel_rack"),)
        for i in range(n):
            if not math.isfinite(u_rack[i]):
                status[i] = "missing target (fuel rack or its reference)"
            elif not 0.0 < u_rack[i] <= hi:
                status[i] = f"fuel setting {u_rack[i]:.3f} from the rack outside (0, {hi}]"
            else:
                u[i] = u_rack[i]
                summaries[i] = steady(u[i], _point(ds, i))
    else:
        key, target_si, used = target_values(ds, tgt)
        for i in range(n):
            t = float(target_si[i])
            if not math.isfinite(t):
                status[i] = f"missing target ({tgt})"
                continue
            pt = _point(ds, i)
            f = lambda x: float(steady(x, pt)[key]) - t  # noqa: E731
            f_lo, f_hi = f(lo) + t, f(hi) + t
            if not (min(f_lo, f_hi) <= t <= max(f_lo, f_hi)):
                status[i] = (
                    f"target {key} = {t:.6g} outside the model's range [{min(f_lo, f_hi):.6g}, "
                    f"{max(f_lo, f_hi):.6g}] over u in [{lo}, {hi}]"
                )
                continue
            ui = brentq(f, lo, hi, xtol=1e-14, rtol=max(rtol, 4 * np.finfo(float).eps), maxiter=200)
            u[i] = ui
            summaries[i] = steady(ui, pt)
            err = abs(float(summaries[i][key]) - t) / max(abs(t), 1e-300)
            if err > 1e-6:
                status[i] = f"matched {key} only to {err:.1e} relative"
    if load_law.law in ("constant_speed", "independent") and tgt != "speed" and "engine_speed_rev_s" in ds.values:
        notes.append(
            f"load law {load_law.law}: speed is set independently of power, which the base model's "
            "propeller law (eq. 3.11) cannot honour; its speed residual measures that mismatch"
        )

    for c in ds.columns:
        if ds.column_quantity[c] == "charge_air_cooler_outlet_temperature_K" and params.submodels.intercooler is None:
            notes.append(
                f"{c}: the base model's value is the constant parameter T_c_K "
                f"({params.T_c_K - 273.15:g} C), not a prediction"
            )
    predicted = predict_columns(
        summaries,
        ds.columns,
        params,
        rated_power_W=ds.rated_power_W,
        p_amb_Pa=ds.ambient["p_amb_Pa"],
        column_quantity=ds.column_quantity,
    )
    keys = list(next((s for s in summaries if s is not None), {}).keys())
    model_si = {k: np.array([float(s[k]) if s is not None else math.nan for s in summaries]) for k in keys}
    # load fraction is power / rated power: with a power column it is not a channel of its own
    redundant = {ds.column_of("load_fraction")} if "power_W" in ds.values else set()
    channels = tuple(c for c in ds.columns if c in predicted and c not in used and c not in redundant)
    return MatchResult(
        dataset=ds,
        params=params,
        law=load_law,
        target=tgt,
        target_columns=tuple(used),
        u=u,
        status=tuple(status),
        predicted=predicted,
        measured={c: ds.raw[c].copy() for c in ds.columns},
        model_si=model_si,
        channels=channels,
        notes=tuple(notes),
    )
