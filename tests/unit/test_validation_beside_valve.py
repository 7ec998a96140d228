"""How a cause joining a model with a valve earns its place (validation/select/evidence.py, BESIDE_VALVE)."""

from __future__ import annotations

import pytest
from scipy import stats

from marine_fdi_env.validation.fit.fitting import Combination
from marine_fdi_env.validation.fit.mechanisms import PHYSICAL_MECHANISMS, SensorCalibration
from marine_fdi_env.validation.select.evidence import BESIDE_VALVE, earns, judged_in_sample

MECH = {m.id: m for m in PHYSICAL_MECHANISMS}
M = 88  # measured cells of a study trial: 8 points x 11 channels


def test_only_a_physical_mechanism_joining_a_model_with_a_valve_is_beside_a_valve():
    gate = Combination((MECH["waste_gate"],))
    cal = SensorCalibration(channel="charge_air_pressure_bar_gauge", reference=2.0)
    assert judged_in_sample(gate, [MECH["ambient_conditions"]])
    assert judged_in_sample(gate, [MECH["ambient_conditions"], MECH["friction_losses"]])  # a pair of them
    assert not judged_in_sample(Combination(), [MECH["ambient_conditions"]])  # no valve in the model
    assert not judged_in_sample(gate, [MECH["bypass_valve"]])  # a second valve brings its own held-out error
    assert not judged_in_sample(gate, [cal])  # calibrations keep the cross-validated bar
    assert not judged_in_sample(gate, [MECH["ambient_conditions"], MECH["bypass_valve"]])
    assert not judged_in_sample(gate, [])


def test_a_calibration_added_beside_a_valve_keeps_the_cross_validated_bar_under_every_rule():
    """Judged in sample at a forward step, a calibration beside a bypass valve named a spurious turbine-inlet
    temperature calibration in development trial d317 (an ablation, not the default): only the exchange step's swap of
    a physical cause for a calibration is judged in sample (``in_sample_exchange``)."""
    gate = Combination((MECH["waste_gate"],))
    cal = SensorCalibration(channel="charge_air_pressure_bar_gauge", reference=2.0)
    for rule in BESIDE_VALVE:
        assert not judged_in_sample(gate, [cal], rule)
    assert judged_in_sample(gate, [MECH["ambient_conditions"]], "in_sample_exchange")
    assert judged_in_sample(gate, [MECH["ambient_conditions"]], "in_sample")
    assert not judged_in_sample(gate, [MECH["ambient_conditions"]], "cross_validated")  # the ablation: nothing is


def test_the_in_sample_bar_is_the_cross_validated_one_on_in_sample_scores():
    """Trial d131's numbers: cross-validated the gate with ambient conditions gains 7.2 % on the gate alone (below the
    10 % bar), in sample it halves the loss (1.35 -> 0.65 per cell, 2 more parameters)."""
    ref, cand = (11.82, 1.35, 5), (10.97, 0.65, 7)
    gain, p, why = earns(ref, cand, M, 0.10, 0.0005, in_sample=False)
    assert gain == pytest.approx((11.82 - 10.97) / 11.82) and "below 10%" in why
    gain, p, why = earns(ref, cand, M, 0.10, 0.0005, in_sample=True)
    F = ((1.35 - 0.65) * M / 2) / (0.65 * M / (M - 7))  # the F-test of nested least squares, in sample
    assert gain == pytest.approx(1 - 0.65 / 1.35) and p == pytest.approx(stats.f.sf(F, 2, M - 7)) and why == ""
    # in sample, the cross-validated score must still drop at all, and the F-test must pass the step's threshold
    assert "not below" in earns(ref, (11.9, 0.65, 7), M, 0.10, 0.0005, in_sample=True)[2]
    small = (11.0, 1.20, 7)  # 11 % in sample with 2 parameters: F = 5.1, p = 0.0085
    gain, p, why = earns(ref, small, M, 0.10, 0.0005, in_sample=True)
    assert gain > 0.10 and p > 0.0005 and why.startswith("in-sample p")
    assert earns((0.0, 0.0, 5), (0.0, 0.0, 7), M, 0.1, 0.01, in_sample=True)[2]  # nothing left to explain


def test_without_the_cross_validated_guard_the_in_sample_gain_and_f_test_alone_decide():
    """Trial d358's numbers (rule ``in_sample_pairs``): the gate with a turbine flow law opens at 4 of 8 points (k = 7)
    and fits 20 % better in sample than the gate alone opening at 7 (k = 8), but its sharper opening's held-out error
    raises its cross-validated score (11.85 against 10.43).  With the guard it is refused for that alone; without it
    the in-sample gain and F-test decide, and they still refuse what they refused before."""
    ref, cand = (10.43, 0.9543, 8), (11.85, 0.7664, 7)
    thr = 0.01 / 71
    assert earns(ref, cand, M, 0.10, thr, in_sample=True)[2] == "cross-validated score 11.85 not below 10.43"
    gain, p, why = earns(ref, cand, M, 0.10, thr, in_sample=True, cv_guard=False)
    F = (0.9543 - 0.7664) * M / (0.7664 * M / (M - 7))  # fewer parameters: the drop counts as one
    assert why == "" and gain == pytest.approx(1 - 0.7664 / 0.9543) and p == pytest.approx(stats.f.sf(F, 1, M - 7))
    assert "in-sample gain" in earns(ref, (11.85, 0.90, 7), M, 0.10, thr, in_sample=True, cv_guard=False)[2]
    assert "in-sample p" in earns((10.43, 0.9543, 6), (11.85, 0.80, 9), M, 0.10, thr, in_sample=True, cv_guard=False)[2]
    # the guard only ever applies in sample: cross-validated, the gain is the cross-validated one either way
    assert earns(ref, cand, M, 0.10, thr, in_sample=False, cv_guard=False)[2].startswith("gain -13.6%")
