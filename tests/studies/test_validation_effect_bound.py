"""The oracle bound on telling an out-of-library effect from a sensor calibration
(studies/validation/effect_bound.py)."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy import stats

from studies.validation import effect_bound as eb
from studies.validation.study import effect_size, trial_data, trial_draw
from tests.paths import ROOT

DOCS = ROOT / "docs" / "figures" / "validation"


def test_an_affine_effect_leaves_nothing_and_an_orthogonal_one_all():
    x = np.linspace(300.0, 600.0, 8)
    assert eb.separation(0.03 * x + 4.0, x, 2.0) < 1e-9 * np.linalg.norm(0.03 * x + 4.0)
    # orthogonal to [1, x]: a centred quadratic made orthogonal to the line
    q = (x - x.mean()) ** 2
    A = np.column_stack([np.ones_like(x), x])
    e = q - A @ np.linalg.lstsq(A, q, rcond=None)[0]
    assert eb.separation(e, x, 2.0) == pytest.approx(np.linalg.norm(e) / 2.0, rel=1e-12)


def test_with_equal_noise_it_is_the_studys_beyond_calibration_size_in_noise_units():
    rng = np.random.default_rng(3)
    x, e = rng.uniform(100, 200, 8), rng.normal(0, 5, 8)
    tol, sd = 5.0, 2.5
    assert eb.separation(e, x, sd) == pytest.approx(effect_size(e, x, tol)["beyond_calibration"] * tol / sd, rel=1e-12)


def test_the_stated_rate_is_what_the_likelihood_ratio_test_achieves():
    """Monte Carlo of the oracle's test on data = gain * reading + offset + effect + noise (heteroscedastic): its
    rejection rate at alpha under H1, and its level under H0, match Φ(z - z_(1-α)) within 4 binomial sigmas."""
    rng = np.random.default_rng(11)
    x = np.linspace(2.0, 4.0, 8)
    sd = 0.02 * x
    e = 0.06 * np.exp(-0.5 * ((x - 3.2) / 0.3) ** 2)
    z = eb.separation(e, x, sd)
    alpha, n = 0.05, 20000
    A = np.column_stack([np.ones_like(x), x]) / sd[:, None]
    P = np.eye(8) - A @ np.linalg.pinv(A)
    u = P @ (e / sd)
    u /= np.linalg.norm(u)
    crit = stats.norm.isf(alpha)
    for effect, expected in ((e, eb.oracle_rate(z, alpha)), (0.0 * e, alpha)):
        y = 1.03 * x + 0.05 + effect + rng.normal(0.0, 1.0, (n, 8)) * sd
        stat = (y / sd) @ u  # the whitened residual's component along the effect's direction: N(z, 1) / N(0, 1)
        rate = float(np.mean(stat > crit))
        assert abs(rate - expected) < 4 * np.sqrt(expected * (1 - expected) / n)
    assert 0.05 < eb.oracle_rate(z, alpha) < 0.999  # the case is informative


def test_the_amplitude_factor_reaches_the_target():
    z = [1.0, 2.5, 4.0, 0.7]
    k = eb.scale_for(z, 0.05, 0.9)
    assert np.mean(eb.oracle_rate(k * np.asarray(z), 0.05)) == pytest.approx(0.9, abs=1e-5)
    assert eb.scale_for(z, 0.05 / 11, 0.9) > k  # a stricter level needs larger effects


def test_bad_inputs_are_refused():
    with pytest.raises(ValueError, match="same length"):
        eb.separation([1.0, 2.0], [1.0, 2.0, 3.0], 1.0)
    with pytest.raises(ValueError, match="positive"):
        eb.separation([1.0, 2.0, 3.0], [1.0, 2.0, 3.0], [1.0, 0.0, 1.0])
    with pytest.raises(ValueError, match="alpha"):
        eb.oracle_rate(1.0, 0.0)
    with pytest.raises(ValueError, match="no \\(e\\) trial"):
        eb.bound([{"condition": "a", "control": False, "seed": 0, "outcome": "identified"}])


def test_a_trial_is_redrawn_from_its_seed_and_a_foreign_file_is_refused():
    mechs, effects, _ = trial_draw("e", 5)
    syn = trial_data("e", 5)
    assert syn.effects == effects and not mechs
    rec = {
        "condition": "e",
        "control": False,
        "seed": 5,
        "effects": effects,
        "unexplained_right_channel": True,
        "trial_settings": {"params": "wartsila-6l46", "points": 8},
    }
    t = eb.trial_bound(rec)
    assert t["channel"] == effects[0]["channel"] and t["z"] > 0 and t["n_channels"] == 11
    assert t["one channel, 5 %"] > t["family-wise 5 % over the channels"]
    assert t["tolerance"] > 0 and t["scan: one channel, 5 %"] <= t["one channel, 5 %"] + 0.05
    bad = dict(rec, effects=[dict(effects[0], amplitude=2 * effects[0]["amplitude"])])
    with pytest.raises(ValueError, match="another version"):
        eb.trial_bound(bad)


def test_the_recorded_study_files_are_redrawn_exactly(tmp_path):
    """The study files in docs/ must stay re-drawable by the current code (the bound is computed from them)."""
    f = DOCS / "open_world_study_seeds_120_140.json"
    trials = json.loads(f.read_text())["trials"]
    e = [r for r in trials if r["condition"] == "e" and not r["control"]][:3]
    b = eb.bound(e)
    assert b["summary"]["n_trials"] == 3
    out = tmp_path / "b.json"
    png = tmp_path / "b.png"
    assert eb.main(["--study", str(f), "--out", str(out), "--plot", str(png)]) == 0
    assert png.stat().st_size > 10_000 and png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    s = json.loads(out.read_text())[str(f)]["summary"]
    assert s["n_trials"] == 20 and 0.0 <= s["family-wise 5 % over the channels"]["oracle_rate"] <= 1.0


def test_the_command_names_a_file_that_is_not_a_study(tmp_path, capsys):
    p = tmp_path / "x.json"
    p.write_text("[1, 2]")
    assert eb.main(["--study", str(p)]) == 2
    assert "not a study file" in capsys.readouterr().err


def test_the_family_scan_holds_its_level_and_knowing_less_costs_power():
    """Under H0 (no effect beyond a gain and offset) the scan reports at its level; on an effect it reports less
    often than the oracle that knows the shape, and less again with the noise floored at a larger tolerance."""
    x = np.linspace(0.25, 1.1, 8)
    reading = 2.0 + 1.5 * x
    sd = np.full(8, 0.02)
    rng = np.random.default_rng(4)
    alpha = 0.05
    null_rate = eb.family_scan_rate(np.zeros(8), reading, sd, x, alpha, rng)
    n = eb.SCAN_ALT_DRAWS
    assert abs(null_rate - alpha) < 4 * np.sqrt(alpha * (1 - alpha) / n) + 1.0 / np.sqrt(eb.SCAN_NULL_DRAWS)
    e = 0.05 * np.exp(-0.5 * ((x - 0.62) / 0.1) ** 2)
    oracle = eb.oracle_rate(eb.separation(e, reading, sd), alpha)
    scan = eb.family_scan_rate(e, reading, sd, x, alpha, rng)
    floored = eb.family_scan_rate(e, reading, np.maximum(sd, 0.03), x, alpha, rng)
    assert 0.2 < floored < scan < oracle < 1.0


def test_pooled_rows_by_size_split_the_pooled_trials(tmp_path):
    """With several files the command also pools by the study's size bins: each effect in the bin of its own
    recorded size, the bins together the pooled trials, each bin's pipeline rate its trials' hits."""
    from studies.validation.study_pool import size_bin

    files = []
    for name in ("open_world_study_seeds_120_140.json", "open_world_study_seeds_140_160.json"):
        trials = json.loads((DOCS / name).read_text())["trials"]
        e = [r for r in trials if r["condition"] == "e" and not r["control"]][:4]
        files.append(tmp_path / name)
        files[-1].write_text(json.dumps({"trials": e}))
    out = tmp_path / "b.json"
    assert eb.main(["--study", *map(str, files), "--out", str(out)]) == 0
    res = json.loads(out.read_text())
    every = [t for f in files for t in res[str(f)]["trials"]]
    assert all(t["size_bin"] == size_bin(t["beyond_calibration"]) for t in every)
    by_size = res["pooled_by_size"]
    assert sum(v["n_trials"] for v in by_size.values()) == res["pooled"]["summary"]["n_trials"] == 8
    for lab, v in by_size.items():
        mine = [t for t in every if t["size_bin"] == lab]
        assert v["n_trials"] == len(mine) > 0
        assert v["pipeline_rate"] == pytest.approx(sum(t["pipeline_hit"] for t in mine) / len(mine))
