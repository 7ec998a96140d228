"""RL Zoo (``rl_zoo3``) out of the box: ``python -m rl_zoo3.train`` with the package's hyperparameters
(``--conf-file marine_fdi_env.training.zoo``) trains on the batched environment with the gated action, and
``marine-fdi evaluate --agent RUN_FOLDER`` scores the run it wrote.  A tiny run (a few hundred steps on 4
engines) checks the path; that the shipped settings learn is measured by hand (docs/sb3.md)."""

from __future__ import annotations

import subprocess
import sys

import pytest
from test_ux import tiny  # noqa: F401 - the two-episode suite fixture

from marine_fdi_env.cli import main as cli_main

pytest.importorskip("rl_zoo3")

SMALL = (
    "vec_env_wrapper:[{'marine_fdi_env.training.zoo.batched_env': dict(num_envs=4, action_mode='gated', "
    "reference_features=True, reward=dict(version='v1', false_alarm=10.0))}]"
)


def test_rl_zoo_trains_with_the_shipped_hyperparameters_and_the_run_evaluates(tmp_path, capsys, tiny):  # noqa: F811
    cmd = [
        sys.executable, "-m", "rl_zoo3.train", "--algo", "ppo", "--env", "MarineFDI-v1",
        "--gym-packages", "marine_fdi_env", "--conf-file", "marine_fdi_env.training.zoo", "--seed", "0",
        "-n", "128", "--eval-freq", "-1", "-f", str(tmp_path / "logs"),
        "--hyperparams", SMALL, "n_steps:16", "batch_size:64",
    ]  # fmt: skip
    run = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr[-3000:]
    assert "'action_mode': 'gated'" in run.stdout  # the shipped entry was read (and our override of its engines)
    folder = tmp_path / "logs" / "ppo" / "MarineFDI-v1_1"
    assert (folder / "MarineFDI-v1.zip").is_file() and (folder / "MarineFDI-v1" / "vecnormalize.pkl").is_file()
    out = tmp_path / "zoo.json"
    code = cli_main(["evaluate", "--agent", str(folder), "--suite", str(tiny), "--out", str(out), "--no-progress"])
    assert code == 0, capsys.readouterr().err
    assert "MarineFDI-v1_1" in capsys.readouterr().out and out.is_file()


def test_rl_zoo_refuses_the_namespaced_id_and_finds_the_registered_one():
    """Why the docs say ``--env MarineFDI-v1``: RL Zoo looks ``--env`` up in Gymnasium's registry as given."""
    code = (
        "import gymnasium, marine_fdi_env; r = set(gymnasium.envs.registry);"
        "print('MarineFDI-v1' in r, 'marine_fdi_env:MarineFDI-v1' in r)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["True", "False"]


def test_a_folder_that_is_neither_a_model_nor_a_run_says_both(tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    code = cli_main(["evaluate", "--agent", str(tmp_path / "empty"), "--out", str(tmp_path / "x.json")])
    err = capsys.readouterr().err
    assert code == 2 and "no agent.json" in err and "RL Zoo run folder" in err
