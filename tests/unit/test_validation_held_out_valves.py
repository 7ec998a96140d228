"""How cross-validation predicts a valve's opening at a held-out point (validation/fit/fitting.py, HELD_OUT_VALVES)."""

from __future__ import annotations

import numpy as np
import pytest

from marine_fdi_env.validation.fit.fitting import Combination, FitResult
from marine_fdi_env.validation.fit.mechanisms import PHYSICAL_MECHANISMS

LOADS = np.array([0.25, 0.36, 0.52, 0.67, 0.77, 0.85, 0.96, 1.08])
GATE = next(m for m in PHYSICAL_MECHANISMS if m.id == "waste_gate")


class _Loads:
    """The one thing held_out_openings asks of a problem: the load of every point."""

    def load_axis(self) -> np.ndarray:
        return LOADS


def _fold(openings: list[float], held_out: list[int], support: list[int] | None) -> FitResult:
    rows = np.setdiff1d(np.arange(LOADS.size), held_out)
    o = np.array(openings, dtype=float)
    o[held_out] = np.nan
    return FitResult(
        Combination((GATE,)),
        np.ones(1),
        np.ones(1),
        np.ones(1),
        {"waste_gate": o},
        {"waste_gate": [int(r) for r in rows if o[r] > 0]},
        0.0,
        0.0,
        0,
        0,
        rows,
        np.full(rows.size, np.nan),
        held_out_support=None if support is None else {"waste_gate": support},
    )


def test_a_held_out_point_is_shut_where_the_full_fit_shuts_it_and_interpolated_among_open_points_elsewhere():
    gate = [0, 0, 0, 0, 0, 0.16, 0.23, 0.32]
    # the last shut point: shut (the schedule would interpolate a half-open gate between 0.67 and 0.85)
    assert _fold(gate, [4], [5, 6, 7]).held_out_openings(_Loads(), [4])["waste_gate"][4] == 0.0
    # the highest load: the line through the two nearest open points, not the last opening held constant
    o = _fold(gate, [7], [5, 6, 7]).held_out_openings(_Loads(), [7])["waste_gate"]
    assert o[7] == pytest.approx(0.23 + (0.23 - 0.16) / (0.96 - 0.85) * (1.08 - 0.96), rel=1e-12)
    assert np.array_equal(o[:7], gate[:7])  # the fold's own openings where it was fitted
    # the first open point: the line through the next two, backwards
    o = _fold(gate, [5], [5, 6, 7]).held_out_openings(_Loads(), [5])["waste_gate"]
    assert o[5] == pytest.approx(0.23 + (0.32 - 0.23) / (1.08 - 0.96) * (0.85 - 0.96), rel=1e-12)
    # between open points: linear in load
    o = _fold([0, 0, 0, 0.1, 0.2, 0.3, 0.3, 0.3], [4], [3, 4, 5, 6, 7]).held_out_openings(_Loads(), [4])
    assert o["waste_gate"][4] == pytest.approx(0.1 + 0.2 * (0.77 - 0.67) / (0.85 - 0.67), rel=1e-12)


def test_an_extrapolated_opening_never_goes_below_shut_and_a_lone_or_missing_open_point_is_handled():
    steep = [0, 0, 0, 0, 0, 0.02, 0.30, 0.32]
    o = _fold(steep, [4], [4, 5, 6, 7]).held_out_openings(_Loads(), [4])["waste_gate"]
    assert o[4] == 0.0  # the line through 0.85 and 0.96 is below zero at 0.77
    lone = [0, 0, 0, 0, 0, 0, 0, 0.3]
    assert _fold(lone, [6], [6, 7]).held_out_openings(_Loads(), [6])["waste_gate"][6] == 0.3
    assert _fold(lone, [7], [7]).held_out_openings(_Loads(), [7])["waste_gate"][7] == 0.0  # no open point left
    with pytest.raises(ValueError, match="full-data support"):
        _fold(lone, [7], None).held_out_openings(_Loads(), [7])


# --- the opening at a held-out point as a state (held_out_valves="state", validation/fit/held_out_state.py) ---

OPEN = np.array([0, 0, 0, 0, 0, 0.12, 0.18, 0.25])  # a gate shut below 85 % load, opening with load above
