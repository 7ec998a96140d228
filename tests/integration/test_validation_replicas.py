"""Replicas of a dataset drawn from fitted hypotheses (:mod:`marine_fdi_env.validation.select.replicas`): the noise, the
design kept, the seeding, and the pipeline run on them."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from marine_fdi_env.validation import DataWarning, load_measured
from marine_fdi_env.validation.fit.mechanisms import PHYSICAL_MECHANISMS
from marine_fdi_env.validation.fit.problem import FitProblem
from marine_fdi_env.validation.fit.synthesize import synthesize
from marine_fdi_env.validation.select.replicas import (
    hypotheses,
    markdown_table,
    noise_scale,
    replica_readings,
    replicate,
    run_replica,
)
from marine_fdi_env.validation.select.rules import SelectionRules
from marine_fdi_env.validation.select.selection import select_causes
from tests.paths import TEST_DATA

#: a small library keeps the pipeline runs of this file to seconds
_LIB = tuple(m for m in PHYSICAL_MECHANISMS if m.id in ("waste_gate", "turbine_flow_law"))


@pytest.fixture(scope="module")
def waste_gate_selection(tmp_path_factory):
    d = tmp_path_factory.mktemp("replicas")
    syn = synthesize(
        "wartsila-6l46", ["waste_gate:above=0.75,opening=0.25,turbine_area_scale=0.8"], points=7, noise=0.005, seed=21
    )
    path = d / "wg.csv"
    syn.write(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        ds = load_measured(path)
    sel = select_causes(FitProblem(ds), _LIB, pairs=False, max_causes=1)
    return syn, sel


def test_the_data_name_the_waste_gate_and_the_alternative_is_the_flow_law(waste_gate_selection):
    _, sel = waste_gate_selection
    assert sel.selected_labels == ["waste_gate"]
    hyps = hypotheses(sel)
    assert [h.name for h in hyps] == ["named", "alternative: turbine_flow_law"]
    assert hyps[1].causes == ("turbine_flow_law",)
    # the named hypothesis is the fit itself: its readings are the fit's, its valve acts where the fit opened it
    assert hyps[0].acts["waste_gate"] == tuple(bool(x > 0) for x in sel.fit.openings["waste_gate"])
    # the alternative fits the waste-gated data worse (otherwise the data would have named it)
    assert hyps[1].in_sample_score > hyps[0].in_sample_score
    with pytest.raises(ValueError, match="unknown physical mechanism"):
        hypotheses(sel, ["no_such_thing"])
    with pytest.raises(ValueError, match="among the named causes"):
        hypotheses(sel, ["waste_gate"])


def test_replica_noise_has_the_stated_scale_and_is_seeded(waste_gate_selection):
    _, sel = waste_gate_selection
    pr = sel.problem
    hyp = hypotheses(sel, [])[0]
    m = pr.measured_mask
    # tolerance: Gaussian of each cell's tolerance; 300 replicas x the measured cells: the sample standard
    # deviation of a unit normal is within 3 % of 1 (its own standard error is 1/sqrt(2 n) < 0.5 %), the mean
    # within 0.05
    tol = noise_scale(sel, "tolerance")
    np.testing.assert_array_equal(tol, pr.tolerance_cells)
    z = np.stack([(replica_readings(pr, hyp, tol, 7, 0, r, "tolerance") - hyp.readings) / tol for r in range(300)])
    assert np.std(z[:, m]) == pytest.approx(1.0, abs=0.03)
    assert abs(np.mean(z[:, m])) < 0.05
    # residual: each cell moves by exactly its own scaled residual, with a random sign (about half each way)
    sc = noise_scale(sel, "residual")
    M = int(m.sum())
    resid = pr.Y - hyp.readings
    np.testing.assert_allclose(sc[m], resid[m] * np.sqrt(M / (M - sel.fit.k)), rtol=1e-9, atol=1e-12)
    signs = np.stack([(replica_readings(pr, hyp, sc, 7, 0, r) - hyp.readings)[m] / sc[m] for r in range(300)])
    np.testing.assert_allclose(np.abs(signs), 1.0, rtol=1e-9)
    assert abs(np.mean(signs)) < 0.05  # standard error 1/sqrt(300 M) < 0.01
    a = replica_readings(pr, hyp, sc, 7, 0, 3)
    assert np.all(np.isnan(a[~m]))
    np.testing.assert_array_equal(a, replica_readings(pr, hyp, sc, 7, 0, 3))  # same seed, same numbers
    assert not np.allclose(a, replica_readings(pr, hyp, sc, 7, 1, 3))  # another hypothesis, other signs
    with pytest.raises(ValueError, match="--noise"):
        noise_scale(sel, "white")
    with pytest.raises(ValueError, match="--noise"):
        replica_readings(pr, hyp, sc, 7, 0, 3, "white")


def test_a_replica_keeps_the_design_and_only_changes_the_readings(waste_gate_selection):
    _, sel = waste_gate_selection
    pr = sel.problem
    hyp = hypotheses(sel, [])[0]
    Y = replica_readings(pr, hyp, noise_scale(sel, "tolerance"), 0, 0, 0, "tolerance")
    rep = pr.ds.with_readings({c: Y[:, j] for j, c in enumerate(pr.channels)})
    q = FitProblem(rep, params=pr.params, target=pr.target, tolerances=dict(zip(pr.channels, pr.tolerance)))
    np.testing.assert_array_equal(q.Y, Y)
    np.testing.assert_array_equal(q.target_si, pr.target_si)
    np.testing.assert_array_equal(q.tolerance_cells, pr.tolerance_cells)
    for c in pr.channels:  # SI values follow the new readings
        np.testing.assert_allclose(rep.from_si(c, rep.values[rep.column_quantity[c]]), rep.raw[c], rtol=1e-12)
    with pytest.raises(ValueError, match="not a reading"):
        pr.ds.with_readings({"no_such_column": Y[:, 0]})
    with pytest.raises(ValueError, match="values for"):
        pr.ds.with_readings({pr.channels[0]: Y[:3, 0]})


@pytest.mark.study  # a few pipeline runs per hypothesis; fast: the replica tests around it and validate --replicas
def test_replicas_of_each_hypothesis_name_it(waste_gate_selection):
    """At the data's design, a waste gate and a flow law are told apart: each hypothesis, taken as the truth with
    noise at the tolerance, is named again (2 replicas each, a few seconds per run); the summary counts it."""
    _, sel = waste_gate_selection
    rep = replicate(sel, replicas=2, noise="tolerance", seed=1, mechanisms=_LIB, progress=False)
    s = {x["hypothesis"]: x for x in rep["summary"]}
    assert s["named"]["named_itself"] == 2 and s["named"]["named_data_causes"] == 2
    assert s["named"]["valve_support"]["waste_gate"]["same_points"] == 2
    assert s["alternative: turbine_flow_law"]["named_itself"] == 2
    assert s["alternative: turbine_flow_law"]["named_data_causes"] == 0
    assert "| named (waste_gate)" in markdown_table(rep)
    # a replica run directly gives the same answer as inside replicate (the seeding is per replica)
    pr = sel.problem
    Y = replica_readings(pr, hypotheses(sel, [])[0], noise_scale(sel, "tolerance"), 1, 0, 0, "tolerance")
    one = run_replica(
        pr.ds,
        pr.params,
        pr.target,
        dict(zip(pr.channels, pr.tolerance)),
        pr.channels,
        Y,
        SelectionRules(pairs=False, max_causes=1, held_out_valves=pr.held_out_valves),
        _LIB,
    )
    assert one["named"] == rep["runs"]["named"][0]["named"]
    assert one["acts"] == rep["runs"]["named"][0]["acts"]


def test_every_replica_follows_the_rules_the_data_were_selected_with(waste_gate_selection, monkeypatch):
    """A replica asks whether *this* pipeline would name the same causes again, so each runs with the data's
    selection rules: the valve rules (``beside_valve``, ``held_out_valves``) and the exchange step too, not the
    defaults (else ``marine-fdi validate --beside-valve ... --replicas N`` would judge the replicas by another rule
    than the data).  No cause may be named here, so each run is a base fit."""
    import marine_fdi_env.validation.select.replicas as replicas

    _, sel0 = waste_gate_selection
    pr = sel0.problem
    q = FitProblem(pr.ds, params=pr.params, target=pr.target, held_out_valves="support")
    sel = select_causes(q, _LIB, pairs=False, max_causes=0, exchange=False, beside_valve="cross_validated")
    seen = []
    real = replicas.select_causes

    def recording(problem, mechanisms=None, **kw):
        seen.append((problem.held_out_valves, kw))
        return real(problem, mechanisms, **kw)

    monkeypatch.setattr(replicas, "select_causes", recording)
    rep = replicate(sel, replicas=2, noise="tolerance", mechanisms=_LIB, progress=False)
    assert len(seen) == 2
    for hov, kw in seen:
        assert hov == "support"
        r = kw["rules"]
        assert r.beside_valve == "cross_validated" and r.exchange is False
        assert r.max_causes == 0 and r.pairs is False and r.held_out_valves == "support"
    assert rep["settings"]["selection"]["beside_valve"] == "cross_validated"
    assert rep["settings"]["selection"]["held_out_valves"] == "support"


def test_a_candidate_pinned_at_a_bound_does_not_screen_the_others_out():
    """Found with the replicas of the Birka protocol (tests/data/protocol_replica_flow_law.json: the data as the
    fitted flow law would give them): the cylinder-outlet calibration fits best in the first step but wants a gain
    below its plausible range, so it is not eligible.  Its cross-validated score would screen every other
    candidate out (their in-sample scores are already worse than it), and nothing would be named; only an eligible
    candidate may screen others out, and the true mechanism is named (the waste gate fits about as well, with
    more parameters)."""
    import json

    from marine_fdi_env.validation import load_shipped
    from marine_fdi_env.validation.fit.mechanisms import SensorCalibration, sensor_reference

    rec = json.loads((TEST_DATA / "protocol_replica_flow_law.json").read_text())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        ds = load_shipped("birka_me1_test_protocol")
    pr = FitProblem(ds)
    assert list(pr.channels) == rec["channels"]
    rep = ds.with_readings(rec["readings"])
    q = FitProblem(rep, params=pr.params, target=pr.target, tolerances=dict(zip(pr.channels, pr.tolerance)))
    ch = "cylinder_exhaust_temperature_mean_C"
    lib = [m for m in PHYSICAL_MECHANISMS if m.id in ("waste_gate", "turbine_flow_law", "turbocharger_map")]
    lib.append(SensorCalibration(channel=ch, reference=sensor_reference(ch, q.Y[:, q.channels.index(ch)])))
    sel = select_causes(q, lib, pairs=False)
    first = {c.added: c for c in sel.steps[0]["candidates"]}
    assert first[f"sensor_calibration[{ch}]"].screened.startswith("not eligible")
    assert first["turbine_flow_law"].cross_validated  # not screened out by the ineligible calibration
    assert sel.selected_labels[0] == "turbine_flow_law", sel.selected_labels


def test_replicas_command_line_bad_input(capsys):
    from marine_fdi_env.cli.replicas import replicas_main as main

    assert main(["--data", "no_such_dataset"]) == 2
    assert "no such file" in capsys.readouterr().err
    assert main(["--data", "birka_me1_test_protocol", "--replicas", "0"]) == 2
    assert "--replicas" in capsys.readouterr().err
    assert main(["--data", "birka_me1_test_protocol", "--top", "-1"]) == 2
    assert "--top" in capsys.readouterr().err
    assert main(["--data", "birka_me1_test_protocol", "--alternatives", "waste_gate,warp_drive"]) == 2
    assert "warp_drive" in capsys.readouterr().err
    assert main(["--data", "birka_me1_test_protocol", "--tolerance", "boost_bar=0.1"]) == 2
    assert "not a compared channel" in capsys.readouterr().err


def test_validate_replicas_option_writes_them_to_the_report(waste_gate_selection, tmp_path, capsys):
    """``marine-fdi validate --replicas N``: the replicas' summary in the JSON report, a table in the Markdown and a
    line per hypothesis on stdout (here with no cause allowed, so one hypothesis, the calibrated base: seconds)."""
    import json

    from marine_fdi_env.cli.validate import validate_main

    syn, _ = waste_gate_selection
    path = tmp_path / "wg.csv"
    syn.write(path)
    out, md = tmp_path / "r.json", tmp_path / "r.md"
    assert (
        validate_main(
            [
                "--data",
                str(path),
                "--out",
                str(out),
                "--markdown",
                str(md),
                "--max-causes",
                "0",
                "--replicas",
                "2",
                "--quiet",
            ]
        )
        == 0
    )
    rep = json.loads(out.read_text())
    s = rep["replicas"]["summary"]
    assert [h["hypothesis"] for h in s] == ["named"] and s[0]["replicas"] == 2
    assert s[0]["named_data_causes"] == 2  # nothing may be named, and nothing is
    assert "Would data like these name the same causes again?" in md.read_text()
    assert "replicas drawn from named (nothing): named itself 2/2" in capsys.readouterr().out
    assert validate_main(["--data", str(path), "--out", str(out), "--replicas", "-1", "--quiet"]) == 2
