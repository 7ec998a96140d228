"""Entries anyone can verify (marine-fdi submit / verify): what each check catches, and what it refuses.

One entry of the reference and one of a file agent on thesis-v1 (20 episodes) are made once; each test
tampers with a copy.  The threat model under test: the hashes catch corruption and name the provenance,
recomputation catches an edited metric, only --rerun catches an edited trace; wall-clock fields are
never compared; an entry stays valid for the suite version it names."""

from __future__ import annotations

import gzip
import hashlib
import json
import shutil
from pathlib import Path

import pytest

from marine_fdi_env.benchmark import suites as suites_mod
from marine_fdi_env.benchmark.entries import (
    ENTRY_FILE,
    read_entry,
    read_trace,
    record_differences,
    rerun_entries,
    suite_block,
    verify_entry,
)
from marine_fdi_env.benchmark.suites import load_suite
from marine_fdi_env.cli import main as cli_main
from tests.paths import ROOT

FILE_AGENT = ROOT / "docs" / "examples" / "fired_modules_agent.py"


def run(capsys, *argv) -> tuple[int, str, str]:
    code = cli_main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    """(reference entry, file-agent entry), each scored on thesis-v1."""
    d = tmp_path_factory.mktemp("entries")
    ref, mine = d / "reference", d / "fired"
    assert cli_main(["submit", "reference", "--suites", "thesis-v1", "--out", str(ref), "--no-progress"]) == 0
    assert (
        cli_main(
            [
                "submit",
                f"{FILE_AGENT}:FiredModulesAgent",
                "--suites",
                "thesis-v1",
                "--out",
                str(mine),
                "--training-data",
                "none: a rule",
                "--no-progress",
            ]
        )
        == 0
    )
    return ref, mine


@pytest.fixture
def entry(made, tmp_path):
    """A copy of the reference's entry to tamper with."""
    return Path(shutil.copytree(made[0], tmp_path / "entry"))


def _edit_entry(d: Path, fn) -> None:
    e = json.loads((d / ENTRY_FILE).read_text())
    fn(e)
    (d / ENTRY_FILE).write_text(json.dumps(e, indent=1))


def test_an_entry_names_its_provenance_and_verifies(made, capsys):
    ref, mine = made
    e = read_entry(ref)
    block = e["suites"][0]
    assert e["agent"] == {
        "kind": "baseline",
        "family": "baseline",
        "name": "reference",
        "code": "marine_fdi_env.baselines.reference_agent:ReferenceAgent",
        "needs": [],
    }
    assert (block["name"], block["version"], block["n_episodes"]) == ("thesis-v1", 1, 20)
    assert {"numpy", "scipy", "numba", "gymnasium", "marine-fdi-env", "python"} <= set(e["software"])
    assert set(block["intervals"]) >= {"isolation_accuracy", "dx_true_detection_rate", "dx_fault_isolation_accuracy"}
    assert set(block["dx_metrics"]) >= {"true_detection_rate", "false_alarm_rate", "fault_isolation_accuracy"}
    records, sha = read_trace(ref, block)
    assert sha == block["trace_sha256"] and all("declared_changes" in r for r in records)
    # a file agent's entry keeps a copy of its file, by hash, and what its submitter declared
    f = read_entry(mine)
    assert f["agent"]["kind"] == "file" and f["declared"] == {"training_data": "none: a rule"}
    assert (mine / "agent" / FILE_AGENT.name).read_bytes() == FILE_AGENT.read_bytes()
    assert f["agent"]["files"][FILE_AGENT.name] == hashlib.sha256(FILE_AGENT.read_bytes()).hexdigest()
    code, out, err = run(capsys, "verify", ref, mine)
    assert code == 0 and err == "" and out.count("verified ") == 2, out


@pytest.mark.parametrize(
    "where",
    [
        ("metrics", "isolation_accuracy"),
        ("metrics", "by_class", "mixed", "detection_rate"),
        ("dx_metrics", "true_detection_rate"),
        ("intervals", "isolation_accuracy", "high"),
    ],
)
def test_one_digit_of_a_metric_changed_is_refused(entry, where, capsys):
    def edit(e):
        d = e["suites"][0]
        for k in where[:-1]:
            d = d[k]
        v = d[where[-1]]
        text = repr(float(v))
        i = next(j for j, ch in enumerate(text) if ch.isdigit() and j > 1)  # a digit after "0."
        d[where[-1]] = float(text[:i] + str((int(text[i]) + 1) % 10) + text[i + 1 :])
        assert d[where[-1]] != v

    _edit_entry(entry, edit)
    code, out, err = run(capsys, "verify", entry)
    path = ".".join(where)
    assert code == 2 and f"suite thesis-v1: {path}: the entry says" in err, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err


def _rewrite_trace(d: Path, fn) -> None:
    """Alter the trace and rewrite its entry block from it, as someone forging a trace would: hashes and
    metrics then agree with the forged trace."""
    e = read_entry(d)
    block = e["suites"][0]
    records, _ = read_trace(d, block)
    fn(records)
    data = json.dumps(records, sort_keys=True, separators=(",", ":")).encode()
    (d / block["trace"]).write_bytes(gzip.compress(data, mtime=0))
    sha = hashlib.sha256(data).hexdigest()
    e["suites"][0] = suite_block(load_suite("thesis-v1"), records, block["trace"], sha, block["env_id"], block["env"])
    (d / ENTRY_FILE).write_text(json.dumps(e, indent=1))


def test_an_altered_trace_passes_recomputation_and_only_the_rerun_catches_it(entry, capsys):
    def forge(records):
        r = next(r for r in records if r["scenario_id"] == "thesis-6.4.1/seed3")
        assert r["declared_changes"][-1][1] != ["S1.1"]
        r["declared_changes"][-1][1] = ["S1.1"]

    _rewrite_trace(entry, forge)
    code, out, _ = run(capsys, "verify", entry)
    assert code == 0 and "verified" in out  # consistent: recomputation cannot tell
    code, out, err = run(capsys, "verify", "--rerun", "--no-progress", entry)
    assert code == 2
    assert "episode thesis-6.4.1/seed3: declared_changes: trace" in err and '["S1.1"]' in err, err


def test_the_truth_in_a_trace_is_the_suites(entry, capsys):
    """A forged trace cannot move the ground truth: faults, seeds and profiles are the suite's."""

    def move(records):
        records[0]["faults"][0]["onset_s"] += 1.0

    _rewrite_trace(entry, move)
    code, _, err = run(capsys, "verify", entry)
    assert code == 2 and "faults in the trace is not the suite's ground truth" in err, err


def test_a_corrupt_or_swapped_trace_is_refused_by_its_hash(entry, capsys):
    block = read_entry(entry)["suites"][0]
    records, _ = read_trace(entry, block)
    records[0]["return"] += 1.0
    (entry / block["trace"]).write_bytes(gzip.compress(json.dumps(records).encode(), mtime=0))
    code, _, err = run(capsys, "verify", entry)
    assert code == 2 and "does not have the entry's sha256" in err, err
    (entry / block["trace"]).write_bytes(b"not gzip")
    code, _, err = run(capsys, "verify", entry)
    assert code == 2 and "not a readable gzip'd JSON trace" in err, err


def test_a_changed_suite_is_refused_and_a_new_version_leaves_the_entry_valid(entry, capsys, monkeypatch):
    real = suites_mod.load_suite
    v1 = real("thesis-v1")
    v2 = suites_mod.Suite(dict(v1, name="thesis-v2", version=2))
    v2["scenarios"] = [s.__class__.from_dict(dict(s.to_dict(), noise_seed=s.noise_seed + 1)) for s in v1.scenarios]
    monkeypatch.setattr(suites_mod, "SUITE_NAMES", suites_mod.SUITE_NAMES + ("thesis-v2",))
    monkeypatch.setattr(suites_mod, "load_suite", lambda n: v2 if n == "thesis-v2" else real(n))
    code, out, _ = run(capsys, "verify", entry)
    assert code == 0 and "verified" in out  # a new version beside it: the entry stays valid for thesis-v1
    changed = suites_mod.Suite(dict(v1))
    changed["scenarios"] = v2["scenarios"]  # the same name and version, other content
    monkeypatch.setattr(suites_mod, "load_suite", lambda n: changed if n == "thesis-v1" else real(n))
    code, _, err = run(capsys, "verify", entry)
    assert code == 2 and "suite thesis-v1: its content sha256 is" in err and "the suite file changed" in err, err


def test_an_agent_file_that_is_not_the_one_scored_is_refused(made, tmp_path, capsys):
    mine = Path(shutil.copytree(made[1], tmp_path / "fired"))
    f = mine / "agent" / FILE_AGENT.name
    f.write_text(f.read_text().replace("min_modules: int = 2", "min_modules: int = 3"))
    code, _, err = run(capsys, "verify", mine)
    assert code == 2 and f"{FILE_AGENT.name} in" in err and "is not the file scored" in err, err


def test_a_rerun_reproduces_an_entry_wall_clock_aside(made):
    """Both entries replayed together on one simulation: every record and metric but the wall clock."""
    checks = rerun_entries(list(made), progress=False, log=None)
    assert all(c.ok for c in checks), [c.problems for c in checks]
    assert all(any("rerun reproduces" in x for x in c.checked) for c in checks)


def test_wall_clock_fields_are_outside_the_identity_checks(entry):
    records, _ = read_trace(entry, read_entry(entry)["suites"][0])
    slower = [dict(r, compute_s=r["compute_s"] + 1.0, agent_compute_s=r["agent_compute_s"] + 1.0) for r in records]
    assert record_differences(records, slower, "thesis-v1") == []
    other = [dict(r, **{"return": r["return"] + 1e-9}) for r in records]
    first = record_differences(records, other, "thesis-v1")[0]
    assert first.startswith("suite thesis-v1: episode thesis-6.4.1/seed0: return")


def test_submit_says_what_is_wrong_in_one_line(made, tmp_path, capsys):
    code, _, err = run(capsys, "submit", "reference", "--suites", "thesis-v1", "--out", made[0])
    assert code == 2 and "already holds an entry; pass --force" in err
    code, _, err = run(capsys, "submit", "reference", "--suites", "thesis-v9", "--out", tmp_path / "x")
    assert code == 2 and "--suites: 'thesis-v9' is not a frozen suite" in err and "thesis-v1" in err
    code, _, err = run(capsys, "submit", "--suites", "thesis-v1", "--out", tmp_path / "x")
    assert code == 2 and "give one AGENT, or --shipped" in err
    code, _, err = run(capsys, "verify", tmp_path)
    assert code == 2 and "neither an entry folder" in err
    assert not (tmp_path / "x").exists()  # a refused command creates nothing
    assert verify_entry(tmp_path).problems[0].endswith("(not an entry folder written by marine-fdi submit)")


def test_ctrl_c_keeps_the_finished_suites_and_the_same_command_resumes(tmp_path, capsys, monkeypatch):
    """Interrupted in its second suite, submit keeps the first in OUT/.work; rerun, it scores only the rest."""
    from marine_fdi_env.benchmark import evaluate as ev

    real, calls = ev.evaluate_agents, []

    def interrupted_at_nominal(specs, suite, outs, **kw):
        calls.append(suite)
        if suite == "nominal-v1":
            raise KeyboardInterrupt
        return real(specs, suite, outs, **kw)

    monkeypatch.setattr(ev, "evaluate_agents", interrupted_at_nominal)
    out = tmp_path / "entry"
    argv = ["submit", "reference", "--suites", "thesis-v1", "nominal-v1", "--out", out, "--no-progress"]
    code, _, err = run(capsys, *argv)
    assert code == 130 and "interrupted; the finished suites are kept in OUT/.work" in err
    assert (out / ".work" / "thesis-v1.json").is_file() and not (out / ENTRY_FILE).exists()
    calls.clear()
    code, _, _ = run(capsys, *argv)
    assert code == 130 and calls == ["nominal-v1"]  # thesis-v1 is not scored again


def test_hashes_only_catches_corruption_not_an_edited_metric(entry, capsys):
    """``verify --hashes-only`` (the fast check of the leaderboard's entries) reads no record: a changed
    trace is refused by its sha256, an edited metric needs the recomputation."""
    _edit_entry(entry, lambda e: e["suites"][0]["metrics"].update(isolation_accuracy=1.0))
    code, out, _ = run(capsys, "verify", "--hashes-only", entry)
    assert code == 0 and "suite and trace sha256" in out
    code, _, err = run(capsys, "verify", entry)
    assert code == 2 and "metrics.isolation_accuracy: the entry says 1.0" in err, err
    block = read_entry(entry)["suites"][0]
    (entry / block["trace"]).write_bytes(gzip.compress(b"[]", mtime=0))
    code, _, err = run(capsys, "verify", "--hashes-only", entry)
    assert code == 2 and "does not have the entry's sha256" in err, err
    code, _, err = run(capsys, "verify", "--hashes-only", "--rerun", entry)
    assert code == 2 and "choose one" in err
