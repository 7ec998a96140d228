"""What a new user tripped on in the first hour (issue 52), each as the behaviour it must have now: the one
error convention of the command line (one line, exit code, the traceback only with --debug; an exception
inside the user's own agent named by its file and line), bad inputs that named nothing, outputs overwritten
silently, the memory check under an address-space limit, what an interrupted export keeps, the sweep's
default folder and the validation report's lead."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from test_ux import tiny  # noqa: F401 - the two-episode suite fixture

from marine_fdi_env.cli import main as cli_main
from marine_fdi_env.coldstart import COMPILING
from tests.paths import ROOT

AGENT = """\
import numpy as np


class Boom:
    name = "boom"

    def reset(self, seeds):
        self.n = len(seeds)

    def act(self, obs, infos):
        return self.helper(obs)

    def helper(self, obs):
        raise {exc}("boom from my agent")
"""
RAISE_LINE = AGENT.splitlines().index('        raise {exc}("boom from my agent")') + 1


def _run(capsys, argv) -> tuple[int, str]:
    code = cli_main([str(a) for a in argv])
    return code, capsys.readouterr().err


def _one_line(err: str) -> str:
    # progress bars and the cold-cache compile notice (printed once per fresh numba cache) aside
    lines = [ln for ln in err.splitlines() if ln.strip() and "%|" not in ln and COMPILING not in ln]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


# ----------------------------------------------------------------------------- the one error convention
@pytest.mark.parametrize("exc", ["RuntimeError", "ValueError"])
def test_an_exception_in_the_users_agent_names_its_file_and_line(exc, tmp_path, capsys, tiny):  # noqa: F811
    """A ValueError inside the agent is the agent's failure, not a refused input: both name the line."""
    (tmp_path / "my_agent.py").write_text(AGENT.format(exc=exc))
    spec = f"{tmp_path / 'my_agent.py'}:Boom"
    code, err = _run(
        capsys, ["evaluate", "--agent", spec, "--suite", tiny, "--out", tmp_path / "r.json", "--no-progress"]
    )
    line = _one_line(err)
    assert code == 1
    assert f"your agent raised {exc}: boom from my agent at " in line and line.endswith("--debug prints the traceback")
    assert f"my_agent.py:{RAISE_LINE};" in line
    code, err = _run(
        capsys,
        ["--debug", "evaluate", "--agent", spec, "--suite", tiny, "--out", tmp_path / "r2.json", "--no-progress"],
    )
    assert code == 1 and "Traceback (most recent call last)" in err and "in helper" in err


def test_the_agents_line_is_found_in_a_worker_process_too(tmp_path, capsys, tiny):  # noqa: F811
    (tmp_path / "my_agent.py").write_text(AGENT.format(exc="KeyError"))
    argv = ["evaluate", "--agent", f"{tmp_path / 'my_agent.py'}:Boom", "--suite", tiny, "--out", tmp_path / "r.json"]
    code, err = _run(capsys, argv + ["--workers", "2", "--batch-size", "1", "--no-progress"])
    assert code == 1 and "your agent raised KeyError" in _one_line(err) and f"my_agent.py:{RAISE_LINE};" in err


def test_debug_anywhere_or_the_environment_variable_prints_the_traceback(tmp_path, capsys, monkeypatch):
    argv = ["validate", "--data", tmp_path, "--out", tmp_path / "v.json"]
    code, err = _run(capsys, argv)
    assert code == 2 and "--data" in _one_line(err)
    code, err = _run(capsys, argv + ["--debug"])
    assert code == 2 and err.startswith("marine-fdi validate: error: --data") and "Traceback" in err
    monkeypatch.setenv("MARINE_FDI_DEBUG", "1")
    code, err = _run(capsys, argv)
    assert code == 2 and "Traceback" in err
    assert (
        "--debug"
        in subprocess.run([sys.executable, "-m", "marine_fdi_env.cli", "--help"], capture_output=True, text=True).stdout
    )


def test_an_unexpected_exception_is_one_line_that_says_so(monkeypatch, capsys, tmp_path):
    import marine_fdi_env.engine.simulator as sim_mod

    def broken(*a, **k):
        raise ZeroDivisionError("division by zero")

    monkeypatch.setattr(sim_mod.Simulator, "run", broken)
    code, err = _run(capsys, ["simulate", "--duration", "1", "--out", tmp_path / "x.npz"])
    assert code == 1 and "ZeroDivisionError: division by zero (unexpected" in _one_line(err)


# ----------------------------------------------------------------------------- bad inputs, one line each
def test_a_folder_or_undecodable_file_where_a_file_is_expected(tmp_path, capsys):
    folder = tmp_path / "somedir"
    folder.mkdir()
    for argv, option in [
        (["validate", "--data", folder, "--out", tmp_path / "v.json"], "--data"),
        (["validate", "--data", folder, "--check"], "--data"),
        (["replicas", "--data", folder], "--data"),
        (["diagnose", "--run", folder, "--out", tmp_path / "d.json"], "--run"),
        (["info", folder], "somedir"),
    ]:
        code, err = _run(capsys, argv)
        line = _one_line(err)
        assert code == 2 and option in line and "is a folder" in line and "does not exist" not in line, argv
    shipped = ROOT / "src" / "marine_fdi_env" / "data" / "measured"
    csv = tmp_path / "latin1.csv"
    csv.write_bytes((shipped / "man_12v32_40_fpp_iso.csv").read_bytes() + "comment: 25 \u00b0C\n".encode("latin-1"))
    (tmp_path / "latin1.meta.json").write_bytes((shipped / "man_12v32_40_fpp_iso.meta.json").read_bytes())
    code, err = _run(capsys, ["validate", "--data", csv, "--check"])
    line = _one_line(err)
    assert code == 2 and "--data" in line and "latin1.csv" in line and "not UTF-8" in line


def _unwritable(tmp_path: Path) -> Path:
    """A folder no file can be created in: a read-only one, or for root (whom permissions do not stop) sysfs."""
    if os.geteuid() != 0:
        ro = tmp_path / "ro"
        ro.mkdir()
        ro.chmod(0o555)
        return ro
    try:
        (Path("/sys") / ".probe").write_text("")
    except OSError:
        return Path("/sys")
    pytest.skip("root on a machine without a read-only sysfs: no folder to refuse")


@pytest.mark.parametrize(
    "argv",
    [
        ["simulate", "--duration", "1", "--out", "{ro}/r.npz"],
        ["evaluate", "--agent", "null", "--out", "{ro}/x.json"],
        ["validate", "--data", "man_12v32_40_fpp_iso", "--out", "{ro}/v.json"],
        ["dataset", "--preset", "default", "--episodes", "1", "--out", "{ro}/ds"],
        ["report", "{none}", "--out", "{ro}/rep", "--no-plots"],
        ["train", "--algo", "ppo", "--out", "{ro}/ppo"],
    ],
)
def test_an_unwritable_out_names_the_option_before_any_work(argv, tmp_path, capsys):
    ro = _unwritable(tmp_path)
    argv = [a.format(ro=ro, none=tmp_path / "none.json") for a in argv]
    code, err = _run(capsys, argv)
    line = _one_line(err)
    assert code == 2 and "--out" in line and "cannot write in the folder" in line and ".tmp" not in line, argv


def test_train_refuses_a_budget_that_is_not_positive_and_says_its_default_env(tmp_path, capsys):
    pytest.importorskip("stable_baselines3")
    for argv in (["--n-timesteps", "-5"], ["--n-timesteps", "0"], ["--params", "n_timesteps=-5"]):
        code, err = _run(capsys, ["train", "--algo", "ppo", "--out", tmp_path / "m", *argv])
        assert code == 2 and "n_timesteps" in _one_line(err).replace("-", "_") and not (tmp_path / "m").exists()
    code = cli_main(["train", "--help"])
    out = capsys.readouterr().out.replace("\n", " ")
    assert code == 0 and "default MarineFDI-v0" in " ".join(out.split())


def test_train_does_not_overwrite_a_trained_model_without_force(tmp_path, capsys, monkeypatch):
    pytest.importorskip("stable_baselines3")
    import marine_fdi_env.training.train as training

    out = tmp_path / "m"
    out.mkdir()
    (out / "config.json").write_text("{}")
    argv = ["train", "--algo", "classifier", "--seed", "3", "--out", str(out)]
    code, err = _run(capsys, argv)
    line = _one_line(err)
    assert code == 2 and "--force" in line and "config.json" in line
    assert (out / "config.json").read_text() == "{}"  # untouched
    calls = []
    monkeypatch.setattr(training, "train_agent", lambda *a, **kw: calls.append(kw) or {"cpu_minutes": 0.0})
    assert cli_main([*argv, "--force", "--no-cache"]) == 0
    # the recorded command makes the model again: neither the overwrite nor the re-export is part of it
    assert calls[0]["command"] == f"marine-fdi train --algo classifier --seed 3 --out {out}"
    assert calls[0]["use_cache"] is False


def test_report_does_not_overwrite_a_report_without_force(tmp_path, capsys, tiny):  # noqa: F811
    res = tmp_path / "r.json"
    assert cli_main(["evaluate", "--agent", "null", "--suite", str(tiny), "--out", str(res), "--no-progress"]) == 0
    out = tmp_path / "rep"
    assert cli_main(["report", str(res), "--out", str(out), "--no-plots"]) == 0
    (out / "report.md").write_text("my notes\n")
    code, err = _run(capsys, ["report", res, "--out", out, "--no-plots"])
    assert code == 2 and "--force" in _one_line(err) and (out / "report.md").read_text() == "my notes\n"
    assert cli_main(["report", str(res), "--out", str(out), "--no-plots", "--force"]) == 0
    assert (out / "report.md").read_text() != "my notes\n"


# ----------------------------------------------------------------------------- memory
def test_the_memory_check_uses_the_address_space_limit(monkeypatch):
    from marine_fdi_env import costs

    monkeypatch.setattr(costs, "available_memory_bytes", lambda: 10**12)
    monkeypatch.setattr(costs, "address_space_left_bytes", lambda: 2 * 10**9)
    costs.check_memory(1.9e9, "x", "--n")
    with pytest.raises(ValueError, match=r"--n: x needs about 2\.5 GB of memory, more than the 2 GB left under "):
        costs.check_memory(2.5e9, "x", "--n")
    monkeypatch.setattr(costs, "address_space_left_bytes", lambda: None)
    costs.check_memory(2.5e9, "x", "--n")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="RLIMIT_AS and /proc/self/status: Linux")
def test_simulate_under_an_address_space_limit_is_refused_in_one_line(tmp_path):
    import resource

    def limit():  # 6 GB of address space, as `ulimit -v 6000000`
        resource.setrlimit(resource.RLIMIT_AS, (6 * 10**9, resource.RLIM_INFINITY))

    cmd = [sys.executable, "-m", "marine_fdi_env.cli", "simulate", "--engines", "1000", "--duration", "300"]
    run = subprocess.run(
        cmd + ["--out", str(tmp_path / "big.npz")], capture_output=True, text=True, preexec_fn=limit, timeout=300
    )
    assert run.returncode == 2, run.stderr[-2000:]
    line = _one_line(run.stderr)
    assert "--engines" in line and "address-space limit" in line and not (tmp_path / "big.npz").exists()


def test_running_out_of_memory_is_one_line(monkeypatch, capsys, tmp_path):
    import marine_fdi_env.engine.simulator as sim_mod

    def oom(*a, **k):
        raise MemoryError("Unable to allocate 4.55 GiB for an array with shape (1000, 30001, 19)")

    monkeypatch.setattr(sim_mod.Simulator, "run", oom)
    code, err = _run(capsys, ["simulate", "--duration", "1", "--out", tmp_path / "x.npz"])
    line = _one_line(err)
    assert code == 2 and "not enough memory" in line and "4.55 GiB" in line and "ask for less" in line


# ----------------------------------------------------------------------------- what Ctrl-C keeps
def test_an_interrupted_dataset_says_exactly_what_it_keeps(monkeypatch, capsys, tmp_path):
    from marine_fdi_env.benchmark import backends

    real = backends.run_tasks

    def before_the_first_chunk(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(backends, "run_tasks", before_the_first_chunk)
    argv = ["dataset", "--preset", "default", "--episodes", "2", "--batch-size", "1", "--no-progress"]
    code, err = _run(capsys, argv + ["--out", tmp_path / "a"])
    assert code == 130 and "nothing is kept" in err and "finished chunks are kept" not in err

    def after_one_chunk(backend, fn, tasks, *, on_result, on_progress=None):
        on_result(0, fn(*tasks[0], progress=None))
        raise KeyboardInterrupt

    monkeypatch.setattr(backends, "run_tasks", after_one_chunk)
    code, err = _run(capsys, argv + ["--out", tmp_path / "b"])
    assert code == 130 and "the 1 of 2 episodes of the finished chunks are kept in" in err
    monkeypatch.setattr(backends, "run_tasks", real)
    code, err = _run(capsys, argv + ["--out", tmp_path / "b"])
    assert code == 0 and "resuming at 1/2" in err


# ----------------------------------------------------------------------------- sweep
def test_the_sweep_writes_to_results_sweep_without_out(tmp_path, monkeypatch, capsys, tiny):  # noqa: F811
    pytest.importorskip("pyarrow")
    monkeypatch.chdir(tmp_path)
    assert cli_main(["sweep", "--agents", "null", "--suites", str(tiny), "--no-progress"]) == 0
    assert (tmp_path / "results" / "sweep" / "episodes.parquet").is_file()
    assert "results/sweep/episodes.parquet" in capsys.readouterr().out


# ----------------------------------------------------------------------------- the validation report's lead
def test_the_validation_report_leads_with_what_the_data_allow():
    from marine_fdi_env.validation.report.markdown import markdown_summary

    rep = json.loads((ROOT / "docs/figures/validation/birka_me1_test_protocol.json").read_text())
    assert next(iter(rep)) == "what_the_data_allow"  # the JSON's first key
    lead = rep["what_the_data_allow"]
    assert lead["explanations"] == 2 and lead["first_ranked"]["causes"][:2] == ["waste_gate", "turbocharger_map"]
    assert lead["deciding_measurement"]["channel"] == "turbine_inlet_temperature_C"
    assert lead["selection_path"] == {"causes": rep["selected_labels"], "rank": 2}
    assert rep["selected_causes"] == ["waste_gate", "sensor_calibration"]  # kept for existing readers
    md = markdown_summary(rep)
    bold = [ln for ln in md.splitlines() if ln.startswith("**")]
    assert bold[0].startswith("**What the data allow: 2 explanations the data do not decide between; first-ranked")
    assert "turbine_inlet_temperature_C at 30 % load" in bold[0]
    assert not any("Selected causes" in ln for ln in bold)
    assert "The forward selection's path ends at `waste_gate`" in md and "#2 of the 2 explanations" in md
    shipped = (ROOT / "docs/figures/validation/birka_me1_test_protocol.md").read_text()
    assert shipped == markdown_summary(rep, "birka_me1_test_protocol") + "\n"  # the shipped page is this
