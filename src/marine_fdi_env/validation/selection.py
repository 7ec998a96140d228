"""Model selection: which named mechanism (or combination) explains the discrepancies, and by how much.

Pipeline (:func:`select_causes`):

1. **Problem.**  A measured dataset prepared for repeated evaluation of the extended model
   (:class:`Problem`): what fixes each operating point (power, fuel flow, speed or fuel rack, as in
   :mod:`.matching`), the comparison channels, the measurements and a tolerance per channel (the
   sidecar's ``tolerances``, else :func:`~.discrepancy.default_tolerance`: 1 % of the mean value,
   5 K for temperatures).  Residuals are ``(model - measured) / tolerance``.
2. **Fit.**  Each candidate (a combination of mechanisms) is fitted with
   :func:`scipy.optimize.least_squares` (trust-region reflective within the mechanisms' plausible
   ranges, multi-start where a mechanism lists extra starts) under the robust ``soft_l1`` loss with
   a scale of 3 tolerances, so that a single bad reading (Birka ME2's 1.3 bar at 25 % load) bends
   the fit little; nothing is removed from the data.  Parameter uncertainty: the covariance
   ``s^2 (J^T J)^-1`` of the Gauss-Newton approximation at the optimum with ``s^2`` the robust cost
   per degree of freedom (standard errors in the mechanisms' units).
3. **Cross-validation.**  Leave-one-engine-out when the dataset has several engines, else
   leave-one-point-out: every fold refits the candidate on the other engines/points (warm-started
   at the full-data fit) and predicts the left-out ones.  The base model has nothing to fit: its
   cross-validated prediction is its prediction.
4. **Score.**  ``S`` = mean robust loss per measured cell of the cross-validated residuals (about
   the mean squared normalised error; 1 = errors at the tolerance); penalised score
   ``S exp(2 k / M)`` with ``k`` free parameters and ``M`` measured cells (the AIC penalty of 2 per
   parameter on ``M ln S``).
5. **Greedy forward selection.**  Starting from the base model, every remaining mechanism is
   added in turn (refitting all parameters); the best penalised score is accepted when it is
   (a) better than the current model's penalised score, (b) at least ``min_gain`` (10 %) lower in
   ``S`` and (c) significant: the one-sided F-test of the drop of the cross-validated loss per added
   parameter against the candidate's loss per residual degree of freedom (the likelihood-ratio test
   of nested least squares, here on cross-validated residuals) gives ``p < alpha / (number of
   candidates tried in the step)`` (Bonferroni, alpha = 0.01).  A paired t-test of the per-point
   losses is reported too (``p_value_points``); it is not used to decide because an effect confined
   to a few points (a bypass opening near full load) can never reach a small p over points as units.
   Selection stops at the first step where nothing qualifies.
6. **Unexplained.**  The discrepancy analysis of :mod:`.discrepancy` runs on the final model's
   residuals (the base model's if nothing was selected).  Its significant findings are reported as
   ``unexplained: channel, kind, region``; outliers need ``p x (number of tested points) < alpha``
   (Bonferroni over the points of the channel) since every point is tested.
"""

from __future__ import annotations

import math
import time
import warnings
from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Any, Mapping, Sequence

import numpy as np
from scipy import stats
from scipy.optimize import least_squares

from ..params import EngineParams, load_params
from .columns import COLUMNS, QUANTITIES
from .dataset import MeasuredDataset
from .discrepancy import (_VAR_QUANTITY, DiscrepancyReport, _replicate_groups, analyse_discrepancies, theil_sen_detrend,
                          default_tolerance, operating_variables)
from .extended_model import MODE_F, MODE_P, MODE_U, NO_HOOKS, SUMMARY_KEYS, ExtendedModel, Hooks
from .matching import MatchResult, _rack_settings, _resolve_target, _target_values, load_law_of
from .mechanisms import Mechanism, library, sensor_reference

__all__ = [
    "Problem", "Combination", "FitResult", "CandidateScore", "Selection", "fit_combination", "cross_validate",
    "cell_losses", "select_causes", "channel_rmse", "point_outliers", "family_significant", "ROBUST_SCALE",
]

ROBUST_SCALE = 3.0  # soft_l1 scale in tolerance units
FAIL_RESIDUAL = 50.0  # normalised residual of a cell whose point has no steady state


def robust_loss(r: np.ndarray) -> np.ndarray:
    """Per-cell soft_l1 loss ``2 f^2 (sqrt(1 + (r/f)^2) - 1)`` (≈ r^2 for |r| << f = ROBUST_SCALE)."""
    f = ROBUST_SCALE
    return 2.0 * f * f * (np.sqrt(1.0 + (r / f) ** 2) - 1.0)


# --------------------------------------------------------------------------------------- problem
def _read_quantity(q: str, V: Mapping[str, np.ndarray], rated_W: float) -> np.ndarray:
    """SI values of quantity ``q`` from steady-state arrays (keys: SUMMARY_KEYS)."""
    if q in V:
        return np.asarray(V[q], float)
    P = np.asarray(V["power_W"], float)
    with np.errstate(divide="ignore", invalid="ignore"):
        if q == "load_fraction":
            return P / rated_W
        if q == "specific_air_flow_kg_per_J":
            return np.where(P > 0, V["air_mass_flow_kg_s"] / P, np.nan)
        if q == "specific_exhaust_flow_kg_per_J":
            return np.where(P > 0, V["exhaust_mass_flow_kg_s"] / P, np.nan)
    raise KeyError(f"the extended model has no quantity {q!r}")


class Problem:
    """A measured dataset prepared for fitting the extended model (see module docstring).

    ds : the dataset.  params : parameter set (name or :class:`EngineParams`; default the sidecar's).
    target : what fixes each point (as :func:`~.matching.match_operating_points`).
    tolerances : per column in its units (default: sidecar ``tolerances``, else the defaults).
    """

    def __init__(self, ds: MeasuredDataset, *, params: str | EngineParams | None = None, target: str = "auto",
                 tolerances: Mapping[str, float] | None = None):
        self.ds = ds
        if isinstance(params, str):
            params = load_params(params)
        self.params: EngineParams = params if params is not None else ds.params
        self.target = _resolve_target(ds, target)
        self.law = load_law_of(ds)
        n = ds.n_points
        self.n_points = n
        nan = np.full(n, np.nan)
        self.speed_measured = ds.values.get("engine_speed_rev_s", nan).astype(float)
        if self.target == "fuel_rack":
            self.target_si, _ = _rack_settings(ds)
            self.target_columns: tuple[str, ...] = (ds.column_of("fuel_rack"),)
        else:
            _, self.target_si, self.target_columns = _target_values(ds, self.target)
        self.predicted_columns = tuple(c for c in ds.columns if QUANTITIES[ds.column_quantity[c]].model is not None)
        redundant = {ds.column_of("load_fraction")} if "power_W" in ds.values else set()
        self.channels = tuple(c for c in self.predicted_columns if c not in self.target_columns and c not in redundant)
        if not self.channels:
            raise ValueError(f"{ds.name}: no channel to compare (every predicted column fixes the operating point)")
        self.Y = np.column_stack([ds.raw[c] for c in self.channels]).astype(float)
        self.measured_mask = np.isfinite(self.Y)
        if tolerances is None:
            tolerances = ds.meta.get("tolerances") if isinstance(ds.meta.get("tolerances"), Mapping) else {}
        shim = SimpleNamespace(dataset=ds)
        self.tolerance = np.array([float(tolerances.get(c, default_tolerance(shim, c))) for c in self.channels])
        self.references = {c: sensor_reference(c, self.Y[:, j]) for j, c in enumerate(self.channels)}
        self._state = np.full((n, 3), np.nan)
        self.n_evaluations = 0
        self.eval_seconds = 0.0

    # ---- model evaluation
    def model(self, hooks: Hooks = NO_HOOKS) -> ExtendedModel:
        return ExtendedModel(self.params, hooks)

    def _inputs(self, model: ExtendedModel, rows: np.ndarray) -> tuple[int, np.ndarray, np.ndarray]:
        t = self.target_si[rows]
        n_meas = self.speed_measured[rows]
        with np.errstate(invalid="ignore", divide="ignore"):
            if self.target == "power":
                n = model.speed_of_power(t, n_meas) if model.hooks.speed_law != "prescribed" else n_meas
                a0, a1, mode = t, n, MODE_P
            elif self.target == "speed":
                try:
                    P = model.power_of_speed(t)
                except ValueError:
                    P = np.full(t.size, np.nan)
                a0, a1, mode = P, t, MODE_P
            elif self.target == "fuel_flow":
                a0, a1, mode = t, n_meas, MODE_F
            else:
                a0, a1, mode = t, n_meas, MODE_U
            a0 = np.where(np.isfinite(a0) & (a0 > 0), a0, np.nan)
            if mode == MODE_P:
                a1 = np.where(np.isfinite(a1) & (a1 > 0), a1, np.nan)
            else:
                a1 = np.where(np.isfinite(a1), a1, 0.0)
        return mode, np.asarray(a0, float), np.asarray(a1, float)

    def solve(self, hooks: Hooks = NO_HOOKS, rows=None):
        """Steady states at the rows' operating points: (model, SteadyPoints, rows)."""
        rows = np.arange(self.n_points) if rows is None else np.asarray(rows, dtype=int)
        t0 = time.perf_counter()
        model = self.model(hooks)
        mode, a0, a1 = self._inputs(model, rows)
        guess = self._state[rows]
        pts = model.solve(mode, a0, a1, guess=guess)
        conv = pts.converged
        if np.any(conv):
            st = self._state[rows]
            st[conv] = pts.state[conv]
            self._state[rows] = st
        self.n_evaluations += 1
        self.eval_seconds += time.perf_counter() - t0
        return model, pts, rows

    def predict_columns(self, model: ExtendedModel, pts, columns: Sequence[str]) -> np.ndarray:
        """Model readings of ``columns`` (their units, sensor hooks applied), NaN where not converged."""
        ds = self.ds
        out = np.empty((len(pts), len(columns)))
        p_amb = ds.ambient["p_amb_Pa"] + model.hooks.dp_amb_Pa  # a gauge reads against the actual ambient
        for j, col in enumerate(columns):
            si = _read_quantity(ds.column_quantity[col], pts.values, ds.rated_power_W)
            v = model.sensor_reading(col, COLUMNS[col].from_si(si, p_amb))
            out[:, j] = np.where(pts.converged, v, np.nan)
        return out

    def predict(self, hooks: Hooks = NO_HOOKS, rows=None) -> tuple[np.ndarray, np.ndarray]:
        """(predictions (rows x channels) in the channels' units, converged per row)."""
        model, pts, rows = self.solve(hooks, rows)
        return self.predict_columns(model, pts, self.channels), pts.converged

    def normalised_residuals(self, pred: np.ndarray, rows=None) -> np.ndarray:
        """``(pred - measured)/tolerance`` on the measured cells of ``rows`` (FAIL_RESIDUAL where the model has
        no value), NaN on cells without a measurement."""
        rows = np.arange(self.n_points) if rows is None else np.asarray(rows, dtype=int)
        r = (pred - self.Y[rows]) / self.tolerance
        m = self.measured_mask[rows]
        r = np.where(m & ~np.isfinite(r), FAIL_RESIDUAL, r)
        return np.where(m, r, np.nan)

    def rows_with_data(self) -> np.ndarray:
        return np.flatnonzero(self.measured_mask.any(axis=1) & np.isfinite(self.target_si))

    def folds(self) -> tuple[str, list[tuple[str, np.ndarray]]]:
        """Cross-validation folds: leave-one-engine-out with several engines, else leave-one-point-out."""
        rows = self.rows_with_data()
        eng = self.ds.engine_ids()
        if len(eng) >= 2:
            e = np.array(self.ds.engines)
            return "leave-one-engine-out", [(str(x), np.array([i for i in rows if e[i] == x], dtype=int))
                                            for x in eng]
        return "leave-one-point-out", [(f"point {i + 1}", np.array([i], dtype=int)) for i in rows]

    def match_result(self, hooks: Hooks = NO_HOOKS) -> MatchResult:
        """A :class:`~.matching.MatchResult` of the (extended) model, for the discrepancy analysis."""
        ds = self.ds
        model, pts, rows = self.solve(hooks)
        pred = self.predict_columns(model, pts, self.predicted_columns)
        status = tuple("ok" if ok else ("missing target" if not math.isfinite(self.target_si[i])
                                        else "no steady state of the extended model")
                       for i, ok in enumerate(pts.converged))
        V = pts.values
        return MatchResult(
            dataset=ds, params=self.params, law=self.law, target=self.target, target_columns=self.target_columns,
            u=np.where(pts.converged, V["fuel_setting"], np.nan), status=status,
            predicted={c: pred[:, j] for j, c in enumerate(self.predicted_columns)},
            measured={c: ds.raw[c].copy() for c in ds.columns},
            model_si={k: np.where(pts.converged, V[k], np.nan) for k in SUMMARY_KEYS},
            channels=self.channels, notes=tuple(ds.notes))


# --------------------------------------------------------------------------------------- combinations
@dataclass(frozen=True)
class Combination:
    """A set of mechanisms fitted together; its parameter vector concatenates theirs."""

    mechanisms: tuple[Mechanism, ...] = ()

    @property
    def labels(self) -> tuple[str, ...]:
        return tuple(m.label for m in self.mechanisms)

    @property
    def ids(self) -> tuple[str, ...]:
        return tuple(m.id for m in self.mechanisms)

    @property
    def names(self) -> list[str]:
        return [f"{m.label}.{p.name}" for m in self.mechanisms for p in m.params]

    @property
    def n_params(self) -> int:
        return sum(len(m.params) for m in self.mechanisms)

    def plus(self, m: Mechanism) -> "Combination":
        return Combination(self.mechanisms + (m,))

    def unpack(self, x) -> list[tuple[Mechanism, dict[str, float]]]:
        out, k = [], 0
        for m in self.mechanisms:
            vals = {}
            for p in m.params:
                vals[p.name] = float(x[k])
                k += 1
            out.append((m, vals))
        return out

    def hooks(self, x, params: EngineParams) -> Hooks:
        h = NO_HOOKS
        for m, v in self.unpack(x):
            h = m.apply(h, v, params)
        return h

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        lo = np.array([p.bounds[0] for m in self.mechanisms for p in m.params], float)
        hi = np.array([p.bounds[1] for m in self.mechanisms for p in m.params], float)
        return lo, hi

    def starts(self, known: Mapping[str, float] | None = None) -> list[np.ndarray]:
        """Starting vectors: defaults (or ``known`` values by name), then each extra start of each parameter."""
        known = known or {}
        x0 = np.array([known.get(f"{m.label}.{p.name}", p.default) for m in self.mechanisms for p in m.params], float)
        out = [x0]
        k = 0
        for m in self.mechanisms:
            for p in m.params:
                if f"{m.label}.{p.name}" not in known:
                    for s in p.starts:
                        x = x0.copy()
                        x[k] = s
                        out.append(x)
                k += 1
        return out


@dataclass
class FitResult:
    """Fitted parameters of a combination on some rows."""

    combination: Combination
    x: np.ndarray
    stderr: np.ndarray
    cov: np.ndarray
    cost: float  # robust cost 0.5 sum(loss)
    n_cells: int
    success: bool
    at_bound: np.ndarray
    nfev: int
    message: str = ""

    def values(self) -> dict[str, float]:
        return dict(zip(self.combination.names, map(float, self.x)))

    def hooks(self, params: EngineParams) -> Hooks:
        return self.combination.hooks(self.x, params)

    def parameters(self) -> dict[str, dict[str, dict[str, Any]]]:
        """``{mechanism label: {param: {value, stderr, unit, at_bound, bounds}}}``."""
        out: dict[str, dict[str, dict[str, Any]]] = {}
        k = 0
        for m in self.combination.mechanisms:
            d = {}
            for p in m.params:
                d[p.name] = {"value": float(self.x[k]), "stderr": float(self.stderr[k]), "unit": p.unit,
                             "at_bound": bool(self.at_bound[k]), "bounds": [float(b) for b in p.bounds],
                             "description": p.description}
                k += 1
            out[m.label] = d
        return out


def _clip_into(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Starting values at least 0.1 % of the range inside the bounds: the trust-region reflective method
    stalls (terminates on xtol without moving) when it starts on a bound."""
    span = hi - lo
    return np.minimum(np.maximum(x, lo + 1e-3 * span), hi - 1e-3 * span)


def fit_combination(problem: Problem, comb: Combination, rows=None, starts: Sequence[np.ndarray] | None = None,
                    max_nfev: int | None = None, uncertainty: bool = True) -> FitResult:
    """Fit ``comb`` on ``rows`` (default all) with :func:`scipy.optimize.least_squares` from each start
    (``uncertainty``: also the parameter covariance)."""
    rows = problem.rows_with_data() if rows is None else np.asarray(rows, dtype=int)
    k = comb.n_params
    mask = problem.measured_mask[rows]
    m = int(mask.sum())
    if k == 0:
        pred, _ = problem.predict(NO_HOOKS, rows)
        r = problem.normalised_residuals(pred, rows)[mask]
        return FitResult(comb, np.zeros(0), np.zeros(0), np.zeros((0, 0)), float(0.5 * robust_loss(r).sum()), m,
                         True, np.zeros(0, bool), 1)
    lo, hi = comb.bounds()
    params = problem.params

    def fun(x):
        pred, _ = problem.predict(comb.hooks(x, params), rows)
        return problem.normalised_residuals(pred, rows)[mask]

    best = None
    for x0 in (starts if starts is not None else comb.starts()):
        x0 = _clip_into(np.asarray(x0, float), lo, hi)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            res = least_squares(fun, x0, bounds=(lo, hi), x_scale=hi - lo, loss="soft_l1", f_scale=ROBUST_SCALE,
                                diff_step=1e-6, xtol=1e-10, ftol=1e-10, max_nfev=max_nfev or 60 * (k + 1))
        if best is None or res.cost < best.cost:
            best = res
    res = best
    x = np.asarray(res.x, float)
    if uncertainty:
        cov = _covariance(fun, x, np.asarray(res.fun, float), lo, hi, m)
    else:
        cov = np.full((k, k), np.nan)
    stderr = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    return FitResult(comb, x, stderr, cov, float(res.cost), m, bool(res.success),
                     np.asarray(res.active_mask) != 0, int(res.nfev), str(res.message))


def _covariance(fun, x: np.ndarray, r0: np.ndarray, lo: np.ndarray, hi: np.ndarray, m: int) -> np.ndarray:
    """Parameter covariance ``s^2 (J^T W J)^-1`` at the optimum: J by forward differences of the raw
    normalised residuals, W the soft_l1 weights ``1/sqrt(1 + (r/f)^2)`` (iteratively reweighted least
    squares), s^2 the weighted residual sum of squares per degree of freedom."""
    k = x.size
    J = np.empty((r0.size, k))
    for j in range(k):
        h = 1e-6 * max(abs(x[j]), 1e-3 * (hi[j] - lo[j]))
        if x[j] + h > hi[j]:
            h = -h
        xj = x.copy()
        xj[j] += h
        J[:, j] = (fun(xj) - r0) / h
    w = 1.0 / np.sqrt(1.0 + (r0 / ROBUST_SCALE) ** 2)
    s2 = float(np.sum(w * r0 * r0)) / max(m - k, 1)
    A = J.T @ (w[:, None] * J)
    try:
        return s2 * np.linalg.pinv(A)
    except np.linalg.LinAlgError:
        return np.full((k, k), np.nan)


def cross_validate(problem: Problem, comb: Combination, full: FitResult | None = None) -> tuple[np.ndarray, list]:
    """Cross-validated predictions (points x channels) of ``comb`` and the fold fits."""
    n, C = problem.n_points, len(problem.channels)
    pred = np.full((n, C), np.nan)
    _, folds = problem.folds()
    if comb.n_params == 0:
        p, _ = problem.predict(NO_HOOKS)
        return p, []
    if full is None:
        full = fit_combination(problem, comb)
    all_rows = problem.rows_with_data()
    fits = []
    for name, test in folds:
        train = np.setdiff1d(all_rows, test)
        if train.size == 0 or not problem.measured_mask[train].any():
            continue
        f = fit_combination(problem, comb, train, starts=[full.x], max_nfev=30 * (comb.n_params + 1),
                            uncertainty=False)
        p, _ = problem.predict(f.hooks(problem.params), test)
        pred[test] = p
        fits.append((name, f))
    return pred, fits


def cell_losses(problem: Problem, pred: np.ndarray) -> tuple[np.ndarray, int]:
    """Robust loss per point (sum over its measured cells) and the number of measured cells."""
    r = problem.normalised_residuals(pred)
    L = np.where(problem.measured_mask, robust_loss(np.nan_to_num(r)), 0.0)
    return L.sum(axis=1), int(problem.measured_mask.sum())


def channel_rmse(problem: Problem, pred: np.ndarray, rows=None) -> dict[str, float]:
    """RMSE per channel (channel units) over the measured cells of ``rows``."""
    rows = np.arange(problem.n_points) if rows is None else np.asarray(rows, int)
    out = {}
    for j, c in enumerate(problem.channels):
        e = pred[rows, j] - problem.Y[rows, j]
        m = problem.measured_mask[rows, j]
        e = e[m]
        out[c] = float(np.sqrt(np.mean(np.where(np.isfinite(e), e, np.inf) ** 2))) if e.size else math.nan
    return out


# --------------------------------------------------------------------------------------- selection
@dataclass
class CandidateScore:
    """A candidate combination scored against the current model of its greedy step.

    in_sample_score : mean robust loss per cell of the full-data fit.  cv_score : the same for the
    cross-validated predictions (NaN when the candidate was screened out, see ``screened``).
    """

    combination: Combination
    added: str
    fit: FitResult
    in_sample_score: float
    cv_pred: np.ndarray | None = None
    cv_score: float = math.nan
    penalised: float = math.nan
    gain: float = math.nan  # relative drop of the CV score against the current model
    p_value: float = math.nan  # one-sided F-test of the CV loss drop (decides significance)
    p_value_points: float = math.nan  # one-sided paired t-test of the per-point CV losses (information)
    point_losses: np.ndarray | None = None
    screened: str = ""

    @property
    def cross_validated(self) -> bool:
        return self.cv_pred is not None

    def as_dict(self) -> dict[str, Any]:
        d = {"mechanism": self.added, "id": self.combination.mechanisms[-1].id,
             "combination": list(self.combination.labels),
             "n_params": self.combination.n_params, "in_sample_score": self.in_sample_score,
             "cv_score": _num(self.cv_score), "penalised_score": _num(self.penalised),
             "gain_vs_current": _num(self.gain), "p_value": _num(self.p_value),
             "p_value_points": _num(self.p_value_points),
             "fit": self.fit.values(), "fit_stderr": dict(zip(self.combination.names, map(float, self.fit.stderr)))}
        if self.screened:
            d["screened"] = self.screened
        return d


def _num(x: float) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


@dataclass
class Selection:
    """Outcome of :func:`select_causes`."""

    problem: Problem
    cv_scheme: str
    base_pred: np.ndarray
    base_score: float
    base_report: DiscrepancyReport
    steps: list[dict[str, Any]]
    selected: Combination
    fit: FitResult
    cv_pred: np.ndarray
    cv_score: float
    final_report: DiscrepancyReport
    unexplained: list[dict[str, Any]]
    outliers: list[dict[str, Any]]
    base_outliers: list[dict[str, Any]]
    seconds: float
    settings: dict[str, Any] = field(default_factory=dict)

    @property
    def selected_causes(self) -> list[str]:
        return list(self.selected.ids)

    @property
    def selected_labels(self) -> list[str]:
        return list(self.selected.labels)

    @property
    def hooks(self) -> Hooks:
        return self.fit.hooks(self.problem.params)

    def candidates(self) -> list[dict[str, Any]]:
        """Every candidate of every step with its CV score (first step: each mechanism alone)."""
        out = []
        for s in self.steps:
            for c in s["candidates"]:
                d = c.as_dict()
                d["step"] = s["step"]
                out.append(d)
        return out

    def cv_rmse(self) -> dict[str, dict[str, float]]:
        b = channel_rmse(self.problem, self.base_pred)
        e = channel_rmse(self.problem, self.cv_pred)
        return {c: {"cv_rmse_base": b[c], "cv_rmse_extended": e[c]} for c in self.problem.channels}


def _f_test_p(S_current: float, S_cand: float, k_current: int, k_cand: int, M: int) -> float:
    """One-sided F-test of the drop of the cross-validated loss per added parameter against the
    candidate's loss per residual degree of freedom (the likelihood-ratio test of nested least squares,
    on cross-validated residuals)."""
    dk = max(k_cand - k_current, 1)
    dof = max(M - k_cand, 1)
    if S_cand <= 0:
        return 0.0 if S_current > 0 else 1.0
    F = ((S_current - S_cand) * M / dk) / (S_cand * M / dof)
    return float(stats.f.sf(F, dk, dof)) if F > 0 else 1.0


def _paired_p(current: np.ndarray, cand: np.ndarray, rows: np.ndarray) -> float:
    d = current[rows] - cand[rows]
    if d.size < 2 or np.allclose(d, d[0]):
        return 0.0 if d.size and d[0] > 0 and d.size >= 2 else 1.0
    return float(stats.ttest_1samp(d, 0.0, alternative="greater").pvalue)


def _local_deviations(ds, idx: np.ndarray, r: np.ndarray, ops: Mapping[str, np.ndarray]):
    """Deviations of the residuals from their local structure (as :mod:`.discrepancy`: the median of
    replicated set points, else a Theil-Sen line on load); returns (positions into idx, deviations,
    mask of the deviations that carry information (not the zero of an odd group's median member))."""
    groups = _replicate_groups(ds, idx)
    n = r.size
    if groups and sum(len(g) for g in groups) >= max(5, n // 2):
        pos, dev, info = [], [], []
        for g in groups:
            d = r[g] - np.median(r[g])
            keep = np.ones(g.size, bool)
            if g.size % 2:
                keep[np.argmin(np.abs(d))] = False
            pos.append(g)
            dev.append(d)
            info.append(keep)
        return np.concatenate(pos), np.concatenate(dev), np.concatenate(info)
    return np.arange(n), theil_sen_detrend(r, ops), np.ones(n, bool)


def point_outliers(match: MatchResult, tolerances: Mapping[str, float], alpha: float) -> list[dict[str, Any]]:
    """Single readings far off the local structure of their channel's residuals, family-wise significant.

    The local structure is that of :mod:`.discrepancy` (median of replicated set points, else a
    Theil-Sen line on load); each deviation is studentized by the standard deviation of the *other*
    deviations (externally studentized, a Grubbs-type test: ``t`` with m - 2 degrees of freedom) and
    judged in the channel's units, as the tolerance and the fit are (the discrepancy analysis judges
    ratio quantities on relative residuals and uses the median absolute deviation, whose sampling
    scatter with 30 points made it flag about one negative control in five).  A reading is reported
    when ``p x channels x m < alpha`` (Bonferroni over every tested reading) and its deviation exceeds
    the tolerance.  Needs at least 5 informative deviations per channel.
    """
    ds = match.dataset
    ops = operating_variables(match)
    C = max(len(match.channels), 1)
    out = []
    for col in match.channels:
        r_all = match.residual(col)
        ok = np.isfinite(r_all)
        idx = np.flatnonzero(ok)
        if idx.size < 5:
            continue
        q = ds.column_quantity[col]
        ch_ops = {k: v[ok] for k, v in ops.items() if q not in _VAR_QUANTITY[k]}
        tol = float(tolerances[col])
        pos, d, info = _local_deviations(ds, idx, r_all[ok], ch_ops)
        m = int(info.sum())
        if m < 5:
            continue
        for k in np.flatnonzero(info):
            others = np.delete(d, k)[np.delete(info, k)]
            sd = float(np.std(others, ddof=1))
            t = abs(d[k]) / sd if sd > 0 else (math.inf if d[k] != 0 else 0.0)
            p = float(2 * stats.t.sf(t, m - 2)) if math.isfinite(t) else 0.0
            if p * C * m < alpha and abs(d[k]) >= tol:
                i = int(idx[pos[k]])
                label = ds.point_label(i)
                out.append({"channel": col, "kind": "outlier", "region": label, "point": i + 1,
                            "magnitude": float(d[k]), "residual": float(r_all[i]), "studentized": float(t),
                            "p_value": p, "score": abs(float(d[k])) / tol, "unit": COLUMNS[col].unit,
                            "text": f"outlier: {col}, {label} (deviation {d[k]:+.4g} {COLUMNS[col].unit} from the "
                                    f"local structure, studentized {t:.3g})"})
    out.sort(key=lambda d: -d["score"])
    return out


def family_significant(d: Mapping[str, Any], report: DiscrepancyReport, alpha: float,
                       outliers: Sequence[Mapping[str, Any]] | None = None) -> bool:
    """Whether a (per-test significant) finding survives a Bonferroni correction over the channels.

    Outlier findings are judged by :func:`point_outliers` instead when its list ``outliers`` is given
    (else: Bonferroni over channels and the tested points of the channel on the finding's own p-value).
    """
    if not d.get("significant", True):
        return False
    if d["kind"] == "outlier" and outliers is not None:
        return any(o["channel"] == d["channel"] and o["point"] == d.get("point") for o in outliers)
    n_ch = max(len(report.channels), 1)
    m = n_ch * (max(report.channels[d["channel"]].n, 1) if d["kind"] == "outlier" else 1)
    return bool(d["p_value"] * m < alpha)


def _unexplained(report: DiscrepancyReport, alpha: float) -> list[dict[str, Any]]:
    """Family-significant region findings (bias, trend, change point) of a discrepancy report."""
    out = []
    for d in report.discrepancies:
        if d["kind"] == "outlier" or not family_significant(d, report, alpha):
            continue
        e = {k: d[k] for k in ("channel", "kind", "region", "magnitude", "score", "p_value", "unit") if k in d}
        if "variable" in d:
            e["variable"] = d["variable"]
        e["text"] = f"unexplained: {d['channel']}, {d['region']} ({d['kind']}, magnitude {d['magnitude']:+.4g} " \
                    f"{d.get('unit', '')})".replace(" )", ")")
        out.append(e)
    return out


def select_causes(
    problem: Problem,
    mechanisms: Sequence[Mechanism] | None = None,
    *,
    max_causes: int = 2,
    alpha: float = 0.01,
    min_gain: float = 0.10,
    penalty: float = 2.0,
    cv_all: bool = False,
    progress=None,
) -> Selection:
    """Greedy forward selection of named mechanisms (see the module docstring).

    mechanisms : candidates (default: :func:`~.mechanisms.library` with one sensor calibration per channel).
    cv_all : cross-validate every candidate.  By default a candidate is cross-validated only if it can
        still win: its in-sample penalised score (a lower bound of its cross-validated one: a fit
        predicts the data it saw better than data it did not) is below the best cross-validated
        penalised score of the step so far and improves the current model by ``min_gain`` in-sample.
    progress : optional callable receiving one-line status messages.
    """
    t0 = time.perf_counter()
    say = progress or (lambda s: None)
    if mechanisms is None:
        mechanisms = library(problem.channels, problem.references)
    scheme, folds = problem.folds()
    rows = problem.rows_with_data()
    tol = dict(zip(problem.channels, problem.tolerance))
    base_match = problem.match_result(NO_HOOKS)
    base_report = analyse_discrepancies(base_match, alpha=alpha, tolerances=tol)
    base_outliers = point_outliers(base_match, tol, alpha)
    base_pred, _ = problem.predict(NO_HOOKS)
    L_base, M = cell_losses(problem, base_pred)
    S_base = float(L_base.sum() / M)
    current = Combination()
    current_fit = fit_combination(problem, current)
    current_pred, current_L, current_S, current_pen = base_pred, L_base, S_base, S_base
    steps: list[dict[str, Any]] = []
    say(f"base model: S = {S_base:.4g} over {M} cells ({scheme}, {len(folds)} folds)")
    for step in range(1, max_causes + 1):
        pool = [m for m in mechanisms if m.label not in current.labels]
        if not pool:
            break
        known = current_fit.values()
        scored: list[CandidateScore] = []
        for mech in pool:
            comb = current.plus(mech)
            full = fit_combination(problem, comb, starts=comb.starts(known))
            scored.append(CandidateScore(comb, mech.label, full, 2.0 * full.cost / M))
        scored.sort(key=lambda c: c.in_sample_score * math.exp(penalty * c.combination.n_params / M))
        best_pen = math.inf
        for c in scored:
            in_pen = c.in_sample_score * math.exp(penalty * c.combination.n_params / M)
            in_gain = (current_S - c.in_sample_score) / current_S if current_S > 0 else 0.0
            if not cv_all:
                if in_gain < min_gain:
                    c.screened = f"not cross-validated: in-sample gain {in_gain:.1%} below {min_gain:.0%}"
                    continue
                if in_pen >= best_pen:
                    c.screened = (f"not cross-validated: in-sample penalised score {in_pen:.4g} already above the best "
                                  f"cross-validated one {best_pen:.4g}")
                    continue
            pred, _ = cross_validate(problem, c.combination, c.fit)
            L, _ = cell_losses(problem, pred)
            c.cv_pred, c.point_losses = pred, L
            c.cv_score = float(L.sum() / M)
            c.penalised = c.cv_score * math.exp(penalty * c.combination.n_params / M)
            c.gain = (current_S - c.cv_score) / current_S if current_S > 0 else 0.0
            c.p_value = _f_test_p(current_S, c.cv_score, current.n_params, c.combination.n_params, M)
            c.p_value_points = _paired_p(current_L, L, rows)
            best_pen = min(best_pen, c.penalised)
        for c in scored:
            say(f"step {step}: {c.added:48s} in-sample {c.in_sample_score:9.4g}  CV {c.cv_score:9.4g}  "
                f"gain {c.gain:+.1%}  p = {c.p_value:.2g}")
        cv = sorted((c for c in scored if c.cross_validated), key=lambda c: c.penalised)
        threshold = alpha / len(scored)
        if not cv:
            steps.append({"step": step, "best": None, "accepted": False, "threshold_p": threshold,
                          "current_score": current_S, "candidates": scored,
                          "decision": f"rejected: no candidate improves the in-sample score by {min_gain:.0%}"})
            say(f"step {step}: {steps[-1]['decision']}")
            break
        best = cv[0]
        accept = best.penalised < current_pen and best.gain >= min_gain and best.p_value < threshold
        why = ("accepted" if accept else
               "rejected: " + "; ".join(s for s, bad in (
                   (f"penalised score {best.penalised:.4g} not below the current {current_pen:.4g}",
                    best.penalised >= current_pen),
                   (f"gain {best.gain:.1%} below {min_gain:.0%}", best.gain < min_gain),
                   (f"p = {best.p_value:.2g} not below alpha/{len(scored)} = {threshold:.2g}",
                    best.p_value >= threshold)) if bad))
        steps.append({"step": step, "best": best.added, "accepted": accept, "decision": why, "threshold_p": threshold,
                      "current_score": current_S, "candidates": scored})
        say(f"step {step}: best {best.added}: {why}")
        if not accept:
            break
        current, current_fit = best.combination, best.fit
        current_pred, current_L, current_S, current_pen = best.cv_pred, best.point_losses, best.cv_score, best.penalised
    final_hooks = current_fit.hooks(problem.params)
    final_match = problem.match_result(final_hooks)
    final_report = analyse_discrepancies(final_match, alpha=alpha, tolerances=tol) if current.n_params else base_report
    unexplained = _unexplained(final_report, alpha)
    if current.n_params:
        # a base discrepancy on a channel the extension did not improve (cross-validated) stays unexplained even
        # if it lost significance after the fit
        cv_b, cv_e = channel_rmse(problem, base_pred), channel_rmse(problem, current_pred)
        have = {(u["channel"], u["kind"]) for u in unexplained}
        for u in _unexplained(base_report, alpha):
            c = u["channel"]
            if (c, u["kind"]) not in have and not cv_e[c] < cv_b[c]:
                u = dict(u, note="base-model discrepancy; the extension did not reduce this channel's cross-validated "
                                 "error")
                unexplained.append(u)
    return Selection(
        problem=problem, cv_scheme=scheme, base_pred=base_pred, base_score=S_base, base_report=base_report, steps=steps,
        selected=current, fit=current_fit, cv_pred=current_pred, cv_score=current_S, final_report=final_report,
        unexplained=unexplained, outliers=point_outliers(final_match, tol, alpha), base_outliers=base_outliers,
        seconds=time.perf_counter() - t0,
        settings={"max_causes": max_causes, "alpha": alpha, "min_gain": min_gain, "penalty": penalty,
                  "robust_scale": ROBUST_SCALE, "cv": scheme, "n_folds": len(folds), "n_cells": M, "cv_all": cv_all},
    )
