"""How cross-validation predicts a valve's opening at a held-out point (validation/fit/fitting.py, HELD_OUT_VALVES)."""

from __future__ import annotations

import numpy as np
import pytest

from marine_fdi_env.validation.fit.fitting import (
    L1_LAMBDA,
    SUPPORT_FRACTION,
    Combination,
    cell_losses,
    cross_validate,
    fit_combination,
    robust_loss,
)
from marine_fdi_env.validation.fit.held_out_state import state_predictions
from marine_fdi_env.validation.fit.mechanisms import PHYSICAL_MECHANISMS
from marine_fdi_env.validation.fit.problem import FitProblem
from studies.validation.study import _trial_settings, loaded, trial, trial_data

LOADS = np.array([0.25, 0.36, 0.52, 0.67, 0.77, 0.85, 0.96, 1.08])
GATE = next(m for m in PHYSICAL_MECHANISMS if m.id == "waste_gate")


class _Loads:
    """The one thing held_out_openings asks of a problem: the load of every point."""

    def load_axis(self) -> np.ndarray:
        return LOADS


def test_the_option_is_checked_and_recorded_only_when_it_is_not_the_default():
    from marine_fdi_env.validation.fit.problem import FitProblem

    with pytest.raises(ValueError, match="held_out_valves"):
        FitProblem(None, held_out_valves="nearest")  # checked before the dataset is touched
    assert "held_out_valves" not in _trial_settings()  # every study file so far followed the schedule
    assert _trial_settings(held_out_valves="support")["held_out_valves"] == "support"
    assert _trial_settings(held_out_valves="state")["held_out_valves"] == "state"


# --- the opening at a held-out point as a state (held_out_valves="state", validation/fit/held_out_state.py) ---

OPEN = np.array([0, 0, 0, 0, 0, 0.12, 0.18, 0.25])  # a gate shut below 85 % load, opening with load above


def _gated(tmp_path, held_out_valves: str = "schedule") -> FitProblem:
    """The study's first closed-world trial's points and channels, read exactly as the base model with a waste gate
    at :data:`OPEN` says (no noise): whatever a prediction misses is the prediction's own error."""
    pr = FitProblem(loaded(trial_data("a", 0), "gated", tmp_path), held_out_valves=held_out_valves)
    Y, _, _ = pr.predict(GATE.with_openings(pr.base_setting, OPEN))
    pr.Y = np.where(pr.measured_mask, Y, np.nan)
    return pr


def _at(pr: FitProblem):
    return lambda state: GATE.with_openings(pr.base_setting, np.full(pr.n_points, state.get("waste_gate", 0.0)))


def _state(pr: FitProblem, rows) -> np.ndarray:
    return state_predictions(pr, _at(pr), (GATE,), rows, robust_loss, L1_LAMBDA, SUPPORT_FRACTION)


def test_a_held_out_opening_estimated_from_the_other_channels_reproduces_every_reading(tmp_path):
    """Noise-free readings of the model itself: each channel, predicted with the opening its point's other channels
    ask for, comes back within 1 % of a tolerance (the grid's interpolation error is about 2e-4 tolerances); where
    the gate is shut the sparsity decision keeps it shut and the prediction is the shut model's (to the solver's
    convergence).  The
    schedule's guess at the first open point (half-way between its neighbours) misses by tolerances."""
    pr = _gated(tmp_path)
    rows = np.arange(pr.n_points)
    z = (_state(pr, rows) - pr.Y) / pr.tolerance_cells
    assert np.nanmax(np.abs(z)) < 0.01
    shut = pr.predict(GATE.with_openings(pr.base_setting, np.zeros(pr.n_points)), rows[:5])[0]
    assert np.allclose(_state(pr, rows[:5]), shut, rtol=1e-9, atol=0.0)  # the steady-state solver's convergence
    half = GATE.with_openings(pr.base_setting, np.full(pr.n_points, 0.5 * (OPEN[4] + OPEN[6])))
    z_schedule = (pr.predict(half, [5])[0][0] - pr.Y[5]) / pr.tolerance_cells[5]
    assert np.nanmax(np.abs(z_schedule)) > 3.0


def test_a_channel_is_predicted_without_its_own_reading(tmp_path):
    """The prediction of cell (r, j) never sees y[r, j] (an honest held-out prediction): a reading moved by 20
    tolerances leaves its own prediction unchanged (to 1e-12, the solver's convergence), while the other channels'
    predictions, whose
    openings were estimated with it, move."""
    pr = _gated(tmp_path)
    before = _state(pr, [6])
    j = pr.channels.index("turbine_inlet_pressure_bar_gauge")
    pr.Y[6, j] += 20.0 * pr.tolerance_cells[6, j]
    after = _state(pr, [6])
    assert after[0, j] == pytest.approx(before[0, j], rel=1e-12)  # to the solver's convergence from a warm start
    others = np.delete(np.arange(len(pr.channels)), j)
    assert np.any(np.abs(after[0, others] - before[0, others]) > 0.01 * pr.tolerance_cells[6, others])


def test_cross_validation_of_the_true_valve_model_no_longer_pays_for_the_schedule(tmp_path):
    """The true model cross-validated on its own noise-free readings: with the schedule, the three open points' held-out
    openings are guessed from their neighbours and each costs hundreds (the shared error that dilutes a second
    mechanism beside a valve); as a state, every point comes back at the interpolation error (< 1e-4 per point)."""
    comb = Combination((GATE,))
    losses = {}
    for mode in ("schedule", "state"):
        pr = _gated(tmp_path, mode)
        pred, fits = cross_validate(pr, comb, fit_combination(pr, comb))
        assert all(f.held_out_state == (mode == "state") for _, f in fits)
        losses[mode] = cell_losses(pr, pred)[0]
    assert np.all(losses["schedule"][5:] > 100.0)
    assert np.all(losses["state"] < 1e-4)


@pytest.mark.slow
def test_with_the_support_a_waste_gate_and_its_partner_are_both_named():
    """Study trial d304 hides a waste gate and changed ambient conditions (in sample the pair's loss is less than half
    the gate's alone: ``identification_bound``).  Under the cross-validated bar beside a valve (the rule these two
    options were compared under; the default judges a partner beside a valve in sample and names both either way),
    predicting the gate at a held-out point from the schedule, the ambient conditions do not pass and only the gate is
    named; from the full-data support, both are (about 30 s per run)."""
    schedule = trial("d", 304, beside_valve="cross_validated")
    support = trial("d", 304, held_out_valves="support", beside_valve="cross_validated")
    assert schedule["selected"] == ["waste_gate"]
    assert support["selected"] == ["ambient_conditions", "waste_gate"] and support["exact"]
    assert support["trial_settings"]["held_out_valves"] == "support"
