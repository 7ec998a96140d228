"""The leaderboard in the repository (leaderboard/): every shipped agent and training seed has an entry,
every entry verifies, the table is the one its entries give, and one entry of every agent kind
reproduces bit for bit when its suites are simulated again.

The default run checks in seconds: every entry's hashes (agent files, suites, traces), one entry of each
agent kind recomputed from its traces, and the table's fingerprints (the sha256 of the entries' files
and of the table's text).  Marked ``study`` (CI runs them with the studies' tests): every entry
recomputed (half a minute), the table built again from the traces (half a minute), and the reruns
(minutes of CPU)."""

from __future__ import annotations

import pytest

from marine_fdi_env.benchmark.entries import ENTRY_FILE, read_entry, rerun_entries, verify_entry
from marine_fdi_env.benchmark.leaderboard import fingerprint_problem
from marine_fdi_env.benchmark.suites import SUITE_NAMES
from marine_fdi_env.cli import main as cli_main
from marine_fdi_env.cli.submit import shipped_specs
from tests.paths import ROOT

LEADERBOARD = ROOT / "leaderboard"
ENTRIES = LEADERBOARD / "entries"
NAMES = sorted(d.name for d in ENTRIES.iterdir() if (d / ENTRY_FILE).is_file()) if ENTRIES.is_dir() else []
DIRS = [ENTRIES / n for n in NAMES]
ONE_OF_EACH_KIND = ("reference", "classifier-seed0", "ppo-seed0", "dec-classifier-decision-seed0")  # one per family


def test_every_shipped_agent_and_training_seed_has_an_entry():
    """``marine-fdi agents``' baselines and every seed folder of the shipped models, one entry each."""
    assert NAMES == sorted(n for n, _ in shipped_specs())
    assert {"reference-lipschitz", "classifier-seed2", "ppo-seed0", "classifier-v1+reference"} <= set(NAMES)
    kinds = {n: read_entry(ENTRIES / n)["agent"]["family"] for n in ONE_OF_EACH_KIND}
    assert kinds == {
        "reference": "baseline",
        "classifier-seed0": "classifier",
        "ppo-seed0": "ppo",
        "dec-classifier-decision-seed0": "dec-classifier",
    }


def test_submit_shipped_adds_only_the_missing_entries(capsys):
    """``submit --shipped`` into the full leaderboard scores nothing and says so in one line (exit 2)."""
    missing = sorted({n for n, _ in shipped_specs()} - set(NAMES))
    assert not missing, f"no entry (the command below would score them into the repository): {missing}"
    code = cli_main(["submit", "--shipped", "--out", str(ENTRIES), "--no-progress"])
    err = capsys.readouterr().err
    assert code == 2 and "every shipped agent has an entry; pass --force" in err


def test_every_entry_has_its_hashes():
    """The installed suites and models and every trace have the entries' sha256, every frozen suite scored."""
    for d in DIRS:
        v = verify_entry(d, recompute=False)
        assert v.ok, (d.name, v.problems)
        assert [b["name"] for b in read_entry(d)["suites"]] == list(SUITE_NAMES)


@pytest.mark.parametrize("name", ONE_OF_EACH_KIND)
def test_one_entry_of_each_kind_verifies_by_recomputation(name):
    """Every metric, DX metric and interval of the entry follows from its traces (a second each)."""
    v = verify_entry(ENTRIES / name)
    assert v.ok, v.problems
    assert sum("metrics recomputed" in x for x in v.checked) == len(SUITE_NAMES)


def test_the_table_is_the_one_its_entries_give(capsys):
    """A stale leaderboard/README.md fails: rerun ``marine-fdi leaderboard`` from the repository's root."""
    out = LEADERBOARD / "README.md"
    code = cli_main(["leaderboard", "--entries", str(ENTRIES), "--out", str(out), "--check", "--hashes-only"])
    _, err = capsys.readouterr()
    assert code == 0, err
    text = out.read_text(encoding="utf-8")
    assert fingerprint_problem(text, DIRS) is None
    # an entry left out (or added, or changed): stale; a number of the table edited by hand: refused
    assert fingerprint_problem(text, DIRS[1:]).startswith("the table is stale")
    edited = text.replace("| 1 | `oracle` |", "| 1 | `oracIe` |")
    assert edited != text and "edited by hand" in fingerprint_problem(edited, DIRS)


@pytest.mark.study
def test_every_entry_verifies_by_recomputation():
    """All of them (half a minute)."""
    for d in DIRS:
        v = verify_entry(d)
        assert v.ok, (d.name, v.problems)


@pytest.mark.study
def test_the_table_built_again_from_the_traces_is_the_committed_one(capsys):
    code = cli_main(["leaderboard", "--entries", str(ENTRIES), "--out", str(LEADERBOARD / "README.md"), "--check"])
    _, err = capsys.readouterr()
    assert code == 0, err


@pytest.mark.study
def test_one_entry_of_every_agent_kind_reproduces_when_rerun():
    """``reference``, ``classifier`` seed 0 and ``ppo`` seed 0, rerun together on one simulation of every
    suite: every record and metric as the entry holds them, wall-clock fields aside."""
    checks = rerun_entries([ENTRIES / n for n in ONE_OF_EACH_KIND], progress=False, log=None)
    for c in checks:
        assert c.ok, (c.entry, c.problems[:3])
        assert sum("rerun reproduces" in x for x in c.checked) == len(SUITE_NAMES)
