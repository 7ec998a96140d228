"""``marine-fdi evaluate``: run an agent on a frozen suite and score it.

Episodes run in batches on the vector environment (all episodes of a suite have the same
length, so a batch starts and ends together; an episode ended early by an engine failure is
simply left).  Every finished episode is appended at once to ``OUT.partial.jsonl``, so an
interrupted run resumes where it stopped and loses nothing; when all are done the results file
``OUT`` (the suite's episodes in suite order and the metrics of :mod:`.metrics`) is written and
the partial log removed.

Reproducibility: the numbers of an episode depend only on its scenario, the seed offset and the
agent (never on the batch size or the number of workers, since engines are independent); the
agent's own randomness is seeded per episode from the scenario id and the seed offset.  Only the
wall-clock fields (``compute_s``) vary from run to run.

``compute_s`` of an episode = the time spent making its observations (the residual generators
run for every agent) + its share of the agent's ``act`` time.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import replace
from pathlib import Path

import numpy as np

from .. import __version__
from .agent_api import load_agent
from .fdi_env import ENV_ID
from .metrics import compute_metrics
from .scenario_sampler import ScenarioSpec
from .suites import load_suite
from .vector import MarineFDIVectorEnv

__all__ = ["run_episodes", "evaluate", "evaluate_main", "episode_seed"]

_MAX_SEED = 2**63 - 1


def episode_seed(scenario_id: str, seed_offset: int) -> int:
    """The agent's seed for one episode (stable across Python versions and platforms)."""
    h = hashlib.sha256(f"{scenario_id}|{seed_offset}".encode()).digest()
    return int.from_bytes(h[:8], "little") & _MAX_SEED


def _offset(sc: ScenarioSpec, seed_offset: int) -> ScenarioSpec:
    if not seed_offset:
        return sc
    return replace(sc, noise_seed=(int(sc.noise_seed) + int(seed_offset)) % _MAX_SEED)


def run_episodes(agent, scenarios: list[ScenarioSpec], env_kwargs: dict | None = None, *, suite: str = "",
                 seed_offset: int = 0, batch_size: int = 32, on_episode=None) -> list[dict]:
    """Run ``agent`` on every scenario; returns the episode records (scenario order).

    ``on_episode(record)`` is called as soon as an episode's record is complete.
    """
    env_kwargs = dict(env_kwargs or {})
    env_kwargs.update(getattr(agent, "env_kwargs", {}))  # options the agent needs (e.g. observe_sequential)
    records: dict[int, dict] = {}
    for start in range(0, len(scenarios), batch_size):
        chunk = [_offset(s, seed_offset) for s in scenarios[start:start + batch_size]]
        for j, rec in enumerate(_run_batch(agent, chunk, env_kwargs, suite, seed_offset)):
            records[start + j] = rec
            if on_episode is not None:
                on_episode(rec)
    return [records[i] for i in range(len(scenarios))]


def _run_batch(agent, scenarios, env_kwargs, suite, seed_offset):
    n = len(scenarios)
    venv = MarineFDIVectorEnv(num_envs=n, **env_kwargs)
    obs, infos = venv.reset(options={"scenarios": scenarios})
    agent.reset([episode_seed(s.scenario_id, seed_offset) for s in scenarios])
    period = venv.batch.decision_period_s
    live = np.ones(n, dtype=bool)
    trace = [[] for _ in range(n)]
    share = [[] for _ in range(n)]
    ret = np.zeros(n)
    terms = [dict() for _ in range(n)]
    agent_s = np.zeros(n)
    feature_s = np.zeros(n)
    steps = np.zeros(n, dtype=np.int64)
    out: list[dict | None] = [None] * n
    while live.any():
        t0 = time.perf_counter()
        actions = np.asarray(agent.act(obs, infos), dtype=np.float32)
        agent_s[live] += (time.perf_counter() - t0) / live.sum()
        obs, rew, term, trunc, infos = venv.step(actions)
        for i in np.flatnonzero(live):
            t = float(infos["decision_time_s"][i])
            declared = list(infos["declared"][i])
            alarm = bool(infos["alarm"][i])
            if not trace[i] or trace[i][-1][1] != declared or trace[i][-1][2] != alarm:
                trace[i].append([t, declared, alarm])
            b = float(infos["belief_on_truth"][i])
            if b == b:  # not NaN: a fault is active
                share[i].append([t, b])
            ret[i] += rew[i]
            for k, v in infos["reward_terms"].items():
                if k.startswith("_"):
                    continue
                terms[i][k] = terms[i].get(k, 0.0) + float(v[i])
            steps[i] += 1
            if term[i] or trunc[i]:
                live[i] = False
                feature_s[i] = venv.batch.compute_s[i]
                sc = scenarios[i]
                fail = infos["engine_failure"]
                reason = str(fail["reason"][i]) if term[i] else None
                out[i] = {
                    "scenario_id": sc.scenario_id, "suite": suite, "seed": int(sc.noise_seed), "agent": agent.name,
                    "profile": sc.profile, "duration_s": t if term[i] else float(sc.duration_s),
                    "decision_period_s": period, "n_samples": int(steps[i] * venv.batch.period_samples),
                    "faults": sc.truth(), "declared_changes": trace[i], "belief_on_truth": share[i],
                    "terminated": bool(term[i]), "failure_reason": reason or None,
                    "compute_s": float(feature_s[i] + agent_s[i]), "return": float(ret[i]),
                    "reward_terms": terms[i],
                }
    return out


def _worker(agent_spec, scenarios_dicts, env_kwargs, suite, seed_offset, batch_size):
    agent = load_agent(agent_spec)
    scs = [ScenarioSpec.from_dict(d) for d in scenarios_dicts]
    return run_episodes(agent, scs, env_kwargs, suite=suite, seed_offset=seed_offset, batch_size=batch_size)


def evaluate(agent_spec: str, suite_name: str, out: Path, *, workers: int = 1, seed_offset: int = 0,
             batch_size: int = 32, progress: bool = True) -> dict:
    """Evaluate an agent on a suite, resumably; returns the results object written to ``out``."""
    if not isinstance(workers, int) or workers < 1:
        raise ValueError(f"--workers must be a positive integer, got {workers!r}")
    if not isinstance(batch_size, int) or batch_size < 1:
        raise ValueError(f"--batch-size must be a positive integer, got {batch_size!r}")
    suite = load_suite(suite_name)
    agent = load_agent(agent_spec)  # fail early on a bad agent
    env_kwargs = {k: v for k, v in suite["env"].items()}
    env_kwargs.update(getattr(agent, "env_kwargs", {}))  # options the agent needs (e.g. observe_sequential)
    header = {"agent": agent.name, "agent_spec": str(agent_spec), "suite": suite.name,
              "suite_version": suite["version"], "seed_offset": int(seed_offset), "env_id": ENV_ID,
              "env": env_kwargs}
    out = Path(out)
    partial = out.with_name(out.name + ".partial.jsonl")
    done: dict[str, dict] = {}
    if partial.exists():
        lines = partial.read_text().splitlines()
        try:
            old = json.loads(lines[0]) if lines else None
        except json.JSONDecodeError:
            old = None
        if old != header:
            raise ValueError(f"{partial} belongs to another evaluation ({old}); remove it or choose another --out")
        for ln in lines[1:]:
            try:
                rec = json.loads(ln)
            except json.JSONDecodeError:  # a line cut by an interruption: that episode reruns
                continue
            done[rec["scenario_id"]] = rec
    else:
        out.parent.mkdir(parents=True, exist_ok=True)
        partial.write_text(json.dumps(header) + "\n")
    todo = [s for s in suite.scenarios if s.scenario_id not in done]
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(suite.scenarios), initial=len(done), desc=f"{agent.name} on {suite.name}",
                   unit="episode", file=sys.stderr)

    def record(rec):
        with partial.open("a") as fh:
            fh.write(json.dumps(rec) + "\n")
        done[rec["scenario_id"]] = rec
        if bar is not None:
            bar.update(1)

    if workers == 1 or len(todo) <= batch_size:
        run_episodes(agent, todo, env_kwargs, suite=suite.name, seed_offset=seed_offset, batch_size=batch_size,
                     on_episode=record)
    else:
        per = max(1, min(batch_size, -(-len(todo) // workers)))
        chunks = [todo[i:i + per] for i in range(0, len(todo), per)]
        with ProcessPoolExecutor(max_workers=workers) as ex:
            futs = [ex.submit(_worker, agent_spec, [s.to_dict() for s in c], env_kwargs, suite.name, seed_offset,
                              batch_size) for c in chunks]
            for f in as_completed(futs):
                for rec in f.result():
                    record(rec)
    if bar is not None:
        bar.close()
    episodes = [done[s.scenario_id] for s in suite.scenarios]
    result = dict(header)
    result.update(package_version=__version__, n_scenarios=len(episodes), metrics=compute_metrics(episodes),
                  episodes=episodes)
    tmp = out.with_name(out.name + ".tmp")
    tmp.write_text(json.dumps(result, separators=(",", ":")) + "\n")  # compact: episodes hold traces
    os.replace(tmp, out)
    partial.unlink()
    return result


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="marine-fdi evaluate",
        description="Run an agent on a frozen evaluation suite and print its metrics. With no arguments: the "
                    "reference diagnoser on thesis-v1.")
    ap.add_argument("--agent", default="reference",
                    help="null | random | reference | sequential | oracle, or a directory with agent.json "
                         "(default: reference)")
    ap.add_argument("--suite", default="thesis-v1", help="suite name or JSON path (default: thesis-v1)")
    ap.add_argument("--out", type=Path, default=None, help="results JSON (default: results/AGENT_SUITE.json)")
    ap.add_argument("--workers", type=int, default=1, help="processes (default 1)")
    ap.add_argument("--seed-offset", type=int, default=0, help="shift every noise seed (new noise, same scenarios)")
    ap.add_argument("--batch-size", type=int, default=32, help="episodes advanced together (default 32)")
    ap.add_argument("--no-progress", action="store_true")
    return ap


def evaluate_main(argv=None) -> int:
    from .report import markdown_table

    try:
        args = build_parser().parse_args(argv)
    except SystemExit as e:
        return e.code if isinstance(e.code, int) else 0
    try:
        name = Path(args.agent).name if Path(args.agent).exists() else args.agent
        out = args.out or Path("results") / f"{name}_{Path(args.suite).stem}.json"
        result = evaluate(args.agent, args.suite, out, workers=args.workers, seed_offset=args.seed_offset,
                          batch_size=args.batch_size, progress=not args.no_progress)
    except ValueError as e:
        print(f"marine-fdi evaluate: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("marine-fdi evaluate: interrupted; rerun the same command to resume", file=sys.stderr)
        return 130
    print(markdown_table([result]))
    print(f"\nresults: {out}")
    return 0
