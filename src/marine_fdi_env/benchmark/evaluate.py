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
run for every agent) + its share of the agent's ``act`` time.  Every process warms up first
(:func:`warm_up`: one throw-away episode of one engine), so numba's compilation of a cold cache
(about a minute) or its cache loading never counts.

Backends (``--backend serial|process|ray``, :mod:`.backends`): the suite is cut into chunks of at
most ``batch_size`` episodes, one task each; results, every metric and every episode record
except ``compute_s``, are the same bit for bit whichever backend and number of workers run them
(tested).  ``--out`` ending in ``.parquet`` writes the episode records as a Parquet table
(:mod:`.records`) with the header and metrics in its metadata instead of JSON.

The two parts of ``compute_s`` are also recorded apart (``feature_compute_s``, ``agent_compute_s``; ``n_decisions``), since the features dominate
and are the same for every agent.  Both depend on the batch size (``--batch-size``, default 32).

Reward: the results record the environment id and reward they score (``env_id``, ``env.reward``):
the suite's ``env.reward`` if it fixes one, else ``--reward`` (default ``v1``).  The reward
changes the ``return`` of an episode, never a metric.  A suite whose scenarios use another sensor
noise scale than 1 (``transfer-v2``) runs them in batches of equal noise scale.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from .._version import __version__
from .agent_api import load_agent, resolve_agent_spec
from .backends import Backend, chunk_size, run_tasks
from ..envs.fdi_env import env_id_for
from .metrics import compute_metrics
from ..envs.reward import make_reward_config
from ..envs.scenario_sampler import ScenarioSpec, with_noise_scale
from .suites import load_suite
from ..envs.vector import MarineFDIVectorEnv

__all__ = ["run_episodes", "evaluate", "episode_seed", "evaluate_chunk", "suite_env_kwargs",
           "WALL_CLOCK_FIELDS", "WALL_CLOCK_METRICS"]

# the fields of an episode record that are wall-clock measurements (everything else reproduces)
WALL_CLOCK_FIELDS = ("compute_s", "feature_compute_s", "agent_compute_s")
# the metrics computed from them
WALL_CLOCK_METRICS = ("compute_s_per_sample", "feature_compute_s_per_sample", "agent_compute_s_per_decision")

_MAX_SEED = 2**63 - 1


def episode_seed(scenario_id: str, seed_offset: int) -> int:
    """The agent's seed for one episode (stable across Python versions and platforms)."""
    h = hashlib.sha256(f"{scenario_id}|{seed_offset}".encode()).digest()
    return int.from_bytes(h[:8], "little") & _MAX_SEED


def _offset(sc: ScenarioSpec, seed_offset: int) -> ScenarioSpec:
    if not seed_offset:
        return sc
    return replace(sc, noise_seed=(int(sc.noise_seed) + int(seed_offset)) % _MAX_SEED)


_WARM = {"done": False}


def warm_up(env_kwargs: dict | None = None) -> None:
    """Run one short episode of one engine (its numbers are thrown away), once per process, so
    that numba's compilation or cache loading of the simulator, the residual generators and the
    features is over before anything is timed: ``compute_s`` never includes it.  The episodes'
    numbers do not change (compiled code has no state; every episode seeds its own streams)."""
    if _WARM["done"]:
        return
    sc = ScenarioSpec(profile="constant:u0=1.0", noise_seed=0, duration_s=2.0, scenario_id="warm-up")
    venv = MarineFDIVectorEnv(num_envs=1, **dict(env_kwargs or {}))
    venv.reset(options={"scenarios": [sc]})
    venv.step(np.zeros((1, venv.single_action_space.shape[0]), dtype=np.float32))
    venv.close()
    _WARM["done"] = True


def run_episodes(agent, scenarios: list[ScenarioSpec], env_kwargs: dict | None = None, *, suite: str = "",
                 seed_offset: int = 0, batch_size: int = 32, on_episode=None, progress=None,
                 on_decision=None) -> list[dict]:
    """Run ``agent`` on every scenario; returns the episode records (scenario order).

    ``on_episode(record)`` is called as soon as an episode's record is complete; ``progress(x)``
    after every decision with the episodes' worth of work done since the last call (fractions);
    ``on_decision(scenario_id, t_s, belief, compute_s)`` for every decision of every episode (the
    belief vector the agent declared at decision time ``t_s`` and the time spent on this decision:
    its observation and its share of the agent's ``act``).
    """
    env_kwargs = dict(env_kwargs or {})
    env_kwargs.update(getattr(agent, "env_kwargs", {}))  # options the agent needs (e.g. observe_sequential)
    warm_up(env_kwargs)  # compile time stays out of compute_s
    records: dict[int, dict] = {}
    groups: dict[float, list[int]] = {}  # one batched engine set per sensor-noise scale
    for i, s in enumerate(scenarios):
        groups.setdefault(float(s.noise_scale), []).append(i)
    for noise_scale, idx in groups.items():
        kw = with_noise_scale(env_kwargs, noise_scale)
        for start in range(0, len(idx), batch_size):
            part = idx[start:start + batch_size]
            chunk = [_offset(scenarios[i], seed_offset) for i in part]
            for i, rec in zip(part, _run_batch(agent, chunk, kw, suite, seed_offset, progress, on_decision)):
                records[i] = rec
                if on_episode is not None:
                    on_episode(rec)
    return [records[i] for i in range(len(scenarios))]


def _run_batch(agent, scenarios, env_kwargs, suite, seed_offset, progress=None, on_decision=None):
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
    n_decisions = np.maximum(1.0, np.round([s.duration_s / period for s in scenarios]))
    obs_cost = venv.batch.compute_s.copy()  # time spent on the observation each slot decides on
    reported = 0.0
    while live.any():
        t0 = time.perf_counter()
        actions = np.asarray(agent.act(obs, infos), dtype=np.float32)
        act_s = (time.perf_counter() - t0) / live.sum()
        agent_s[live] += act_s
        feats_before = venv.batch.compute_s.copy() if on_decision is not None else None
        obs, rew, term, trunc, infos = venv.step(actions)
        if on_decision is not None:
            for i in np.flatnonzero(live):
                on_decision(scenarios[i].scenario_id, float(infos["decision_time_s"][i]), actions[i],
                            float(obs_cost[i]) + act_s)
            obs_cost = venv.batch.compute_s - feats_before  # the next observation's cost
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
                    "reward_terms": terms[i], "feature_compute_s": float(feature_s[i]),
                    "agent_compute_s": float(agent_s[i]), "n_decisions": int(steps[i]),
                }
        if progress is not None:
            done = float(np.where(live, steps / n_decisions, 1.0).clip(0.0, 1.0).sum())
            progress(done - reported)
            reported = done
    return out


_AGENTS: dict[tuple, object] = {}  # agents loaded in this process (workers reuse theirs across tasks)


def _spec_stamp(spec: str) -> float:
    """The newest modification time of the files a spec loads (0 for names): a retrained model
    folder or an edited agent file is loaded anew."""
    from .agent_api import _split_file_spec

    fs = _split_file_spec(str(spec))
    path = fs[0] if fs is not None else Path(str(spec))
    try:
        if path.is_dir():
            return max((f.stat().st_mtime for f in path.iterdir() if f.is_file()), default=0.0)
        return path.stat().st_mtime if path.is_file() else 0.0
    except OSError:
        return 0.0


def cached_agent(spec: str):
    """The agent of ``spec``, loaded once per process (agents are reset at every batch)."""
    key = (spec, _spec_stamp(spec))
    if key not in _AGENTS:
        _AGENTS[key] = load_agent(spec)
    return _AGENTS[key]


def evaluate_chunk(agent_spec, scenarios_dicts, env_kwargs, suite, seed_offset, batch_size, progress=None):
    """One task of a backend: the episode records of a chunk of scenarios (given as dicts)."""
    agent = cached_agent(agent_spec)
    scs = [ScenarioSpec.from_dict(d) for d in scenarios_dicts]
    return run_episodes(agent, scs, env_kwargs, suite=suite, seed_offset=seed_offset, batch_size=batch_size,
                        progress=progress)


def suite_env_kwargs(suite, reward: "str | dict | None" = None) -> tuple[dict, object]:
    """The environment arguments a suite is scored with and its reward config: the suite's own
    ``env.reward`` if it fixes one (another ``reward`` is refused), else ``reward``, else ``v1``."""
    env_kwargs = {k: v for k, v in suite["env"].items()}
    fixed = env_kwargs.get("reward")
    if fixed is not None and reward is not None and make_reward_config(reward) != make_reward_config(fixed):
        raise ValueError(f"suite {suite.name} is scored with reward {fixed!r}; got --reward {reward!r}")
    reward_cfg = make_reward_config(fixed if fixed is not None else (reward if reward is not None else "v1"))
    env_kwargs["reward"] = reward_cfg.to_dict()
    return env_kwargs, reward_cfg


def evaluate(agent_spec: str, suite_name: str, out: Path, *, workers: int = 1, seed_offset: int = 0,
             batch_size: int = 32, progress: bool = True, backend: "Backend | str | None" = None,
             ray_address: str | None = None, reward: "str | dict | None" = None) -> dict:
    """Evaluate an agent on a suite, resumably; returns the results object written to ``out``.

    ``backend``: a :class:`~.backends.Backend` or its name (default: ``process`` if
    ``workers > 1``, else ``serial``).  ``reward``: the reward to score (``v0``, ``v1`` or a config
    dict); default: the suite's ``env.reward``, else ``v1``.  A suite that fixes its reward refuses
    another one.
    """
    if not isinstance(backend, Backend):
        backend = Backend.make(backend, workers, ray_address)
    workers = backend.workers
    if not isinstance(batch_size, int) or batch_size < 1:
        raise ValueError(f"--batch-size must be a positive integer, got {batch_size!r}")
    suite = load_suite(suite_name)
    spec = resolve_agent_spec(agent_spec)  # names stay names, paths become absolute (workers may run elsewhere)
    agent = cached_agent(spec)  # fail early on a bad agent
    env_kwargs, reward_cfg = suite_env_kwargs(suite, reward)
    env_kwargs.update(getattr(agent, "env_kwargs", {}))  # options the agent needs (e.g. observe_sequential)
    header = {"agent": agent.name, "agent_spec": str(agent_spec), "suite": suite.name,
              "suite_version": suite["version"], "seed_offset": int(seed_offset), "env_id": env_id_for(reward_cfg),
              "env": env_kwargs}
    if getattr(agent, "training_seed", None) is not None:  # a learned agent: which of its trainings this is
        header["training_seed"] = int(agent.training_seed)
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
            from ..outputs import differing_fields

            raise ValueError(f"{partial} belongs to another evaluation ({differing_fields(old, header)}); rerun "
                             "that command to finish it, remove the file, or choose another --out")
        for ln in lines[1:]:
            try:
                rec = json.loads(ln)
            except json.JSONDecodeError:  # a line cut by an interruption: that episode reruns
                continue
            done[rec["scenario_id"]] = rec
    else:
        out.parent.mkdir(parents=True, exist_ok=True)  # the CLI checked that at most this one level is new
        partial.write_text(json.dumps(header) + "\n")
    todo = [s for s in suite.scenarios if s.scenario_id not in done]
    from ..progress import progress_bar

    if todo:
        warm_up(env_kwargs)  # before the bar (and before forking workers, which inherit the compiled code)

    bar = progress_bar(len(suite.scenarios), len(done), f"{agent.name} on {suite.name}", progress)
    per = chunk_size(len(todo), batch_size, workers)
    chunks = [todo[i:i + per] for i in range(0, len(todo), per)]
    tasks = [(spec, [s.to_dict() for s in c], env_kwargs, suite.name, seed_offset, batch_size) for c in chunks]

    def record(i, recs):
        with partial.open("a") as fh:
            for rec in recs:
                fh.write(json.dumps(rec) + "\n")
                done[rec["scenario_id"]] = rec
        in_flight.pop(i, None)  # this chunk now counts as done; the others as far as they got
        bar.set_done(len(done) + sum(in_flight.values()))

    in_flight: dict[int, float] = {}

    def advance(i, x):
        in_flight[i] = in_flight.get(i, 0.0) + x
        bar.advance(x)

    try:
        run_tasks(backend, evaluate_chunk, tasks, on_result=record, on_progress=advance)
    finally:
        bar.close()
    episodes = [done[s.scenario_id] for s in suite.scenarios]
    result = dict(header)
    result.update(package_version=__version__, n_scenarios=len(episodes), metrics=compute_metrics(episodes),
                  episodes=episodes)
    tmp = out.with_name(out.name + ".tmp")
    if out.suffix == ".parquet":
        from .records import write_results_parquet

        write_results_parquet(tmp, result)
    else:
        tmp.write_text(json.dumps(result, separators=(",", ":")) + "\n")  # compact: episodes hold traces
    os.replace(tmp, out)
    partial.unlink()
    return result
