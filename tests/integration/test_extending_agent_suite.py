"""docs/extending.md, "Add a suite" and "Add an agent": the recipes' Python blocks run as written, in a fresh
folder (the agent's file block written as its file), and give what they say they print."""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from tests.paths import ROOT

DOC = ROOT / "docs" / "extending.md"


def section_blocks(title: str) -> list[str]:
    """The Python blocks of the section ``## title``, in order."""
    text = DOC.read_text(encoding="utf-8")
    start = text.index(f"## {title}\n")
    nxt = text.find("\n## ", start + 3)
    section = text[start : nxt if nxt >= 0 else len(text)]
    return re.findall(r"^```python\n(.*?)^```", section, flags=re.S | re.M)


def run_recipe(title: str, ns: dict) -> None:
    """Run the section's blocks; a block whose first line is ``# NAME.py`` is written to that file instead."""
    for block in section_blocks(title):
        first = block.splitlines()[0]
        if re.fullmatch(r"# \w+\.py", first):
            Path(first[2:]).write_text(block, encoding="utf-8")
        else:
            exec(compile(block, str(DOC), "exec"), ns)


@pytest.fixture
def suite_recipe(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    ns: dict = {"__name__": "recipe"}
    run_recipe("Add a suite", ns)
    return ns, capsys.readouterr().out


def test_the_suite_recipe_writes_a_suite_that_loads(suite_recipe, tmp_path):
    _, out = suite_recipe
    assert out.strip() == "2 scenarios"
    suite = json.loads((tmp_path / "my-bench-v1.json").read_text())
    assert suite["name"] == "my-bench-v1" and [s["scenario_id"] for s in suite["scenarios"]] == [
        "healthy",
        "charge-air-offset",
    ]


def test_the_agent_recipe_scores_its_agent_on_the_suite(suite_recipe, tmp_path, capsys):
    ns, _ = suite_recipe
    run_recipe("Add an agent", ns)
    assert capsys.readouterr().out.strip() == "alarm 2"
    assert (tmp_path / "alarm_agent.py").exists()
    result = json.loads((tmp_path / "alarm.json").read_text())
    assert result["agent"] == "alarm" and result["metrics"]["n_episodes"] == 2
    assert sorted(e["scenario_id"] for e in result["episodes"]) == ["charge-air-offset", "healthy"]
