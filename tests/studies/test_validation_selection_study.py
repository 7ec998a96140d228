"""Model selection on data with hidden effects (the open-world study, a few trials here), the fitted engine as a
parameter set of the one model, the shipped datasets and the ``validate`` command line.

The study's conditions (:data:`studies.validation.study.CONDITIONS`): (a) closed world, (b) model
error, (c) noise proportional to the reading, (d) two mechanisms, (e) an effect outside the library; each trial
has a negative control (the same data without the hidden effect).  A few trials run in CI; the whole study is a
documented command (docs/validation.md) and a slow test.
"""

from __future__ import annotations

import json
import warnings

import numpy as np
import pytest

from marine_fdi_env.validation import DataWarning, load_measured
from marine_fdi_env.validation.fit.problem import FitProblem
from marine_fdi_env.validation.fit.synthesize import synthesize
from marine_fdi_env.validation.select.selection import select_causes
from studies.validation.study import CONDITIONS, study, trial


def _load(path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        return load_measured(path)


# --------------------------------------------------------------------------------------- the study, CI-sized
@pytest.mark.parametrize("condition, seed", [("a", 0), ("e", 0)])
def test_study_trial_and_its_control(condition, seed, tmp_path, monkeypatch):
    """One trial of a closed-world and of an out-of-library condition, with its negative control: the hidden
    mechanism is named exactly (with the points where a valve acts), the out-of-library bump comes back as
    unexplained on its channel and load region, and the controls name nothing.  A rerun with the same
    checkpoint resumes from it without running a trial again."""
    ckpt = tmp_path / "study.trials.jsonl"
    res = study([condition], [seed], controls=True, progress=False, points=7, checkpoint=ckpt)
    assert len(ckpt.read_text().splitlines()) == 2

    def no_rerun(*a, **k):
        raise AssertionError("a finished trial was run again")

    import studies.validation.study as synth

    monkeypatch.setattr(synth, "trial", no_rerun)
    again = study([condition], [seed], controls=True, progress=False, points=7, checkpoint=ckpt)

    def dump(x):
        return json.dumps(x, default=float, sort_keys=True)

    assert dump(again["conditions"]) == dump(res["conditions"])
    with pytest.raises(AssertionError, match="run again"):  # other settings: not taken from the checkpoint
        study([condition], [seed], controls=True, progress=False, points=7, prune=False, checkpoint=ckpt)
    tr = [r for r in res["trials"] if not r["control"]][0]
    ct = [r for r in res["trials"] if r["control"]][0]
    assert not ct["named_any"], ct["selected"]
    if condition == "e":
        assert tr["unexplained_right_channel"] and tr["unexplained_right_region"], (tr["effects"], tr["unexplained"])
        assert not tr["named_any"], tr["selected"]
    else:
        assert tr["exact"], (tr["mechanisms"], tr["selected"])
        for ok in (tr.get("activity_support_match") or {}).values():
            assert ok
    s = res["conditions"][condition]
    assert s["n_trials"] == 1 and s["control_named_rate"] == 0.0


def test_study_told_the_true_noise(monkeypatch):
    """The ``--tolerance noise`` ablation hands the selection each channel's true noise (the mean standard deviation
    drawn on it: in (c) 1.5 % of each reading, so about 0.75 K on a 50 C cooler outlet and 9 K on a 600 C exhaust,
    where the stated tolerance is 5 K on both), records it in the trial's settings (a resumed study does not mix it
    with the stated-tolerance trials; the default is not recorded, so earlier files still resume) and refuses an
    unknown mode."""
    import marine_fdi_env.validation.select.selection as selection
    from studies.validation.study import _trial_settings, noise_tolerances, trial_data

    seen = {}

    class Stop(Exception):
        pass

    def capture(problem, **kw):
        seen["channels"], seen["tolerance"] = list(problem.channels), problem.tolerance.copy()
        raise Stop

    monkeypatch.setattr(selection, "select_causes", capture)
    with pytest.raises(Stop):
        trial("c", 3, tolerance="noise")
    syn = trial_data("c", 3)
    told = noise_tolerances(syn, seen["channels"])
    np.testing.assert_allclose(seen["tolerance"], [told[c] for c in seen["channels"]], rtol=1e-12)
    clean = {c: np.asarray(syn.clean[c], dtype=float) for c in seen["channels"]}
    for c in seen["channels"]:  # 1.5 % of the mean absolute reading, in the column's units
        assert told[c] == pytest.approx(0.015 * np.mean(np.abs(clean[c])), rel=1e-9)
    cooler = told["charge_air_cooler_outlet_temperature_C"]
    exhaust = told["cylinder_exhaust_temperature_mean_C"]
    assert cooler < 1.5 and exhaust > 6.0, (cooler, exhaust)  # the stated 5 K misstates both
    assert "tolerance" not in _trial_settings() and _trial_settings()["exchange"] is True
    assert _trial_settings(tolerance="noise")["tolerance"] == "noise"
    assert "exchange" not in _trial_settings(exchange=False)  # as in every file written before the exchange step
    assert _trial_settings()["calibration_scan"] == "per named calibration"  # older files scanned over every channel
    with pytest.raises(ValueError, match="tolerance must be one of"):
        trial("c", 3, tolerance="exact")


def test_a_miscalibrated_sensor_is_named_alone_once_the_model_is_refitted_with_it():
    """Closed world, one thermocouple reading 8 % low and 24 K off (study trial a25): the calibration is named and
    nothing else.  Before the model was refitted with an accepted calibration, the nuisance fitted to the
    uncorrected channel stayed bent, and the next step credited `ambient_conditions` with the gain of refitting."""
    tr = trial("a", 25)
    assert tr["selected"] == ["sensor_calibration[cylinder_exhaust_temperature_mean_C]"], tr["selected"]
    assert tr["exact"]


def test_a_cause_that_later_causes_make_redundant_is_removed():
    """Study trial d7 (a bypass valve and a turbine-inlet pressure gauge off): the first step names the bypass valve
    with a turbine flow law as a pair; the next names the gauge's calibration, after which the flow law adds too
    little.  Without the final removal step the selection named all three."""
    tr = trial("d", 7)
    assert tr["selected"] == ["bypass_valve", "sensor_calibration[turbine_inlet_pressure_bar_gauge]"], tr["selected"]


@pytest.mark.slow
def test_the_exchange_step_names_the_calibration_a_physical_cause_had_absorbed():
    """Study trial d260 (friction + a maximum-pressure gauge reading 5 % high and 7.5 bar off): forward selection
    names cylinder heat loss with friction as a pair (the heat loss absorbs part of the gauge's error, so the gauge's
    calibration then leaves structure and is not eligible) and then ambient + turbine flow law to mop up.  With the
    exchange step the heat loss is replaced by the calibration, the removal step drops the other two, and the
    exact pair is named.  Without it (``--no-exchange``) the four causes stay."""
    truth = ["friction_losses", "sensor_calibration[max_cylinder_pressure_bar_gauge]"]
    assert trial("d", 260)["selected"] == sorted(truth)
    assert len(trial("d", 260, exchange=False)["selected"]) == 4


def test_two_mechanisms_that_only_fit_together_are_named_as_a_pair(tmp_path):
    """The data of study trial d/6: extra friction (more fuel, hotter exhaust) and a manifold heat loss (cooler
    turbine inlet) at once.  Alone, each explains little (friction 7 % of the base's loss in-sample), and the best
    single
    candidate of the first step is a 38 % gain on the cylinder-outlet thermocouples that absorbs the one channel
    the two disagree on; taking it (plain greedy selection did) left fuel flow 360 kg/h off and named neither.
    The pair, fitted jointly, must be named exactly, and each member must have earned its place."""
    d = CONDITIONS["d"]
    syn = synthesize(
        "wartsila-6l46",
        ["friction_losses", "exhaust_heat_loss"],
        points=8,
        noise=d["noise"],
        seed=6 * 31 + 7,
        noise_model=d["noise_model"],
        perturb=d["perturb"],
    )
    path = tmp_path / "d6.csv"
    syn.write(path)
    sel = select_causes(FitProblem(_load(path)))
    assert sorted(sel.selected_labels) == ["exhaust_heat_loss", "friction_losses"], sel.selected_labels
    step1 = sel.steps[0]
    assert step1.get("pair") and set(step1["best"].split(" + ")) == {"friction_losses", "exhaust_heat_loss"}
    singles = [c for c in step1["candidates"] if c.members is None and c.cross_validated and not c.screened]
    best_single = min(singles, key=lambda c: c.penalised)
    assert best_single.added.startswith("sensor_calibration[cylinder_exhaust"), best_single.added
    pair = next(c for c in step1["candidates"] if c.added == step1["best"])
    assert pair.penalised < best_single.penalised
    for m in pair.members:  # each member alone is far worse than the pair (cross-validated)
        assert m.cv_score > 2 * pair.cv_score, (m.added, m.cv_score, pair.cv_score)


@pytest.mark.slow
def test_a_blade_speed_ratio_loss_is_named_although_its_parameters_trade_off():
    """Closed world, a turbine efficiency parabola with its optimum away from the measured range (study trial a/2):
    the optimum and the curvature trade off (the fit touches the optimum's bound, the curvature is not determined)
    but the data do not want more than the bound, so the mechanism is named -- not the waste gate, which mimics it
    with an opening per point."""
    res = trial("a", 2)
    assert res["truth"][0]["id"] == "turbine_efficiency_bsr"
    assert res["selected"] == ["turbine_efficiency_bsr"], res["selected"]


@pytest.mark.slow
def test_open_world_study_rates():
    """The whole study at reduced size (the README quotes the full run): identification >= 95 % up to structural
    equivalence in (a), controls name a cause in <= 5 %."""
    res = study(["a"], range(20), controls=True, progress=False)
    s = res["conditions"]["a"]
    assert s["identification_rate_up_to_equivalence"] >= 0.9 and s["control_named_rate"] <= 0.05
