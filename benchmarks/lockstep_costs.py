"""Where the time of every agent on a suite goes: one process, the first ``--episodes`` of single-v1.

    python benchmarks/lockstep_costs.py --json

prints one JSON object (CPU seconds of this process, all its threads, per 300 s episode; best of
``--repeats``; compilation and loading kept out of the simulation and scoring numbers):

``simulate_cpu_s``      :func:`~marine_fdi_env.envs.trajectory.simulate` of the episodes in one
                        batch, per environment: ``default`` (what ``reference`` alone needs),
                        ``sequential`` (``observe_sequential``: every agent's pass without the other
                        cell sets), ``every_cell_set`` (``observe_sequential`` and
                        ``diagnosis_cells`` thesis, grid and sized: the pass of every agent).
``cell_sets_cpu_s``     ``every_cell_set`` minus ``sequential``: the two extra cell sets' decision logic.
``score_cpu_s``         :func:`~marine_fdi_env.benchmark.lockstep.score_agents` on the every-cell-set
                        trajectory: ``one`` (``reference``) and ``every`` (every registered agent).
``act_s``               per agent, its ``act`` time per episode (wall, ``agent_compute_s`` of its records).
``load_agents_cpu_s``   loading every registered agent (importing torch, reading the models), once
                        per process: ``marine-fdi sweep`` with ``--workers 2`` pays it in each worker.
``predicted_every_over_one`` (simulate every_cell_set + score every) / (simulate default + score one),
                        per episode, the ratio ``benchmarks/sweep.py`` measures apart from process start,
                        imports and loading.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import emit  # noqa: E402

from marine_fdi_env.benchmark.agent_api import load_agent  # noqa: E402
from marine_fdi_env.benchmark.agent_registry import list_agents  # noqa: E402
from marine_fdi_env.benchmark.evaluate import suite_env_kwargs  # noqa: E402
from marine_fdi_env.benchmark.lockstep import agent_view, score_agents  # noqa: E402
from marine_fdi_env.benchmark.suites import load_suite  # noqa: E402
from marine_fdi_env.diagnosis.cell_sets import CELL_SETS  # noqa: E402
from marine_fdi_env.envs.trajectory import simulate  # noqa: E402

ENVIRONMENTS = {
    "default": {},
    "sequential": {"observe_sequential": True},
    "every_cell_set": {"observe_sequential": True, "diagnosis_cells": list(CELL_SETS)},
}


def _cpu(fn, repeats: int):
    """(best CPU seconds of ``repeats`` calls, the last call's result)."""
    best, out = float("inf"), None
    for _ in range(repeats):
        c0 = time.process_time()
        out = fn()
        best = min(best, time.process_time() - c0)
    return best, out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--episodes", type=int, default=32)
    ap.add_argument("--repeats", type=int, default=2)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    suite = load_suite("single-v1")
    env_kwargs, reward = suite_env_kwargs(suite)
    scenarios = suite.scenarios[: args.episodes]
    per = 300.0 / scenarios[0].duration_s / len(scenarios)  # CPU of the batch -> per 300 s episode
    simulate(scenarios[:1], dict(env_kwargs, **ENVIRONMENTS["every_cell_set"]))  # compile or load numba's cache
    sim, traj = {}, None
    for name, kw in ENVIRONMENTS.items():
        cpu, traj = _cpu(lambda kw=kw: simulate(scenarios, dict(env_kwargs, **kw)), args.repeats)
        sim[name] = round(cpu * per, 4)
    names = [e.name for e in list_agents() if e.available]
    load_cpu, agents = _cpu(lambda: [load_agent(n) for n in names], 1)
    views = [agent_view(dict(env_kwargs, **getattr(a, "env_kwargs", {})), traj) for a in agents]
    one = names.index("reference")
    score_agents([agents[one]], [views[one]], traj, reward)  # warm every agent's first call
    score_agents(agents, views, traj, reward)
    score_one, _ = _cpu(lambda: score_agents([agents[one]], [views[one]], traj, reward), args.repeats)
    score_every, recs = _cpu(lambda: score_agents(agents, views, traj, reward), args.repeats)
    score = {"one": round(score_one * per, 4), "every": round(score_every * per, 4)}
    act = {n: round(sum(r["agent_compute_s"] for r in rs) * per, 4) for n, rs in zip(names, recs)}
    out = {
        "episodes": len(scenarios),
        "n_agents": len(names),
        "simulate_cpu_s": sim,
        "cell_sets_cpu_s": round(sim["every_cell_set"] - sim["sequential"], 4),
        "score_cpu_s": score,
        "act_s": act,
        "load_agents_cpu_s": round(load_cpu, 2),
        "predicted_every_over_one": round(
            (sim["every_cell_set"] + score["every"]) / (sim["default"] + score["one"]), 2
        ),
        "load_average_1min": round(os.getloadavg()[0], 2),
    }
    emit(out, args.json)


if __name__ == "__main__":
    main()
