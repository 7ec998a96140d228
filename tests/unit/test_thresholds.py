"""The readings of the observer modules' thresholds (diagnosis.thresholds): one switch, the residuals
unchanged, each reading's thresholds what its definition says."""

import numpy as np
import pytest

from marine_fdi_env.baselines.reference_agent import ReferenceAgent, ReferenceLipschitzAgent, thresholds_name
from marine_fdi_env.diagnosis.agent import ReferenceDiagnoser
from marine_fdi_env.diagnosis.cell_sets import cell_files
from marine_fdi_env.diagnosis.modules import MODULE_IDS
from marine_fdi_env.diagnosis.residuals import model_terms, residuals_for_run
from marine_fdi_env.diagnosis.thresholds import (
    H_TERMS,
    TABLE_6_1,
    THRESHOLD_READINGS,
    check_thresholds,
    closed_form_threshold,
    load_global_bounds,
    threshold_array,
)
from marine_fdi_env.engine.constants import model_constants
from marine_fdi_env.engine.faults import FaultSpec
from marine_fdi_env.engine.params import load_params
from marine_fdi_env.engine.sensors import NOISE_BOUNDS, sensor_index
from marine_fdi_env.engine.simulator import Simulator
from marine_fdi_env.envs.vector import MarineFDIVectorEnv

OBSERVERS = [MODULE_IDS.index(m) for m in ("M1.1", "M1.2", "M3.1", "M3.2", "M4.1", "M4.2")]
M4 = [MODULE_IDS.index(m) for m in ("M4.1", "M4.2")]
M3 = [MODULE_IDS.index(m) for m in ("M3.1", "M3.2")]


@pytest.fixture(scope="module")
def run():
    """Two engines, 60 s: a manoeuvring profile and a compressor seal leak at constant load."""
    sim = Simulator(
        "thesis-12v28", 2, seeds=[5, 6], faults=[[], [FaultSpec("compressor_seal_leak", 10.0)]],
        profiles=["manoeuvring", "constant"],
    )  # fmt: skip
    res = sim.run(60.0)
    return res, sim.dt


def _trace(run, engine, reading):
    res, dt = run
    c = model_constants(load_params("thesis-12v28"))
    return residuals_for_run(c, res.measurements[:, engine], res.truth_of("u")[:, engine], dt, thresholds=reading)


def test_an_unknown_reading_is_refused_by_name():
    with pytest.raises(ValueError, match="thesis-lipschitz"):
        check_thresholds("thesis")
    with pytest.raises(ValueError, match="thresholds must be one of"):
        ReferenceDiagnoser("thesis-12v28", thresholds="lipschitz")


def test_the_local_reading_weighs_every_term_once_and_adds_nothing():
    a = threshold_array("local")
    assert np.all(a[:, : len(H_TERMS)] == 1.0) and np.all(a[:, len(H_TERMS) :] == 0.0)


@pytest.mark.parametrize("reading", THRESHOLD_READINGS[1:])
def test_every_reading_changes_the_observers_thresholds_only(run, reading):
    for engine in (0, 1):
        base = _trace(run, engine, "local")
        other = _trace(run, engine, reading)
        assert np.array_equal(base.residuals, other.residuals, equal_nan=True)
        algebraic = [k for k in range(len(MODULE_IDS)) if k not in OBSERVERS]
        assert np.array_equal(base.thresholds[:, algebraic], other.thresholds[:, algebraic])


def test_without_the_interconnection_terms_no_observer_threshold_grows(run):
    for engine in (0, 1):
        base = _trace(run, engine, "local").thresholds
        no = _trace(run, engine, "thesis-no-interconnection").thresholds
        assert np.all(no[:, M3 + M4] <= base[:, M3 + M4])
        # the interconnection terms are most of M3.q's (x1, x4, T1), a few per cent of M4.q's
        assert np.median(no[100:, M3] / base[100:, M3]) < 0.6
        assert np.median(no[100:, M4] / base[100:, M4]) > 0.9


def test_the_kernels_closed_form_is_eq_5_10_to_5_12_with_table_6_1(run):
    res, dt = run
    tr = _trace(run, 1, "thesis-table-6.1-m4")
    row = threshold_array("thesis-table-6.1-m4")[2]
    k = TABLE_6_1["M4"]
    t = np.arange(tr.thresholds.shape[0]) * dt
    for m, s in zip(M4, ("S4.1", "S4.2")):
        d = NOISE_BOUNDS[sensor_index(s)]
        want = [
            closed_form_threshold(x, d, k.rho, k.xi_per_s, k.rho_d, k.xi_d_per_s, row[13], row[14], row[15]) for x in t
        ]
        np.testing.assert_allclose(tr.thresholds[:, m], want, rtol=1e-12)
    # the steady part: d̄ (1 + ρ_d/ξ) = 1.1 d̄ (the noise term 0.1 d̄ where a valid ρ_d >= L gives 0.95 d̄)
    d = NOISE_BOUNDS[sensor_index("S4.1")]
    assert tr.thresholds[-1, M4[0]] == pytest.approx(d * (1.0 + k.rho_d / k.xi_per_s), rel=1e-3)
    # ... and M3.q stays local in this reading
    assert np.array_equal(tr.thresholds[:, M3], _trace(run, 1, "local").thresholds[:, M3])


def test_the_closed_form_starts_at_twice_the_noise_bound_and_matches_its_integral():
    # x̄ = d̄/ρ: E(0) = d̄, so the threshold starts at 2 d̄; the integral term against a quadrature
    k = TABLE_6_1["M3"]
    d, lam, hbar = 990.0, 50.0, 1e5
    assert closed_form_threshold(
        0.0, d, k.rho, k.xi_per_s, k.rho_d, k.xi_d_per_s, lam, hbar, 1 / k.rho
    ) == pytest.approx(2 * d)
    t = 0.05
    s = np.linspace(0.0, t, 20001)
    K = (k.rho_d * d + k.rho * hbar) / k.xi_per_s
    E = k.rho * np.exp(-k.xi_per_s * s) * d / k.rho + K * (1 - np.exp(-k.xi_d_per_s * s))
    integral = np.trapezoid(E * np.exp(-k.xi_per_s * (t - s)), s)
    want = E[-1] + k.rho * lam * integral + d
    got = closed_form_threshold(t, d, k.rho, k.xi_per_s, k.rho_d, k.xi_d_per_s, lam, hbar, 1 / k.rho)
    assert got == pytest.approx(want, rel=1e-6)


def test_the_global_bounds_cover_the_local_terms_at_full_load():
    # the Lipschitz reading's constant is the envelope's largest term: at a full-load steady state
    # (inside the envelope) every local term is below it
    sim = Simulator("thesis-12v28", 1, seeds=[1], profiles="constant:u0=1.0", noise_scale=0.0)
    y = sim.run(20.0).measurements[-1, 0]
    terms = model_terms(model_constants(load_params("thesis-12v28")), y[None])[0]
    b = load_global_bounds("thesis-12v28")
    for q, obs in enumerate(("M3", "M4")):
        for i, name in enumerate(("x1", "x3", "x4", "T1", "T_in")):
            assert 0.0 < terms[q, i] <= b[obs]["terms"][name]


def test_reading_agents_ask_the_environment_for_their_reading_and_cells():
    a = ReferenceLipschitzAgent()
    assert a.name == "reference-lipschitz" == thresholds_name("reference", "thesis-lipschitz")
    assert a.env_kwargs == {"diagnosis_cells": "sized", "diagnosis_thresholds": "thesis-lipschitz"}
    assert ReferenceAgent().env_kwargs == {"diagnosis_cells": "sized"}
    assert cell_files("reference", "thesis-lipschitz")["sized"] == "thresholds/thesis-lipschitz/sized_cells.json"
    with pytest.raises(ValueError, match="local thresholds only"):
        cell_files("sequential", "thesis-lipschitz")


def test_the_sequential_tests_refuse_another_reading():
    with pytest.raises(ValueError, match="observe_sequential"):
        MarineFDIVectorEnv(num_envs=1, observe_sequential=True, diagnosis_thresholds="thesis-lipschitz")
