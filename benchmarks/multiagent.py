"""What the multi-agent path costs: a suite scored through the batched multi-agent environment against
the single-agent evaluation of the same team as one agent, in one process and one run.

    python benchmarks/multiagent.py --json                     # multi-v1, reference-distributed
    python benchmarks/multiagent.py --suite single-v1 --team training/models/dec-classifier-decision/seed0

prints one JSON object (CPU seconds of this process, all its threads; best of ``--repeats``; numba's
compilation, imports and loading kept out by a warm-up on the suite's first batch):

``single_cpu_s``   :func:`~marine_fdi_env.benchmark.evaluate.run_episodes` of the team as one agent
                   (:class:`~marine_fdi_env.multiagent.team.TeamAgent`: ``marine-fdi evaluate``'s path,
                   batches of 32, the simulation shared with nothing else);
``multi_cpu_s``    :func:`~marine_fdi_env.multiagent.evaluate.evaluate_team` (batches of 32 of
                   :class:`~marine_fdi_env.multiagent.batch.MultiAgentBatchEnv`, the locals' messages and
                   the global's declarations passed through the environment);
``ratio``          ``multi_cpu_s / single_cpu_s`` (target <= 1.5);
``same_records``   whether both paths gave the same episode records but the wall-clock fields.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import emit  # noqa: E402

from marine_fdi_env.benchmark.evaluate import WALL_CLOCK_FIELDS, run_episodes, suite_env_kwargs  # noqa: E402
from marine_fdi_env.benchmark.suites import load_suite  # noqa: E402
from marine_fdi_env.multiagent.evaluate import evaluate_team  # noqa: E402
from marine_fdi_env.multiagent.team import TeamAgent  # noqa: E402


def load_team(spec: str):
    """``reference-distributed`` or a trained team's model folder."""
    if spec == "reference-distributed":
        from marine_fdi_env.baselines.reference_distributed_agent import reference_distributed_team

        return reference_distributed_team()
    from marine_fdi_env.training.decentralised_agent import load_team as load_trained

    return load_trained(spec)


def _cpu(fn, repeats: int):
    """(best CPU seconds and wall seconds of ``repeats`` calls, the last call's result)."""
    best, wall, out = float("inf"), float("inf"), None
    for _ in range(repeats):
        c0, w0 = time.process_time(), time.perf_counter()
        out = fn()
        best, wall = min(best, time.process_time() - c0), min(wall, time.perf_counter() - w0)
    return best, wall, out


def _strip(records: list[dict]) -> list[dict]:
    return [{k: v for k, v in r.items() if k not in WALL_CLOCK_FIELDS} for r in records]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--suite", default="multi-v1")
    ap.add_argument("--team", default="reference-distributed", help="reference-distributed or a model folder")
    ap.add_argument("--repeats", type=int, default=1)
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args()
    suite = load_suite(args.suite)
    env_kwargs, _ = suite_env_kwargs(suite)
    team = load_team(args.team)
    agent = TeamAgent(team)
    run_episodes(agent, suite.scenarios[:2], env_kwargs, suite=suite.name)  # compile or load numba's cache
    single_cpu, single_wall, recs = _cpu(
        lambda: run_episodes(agent, suite.scenarios, env_kwargs, suite=suite.name), args.repeats
    )
    multi_cpu, multi_wall, res = _cpu(lambda: evaluate_team(team, suite.name), args.repeats)
    out = {
        "suite": suite.name,
        "episodes": len(suite.scenarios),
        "team": team.name,
        "budget": team.budget.name,
        "single_cpu_s": round(single_cpu, 2),
        "multi_cpu_s": round(multi_cpu, 2),
        "ratio": round(multi_cpu / single_cpu, 3),
        "single_wall_s": round(single_wall, 2),
        "multi_wall_s": round(multi_wall, 2),
        "same_records": _strip(recs) == _strip(res["episodes"]),
        "load_average_1min": round(os.getloadavg()[0], 2),
    }
    emit(out, args.json)


if __name__ == "__main__":
    main()
