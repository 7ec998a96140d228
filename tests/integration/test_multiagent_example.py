"""docs/examples/multiagent_sb3.py (docs/multiagent.md's example) runs: SB3's PPO as the global agent of
the ParallelEnv, then one episode of the whole team."""

import subprocess
import sys

import pytest

from tests.paths import ROOT

pytest.importorskip("stable_baselines3")
pytest.importorskip("pettingzoo")


@pytest.mark.slow
def test_the_sb3_global_agent_example_runs():
    out = subprocess.run(
        [sys.executable, str(ROOT / "docs" / "examples" / "multiagent_sb3.py"), "--timesteps", "64"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert out.returncode == 0, out.stderr
    assert "team return" in out.stdout
