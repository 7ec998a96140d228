"""Pooling study files: counts add up to the study's own summaries, a trial is never counted twice, and the
verdicts follow the exact binomial interval (the numbers docs/validation.md quotes as pooled)."""

from __future__ import annotations

import json
import sys

import pytest

from studies.validation.study_pool import load_trials, pool, pool_main, pool_markdown
from tests.paths import ROOT

FIG = ROOT / "docs" / "figures" / "validation"


def _trial(c, seed, hit, control=False, named=False):
    t = {"condition": c, "seed": seed, "control": control, "outcome": "control" if control else "x", "named_any": named}
    t["unexplained_right_channel" if c == "e" else "exact"] = hit
    return t


def _write(tmp_path, name, trials):
    p = tmp_path / name
    p.write_text(json.dumps({"trials": trials}))
    return p


def test_pool_matches_each_files_own_summary():
    files = sorted(FIG.glob("open_world_study_seeds_*_*.json"))
    assert len(files) >= 8
    res = pool(load_trials(files))
    for i, f in enumerate(files):
        summ = json.loads(f.read_text())["conditions"]
        for c, s in summ.items():
            k, n = res["conditions"][c]["per_file"][i]
            assert n == s["n_trials"]
            rate = s["unexplained_right_channel_rate"] if c == "e" else s["identification_rate"]
            assert k == round(rate * n)
            kc, nc = res["conditions"][c]["controls_per_file"][i]
            assert (nc, kc) == (s["n_controls"], round(s["control_named_rate"] * nc))
            kl, nl = res["conditions"][c]["controls_local_per_file"][i]
            assert (nl, kl) == (s["n_controls"], round(s["control_unexplained_local_rate"] * nl))


def test_verdicts_follow_the_exact_interval(tmp_path):
    # 20/20 at a 95 % bar: met, but 20 trials cannot confirm it (Clopper-Pearson lower bound 0.025^(1/20) = 83.2 %)
    a = _write(
        tmp_path,
        "a.json",
        [_trial("a", s, True) for s in range(20)] + [_trial("a", s, False, control=True) for s in range(20)],
    )
    v = pool(load_trials([a]))["conditions"]["a"]
    assert v["pooled"]["met"] and v["pooled"]["interval_says"] == "undecided"
    assert v["pooled"]["ci95"][0] == pytest.approx(0.025 ** (1 / 20), rel=1e-9)
    # 0/20 controls: at most 5 % is met, and the upper bound 1 - 0.025^(1/20) = 16.8 % leaves it undecided
    assert v["controls_pooled"]["met"] and v["controls_pooled"]["interval_says"] == "undecided"
    assert v["controls_pooled"]["ci95"][1] == pytest.approx(1 - 0.025 ** (1 / 20), rel=1e-9)
    # 64/100 against 90 %: refuted; 99/100 against 80 %: confirmed
    e = _write(tmp_path, "e.json", [_trial("e", s, s < 64) for s in range(100)])
    d = _write(tmp_path, "d.json", [_trial("d", s, s < 99) for s in range(100)])
    res = pool(load_trials([e, d]))["conditions"]
    assert not res["e"]["pooled"]["met"] and res["e"]["pooled"]["interval_says"] == "refuted"
    assert res["d"]["pooled"]["met"] and res["d"]["pooled"]["interval_says"] == "confirmed"
    assert res["e"]["per_file"] == [[64, 100], [0, 0]] and res["d"]["per_file"] == [[0, 0], [99, 100]]


def test_a_trial_counted_twice_or_a_bad_file_is_refused(tmp_path, capsys):
    a = _write(tmp_path, "a.json", [_trial("c", 5, True)])
    b = _write(tmp_path, "b.json", [_trial("c", 5, False), _trial("c", 6, True)])
    with pytest.raises(ValueError, match="counted twice"):
        load_trials([a, b])
    (tmp_path / "empty.json").write_text("{}")
    for argv, msg in (
        ([str(a), str(b)], "counted twice"),
        ([str(tmp_path / "nope.json")], "not a readable"),
        ([str(tmp_path / "empty.json")], "no trials"),
    ):
        assert pool_main(argv) == 2
        assert msg in capsys.readouterr().err
    out = tmp_path / "pool.json"
    assert pool_main([str(a), "--markdown", str(tmp_path / "pool.md"), "--out", str(out)]) == 0
    assert "| (c) right cause (exact set) | 1/1 |" in (tmp_path / "pool.md").read_text()
    assert json.loads(out.read_text())["conditions"]["c"]["pooled"]["k"] == 1


def test_local_findings_of_the_controls_are_held_to_the_level_only_where_they_are_false_alarms(tmp_path):
    """In (a) and (c) the controls are the model plus noise: a local finding is a false alarm, and 4 of 20 against
    the reporting level of 5 % is "not met"; in (b) the engine is off the model, so the row carries no verdict."""
    trials = []
    for c in ("a", "b", "c"):
        for s in range(20):
            t = _trial(c, s, False, control=True)
            t["unexplained_local"] = s < 4
            trials.append(t)
    res = pool(load_trials([_write(tmp_path, "x.json", trials)]))["conditions"]
    for c in ("a", "b", "c"):
        v = res[c]["controls_local_pooled"]
        assert (v["k"], v["n"], v["met"]) == (4, 20, False)
        assert v["held"] is (c != "b")
    md = pool_markdown(pool(load_trials([_write(tmp_path, "y.json", trials)])))
    assert "| (a) controls with a local finding | 4/20 | 4/20 = 20.0 % [5.7, 43.7] | ≤ 5 % (level) | **no** |" in md
    assert "| (b) controls with a local finding | 4/20 | 4/20 = 20.0 % [5.7, 43.7] | – | – | – |" in md


def test_the_forest_plot_is_drawn_and_a_missing_matplotlib_is_one_line_before_any_work(tmp_path, capsys, monkeypatch):
    pytest.importorskip("matplotlib")
    trials = [_trial(c, s, s % 7 != 0) for c in "abcde" for s in range(20)]
    trials += [_trial(c, s, False, control=True, named=s == 3) for c in "abcde" for s in range(20)]
    a = _write(tmp_path, "a.json", trials)
    png = tmp_path / "fig" / "pool.png"
    assert pool_main([str(a), "--plot", str(png)]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 20_000
    monkeypatch.setitem(sys.modules, "matplotlib", None)  # import matplotlib now raises ImportError
    md = tmp_path / "pool.md"
    assert pool_main([str(a), "--markdown", str(md), "--plot", str(tmp_path / "again.png")]) == 2
    err = capsys.readouterr().err
    assert "marine-fdi-env[plots]" in err and not md.exists() and not (tmp_path / "again.png").exists()


def test_the_study_command_and_its_pool_run_from_the_studies_folder():
    """``python -m studies.validation.study [pool]`` from the repository's root."""
    import subprocess

    def run(*a):
        return subprocess.run([sys.executable, "-m", *a], capture_output=True, text=True, cwd=ROOT)

    new = run("studies.validation.study", "--help")
    assert new.returncode == 0 and "--conditions" in new.stdout
    pooled = run("studies.validation.study", "pool", "--help")
    assert pooled.returncode == 0 and "study pool" in pooled.stdout


def test_e_by_size_adds_up_to_each_files_own_size_summary():
    """The pooled (e) rate per effect size counts the same trials as each study file's own binned summary, and the
    bins together are the (e) row."""
    files = sorted(FIG.glob("open_world_study_seeds_*_*.json"))
    res = pool(load_trials(files))["conditions"]["e"]
    sizes = res["by_size"]
    assert list(sizes) == ["0-3", "3-5", ">=5"]
    for i, f in enumerate(files):
        own = json.loads(f.read_text())["conditions"]["e"]["unexplained_by_size_beyond_calibration"]
        assert {lab: "{}/{}".format(*r["per_file"][i]) for lab, r in sizes.items()} == own
    for j in (0, 1):
        assert sum(r["pooled"][("k", "n")[j]] for r in sizes.values()) == res["pooled"][("k", "n")[j]]


def test_size_bins_are_half_open_and_refuse_a_negative_size():
    from studies.validation.study_pool import size_bin

    assert [size_bin(x) for x in (0.0, 2.999, 3.0, 4.999, 5.0, 1e9)] == ["0-3", "0-3", "3-5", "3-5", ">=5", ">=5"]
    with pytest.raises(ValueError):
        size_bin(-0.1)
    with pytest.raises(ValueError):
        size_bin(float("nan"))


def test_e_by_size_leaves_out_trials_without_a_size(tmp_path):
    trials = [dict(_trial("e", s, s % 2 == 0), effect_size={"beyond_calibration": float(s)}) for s in range(8)]
    trials.append(_trial("e", 8, True))  # written before sizes were recorded
    res = pool(load_trials([_write(tmp_path, "e.json", trials)]))["conditions"]["e"]
    assert res["pooled"]["n"] == 9
    assert {lab: r["per_file"][0] for lab, r in res["by_size"].items()} == {"0-3": [2, 3], "3-5": [1, 2], ">=5": [1, 3]}
    md = pool_markdown(pool(load_trials([_write(tmp_path, "e2.json", trials)])))
    assert "| (e) unexplained on the right channel, >=5 tolerances beyond a calibration | 1/3 |" in md
