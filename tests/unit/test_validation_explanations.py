"""The evidence set (validation/explain/explanations.py), profile-likelihood intervals (profiles.py) and the deciding
measurement (deciding.py)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import least_squares

from marine_fdi_env.validation.explain.deciding import deciding_measurements, readings_over_load
from marine_fdi_env.validation.explain.explanations import explanation_set
from marine_fdi_env.validation.explain.profiles import fit_profiles, profile_interval, profile_threshold
from marine_fdi_env.validation.fit.fitting import Combination, cross_validate, fit_combination, predict_setting
from marine_fdi_env.validation.fit.mechanisms import get_mechanism
from marine_fdi_env.validation.fit.problem import FitProblem
from marine_fdi_env.validation.fit.synthesize import synthesize
from studies.validation.study import loaded


# --------------------------------------------------------------------------------------- profiles
def _toy(seed: int = 4):
    """y = a exp(-b x) at 12 points with 2 % noise: a two-parameter least-squares problem with a closed-form
    profile in ``a`` for every ``b``."""
    rng = np.random.default_rng(seed)
    x = np.linspace(0.0, 1.0, 12)
    y = 2.0 * np.exp(-1.5 * x) + rng.normal(0.0, 0.02, x.size)
    fun = lambda z: (z[0] * np.exp(-z[1] * x) - y) / 0.02  # noqa: E731
    return x, y, fun


def _brute_profile_b(x, y, b_grid):
    """min over a of the sum of squares, for every b of the grid (a = <y, e> / <e, e>, e = exp(-b x))."""
    E = np.exp(-np.outer(b_grid, x))
    a = (E @ y) / np.sum(E * E, axis=1)
    return np.sum(((a[:, None] * E) - y) ** 2, axis=1) / 0.02**2


def test_profile_interval_matches_a_brute_force_scan():
    """The profile search (walk out, regula falsi on sqrt(SS - SS*)) finds the ends a dense scan of the exact profile
    finds, to a small part of the interval's width (the scan's own resolution is 1e-5 in b)."""
    x, y, fun = _toy()
    lo, hi = np.array([0.0, 0.0]), np.array([10.0, 10.0])
    opt = least_squares(fun, [1.0, 1.0], bounds=(lo, hi))
    ss = 2.0 * opt.cost
    thr = profile_threshold(ss, x.size - 2)
    a, b, ao, bo, n = profile_interval(fun, opt.x, lo, hi, 1, thr)
    grid = np.linspace(opt.x[1] - 0.5, opt.x[1] + 0.5, 100001)
    inside = grid[_brute_profile_b(x, y, grid) <= thr]
    assert not ao and not bo
    width = inside[-1] - inside[0]
    assert a == pytest.approx(inside[0], abs=2e-3 * width)
    assert b == pytest.approx(inside[-1], abs=2e-3 * width)
    assert a < opt.x[1] < b and n <= 30


def test_a_profile_that_does_not_close_is_open_at_the_bound():
    """Bounds inside the interval: the profile reaches them below the threshold, and says so."""
    x, y, fun = _toy()
    lo, hi = np.array([0.0, 1.49]), np.array([10.0, 1.52])
    opt = least_squares(fun, [1.0, 1.5], bounds=(lo, hi))
    thr = profile_threshold(2.0 * opt.cost, x.size - 2)
    a, b, ao, bo, _ = profile_interval(fun, opt.x, lo, hi, 1, thr)
    assert ao and bo and a == 1.49 and b == 1.52


# --------------------------------------------------------------------------------------- the evidence set
@pytest.fixture(scope="module")
def gate_case():
    """Data from a waste gate opening above 75 % load, its smallest opening (3.5 % of the turbine area, at the
    point nearest the threshold) about the size the noise can hide; the gate fitted with three supports: the true
    one, the true one without that point, and three part-load points (wrong)."""
    syn = synthesize(
        "wartsila-6l46", ["waste_gate:above=0.75,opening=0.06,turbine_area_scale=0.85"], points=8, noise=0.01, seed=2
    )
    pr = FitProblem(loaded(syn))
    base = fit_combination(pr, Combination())
    base_cv, _ = cross_validate(pr, Combination(), base)
    gate = Combination((get_mechanism("waste_gate"),))
    true = [i for i, o in enumerate(syn.truth[0]["openings"]) if o > 0]
    fits = {"true": fit_combination(pr, gate, start=base, support={"waste_gate": true})}
    fits["without_first"] = fit_combination(pr, gate, start=fits["true"], support={"waste_gate": true[1:]})
    fits["part_load"] = fit_combination(pr, gate, start=fits["true"], support={"waste_gate": [0, 1, 2]})
    return pr, base_cv, fits, true


def test_a_tie_constructed_on_synthetic_data_is_reported_as_a_tie(gate_case):
    """Whether the gate acts at the point where it barely opens is not decided by these data: both supports are in
    the set, the one without that point within the band of 2."""
    pr, base_cv, fits, true = gate_case
    es = explanation_set(pr, fits["true"], [], base_cv=base_cv, profiles=False, extra=[fits["without_first"]])
    members = {tuple(e.fit.support["waste_gate"]) for e in es.members}
    assert members == {tuple(true), tuple(true[1:])}
    assert all(abs(e.delta_aic) <= 2.0 for e in es.members)


def test_a_clear_case_gives_a_set_of_one(gate_case):
    """A gate at three part-load points misses the data by far and at every point: out of the set, and so is the
    calibrated base (a part of the gate model, whose gate earns its place)."""
    pr, base_cv, fits, true = gate_case
    es = explanation_set(pr, fits["true"], [], base_cv=base_cv, profiles=False, extra=[fits["part_load"]])
    assert len(es.members) == 1 and es.members[0].fit.support["waste_gate"] == true
    wrong = next(e for e in es.tried if e.fit.support.get("waste_gate") == [0, 1, 2])
    assert not wrong.in_set and wrong.delta_aic > 2.0 and wrong.p_worse < 0.05
    assert not next(e for e in es.tried if not e.labels).in_set


def test_profiles_of_a_fitted_gate_contain_the_truth(gate_case):
    """The profile intervals of the true structure's turbine area and openings close inside their ranges and hold
    the values the data were drawn with (1 % noise; one draw, so a 95 % interval may miss: these do not)."""
    pr, _, fits, true = gate_case
    prof = fit_profiles(pr, fits["true"])
    area = prof["waste_gate.turbine_area_scale"]
    assert area.identified and area.lower < 0.85 < area.upper
    for i in true:
        p = prof[f"waste_gate[{i + 1}]"]
        assert p.lower <= p.value <= p.upper and not p.upper_open


def test_the_fitted_engine_on_the_grid_reproduces_the_fit_at_the_measured_points(gate_case):
    """The deciding measurement solves each explanation's fitted engine (valves on their schedules) at new loads:
    at the measured loads and ambient it must read what the fit reads there (the schedule passes through the
    fitted openings; the steady-state solver's tolerance is far below a reading's last digit)."""
    pr, _, fits, _ = gate_case
    f = fits["without_first"]
    load = pr.load_axis()
    grid = readings_over_load(pr, f, load, pr.params.p_amb_Pa, pr.params.T_amb_K)
    fit = predict_setting(pr, f, np.arange(pr.n_points))
    np.testing.assert_allclose(grid, fit, rtol=1e-6, atol=1e-9)
    d = deciding_measurements(pr, [("A", fits["true"]), ("B", f)])[0]["measurements"][0]
    assert d["n_tolerances"] > 0 and 0.25 <= d["load"] <= 1.1
