"""Fitting a combination of mechanisms to measured data, and cross-validating it.

Every fit adjusts the model-error nuisance of :mod:`.nuisance` (prior σ = 3 %) together with the
mechanisms' parameters.  The objective, minimised by :func:`scipy.optimize.least_squares` (trust region
reflective within the plausible ranges), is

    ``Σ ρ(r_ic) + Σ ((s_g - 1)/σ)² [+ 2 λ Σ o_vi / o_v]``

with ``r_ic = (model - measured)/tolerance`` per measured cell, the robust soft-L1 loss
``ρ(r) = 2 f² (sqrt(1 + (r/f)²) - 1)`` (≈ r² for |r| << f = 3 tolerances: a single bad reading bends the
fit little; nothing is removed from the data) and, while the points where a valve acts are being
selected, a sparsity (L1) penalty on its openings.

Valve-type mechanisms (one opening per measured point) are selected without enumerating the 2^n
subsets of points:

1. **Relaxation.**  All openings free, with the L1 penalty (``λ = 2``: an opening of one typical size
   ``o_v`` must lower Σρ by 4).  The openings are parametrised as ``o = v²`` with a quadratic penalty on
   v, which is the L1 penalty on o ≥ 0 in a smooth least-squares form.  Points whose opening stays above
   5 % of ``o_v`` form the support.
2. **Confirmation.**  A refit without the penalty, openings free on the support only; then backward
   elimination: the point whose closing costs least is closed while the F-test of its one opening
   (cost increase against the residual cost per degree of freedom) gives ``p >= 0.01``.

The number of free parameters of a fit is its global parameters plus the size of the support.

Cross-validation refits everything on the training rows, the selection of the valve supports included
(relaxation and one confirmation refit; the backward elimination is left to the full-data fit, to save
time).  A held-out point's valve opening is not known.  By default (:data:`HELD_OUT_VALVES` ``"schedule"``) it comes
from the schedule through all the training points' openings (piecewise linear in the fuel setting, constant beyond
the ends), as the fitted engine would predict it.  Leaving out the last shut point, the first open one or the highest
load then predicts a half-open or a too-small opening there: an error of tens of tolerances shared by every model
with that valve, which swamps what a second mechanism adds to it (a waste gate and a second mechanism named as the
gate alone; docs/validation.md).  The selection
therefore judges a physical mechanism beside a valve on its in-sample gain and F-test (``evidence.earns``); the held-out
prediction itself stays the schedule.  The option ``"support"`` (``FitProblem(..., held_out_valves="support")``,
:meth:`FitResult.held_out_openings`) predicts it in two parts: *whether* the valve acts there is the full-data fit's
support (a per-point state the selection counts as one free parameter per open point, like the opening itself), and *how
much* it opens is interpolated in load among the training points where it acts, extrapolated linearly beyond them (never
below shut). An ablation, not the default: in the open-world study it corrected two such misses and lost ten trials,
where model error or proportional noise then passed the selection's bar as a second mechanism beside a valve
(``docs/figures/validation/held_out_valves/``).  The option ``"state"``
(:mod:`.held_out_state`, :attr:`FitResult.held_out_state`) estimates the opening at the held-out point from that point's
other channels, each channel predicted without its own reading: what a per-point state claims is tested, not a load
dependence it does not claim; an ablation, not the default (it lets model error in as a valve or beside one:
``docs/figures/validation/held_out_state/``).  The fitted engine between and beyond the measured points follows the
schedule in every mode (:meth:`FitResult.schedules`).

A sensor calibration changes no model state: added to a model it is fitted on that model's readings
(:func:`fit_sensor`, per fold on the fold's readings), without solving the engine again; the nuisance is
not refitted with it in that step (it is in every later joint fit).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np
from scipy import stats
from scipy.optimize import least_squares

from ...engine.submodels import Schedule
from .held_out_state import state_predictions
from .mechanisms import Mechanism, ValveMechanism
from .nuisance import NUISANCE, nuisance_bounds, prior_residuals, scales_of
from .problem import HELD_OUT_VALVES, FitProblem, Setting

__all__ = [
    "ROBUST_SCALE",
    "robust_loss",
    "training_folds",
    "refit_fold",
    "Combination",
    "FitResult",
    "fit_combination",
    "cross_validate",
    "cell_losses",
    "channel_rmse",
    "L1_LAMBDA",
    "SUPPORT_FRACTION",
    "POINT_ALPHA",
    "predict_setting",
    "FoldData",
    "fold_data",
    "fit_sensor",
    "loco_predictions",
    "HELD_OUT_VALVES",
    "support_objective",
]

ROBUST_SCALE = 3.0  # soft_l1 scale in tolerance units
L1_LAMBDA = 2.0
SUPPORT_FRACTION = 0.05
POINT_ALPHA = 0.01
N_NUIS = len(NUISANCE)


def robust_loss(r: np.ndarray) -> np.ndarray:
    """Per-cell soft_l1 loss ``2 f^2 (sqrt(1 + (r/f)^2) - 1)`` (≈ r^2 for |r| << f = ROBUST_SCALE)."""
    f = ROBUST_SCALE
    return 2.0 * f * f * (np.sqrt(1.0 + (r / f) ** 2) - 1.0)


def _robust_residual(r: np.ndarray) -> np.ndarray:
    """``sign(r) sqrt(ρ(r))``: plain least squares on these minimises Σρ."""
    return np.sign(r) * np.sqrt(robust_loss(r))


@dataclass(frozen=True)
class Combination:
    """A set of mechanisms fitted together (with the nuisance); global parameters first, then valves."""

    mechanisms: tuple[Mechanism, ...] = ()

    @property
    def labels(self) -> tuple[str, ...]:
        return tuple(m.label for m in self.mechanisms)

    @property
    def ids(self) -> tuple[str, ...]:
        return tuple(m.id for m in self.mechanisms)

    @property
    def globals(self) -> tuple[Mechanism, ...]:
        """The mechanisms with global parameters (a valve may have some besides its openings)."""
        return tuple(m for m in self.mechanisms if m.params)

    @property
    def valves(self) -> tuple[ValveMechanism, ...]:
        return tuple(m for m in self.mechanisms if m.pointwise)  # type: ignore[misc]

    @property
    def names(self) -> list[str]:
        return [f"{m.label}.{p.name}" for m in self.globals for p in m.params]

    @property
    def n_global(self) -> int:
        return sum(len(m.params) for m in self.globals)

    def plus(self, m: Mechanism) -> "Combination":
        return Combination(self.mechanisms + (m,))

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        lo = np.array([p.bounds[0] for m in self.globals for p in m.params], float)
        hi = np.array([p.bounds[1] for m in self.globals for p in m.params], float)
        return lo, hi

    def unpack(self, x) -> list[tuple[Mechanism, dict[str, float]]]:
        out, k = [], 0
        for m in self.globals:
            vals = {}
            for p in m.params:
                vals[p.name] = float(x[k])
                k += 1
            out.append((m, vals))
        return out

    def defaults(self, known: Mapping[str, float] | None = None) -> np.ndarray:
        known = known or {}
        return np.array([known.get(f"{m.label}.{p.name}", p.default) for m in self.globals for p in m.params], float)

    def extra_starts(self, x0: np.ndarray, known: Mapping[str, float] | None = None) -> list[np.ndarray]:
        known = known or {}
        out = []
        k = 0
        for m in self.globals:
            for p in m.params:
                if f"{m.label}.{p.name}" not in known:
                    for s in p.starts:
                        x = x0.copy()
                        x[k] = s
                        out.append(x)
                k += 1
        return out

    def setting(self, problem: FitProblem, nuis, xg, openings: Mapping[str, np.ndarray] | None = None) -> Setting:
        """The :class:`Setting` of nuisance ``nuis``, global parameters ``xg`` and valve ``openings`` (per point)."""
        s = problem.base_setting.replace(scales=scales_of(nuis))
        for m, v in self.unpack(xg):
            s = m.apply(s, v, problem.params)
        for m in self.valves:
            o = (openings or {}).get(m.id)
            s = m.with_openings(s, np.zeros(problem.n_points) if o is None else o)
        return s


@dataclass
class FitResult:
    """A fitted combination on some rows.

    nuisance : the nuisance multipliers (:data:`~.nuisance.NUISANCE` order).  x : global parameters.
    openings : per valve id, the opening at every point (0 where closed, NaN on rows not fitted).
    support : per valve id, the rows where it is open.  cost : 0.5 (Σρ + prior) at the optimum.
    data_cost : 0.5 Σρ.  k : free parameters (globals + support sizes; the nuisance is not counted, every
    model has it).  u : fuel setting of every fitted row (the knots of the valve schedules).
    """

    combination: Combination
    nuisance: np.ndarray
    x: np.ndarray
    stderr: np.ndarray
    openings: dict[str, np.ndarray]
    support: dict[str, list[int]]
    cost: float
    data_cost: float
    n_cells: int
    k: int
    rows: np.ndarray
    u: np.ndarray
    success: bool = True
    at_bound: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    nfev: int = 0
    relaxed: dict[str, np.ndarray] = field(default_factory=dict)
    eliminated: dict[str, list[dict[str, Any]]] = field(default_factory=dict)
    #: a cross-validation fold's fit: per valve id, the rows where the full-data fit opens it (held-out rows are then
    #: predicted with :meth:`held_out_openings`); None: held-out rows follow the schedule
    held_out_support: dict[str, list[int]] | None = None
    #: a cross-validation fold's fit whose held-out rows take each valve's opening as a state estimated from the
    #: row's other channels (:mod:`.held_out_state`)
    held_out_state: bool = False

    def values(self) -> dict[str, float]:
        return dict(zip(self.combination.names, map(float, self.x)))

    def setting(self, problem: FitProblem) -> Setting:
        """The fitted model at the measured points (openings as overrides)."""
        return self.combination.setting(problem, self.nuisance, self.x, self.openings)

    def schedules(self) -> dict[str, Schedule]:
        """Per valve id, the schedule over the fuel setting through the fitted rows' openings."""
        out = {}
        for m in self.combination.valves:
            o = self.openings[m.id][self.rows]
            u = self.u
            ok = np.isfinite(u) & np.isfinite(o)
            order = np.argsort(u[ok])
            uu, oo = u[ok][order], np.maximum(o[ok][order], 0.0)
            keep = np.concatenate([[True], np.diff(uu) > 1e-9])  # distinct knots (duplicated set points averaged)
            if not np.all(keep):
                groups = np.cumsum(keep) - 1
                uu = np.array([uu[groups == g].mean() for g in range(groups[-1] + 1)])
                oo = np.array([oo[groups == g].mean() for g in range(groups[-1] + 1)])
            out[m.id] = Schedule(tuple(map(float, uu)), tuple(map(float, oo))) if uu.size else Schedule.constant(0.0)
        return out

    def held_out_openings(self, problem: FitProblem, rows) -> dict[str, np.ndarray]:
        """Per valve id, the openings at every point: this fit's own where it was fitted, at ``rows`` (held out) 0
        where :attr:`held_out_support` shuts the valve, else interpolated in load (:meth:`FitProblem.load_axis`) among
        this fit's open rows, extrapolated linearly from the nearest two beyond them, at least 0 (one open row: its
        opening; none: shut)."""
        if self.held_out_support is None:
            raise ValueError("held_out_openings needs the full-data support (a cross-validation fold's fit)")
        load = problem.load_axis()
        out = {}
        for m in self.combination.valves:
            o = np.array(self.openings[m.id], dtype=float)
            opened = self.rows[np.nan_to_num(o[self.rows]) > 0]
            opened = opened[np.argsort(load[opened], kind="stable")]
            x, y = load[opened], o[opened]
            acts = set(int(r) for r in self.held_out_support.get(m.id, ()))
            for r in np.asarray(rows, dtype=int):
                if int(r) not in acts or x.size == 0:
                    o[r] = 0.0
                elif x.size == 1:
                    o[r] = y[0]
                else:
                    lr = load[r]
                    if x[0] <= lr <= x[-1]:
                        v = float(np.interp(lr, x, y))
                    else:  # beyond the open rows: the line through the nearest two
                        a, b = (0, 1) if lr < x[0] else (-1, -2)
                        slope = (y[b] - y[a]) / (x[b] - x[a]) if x[b] != x[a] else 0.0
                        v = y[a] + slope * (lr - x[a])
                    o[r] = max(float(v), 0.0)
            out[m.id] = o
        return out

    def schedule_setting(self, problem: FitProblem) -> Setting:
        """The fitted model with the valves on their schedules (what predicts points it was not fitted on)."""
        s = problem.base_setting.replace(scales=scales_of(self.nuisance))
        for m, v in self.combination.unpack(self.x):
            s = m.apply(s, v, problem.params)
        for m in self.combination.valves:
            s = m.with_schedule(s, self.schedules()[m.id])
        return s

    def parameters(self) -> dict[str, dict[str, dict[str, Any]]]:
        """``{mechanism label: {param: {value, stderr, unit, at_bound, bounds}}}``."""
        out: dict[str, dict[str, dict[str, Any]]] = {}
        k = 0
        for m in self.combination.globals:
            d = {}
            for p in m.params:
                d[p.name] = {
                    "value": float(self.x[k]),
                    "stderr": float(self.stderr[k]),
                    "unit": p.unit,
                    "at_bound": bool(self.at_bound[k]) if self.at_bound.size > k else False,
                    "bounds": [float(b) for b in p.bounds],
                    "description": p.description,
                }
                k += 1
            out[m.label] = d
        return out

    def nuisance_values(self) -> dict[str, float]:
        return {g.name: float(s) for g, s in zip(NUISANCE, self.nuisance)}


def _clip_into(x: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Start at least 0.1 % of the range inside the bounds (the trust-region reflective method stalls on a bound)."""
    span = hi - lo
    return np.minimum(np.maximum(x, lo + 1e-3 * span), hi - 1e-3 * span)


class _Objective:
    """Residual vector of one fit: layout [nuisance | globals | v of each valve at its free rows]."""

    def __init__(
        self,
        problem: FitProblem,
        comb: Combination,
        rows: np.ndarray,
        free: Mapping[str, np.ndarray],
        l1: float,
        penalised: set[str] | None = None,
    ):
        self.problem, self.comb, self.rows, self.free, self.l1 = problem, comb, rows, free, l1
        self.penalised = {m.id for m in comb.valves} if penalised is None else penalised
        self.mask = problem.measured_mask[rows]
        self.ng = comb.n_global
        self.nv = {m.id: len(free[m.id]) for m in comb.valves}

    def split(self, z):
        nuis = z[:N_NUIS]
        xg = z[N_NUIS : N_NUIS + self.ng]
        openings, k = {}, N_NUIS + self.ng
        for m in self.comb.valves:
            o = np.zeros(self.problem.n_points)
            idx = self.free[m.id]
            o[idx] = z[k : k + idx.size] ** 2
            openings[m.id] = o
            k += idx.size
        return nuis, xg, openings

    def data_residuals(self, z) -> np.ndarray:
        nuis, xg, openings = self.split(z)
        s = self.comb.setting(self.problem, nuis, xg, openings)
        pred, _, _ = self.problem.predict(s, self.rows)
        return self.problem.normalised_residuals(pred, self.rows)[self.mask]

    def __call__(self, z) -> np.ndarray:
        parts = [_robust_residual(self.data_residuals(z)), prior_residuals(z[:N_NUIS])]
        if self.l1 > 0:
            k = N_NUIS + self.ng
            for m in self.comb.valves:
                n = self.nv[m.id]
                if m.id in self.penalised:
                    parts.append(math.sqrt(2.0 * self.l1 / m.opening_scale) * z[k : k + n])
                k += n
        return np.concatenate(parts)

    def bounds(self):
        nlo, nhi = nuisance_bounds()
        glo, ghi = self.comb.bounds()
        vlo = [np.zeros(self.nv[m.id]) for m in self.comb.valves]
        vhi = [np.full(self.nv[m.id], math.sqrt(m.opening_max)) for m in self.comb.valves]
        return np.concatenate([nlo, glo] + vlo), np.concatenate([nhi, ghi] + vhi)


def _solve(obj: _Objective, starts: Sequence[np.ndarray], max_nfev: int):
    lo, hi = obj.bounds()
    best = None
    for z0 in starts:
        z0 = _clip_into(np.asarray(z0, float), lo, hi)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            res = least_squares(
                obj, z0, bounds=(lo, hi), x_scale=hi - lo, diff_step=1e-6, xtol=1e-7, ftol=1e-7, max_nfev=max_nfev
            )
        if best is None or res.cost < best.cost:
            best = res
    return best


def fit_combination(
    problem: FitProblem,
    comb: Combination,
    rows=None,
    *,
    start: "FitResult | None" = None,
    known: Mapping[str, float] | None = None,
    max_nfev: int | None = None,
    uncertainty: bool = True,
    support: Mapping[str, Sequence[int]] | None = None,
    eliminate: bool = True,
) -> FitResult:
    """Fit ``comb`` (with the nuisance) on ``rows`` (default all with data); valve supports are selected as in the
    module docstring except for the valves whose support ``support`` fixes (a greedy step keeps the supports the
    current model selected and selects only the new valve's; cross-validation folds select every support anew).
    ``start``/``known``: warm start (values by name)."""
    rows = problem.rows_with_data() if rows is None else np.asarray(rows, dtype=int)
    mask = problem.measured_mask[rows]
    M = int(mask.sum())
    known = dict(known or {})
    xg0 = comb.defaults(known)
    nuis0 = np.ones(N_NUIS) if start is None else start.nuisance.copy()
    if start is not None:
        prev = start.values()
        xg0 = np.array([prev.get(n, x) for n, x in zip(comb.names, xg0)], float)
    g_starts = [xg0] + comb.extra_starts(xg0, known if start is None else {**known, **start.values()})
    budget = max_nfev or 40 * (N_NUIS + comb.n_global + 1)
    relaxed: dict[str, np.ndarray] = {}
    eliminated: dict[str, list[dict[str, Any]]] = {m.id: [] for m in comb.valves}
    nfev = 0

    def v_start(m: ValveMechanism, idx: np.ndarray, level: float) -> np.ndarray:
        if start is not None and m.id in start.openings:
            o = np.nan_to_num(start.openings[m.id][idx])
            return np.sqrt(np.maximum(o, 0.25 * level))
        return np.full(idx.size, math.sqrt(level))

    # 1. relaxation (valves whose support is not fixed)
    fixed = dict(support or {})
    relax = [m for m in comb.valves if m.id not in fixed]
    rowset = set(rows.tolist())
    if relax:
        free = {
            m.id: (rows.copy() if m.id not in fixed else np.array([i for i in fixed[m.id] if i in rowset], int))
            for m in comb.valves
        }
        obj = _Objective(problem, comb, rows, free, L1_LAMBDA, penalised={m.id for m in relax})
        starts = [
            np.concatenate([nuis0, g] + [v_start(m, free[m.id], m.opening_scale) for m in comb.valves])
            for g in g_starts
        ]
        res = _solve(obj, starts, budget + 30 * sum(obj.nv.values()))
        nfev += res.nfev
        nuis0, xg0 = res.x[:N_NUIS], res.x[N_NUIS : N_NUIS + comb.n_global]
        _, _, op = obj.split(res.x)
        for m in relax:
            relaxed[m.id] = op[m.id].copy()
            fixed[m.id] = [int(i) for i in rows if op[m.id][i] > SUPPORT_FRACTION * m.opening_scale]
        g_starts = [xg0]
    support = {m.id: sorted(int(i) for i in fixed.get(m.id, ()) if i in rowset) for m in comb.valves}
    elim_ids = {m.id for m in relax} if eliminate else set()

    # 2. confirmation: refit on the support, then backward elimination of insignificant openings
    def refit(sup, nuis_s, g_list, open_start=None):
        free = {m.id: np.array(sup[m.id], dtype=int) for m in comb.valves}
        obj = _Objective(problem, comb, rows, free, 0.0)
        starts = []
        for g in g_list:
            vs = []
            for m in comb.valves:
                idx = free[m.id]
                if open_start is not None and m.id in open_start:
                    vs.append(np.sqrt(np.maximum(open_start[m.id][idx], 0.05 * m.opening_scale)))
                else:
                    vs.append(v_start(m, idx, m.opening_scale))
            starts.append(np.concatenate([nuis_s, g] + vs))
        res = _solve(obj, starts, budget + 30 * sum(obj.nv.values()))
        return obj, res

    obj, res = refit(support, nuis0, g_starts, relaxed or None)
    nfev += res.nfev
    while elim_ids:
        k_now = comb.n_global + sum(len(v) for v in support.values())
        dcost = float(np.sum(robust_loss(obj.data_residuals(res.x))))
        _, _, op = obj.split(res.x)
        trials = []
        for m in comb.valves:
            if m.id not in elim_ids:
                continue
            for i in support[m.id]:
                sup2 = {k: [j for j in v if not (k == m.id and j == i)] for k, v in support.items()}
                o2, r2 = refit(sup2, res.x[:N_NUIS], [res.x[N_NUIS : N_NUIS + comb.n_global]], op)
                nfev_add = r2.nfev
                c2 = float(np.sum(robust_loss(o2.data_residuals(r2.x))))
                dof = max(M - k_now - N_NUIS, 1)
                F = max(c2 - dcost, 0.0) / max(dcost / dof, 1e-12)
                p = float(stats.f.sf(F, 1, dof)) if F > 0 else 1.0
                trials.append((p, m.id, i, sup2, o2, r2, nfev_add))
        if not trials:
            break
        p, mid, i, sup2, o2, r2, nfev_add = max(trials, key=lambda t: t[0])
        nfev += sum(t[6] for t in trials)
        if p < POINT_ALPHA:
            break
        eliminated[mid].append({"point": i + 1, "p_value": p, "opening": float(op[mid][i])})
        support, obj, res = sup2, o2, r2

    z = res.x
    nuis, xg, openings = obj.split(z)
    for m in comb.valves:  # rows not fitted: NaN
        o = np.full(problem.n_points, np.nan)
        o[rows] = openings[m.id][rows]
        openings[m.id] = o
    data_cost = 0.5 * float(np.sum(robust_loss(obj.data_residuals(z))))
    k = comb.n_global + sum(len(v) for v in support.values())
    lo, hi = obj.bounds()
    ng = comb.n_global
    if uncertainty and ng:
        stderr = _stderr(obj, z, M, k)[N_NUIS : N_NUIS + ng]
    else:
        stderr = np.full(ng, np.nan)
    at_bound = (np.abs(z - lo) < 1e-6 * (hi - lo)) | (np.abs(hi - z) < 1e-6 * (hi - lo))
    setting = comb.setting(problem, nuis, xg, openings)
    vals, conv = problem.solve(setting, rows)
    u = np.full(rows.size, np.nan)
    u[conv] = vals["fuel_setting"][conv]
    return FitResult(
        comb,
        np.asarray(nuis, float),
        np.asarray(xg, float),
        stderr,
        openings,
        support,
        float(res.cost),
        data_cost,
        M,
        k,
        rows,
        u,
        bool(res.success),
        at_bound[N_NUIS : N_NUIS + ng],
        nfev,
        relaxed,
        eliminated,
    )


def _fd_step(z: float, lo: float, hi: float) -> float:
    """Forward-difference step of a parameter at ``z`` in ``[lo, hi]``: inwards at the upper bound (a parameter
    fitted to a natural limit, e.g. an ideal cooler, must not step outside what its submodel accepts)."""
    h = 1e-6 * max(abs(z), 1e-3 * (hi - lo))
    return -h if z + h > hi else h


def _stderr(obj: _Objective, z: np.ndarray, M: int, k: int) -> np.ndarray:
    """Standard errors ``sqrt(diag(s² (JᵀWJ)^-1))`` from the Jacobian of the raw normalised residuals and the
    prior at the optimum (W: the soft-L1 weights; s²: the weighted residual sum of squares per dof)."""
    r0 = obj.data_residuals(z)
    lo, hi = obj.bounds()
    n = z.size
    J = np.empty((r0.size + N_NUIS, n))
    for j in range(n):
        h = _fd_step(z[j], lo[j], hi[j])
        zj = z.copy()
        zj[j] += h
        J[: r0.size, j] = (obj.data_residuals(zj) - r0) / h
        J[r0.size :, j] = (prior_residuals(zj[:N_NUIS]) - prior_residuals(z[:N_NUIS])) / h
    w = np.concatenate([1.0 / np.sqrt(1.0 + (r0 / ROBUST_SCALE) ** 2), np.ones(N_NUIS)])
    s2 = float(np.sum(w[: r0.size] * r0 * r0)) / max(M - k, 1)
    A = J.T @ (w[:, None] * J)
    try:
        cov = s2 * np.linalg.pinv(A)
    except np.linalg.LinAlgError:
        return np.full(n, np.nan)
    return np.sqrt(np.clip(np.diag(cov), 0.0, None))


def support_objective(problem: FitProblem, fit: FitResult):
    """The objective of ``fit`` with its valve supports held (what a confirmation refit minimises): ``(residuals,
    z, lower, upper, names)``, ``residuals(z)`` the vector whose half sum of squares is the fit's cost, ``z`` the
    fit's optimum in the layout [nuisance | globals | sqrt of each valve's opening at its support rows], and the
    parameters' names (``valve_id[row]`` for an opening's square root)."""
    comb = fit.combination
    free = {m.id: np.array(fit.support.get(m.id, []), dtype=int) for m in comb.valves}
    obj = _Objective(problem, comb, fit.rows, free, 0.0)
    z = np.concatenate(
        [fit.nuisance, fit.x]
        + [np.sqrt(np.maximum(np.nan_to_num(fit.openings[m.id][free[m.id]]), 0.0)) for m in comb.valves]
    )
    lo, hi = obj.bounds()
    names = [g.name for g in NUISANCE] + comb.names + [f"{m.id}[{int(i)}]" for m in comb.valves for i in free[m.id]]
    return obj, z, lo, hi, names


def predict_setting(problem: FitProblem, fit: FitResult, rows) -> np.ndarray:
    """Readings at ``rows`` of a fit: its own openings where it fitted them; elsewhere the held-out openings of a
    cross-validation fold (:meth:`FitResult.held_out_openings`), else the schedule."""
    rows = np.asarray(rows, dtype=int)
    if not fit.combination.valves:
        pred, _, _ = problem.predict(fit.setting(problem), rows)
        return pred
    fitted = np.isin(rows, fit.rows)
    out = np.full((rows.size, len(problem.channels)), np.nan)
    if np.any(fitted):
        out[fitted] = problem.predict(fit.setting(problem), rows[fitted])[0]
    if np.any(~fitted):
        held = rows[~fitted]
        if fit.held_out_state:
            comb = fit.combination

            def setting_of(state):
                return comb.setting(
                    problem, fit.nuisance, fit.x, {k: np.full(problem.n_points, v) for k, v in state.items()}
                )

            out[~fitted] = state_predictions(
                problem, setting_of, comb.valves, held, robust_loss, L1_LAMBDA, SUPPORT_FRACTION
            )
            return out
        if fit.held_out_support is not None:
            s = fit.combination.setting(problem, fit.nuisance, fit.x, fit.held_out_openings(problem, held))
        else:
            s = fit.schedule_setting(problem)
        out[~fitted] = problem.predict(s, held)[0]
    return out


def training_folds(problem: FitProblem, max_folds: int | None = None):
    """The cross-validation folds that can be fitted, as ``(name, training rows, test rows)``: a fold whose
    training rows are empty or hold no measurement is left out."""
    _, folds = problem.folds(max_folds)
    rows = problem.rows_with_data()
    for name, test in folds:
        train = np.setdiff1d(rows, test)
        if train.size and problem.measured_mask[train].any():
            yield name, train, test


def refit_fold(problem: FitProblem, comb: Combination, train: np.ndarray, start: FitResult, **held) -> FitResult:
    """A cross-validation fold's refit of ``comb`` on the rows ``train``, started from ``start``: no uncertainty,
    no elimination, a bounded number of evaluations; ``held``: what the refit keeps (``known``, ``support``)."""
    return fit_combination(
        problem,
        comb,
        train,
        start=start,
        uncertainty=False,
        max_nfev=25 * (N_NUIS + comb.n_global + 1),
        eliminate=False,
        **held,
    )


def cross_validate(
    problem: FitProblem, comb: Combination, full: FitResult | None = None, *, max_folds: int | None = None
) -> tuple[np.ndarray, list]:
    """Cross-validated predictions (points x channels) of ``comb`` (refit per fold, supports included) and the
    fold fits (a valve's opening at a held-out point as ``problem.held_out_valves`` says, module docstring)."""
    n, C = problem.n_points, len(problem.channels)
    pred = np.full((n, C), np.nan)
    if full is None:
        full = fit_combination(problem, comb)
    fits = []
    for name, train, test in training_folds(problem, max_folds):
        f = refit_fold(problem, comb, train, full)
        if comb.valves and problem.held_out_valves == "support":
            f.held_out_support = {k: list(v) for k, v in full.support.items()}
        f.held_out_state = bool(comb.valves) and problem.held_out_valves == "state"
        pred[test] = predict_setting(problem, f, test)
        fits.append((name, f))
    return pred, fits


@dataclass
class FoldData:
    """A model's cross-validation folds: per fold the training and test rows and its predictions on both."""

    folds: list[tuple[str, np.ndarray, np.ndarray, np.ndarray, np.ndarray]]  # name, train, test, pred_train, pred_test


def fold_data(problem: FitProblem, fits: Sequence[tuple[str, FitResult]], max_folds: int | None = None) -> FoldData:
    """Predictions of every fold fit on its own training rows and on its test rows."""
    _, folds = problem.folds(max_folds)
    test_of = dict((name, test) for name, test in folds)
    out = []
    for name, f in fits:
        test = test_of[name]
        out.append((name, f.rows, test, predict_setting(problem, f, f.rows), predict_setting(problem, f, test)))
    return FoldData(out)


def fit_sensor(problem: FitProblem, j: int, pred: np.ndarray, rows: np.ndarray, bounds) -> tuple[float, float]:
    """Gain and offset of channel ``j`` on fixed model readings ``pred`` (rows x channels) of ``rows``: the robust
    least-squares fit of ``gain * pred + offset`` to the measurements (a sensor calibration changes no model state,
    so the model need not be solved again)."""
    y = problem.Y[rows, j]
    x = pred[:, j]
    tol = problem.tolerance_cells[rows, j]
    ok = np.isfinite(y) & np.isfinite(x)
    if ok.sum() < 2:
        return 1.0, 0.0
    (glo, ghi), (olo, ohi) = bounds
    lo, hi = np.array([glo, olo]), np.array([ghi, ohi])
    fun = lambda z: _robust_residual((z[0] * x[ok] + z[1] - y[ok]) / tol[ok])  # noqa: E731
    res = least_squares(fun, _clip_into(np.array([1.0, 0.0]), lo, hi), bounds=(lo, hi), x_scale=hi - lo)
    return float(res.x[0]), float(res.x[1])


def cell_losses(problem: FitProblem, pred: np.ndarray) -> tuple[np.ndarray, int]:
    """Robust loss per point (sum over its measured cells) and the number of measured cells."""
    r = problem.normalised_residuals(pred)
    L = np.where(problem.measured_mask, robust_loss(np.nan_to_num(r)), 0.0)
    return L.sum(axis=1), int(problem.measured_mask.sum())


def channel_rmse(problem: FitProblem, pred: np.ndarray, rows=None) -> dict[str, float]:
    """RMSE per channel (channel units) over the measured cells of ``rows``."""
    rows = np.arange(problem.n_points) if rows is None else np.asarray(rows, int)
    out = {}
    for j, c in enumerate(problem.channels):
        e = pred[rows, j] - problem.Y[rows, j]
        m = problem.measured_mask[rows, j]
        e = e[m]
        out[c] = float(np.sqrt(np.mean(np.where(np.isfinite(e), e, np.inf) ** 2))) if e.size else math.nan
    return out


def loco_predictions(problem: FitProblem, fit: FitResult, rows=None) -> np.ndarray:
    """Leave-one-channel-out readings (points x channels): each channel as predicted by the fit refitted without it.

    A single sensor's anomaly (a bump, a step, a bad calibration) bends a fit that includes the channel towards
    it; the other channels' view of the engine does not bend.  The refit is the Gauss-Newton step from the full
    fit's optimum (valve openings held): with J the Jacobian of the normalised residuals in the nuisance and global
    parameters, W the soft-L1 weights and P the nuisance prior, removing channel c moves the parameters by
    ``Δ = (JᵀWJ + P - J_cᵀW_cJ_c)^-1 J_cᵀW_c r_c`` and channel c's residual to ``r_c + J_c Δ``.
    """
    rows = fit.rows if rows is None else np.asarray(rows, dtype=int)
    comb = fit.combination
    support = {m.id: np.array(fit.support.get(m.id, []), dtype=int) for m in comb.valves}
    obj = _Objective(problem, comb, rows, support, 0.0)
    z0_parts = [fit.nuisance, fit.x]
    for m in comb.valves:
        z0_parts.append(np.sqrt(np.maximum(np.nan_to_num(fit.openings[m.id][support[m.id]]), 0.0)))
    z0 = np.concatenate(z0_parts)
    n_par = N_NUIS + comb.n_global  # valve openings held
    # a sensor calibration describes its own channel only: held when that channel is left out (undetermined then)
    own: dict[int, list[int]] = {}
    k = N_NUIS
    for m in comb.globals:
        for _ in m.params:
            if getattr(m, "channel", None) in problem.channels:
                own.setdefault(problem.channels.index(m.channel), []).append(k)
            k += 1
    mask = problem.measured_mask[rows]
    r0 = obj.data_residuals(z0)
    lo, hi = obj.bounds()
    J = np.empty((r0.size, n_par))
    for j in range(n_par):
        h = _fd_step(z0[j], lo[j], hi[j])
        zj = z0.copy()
        zj[j] += h
        J[:, j] = (obj.data_residuals(zj) - r0) / h
    w = 1.0 / np.sqrt(1.0 + (r0 / ROBUST_SCALE) ** 2)
    P = np.zeros((n_par, n_par))
    for k, g in enumerate(NUISANCE):
        P[k, k] = 1.0 / g.sigma**2
    P[N_NUIS:, N_NUIS:] += 1e-9 * np.eye(n_par - N_NUIS)  # keep the system regular
    H = J.T @ (w[:, None] * J) + P
    # cell -> channel of the flattened measured cells (row-major over rows x channels)
    chan_of_cell = np.nonzero(mask)[1]
    out = np.full((rows.size, len(problem.channels)), np.nan)
    full = np.full(mask.shape, np.nan)
    full[mask] = r0
    for c in range(len(problem.channels)):
        sel = chan_of_cell == c
        if not sel.any():
            continue
        Jc, wc, rc = J[sel], w[sel], r0[sel]
        free = np.array([i for i in range(n_par) if i not in own.get(c, ())], dtype=int)
        Hm = (H - Jc.T @ (wc[:, None] * Jc))[np.ix_(free, free)]
        g = (Jc.T @ (wc * rc))[free]
        delta = np.zeros(n_par)
        try:
            delta[free] = np.linalg.solve(Hm, g)
        except np.linalg.LinAlgError:
            delta[free] = np.linalg.lstsq(Hm, g, rcond=None)[0]
        col = full[:, c].copy()
        col[mask[:, c]] = rc + Jc @ delta
        out[:, c] = col
    pred = problem.Y[rows] + out * problem.tolerance_cells[rows]
    res = np.full((problem.n_points, len(problem.channels)), np.nan)
    res[rows] = pred
    return res
