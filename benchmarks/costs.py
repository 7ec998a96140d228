"""The per-unit costs behind the up-front estimates of the long commands (``marine_fdi_env.costs``).

    python benchmarks/costs.py [--episodes 32] [--json]

prints one JSON object (or one line per metric):

``env_cpu_s_per_episode``        CPU seconds (this process, all its threads) per 300 s episode of
                                 the environment alone (simulation and observation features), run
                                 with the ``null`` agent on the first ``--episodes`` scenarios of
                                 single-v1, in one batch, after a warm-up (compilation excluded).
``agent_cpu_s_per_episode``      per agent (``reference``, ``sequential``, ``ppo``, ``classifier``):
                                 the same run's CPU seconds per episode minus the environment's
                                 (``sequential`` includes its extra CUSUM features).
``raw_bytes_per_sample``, ``raw_cpu_s_per_sample``
                                 bytes ``export-raw`` writes per 100 Hz sample (two scenarios of
                                 thesis-v1; data and ground truth files), and its CPU seconds per sample.
``run_file_bytes_per_engine_sample``, ``simulate_engine_samples_per_cpu_s``
                                 ``marine-fdi simulate`` of 8 engines x 300 s: file size per engine-sample,
                                 and engine-samples per CPU second of the whole command.
``load_average_1min``            the machine's load while measuring (the machine is shared).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import emit  # noqa: E402

from marine_fdi_env.benchmark.agent_api import load_agent  # noqa: E402
from marine_fdi_env.benchmark.evaluate import run_episodes, suite_env_kwargs, warm_up  # noqa: E402
from marine_fdi_env.benchmark.suites import load_suite  # noqa: E402

AGENTS = ("reference", "sequential", "ppo-v1", "classifier-v1", "classifier")


def cpu_per_episode(agent_spec: str, scenarios, env_kwargs) -> float:
    agent = load_agent(agent_spec)
    kw = dict(env_kwargs, **getattr(agent, "env_kwargs", {}))
    warm_up(kw)
    run_episodes(agent, scenarios[:2], kw, suite="single-v1", batch_size=len(scenarios))  # warm the agent too
    c0 = time.process_time()
    run_episodes(agent, scenarios, kw, suite="single-v1", batch_size=len(scenarios))
    return (time.process_time() - c0) / len(scenarios) * 300.0 / scenarios[0].duration_s


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=32)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    suite = load_suite("single-v1")
    env_kwargs, _ = suite_env_kwargs(suite)
    scenarios = suite.scenarios[: args.episodes]
    env = cpu_per_episode("null", scenarios, env_kwargs)
    out = {
        "env_cpu_s_per_episode": round(env, 3),
        "agent_cpu_s_per_episode": {
            a: round(max(0.0, cpu_per_episode(a, scenarios, env_kwargs) - env), 3) for a in AGENTS
        },
    }
    from marine_fdi_env.cli import main as cli

    with tempfile.TemporaryDirectory() as tmp, contextlib.redirect_stdout(io.StringIO()):  # the commands' own reports
        t = load_suite("thesis-v1")
        mini = dict(t, scenarios=[s.to_dict() for s in t.scenarios[:2]])
        (Path(tmp) / "mini.json").write_text(json.dumps(mini))
        raw = Path(tmp) / "raw"
        c0 = time.process_time()
        assert cli(["export-raw", "--suite", str(Path(tmp) / "mini.json"), "--out", str(raw), "--no-progress"]) == 0
        raw_cpu = time.process_time() - c0
        samples = sum(e["n_samples"] for e in json.loads((raw / "manifest.json").read_text())["scenarios"])
        size = sum(f.stat().st_size for f in raw.rglob("*") if f.is_file())
        out["raw_bytes_per_sample"] = round(size / samples, 1)
        out["raw_cpu_s_per_sample"] = round(raw_cpu / samples, 7)
        run = Path(tmp) / "run.npz"
        c0 = time.process_time()
        assert cli(["simulate", "--engines", "8", "--duration", "300", "--out", str(run), "--no-progress"]) == 0
        cpu = time.process_time() - c0
        out["run_file_bytes_per_engine_sample"] = round(run.stat().st_size / (8 * 30001), 1)
        out["simulate_engine_samples_per_cpu_s"] = round(8 * 30001 / cpu)
    out["load_average_1min"] = round(os.getloadavg()[0], 2)
    emit(out, args.json)


if __name__ == "__main__":
    main()
