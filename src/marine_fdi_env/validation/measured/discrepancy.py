"""Discrepancy analysis: where and how the model misses the measurement, per channel, ranked.

For every comparison channel of a :class:`~marine_fdi_env.validation.measured.matching.MatchResult` the residual
is ``model - measurement`` in the channel's units (a positive bias: the model reads high).  Points where
either side is missing are left out of that channel only (and counted).

Per channel: bias, RMSE, mean relative error ``mean |r| / |measured|`` (on the SI value, i.e. absolute
pressure and kelvin, so that it is a ratio), and the structure of the residuals against the operating
variables ``load`` (load fraction), ``speed`` [rpm] and ``charge pressure`` [bar abs] (measured where the
data have them, else the model's):

* **trend** - ``scipy.stats.linregress`` of the residual on the variable: slope, R^2, p-value; its
  magnitude is the change of the residual over the measured range (slope x range);
* **change point** - the best single breakpoint x0 of a continuous piecewise-linear fit (hinge
  ``a + b x + c max(x - x0, 0)``, at least two distinct values of x on each side), its improvement in
  SSE over the straight line and an F-test (2 extra parameters: slope change and location, which
  is conservative for the search over x0); its magnitude is the largest departure of the piecewise fit
  from the straight line over the data;
* **outliers** - robust z-score ``0.6745 (d - median d) / MAD > 3.5`` of the residuals about their local
  structure: the median residual of the same set point where several engines share it (Birka), else a
  robust (Theil-Sen) line on load, so that a systematic trend does not hide or create outliers.
  Relevant outliers are left out of the trend and change-point fits.

A channel is not tested against its own quantity (charge pressure against charge pressure: circular).
Noise: the tests estimate it from the residual scatter when at least 3 residual degrees of freedom
remain; with fewer points (the 4 complete points of the MAN data) they use the tolerance as the noise
level instead (z and chi-square tests; ``noise`` in each finding says which).

Each finding has a p-value (for trend and change point: Bonferroni-corrected for the choice among
the operating variables) and a ``score = |magnitude| / tolerance``; the tolerance is the smallest
discrepancy worth naming (default 1 % of the measured value for ratio quantities, 5 K for temperatures,
0.01 for load fraction; override per column).  A finding is *significant* when ``p < alpha`` and
``score >= 1``: statistically real and practically relevant.  The ranked list holds the significant
findings by decreasing score, each ``{channel, kind, region, magnitude, score, ...}`` with
``kind`` in ``bias | trend | change_point | outlier`` and ``region`` like ``"all"`` or ``"load > 0.75"``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np
from scipy import stats

from .columns import QUANTITIES
from .matching import MatchResult

__all__ = [
    "ChannelDiscrepancy",
    "DiscrepancyReport",
    "analyse_discrepancies",
    "linear_trend",
    "change_point",
    "robust_zscores",
    "operating_variables",
    "default_tolerance",
    "column_tolerance",
    "KINDS",
    "VARIABLES",
    "VAR_QUANTITY",
    "replicate_groups",
]

KINDS = ("bias", "trend", "change_point", "outlier")
VARIABLES = ("load", "speed", "charge_pressure")
_VAR_UNIT = {"load": "", "speed": " rpm", "charge_pressure": " bar"}
VAR_QUANTITY = {
    "load": ("load_fraction", "power_W"),
    "speed": ("engine_speed_rev_s",),
    "charge_pressure": ("charge_air_pressure_Pa",),
}
_VAR_LABEL = {"load": "load", "speed": "speed", "charge_pressure": "charge pressure"}

REL_TOL = 0.01
TEMPERATURE_TOL_K = 5.0
LOAD_TOL = 0.01
Z_OUTLIER = 3.5


# --------------------------------------------------------------------------------------- statistics
def linear_trend(x, r, sigma: float | None = None, min_dof: int = 3) -> dict[str, float]:
    """Least-squares line of ``r`` on ``x``: slope, intercept, R^2, p-value (H0: slope 0), magnitude.

    The p-value uses the scatter about the line as the noise (``linregress``) when there are at least
    ``min_dof`` residual degrees of freedom; with fewer it uses the known noise level ``sigma`` (z-test),
    or is NaN without one.  ``noise`` says which.
    """
    x, r = np.asarray(x, float), np.asarray(r, float)
    n = int(x.size)
    nan = {
        "slope": math.nan,
        "intercept": math.nan,
        "r2": math.nan,
        "p_value": math.nan,
        "magnitude": math.nan,
        "n": n,
        "noise": "none",
    }
    if n < 3 or np.ptp(x) == 0:
        return nan
    if np.ptp(r) == 0:  # exactly flat residuals: no trend (linregress would divide by zero)
        return {
            "slope": 0.0,
            "intercept": float(r[0]),
            "r2": 0.0,
            "p_value": 1.0,
            "magnitude": 0.0,
            "n": n,
            "noise": "estimated",
        }
    lr = stats.linregress(x, r)
    out = {
        "slope": float(lr.slope),
        "intercept": float(lr.intercept),
        "r2": float(lr.rvalue**2),
        "p_value": float(lr.pvalue),
        "magnitude": float(lr.slope * np.ptp(x)),
        "n": n,
        "noise": "estimated",
    }
    if n - 2 < min_dof:
        if sigma is not None and sigma > 0:
            se = sigma / math.sqrt(float(np.sum((x - x.mean()) ** 2)))
            out["p_value"] = float(2 * stats.norm.sf(abs(lr.slope) / se))
            out["noise"] = "tolerance"
        else:
            out["p_value"], out["noise"] = math.nan, "none"
    return out


def _lstsq_sse(A: np.ndarray, r: np.ndarray) -> tuple[float, np.ndarray]:
    coef, *_ = np.linalg.lstsq(A, r, rcond=None)
    res = r - A @ coef
    return float(res @ res), coef


def change_point(x, r, min_side: int = 2, sigma: float | None = None, min_dof: int = 3) -> dict[str, Any] | None:
    """Best single breakpoint of a continuous piecewise-linear fit of ``r`` on ``x``.

    Candidates are the distinct x values and the midpoints between them that leave at least
    ``min_side`` distinct x values on each side (strictly beyond the breakpoint on the right).
    The improvement over the straight line is tested with an F-test (2 extra parameters) when the
    piecewise fit leaves at least ``min_dof`` degrees of freedom, else with a chi-square test against the
    known noise level ``sigma`` (``noise`` says which).  Returns ``None`` when no breakpoint is possible
    (fewer than 2 min_side distinct x values, or too few points for either test).
    """
    x, r = np.asarray(x, float), np.asarray(r, float)
    ux = np.unique(x)
    m = ux.size
    n = x.size
    known = sigma is not None and sigma > 0
    if m < 2 * min_side or n < 4 or (n - 4 < min_dof and not known):
        return None
    A_lin = np.column_stack([np.ones(n), x])
    sse_lin, _ = _lstsq_sse(A_lin, r)
    cands = []
    for k in range(min_side - 1, m - min_side):
        cands.append(ux[k])
        cands.append(0.5 * (ux[k] + ux[k + 1]))
    cands = sorted({float(c) for c in cands if np.sum(ux > c) >= min_side and np.sum(ux <= c) >= min_side})
    if not cands:
        return None
    best = None
    for x0 in cands:
        A = np.column_stack([np.ones(n), x, np.maximum(x - x0, 0.0)])
        sse, coef = _lstsq_sse(A, r)
        if best is None or sse < best[0] - 1e-12 * max(sse_lin, 1e-300):
            best = (sse, x0, coef, A)
    sse_pw, x0, coef, A = best
    # magnitude: the largest departure of the piecewise fit from the straight line over the data
    dev = A @ coef - A_lin @ _lstsq_sse(A_lin, r)[1]
    magnitude = float(dev[np.argmax(np.abs(dev))])
    gain = max(sse_lin - sse_pw, 0.0)
    df1, df2 = 2, n - 4
    if df2 >= min_dof:
        noise = "estimated"
        if sse_pw <= 1e-24 * max(sse_lin, 1e-300):
            F, p = (math.inf, 0.0) if gain > 0 else (0.0, 1.0)
        else:
            F = (gain / df1) / (sse_pw / df2)
            p = float(stats.f.sf(F, df1, df2))
    else:
        noise = "tolerance"
        F = gain / df1 / sigma**2
        p = float(stats.chi2.sf(gain / sigma**2, df1))
    return {
        "location": x0,
        "slope_left": float(coef[1]),
        "slope_right": float(coef[1] + coef[2]),
        "slope_change": float(coef[2]),
        "sse_linear": sse_lin,
        "sse_piecewise": sse_pw,
        "sse_improvement": gain,
        "sse_improvement_rel": gain / sse_lin if sse_lin > 0 else 0.0,
        "F": float(F),
        "p_value": p,
        "magnitude": magnitude,
        "n": int(n),
        "noise": noise,
    }


def robust_zscores(d) -> np.ndarray:
    """Robust z-scores ``0.6745 (d - median) / MAD`` (inf where MAD = 0 and d differs from the median)."""
    d = np.asarray(d, float)
    med = np.median(d)
    mad = np.median(np.abs(d - med))
    dev = d - med
    if mad == 0:
        return _inf_where_nonzero(dev)
    return 0.6745 * dev / mad


def theil_sen_detrend(r: np.ndarray, ops: Mapping[str, np.ndarray]) -> np.ndarray:
    """Residuals minus a robust (Theil-Sen) line on the first usable operating variable (load
    first), centred on their median."""
    d = r.copy()
    for var in ("load",) + tuple(ops):
        x = ops.get(var)
        if x is not None and np.all(np.isfinite(x)) and np.ptp(x) > 0:
            slope, intercept, *_ = stats.theilslopes(r, x)
            d = r - (intercept + slope * x)
            break
    return d - np.median(d)


def _inf_where_nonzero(d: np.ndarray) -> np.ndarray:
    z = np.zeros_like(d, dtype=float)
    nz = d != 0
    z[nz] = np.copysign(np.inf, d[nz])
    return z


# --------------------------------------------------------------------------------------- report types
@dataclass(frozen=True)
class ChannelDiscrepancy:
    """Statistics of one channel's residuals (``model - measured``, in the channel's units)."""

    channel: str
    quantity: str
    unit: str
    n: int
    n_missing: int
    bias: float
    rmse: float
    std: float
    mean_abs_rel_error: float
    max_abs_error: float
    tolerance: float
    bias_p_value: float
    trends: dict[str, dict[str, float]] = field(default_factory=dict)
    change_points: dict[str, dict[str, Any] | None] = field(default_factory=dict)
    outliers: list[dict[str, Any]] = field(default_factory=list)
    bias_by_engine: dict[str, float] = field(default_factory=dict)
    bias_noise: str = "estimated"
    excluded_from_structure: tuple[int, ...] = ()  # points (1-based) left out of trend / change point

    def as_dict(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in self.__dataclass_fields__}


@dataclass(frozen=True)
class DiscrepancyReport:
    """Per-channel statistics and the ranked findings.

    discrepancies : significant findings, ranked by decreasing score.
    findings : every finding (significant or not) per channel and kind, for inspection.
    """

    dataset: str
    target: str
    channels: dict[str, ChannelDiscrepancy]
    discrepancies: list[dict[str, Any]]
    findings: list[dict[str, Any]]
    operating: dict[str, np.ndarray]
    alpha: float

    @property
    def any_significant(self) -> bool:
        return bool(self.discrepancies)

    def top(self, channel: str | None = None) -> dict[str, Any] | None:
        """The highest-ranked significant discrepancy (of ``channel`` if given)."""
        for d in self.discrepancies:
            if channel is None or d["channel"] == channel:
                return d
        return None

    def summary_table(self) -> str:
        """Per-channel bias, RMSE and relative error, then the ranked discrepancies, as text."""
        lines = [
            f"{self.dataset} (matched on {self.target}): residual = model - measured",
            f"{'channel':34s} {'n':>3s} {'bias':>10s} {'RMSE':>10s} {'mean|rel|':>9s} {'tol':>8s}",
        ]
        for c in self.channels.values():
            lines.append(
                f"{c.channel:34s} {c.n:3d} {c.bias:10.4g} {c.rmse:10.4g} {c.mean_abs_rel_error:9.2%} {c.tolerance:8.3g}"
            )
        lines.append(f"ranked discrepancies (p < {self.alpha}, |magnitude| >= tolerance):")
        if not self.discrepancies:
            lines.append("  none")
        for k, d in enumerate(self.discrepancies, 1):
            lines.append(
                f"  {k:2d}. {d['channel']:34s} {d['kind']:12s} {d['region']:28s} "
                f"magnitude {d['magnitude']:+.4g}  score {d['score']:.1f}  p {d['p_value']:.2g}"
            )
        return "\n".join(lines)

    def to_dict(self) -> dict[str, Any]:
        """JSON-serialisable form (numpy arrays as lists)."""
        return {
            "dataset": self.dataset,
            "target": self.target,
            "alpha": self.alpha,
            "channels": {k: v.as_dict() for k, v in self.channels.items()},
            "discrepancies": self.discrepancies,
            "operating": {k: v.tolist() for k, v in self.operating.items()},
        }


# --------------------------------------------------------------------------------------- analysis
def operating_variables(match: MatchResult) -> dict[str, np.ndarray]:
    """Load fraction, speed [rpm] and charge pressure [bar abs] per point: measured where the data have
    them, else the model's at the matched point."""
    ds, v, m = match.dataset, match.dataset.values, match.model_si
    nan = np.full(ds.n_points, np.nan)

    def pick(measured, model):
        out = nan.copy() if measured is None else np.asarray(measured, float).copy()
        if model is not None:
            fill = ~np.isfinite(out)
            out[fill] = np.asarray(model, float)[fill]
        return out

    rated = ds.rated_power_W
    load_meas = v.get("load_fraction")
    if load_meas is None and "power_W" in v:
        load_meas = v["power_W"] / rated
    load = pick(load_meas, m["power_W"] / rated if "power_W" in m else None)
    speed = pick(
        v["engine_speed_rev_s"] * 60 if "engine_speed_rev_s" in v else None,
        m["engine_speed_rev_s"] * 60 if "engine_speed_rev_s" in m else None,
    )
    pc = pick(
        v["charge_air_pressure_Pa"] / 1e5 if "charge_air_pressure_Pa" in v else None,
        m["charge_air_pressure_Pa"] / 1e5 if "charge_air_pressure_Pa" in m else None,
    )
    return {"load": load, "speed": speed, "charge_pressure": pc}


def default_tolerance(
    match: MatchResult,
    column: str,
    rel_tol: float = REL_TOL,
    temperature_tol_K: float = TEMPERATURE_TOL_K,
    load_tol: float = LOAD_TOL,
) -> float:
    """Smallest discrepancy worth naming on ``column``, in the column's units."""
    return column_tolerance(match.dataset, column, rel_tol, temperature_tol_K, load_tol)


def column_tolerance(
    ds, column: str, rel_tol: float = REL_TOL, temperature_tol_K: float = TEMPERATURE_TOL_K, load_tol: float = LOAD_TOL
) -> float:
    """Smallest discrepancy worth naming on a dataset's ``column``, in the column's units: 1 % of the mean measured
    value (ratio quantities), 5 K (temperatures), 0.01 (load fraction)."""
    spec = ds.spec(column)
    q = QUANTITIES[ds.column_quantity[column]]
    if q.kind == "temperature":
        return temperature_tol_K / spec.scale
    if q.name == "load_fraction":
        return load_tol / spec.scale
    meas_si = ds.values[q.name]
    scale = float(np.nanmean(np.abs(meas_si))) if np.any(np.isfinite(meas_si)) else 1.0
    return rel_tol * scale / spec.scale


def _fmt_region(var: str, x0: float) -> str:
    return f"{_VAR_LABEL[var]} > {x0:.3g}{_VAR_UNIT[var]}"


def analyse_discrepancies(
    match: MatchResult,
    *,
    alpha: float = 0.01,
    tolerances: Mapping[str, float] | None = None,
    rel_tol: float = REL_TOL,
    temperature_tol_K: float = TEMPERATURE_TOL_K,
    z_outlier: float = Z_OUTLIER,
    variables: Sequence[str] = VARIABLES,
    channels: Sequence[str] | None = None,
) -> DiscrepancyReport:
    """Bias, RMSE, relative error and residual structure of every channel of ``match``, ranked.

    tolerances : per column, in the column's units (default: the sidecar's ``tolerances``, else
        :func:`default_tolerance`).
    variables : operating variables to test the residuals against (subset of ``VARIABLES``).
    channels : restrict to these columns (default ``match.channels``).
    """
    ds = match.dataset
    ops_all = operating_variables(match)
    ops = {k: ops_all[k] for k in variables if k in ops_all}
    if tolerances is None:  # the sidecar may state them: {"tolerances": {column: value in its units}}
        tolerances = ds.meta.get("tolerances") if isinstance(ds.meta.get("tolerances"), Mapping) else {}
    tolerances = dict(tolerances)
    out: dict[str, ChannelDiscrepancy] = {}
    findings: list[dict[str, Any]] = []
    for col in channels if channels is not None else match.channels:
        r_all = match.residual(col)
        meas_si = ds.to_si(col, match.measured[col])
        pred_si = ds.to_si(col, match.predicted[col])
        ok = np.isfinite(r_all)
        idx = np.flatnonzero(ok)
        r = r_all[ok]
        n = int(r.size)
        tol = float(tolerances.get(col, default_tolerance(match, col, rel_tol, temperature_tol_K)))
        q = ds.column_quantity[col]
        unit = ds.spec(col).unit
        if n == 0:
            out[col] = ChannelDiscrepancy(
                col, q, unit, 0, int(ds.n_points), math.nan, math.nan, math.nan, math.nan, math.nan, tol, math.nan
            )
            continue
        bias = float(np.mean(r))
        rmse = float(np.sqrt(np.mean(r * r)))
        std = float(np.std(r, ddof=1)) if n > 1 else math.nan
        rel = float(np.mean(np.abs(pred_si[ok] - meas_si[ok]) / np.abs(meas_si[ok])))
        p_bias, bias_noise = _bias_p_value(r, tol)
        by_engine = {}
        if ds.engines is not None:
            eng = np.array(ds.engines)[ok]
            for e in dict.fromkeys(eng):
                by_engine[str(e)] = float(np.mean(r[eng == e]))

        # a channel's residual is not tested against its own quantity (circular: r = model - x)
        ch_ops = {k: v[ok] for k, v in ops.items() if q not in VAR_QUANTITY[k]}
        # ratio quantities: errors scale with the value, so outliers are judged on relative residuals
        if QUANTITIES[q].kind == "ratio":
            w = np.abs(meas_si[ok]) / np.mean(np.abs(meas_si[ok]))
        else:
            w = np.ones(n)
        outliers = _outliers(ds, idx, r, ch_ops, z_outlier, w)
        # trend and change point without the relevant outliers, which would otherwise shape them
        drop = {o["point"] - 1 for o in outliers if abs(o["deviation"]) >= tol * o["weight"]}
        keep = np.array([int(i) not in drop for i in idx], dtype=bool)
        trends, cps = {}, {}
        for var, x in ch_ops.items():
            good = np.isfinite(x) & keep
            trends[var] = linear_trend(x[good], r[good], sigma=tol)
            cps[var] = change_point(x[good], r[good], sigma=tol)
        ch = ChannelDiscrepancy(
            col,
            q,
            unit,
            n,
            int(ds.n_points - n),
            bias,
            rmse,
            std,
            rel,
            float(np.max(np.abs(r))),
            tol,
            p_bias,
            trends,
            cps,
            outliers,
            by_engine,
            bias_noise,
            tuple(sorted(i + 1 for i in drop)),
        )
        out[col] = ch
        findings.extend(_channel_findings(ch, alpha, tol))

    findings.sort(key=lambda f: -f["score"] if math.isfinite(f["score"]) else -1e300)
    ranked = [f for f in findings if f["significant"]]
    for k, f in enumerate(ranked, 1):
        f["rank"] = k
    return DiscrepancyReport(
        dataset=ds.name,
        target=match.target,
        channels=out,
        discrepancies=ranked,
        findings=findings,
        operating=ops,
        alpha=alpha,
    )


def _bias_p_value(r: np.ndarray, tol: float, min_dof: int = 3) -> tuple[float, str]:
    """p-value of a zero mean: t-test when the residuals have >= min_dof degrees of freedom, else a z-test
    with the tolerance as the noise level."""
    n = r.size
    bias = float(np.mean(r))
    if n - 1 >= min_dof:
        std = float(np.std(r, ddof=1))
        if std == 0:
            return (0.0 if bias != 0 else 1.0), "estimated"
        return float(stats.ttest_1samp(r, 0.0).pvalue), "estimated"
    if tol > 0:
        return float(2 * stats.norm.sf(abs(bias) / (tol / math.sqrt(n)))), "tolerance"
    return math.nan, "none"


def replicate_groups(ds, idx: np.ndarray) -> list[np.ndarray]:
    """Positions (into idx) of points sharing a set point (load, speed, power columns), groups of >= 2."""
    from .plausibility import SETPOINT_QUANTITIES

    keys = [q for q in SETPOINT_QUANTITIES if q in ds.values]
    if not keys:
        return []
    groups: dict[tuple, list[int]] = {}
    for k, i in enumerate(idx):
        key = tuple(round(float(ds.values[q][i]), 9) for q in keys)
        if all(math.isfinite(v) for v in key):
            groups.setdefault(key, []).append(k)
    return [np.array(g) for g in groups.values() if len(g) >= 2]


def _outliers(
    ds,
    idx: np.ndarray,
    r_abs: np.ndarray,
    ops: Mapping[str, np.ndarray],
    z_outlier: float,
    weight: np.ndarray | None = None,
) -> list[dict]:
    """Points whose residual deviates from the local structure by a robust z-score above ``z_outlier``.

    With replicated set points (several engines at the same load) the structure is the median residual
    of each set point and only replicated points are tested; the scale is the MAD of the deviations,
    leaving out the zero of each odd group's median member (zero by construction, it would bias the
    scale low).  Otherwise the structure is a robust (Theil-Sen) line on load (else the first operating
    variable available) and the scale the MAD about it.  Needs at least 5 tested points.
    ``weight``: the residuals are judged as ``r / weight`` (relative residuals for ratio quantities);
    deviations are reported in the channel's units.
    """
    w = np.ones(r_abs.size) if weight is None else np.asarray(weight, float)
    r = r_abs / w
    n = r.size
    groups = replicate_groups(ds, idx)
    if groups and sum(len(g) for g in groups) >= max(5, n // 2):
        pos = np.concatenate(groups)
        devs = [r[g] - np.median(r[g]) for g in groups]
        d = np.concatenate(devs)
        scale_d = np.concatenate([np.delete(dv, np.argmin(np.abs(dv))) if dv.size % 2 else dv for dv in devs])
        mad = float(np.median(np.abs(scale_d)))
        z = _inf_where_nonzero(d) if mad == 0 else 0.6745 * d / mad
    else:
        if n < 5:
            return []
        pos = np.arange(n)
        d = theil_sen_detrend(r, ops)
        z = robust_zscores(d)
    out = []
    for k in np.flatnonzero(np.abs(z) > z_outlier):
        i = int(idx[pos[k]])
        out.append(
            {
                "point": i + 1,
                "label": ds.point_label(i),
                "residual": float(r_abs[pos[k]]),
                "deviation": float(d[k] * w[pos[k]]),
                "robust_z": float(z[k]),
                "weight": float(w[pos[k]]),
            }
        )
    return out


def _pick_variable(items: list[tuple[str, dict]], key, rel_tie: float) -> tuple[str, dict]:
    """The best (smallest ``key``) operating variable; within ``rel_tie`` of the best, the first in VARIABLES."""
    best = min(key(d) for _, d in items)
    order = {v: k for k, v in enumerate(VARIABLES)}
    close = [(v, d) for v, d in items if key(d) <= best + rel_tie * abs(best) + 1e-300]
    return min(close, key=lambda vd: order.get(vd[0], 99))


def _finding(
    ch: ChannelDiscrepancy, kind: str, region: str, magnitude: float, p: float, alpha: float, tol: float, **extra
) -> dict[str, Any]:
    score = abs(magnitude) / tol if tol > 0 and math.isfinite(magnitude) else math.nan
    sig = bool(math.isfinite(p) and p < alpha and math.isfinite(score) and score >= 1.0)
    return {
        "channel": ch.channel,
        "kind": kind,
        "region": region,
        "magnitude": float(magnitude),
        "score": float(score),
        "p_value": float(p),
        "significant": sig,
        "unit": ch.unit,
        **extra,
    }


def _channel_findings(ch: ChannelDiscrepancy, alpha: float, tol: float) -> list[dict[str, Any]]:
    f = [_finding(ch, "bias", "all", ch.bias, ch.bias_p_value, alpha, tol, rmse=ch.rmse, noise=ch.bias_noise)]
    # trend: the operating variable whose line leaves the least unexplained (highest R^2; ties -> load)
    tr = [(v, t) for v, t in ch.trends.items() if math.isfinite(t["r2"])]
    if tr:
        var, t = _pick_variable(tr, lambda d: 1.0 - d["r2"], 0.05)
        f.append(
            _finding(
                ch,
                "trend",
                "all",
                t["magnitude"],
                min(1.0, t["p_value"] * len(tr)),
                alpha,
                tol,
                variable=var,
                slope=t["slope"],
                r2=t["r2"],
                noise=t["noise"],
                p_value_raw=t["p_value"],
            )
        )
    # change point: the variable with the best piecewise fit (smallest SSE; ties -> load)
    cp = [(v, c) for v, c in ch.change_points.items() if c is not None]
    if cp:
        var, c = _pick_variable(cp, lambda d: d["sse_piecewise"], 0.05)
        f.append(
            _finding(
                ch,
                "change_point",
                _fmt_region(var, c["location"]),
                c["magnitude"],
                min(1.0, c["p_value"] * len(cp)),
                alpha,
                tol,
                variable=var,
                p_value_raw=c["p_value"],
                location=c["location"],
                slope_change=c["slope_change"],
                sse_improvement=c["sse_improvement"],
                sse_improvement_rel=c["sse_improvement_rel"],
                F=c["F"],
                noise=c["noise"],
            )
        )
    for o in ch.outliers:
        # p-value of a robust z under normal residuals (two-sided)
        p = float(2 * stats.norm.sf(abs(o["robust_z"]))) if math.isfinite(o["robust_z"]) else 0.0
        # ratio quantities: the tolerance of a point scales with its value like the residuals do
        f.append(
            _finding(
                ch,
                "outlier",
                o["label"],
                o["deviation"],
                p,
                alpha,
                tol * o["weight"],
                robust_z=o["robust_z"],
                point=o["point"],
            )
        )
    return f
