"""Profile-likelihood intervals of a fitted explanation's parameters.

A parameter's profile fixes it at a value and refits every other parameter (the nuisance included, valve supports
held); its interval is where the refitted sum of squares ``SS`` stays below

    ``SS* (1 + F(1, M - k; level) / (M - k))``

with ``SS*`` the fit's own, ``M`` measured cells and ``k`` free parameters: the likelihood-ratio interval of nonlinear
least squares with the residual scale estimated from the fit (Bates & Watts 1988, §6.1; the F statistic of lmfit's
``conf_interval``).  ``SS`` is twice the fit's cost: the soft-L1 loss of the cells plus the nuisance prior.  An
interval that reaches a bound of the plausible range before the profile crosses the threshold is *open* there: the
data do not close it (Raue et al. 2009, "practically non-identifiable"), which Fisher standard errors cannot show
(Wieland et al. 2021).  Valve openings are profiled in the square root the fit uses (``o = v²``) and reported as
openings; their lower bound 0 (the valve shut) is a natural limit.

lmfit's ``conf_interval`` computes the same statistic, but it refuses a parameter without a finite Fisher standard
error (the parameters a profile is for) and refits with its own minimiser; the search here refits with the
trust-region least squares of :mod:`.fit.fitting`, warm-started from the neighbouring profile point.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np
from scipy import stats
from scipy.optimize import least_squares

from ..fit.fitting import FitResult, support_objective
from ..fit.nuisance import NUISANCE
from ..fit.problem import FitProblem

__all__ = ["LEVEL", "ProfileInterval", "fit_profiles", "profile_interval", "profile_threshold"]

#: confidence level of the intervals
LEVEL = 0.95


def profile_threshold(ss_min: float, dof: int, level: float = LEVEL) -> float:
    """The sum of squares a profile may reach inside the interval (module docstring)."""
    dof = max(int(dof), 1)
    return float(ss_min * (1.0 + stats.f.ppf(level, 1, dof) / dof))


@dataclass(frozen=True)
class ProfileInterval:
    """A parameter's profile-likelihood interval (``level``).  ``lower``/``upper``: its ends, or the bound of the
    plausible range where the profile stays below the threshold (``lower_open``/``upper_open``); ``natural``: whether
    each bound is a natural limit (a shut valve, a flat map).  ``evaluations``: refits spent."""

    name: str
    value: float
    lower: float
    upper: float
    lower_open: bool
    upper_open: bool
    bounds: tuple[float, float]
    natural: tuple[bool, bool] = (False, False)
    level: float = LEVEL
    evaluations: int = 0

    @property
    def identified(self) -> bool:
        """Whether the profile closes inside the plausible range on both sides (an end at a natural limit, such as
        a valve that may be shut, counts as closed: the limit is a physical answer, not a missing one)."""
        return (not self.lower_open or self.natural[0]) and (not self.upper_open or self.natural[1])

    def describe(self, fmt: str = ".3g") -> str:
        lo = f"{self.lower:{fmt}}" + (" (bound)" if self.lower_open else "")
        hi = f"{self.upper:{fmt}}" + (" (bound)" if self.upper_open else "")
        return f"[{lo}, {hi}]" + ("" if self.identified else " not identified")

    def as_dict(self) -> dict[str, Any]:
        return {
            "value": self.value,
            "lower": self.lower,
            "upper": self.upper,
            "lower_open": self.lower_open,
            "upper_open": self.upper_open,
            "identified": self.identified,
            "level": self.level,
            "bounds": list(self.bounds),
            "natural": list(self.natural),
            "evaluations": self.evaluations,
        }


def _refit_fixed(
    fun: Callable[[np.ndarray], np.ndarray],
    z: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    j: int,
    theta: float,
    max_nfev: int,
) -> tuple[float, np.ndarray]:
    """Sum of squares of ``fun`` minimised over every parameter but ``j`` (held at ``theta``), from ``z``."""
    free = np.arange(z.size) != j
    base = z.copy()
    base[j] = theta
    if not free.any():
        return float(np.sum(fun(base) ** 2)), base
    span = hi[free] - lo[free]
    z0 = np.minimum(np.maximum(base[free], lo[free] + 1e-9 * span), hi[free] - 1e-9 * span)

    def f(zf):
        zz = base.copy()
        zz[free] = zf
        return fun(zz)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        res = least_squares(
            f, z0, bounds=(lo[free], hi[free]), x_scale=span, diff_step=1e-6, xtol=1e-8, ftol=1e-8, max_nfev=max_nfev
        )
    out = base.copy()
    out[free] = res.x
    return 2.0 * float(res.cost), out


def profile_interval(
    fun: Callable[[np.ndarray], np.ndarray],
    z: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    j: int,
    threshold: float,
    *,
    step: float | None = None,
    max_steps: int = 12,
    refine: int = 4,
    max_nfev: int = 60,
) -> tuple[float, float, bool, bool, int]:
    """The interval of parameter ``j`` of the least-squares problem ``fun`` (optimum ``z``, bounds ``lo``/``hi``)
    inside which the profile's sum of squares stays below ``threshold``: ``(lower, upper, lower_open, upper_open,
    refits)``.

    Each side walks out from the optimum in steps that double while the profile rises by less than a quarter of the
    way to the threshold, each refit warm-started from the last; the crossing is then located by ``refine`` steps
    of regula falsi on ``sqrt(SS - SS*)`` (about linear in the parameter near a quadratic minimum)."""
    z = np.asarray(z, dtype=float)
    ss0 = float(np.sum(fun(z) ** 2))
    span = float(hi[j] - lo[j])
    h0 = step if step is not None and step > 0 else 0.02 * span
    ends, opens, n = [], [], 0
    for d in (-1.0, 1.0):
        limit = lo[j] if d < 0 else hi[j]
        t_prev, s_prev, z_prev = float(z[j]), ss0, z
        h = h0
        end, opened = limit, True
        for _ in range(max_steps):
            t = t_prev + d * h
            at_limit = (t <= limit) if d < 0 else (t >= limit)
            t = limit if at_limit else t
            s, z_t = _refit_fixed(fun, z_prev, lo, hi, j, t, max_nfev)
            n += 1
            if s >= threshold:
                a, sa, b, sb, z_a = t_prev, s_prev, t, s, z_prev
                for _ in range(refine):  # regula falsi on g = sqrt(SS - SS*) - sqrt(threshold - SS*)
                    ga = math.sqrt(max(sa - ss0, 0.0)) - math.sqrt(threshold - ss0)
                    gb = math.sqrt(max(sb - ss0, 0.0)) - math.sqrt(threshold - ss0)
                    c = b if gb == ga else a + (b - a) * (-ga) / (gb - ga)
                    if not (min(a, b) < c < max(a, b)):
                        c = 0.5 * (a + b)
                    sc, z_c = _refit_fixed(fun, z_a, lo, hi, j, c, max_nfev)
                    n += 1
                    if sc >= threshold:
                        b, sb = c, sc
                    else:
                        a, sa, z_a = c, sc, z_c
                ga = math.sqrt(max(sa - ss0, 0.0)) - math.sqrt(threshold - ss0)
                gb = math.sqrt(max(sb - ss0, 0.0)) - math.sqrt(threshold - ss0)
                end, opened = (a + (b - a) * (-ga) / (gb - ga) if gb != ga else 0.5 * (a + b)), False
                break
            if at_limit:
                break
            rise = (s - ss0) / max(threshold - ss0, 1e-300)
            t_prev, s_prev, z_prev = t, min(s, threshold), z_t
            if rise < 0.25:
                h *= 2.0
        ends.append(float(end))
        opens.append(opened)
    return ends[0], ends[1], opens[0], opens[1], n


def fit_profiles(
    problem: FitProblem, fit: FitResult, *, level: float = LEVEL, max_steps: int = 10, refine: int = 3
) -> dict[str, ProfileInterval]:
    """Profile intervals of every fitted parameter of ``fit`` (its mechanisms' global parameters and each valve's
    opening at the points where it acts; the nuisance is refitted, not reported), its valve supports held.  Keys:
    ``label.param`` as :meth:`~.fit.fitting.FitResult.values`, ``valve_id[point]`` (1-based point) for an opening."""
    obj, z, lo, hi, names = support_objective(problem, fit)
    ss = float(np.sum(obj(z) ** 2))
    thr = profile_threshold(ss, fit.n_cells - fit.k, level)
    natural = {f"{m.label}.{p.name}": p.natural for m in fit.combination.globals for p in m.params}
    stderr = dict(zip(fit.combination.names, map(float, fit.stderr)))
    out: dict[str, ProfileInterval] = {}
    for j in range(len(NUISANCE), z.size):
        name = names[j]
        opening = "[" in name and name.split("[")[0] in {m.id for m in fit.combination.valves}
        se = stderr.get(name, math.nan)
        step = 0.5 * se if math.isfinite(se) and 0 < se < (hi[j] - lo[j]) else None
        a, b, ao, bo, n = profile_interval(obj, z, lo, hi, j, thr, step=step, max_steps=max_steps, refine=refine)
        if opening:
            vid, row = name[:-1].split("[")
            key = f"{vid}[{int(row) + 1}]"
            out[key] = ProfileInterval(
                key,
                float(z[j] ** 2),
                a * a,
                b * b,
                ao,
                bo,
                (float(lo[j] ** 2), float(hi[j] ** 2)),
                (True, False),
                level,
                n,
            )
        else:
            out[name] = ProfileInterval(
                name,
                float(z[j]),
                a,
                b,
                ao,
                bo,
                (float(lo[j]), float(hi[j])),
                tuple(natural.get(name, (False, False))),
                level,
                n,
            )
    return out
