"""``marine-fdi evaluate``: run agents on a frozen suite and score them.

**Simulate once, score every agent.**  An agent's declarations change only its reward and its
declaration trace, never the engines, the sensors, the observation features or the diagnosers'
conclusions.  So the episodes of a batch are simulated once
(:func:`~marine_fdi_env.envs.trajectory.simulate`) and every agent asked for is stepped on that
batch in lockstep (:mod:`.lockstep`), seeing exactly what the vector environment shows it alone
(tested bit for bit, for every shipped agent on every shipped suite).  Agents that ask for
observation options (``env_kwargs``: ``observe_sequential`` for ``sequential``, ``observe_sensors``)
or for another cell set of the diagnosers (``diagnosis_cells``: ``reference-thesis``, ...) share
one pass that computes the union of the options and decides with every cell set asked for, and
each gets its own columns and conclusions; an agent asking for other environment arguments gets a
pass of its own (:func:`plan_passes`).  A suite's
trajectories can be kept as a feature cache and scored again without simulating
(:mod:`.feature_cache`, ``--cache``).

Episodes run in batches (all episodes of a suite have the same length, so a batch starts and ends
together; an episode ended early by an engine failure is simply left).  Every finished chunk's
episode records are appended at once to ``OUT.partial.jsonl`` (one per agent), so an interrupted
run resumes where it stopped and loses nothing; when all are done the results file ``OUT`` (the
suite's episodes in suite order, the metrics of :mod:`.metrics` and the DX 2025 metrics per decision,
``dx_metrics``) is written and the partial
log removed.

Reproducibility: the numbers of an episode depend only on its scenario, the seed offset and the
agent (never on the batch size, the number of workers, the other agents scored with it or whether
it came from a cache, since engines are independent); the agent's own randomness is seeded per
episode from the scenario id and the seed offset.  Only the wall-clock fields (``compute_s``) vary
from run to run.

``compute_s`` of an episode = the time spent making its observations (``feature_compute_s``: the
residual generators, shared by every agent of the pass; from a cache, the time they took when it
was made) + its share of the agent's ``act`` time (``agent_compute_s``; ``n_decisions``).  Every
process warms up first (:func:`warm_up`: one throw-away episode of one engine), so numba's
compilation of a cold cache (about a minute) or its cache loading never counts.  Both depend on
the batch size (``--batch-size``, default 32).

Backends (``--backend serial|process|ray``, :mod:`.backends`): the suite is cut into chunks of at
most ``batch_size`` episodes, one task each with every agent; results, every metric and every
episode record except the wall-clock fields, are the same bit for bit whichever backend and number
of workers run them (tested).  ``--out`` ending in ``.parquet`` writes the episode records as a
Parquet table (:mod:`.records`) with the header and metrics in its metadata instead of JSON.

Reward: the results record the environment id and reward they score (``env_id``, ``env.reward``):
the suite's ``env.reward`` if it fixes one, else ``--reward`` (default ``v1``).  The reward
changes the ``return`` of an episode, never a metric.  A suite whose scenarios use another sensor
noise scale than 1 (``transfer-v2``) runs them in batches of equal noise scale.
"""

from __future__ import annotations

import inspect
import json
import os
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from .._version import __version__
from ..diagnosis.cell_sets import CELL_SETS, DEFAULT_CELLS
from ..envs.fdi_env import env_id_for
from ..envs.reward import make_reward_config
from ..envs.scenario_sampler import ScenarioSpec
from ..envs.trajectory import Trajectory, assemble, cell_sets_of, one_cell_set, simulate
from ..envs.vector import MarineFDIVectorEnv
from ..jsonfile import json_safe
from .agent_api import load_agent, resolve_agent_spec
from .backends import Backend, chunk_size, run_tasks_counted
from .lockstep import agent_view, episode_seed, score_agents
from .metrics import metric_blocks
from .suites import load_suite

__all__ = [
    "offset_scenario",
    "run_episodes",
    "run_agents",
    "evaluate",
    "evaluate_agents",
    "episode_seed",
    "evaluate_chunk",
    "suite_env_kwargs",
    "plan_passes",
    "Pass",
    "suite_caches",
    "WALL_CLOCK_FIELDS",
    "WALL_CLOCK_METRICS",
]

# the fields of an episode record that are wall-clock measurements (everything else reproduces)
WALL_CLOCK_FIELDS = ("compute_s", "feature_compute_s", "agent_compute_s")
# the metrics computed from them
WALL_CLOCK_METRICS = ("compute_s_per_sample", "feature_compute_s_per_sample", "agent_compute_s_per_decision")
# environment options that only add observation columns or infos: one pass computes their union
OBSERVATION_OPTIONS = ("observe_sensors", "observe_sequential")
# the option that only changes the diagnosers' conclusions: one pass decides with every cell set asked for
CELLS_OPTION = "diagnosis_cells"
_SHARED_OPTIONS = OBSERVATION_OPTIONS + (CELLS_OPTION,)
_SIMULATION_SHARE = 0.8  # of a chunk's progress when it simulates (the rest is scoring)

_MAX_SEED = 2**63 - 1


def offset_scenario(sc: ScenarioSpec, seed_offset: int) -> ScenarioSpec:
    """``sc`` with its noise seed shifted by ``seed_offset`` (new noise, the same scenario); ``sc`` itself at 0."""
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
    venv = MarineFDIVectorEnv(num_envs=1, **one_cell_set(dict(env_kwargs or {})))
    venv.reset(options={"scenarios": [sc]})
    venv.step(np.zeros((1, venv.single_action_space.shape[0]), dtype=np.float32))
    venv.close()
    _WARM["done"] = True


# ----------------------------------------------------------------------------- passes
@dataclass(frozen=True)
class Pass:
    """One simulation for a group of agents: the environment it runs (``env_kwargs``, with the union
    of their observation options and the list of their cell sets, or every option and cell set for
    a feature cache), the agents (indices) and the environment each would be made with alone."""

    key: str
    env_kwargs: dict
    agents: tuple[int, ...]
    agent_env: tuple[dict, ...]


# the vector environment's own defaults: an option given at its default value makes the same simulation as one
# left out (the reference agent asks for the default cell set, the null agent for nothing: one pass serves both)
_ENV_DEFAULTS = {
    k: p.default
    for k, p in inspect.signature(MarineFDIVectorEnv.__init__).parameters.items()
    if p.default is not inspect.Parameter.empty
}


def _is_default(option: str, value) -> bool:
    return option in _ENV_DEFAULTS and _ENV_DEFAULTS[option] == value


def _key(env_kwargs: dict) -> str:
    return json.dumps(
        {
            k: json_safe(v, nonfinite="keep")
            for k, v in env_kwargs.items()
            if k not in _SHARED_OPTIONS and not _is_default(k, v)
        },
        sort_keys=True,
        default=repr,
    )


def plan_passes(agents: list, env_kwargs: dict, all_options: bool = False) -> list[Pass]:
    """The passes that serve ``agents`` on an environment made with ``env_kwargs`` (each agent's
    ``env_kwargs`` attribute added); ``all_options``: every pass computes every observation option
    and decides with every cell set.  A pass's ``diagnosis_cells`` lists its cell sets (in
    ``CELL_SETS`` order), left out when only the default is asked for."""
    groups: dict[str, list[tuple[int, dict]]] = {}
    for j, a in enumerate(agents):
        kw = dict(env_kwargs)
        kw.update(getattr(a, "env_kwargs", {}))  # options the agent needs (e.g. observe_sequential)
        groups.setdefault(_key(kw), []).append((j, kw))
    out = []
    for key, members in groups.items():
        kw = {k: v for k, v in members[0][1].items() if k not in _SHARED_OPTIONS and not _is_default(k, v)}
        for opt in OBSERVATION_OPTIONS:
            if all_options or any(m.get(opt, False) for _, m in members):
                kw[opt] = True
            elif any(opt in m for _, m in members):
                kw[opt] = False
        wanted = {c for _, m in members for c in cell_sets_of(m)}
        cells = [c for c in CELL_SETS if all_options or c in wanted]
        if cells != [DEFAULT_CELLS]:
            kw[CELLS_OPTION] = cells
        out.append(Pass(key, kw, tuple(j for j, _ in members), tuple(m for _, m in members)))
    return out


def run_agents(
    agents: list,
    scenarios: list[ScenarioSpec],
    env_kwargs: dict | None = None,
    *,
    suite: str = "",
    seed_offset: int = 0,
    batch_size: int = 32,
    trajectories: dict | None = None,
    keep: bool = False,
    all_options: bool = False,
    progress=None,
    on_decision=None,
) -> tuple[list[list[dict]], dict]:
    """Run every agent on every scenario, simulating each batch once per pass.

    Returns the episode records (one list per agent, scenario order) and, with ``keep``, the
    trajectories of the scenarios ``{pass key: Trajectory}``.  ``trajectories`` (``{pass key:
    Trajectory}`` of exactly these scenarios, seed offset applied, e.g. from a feature cache)
    replaces the simulation of those passes.  ``progress(x)`` reports episodes' worth of work
    (fractions); ``on_decision(agent, scenario_id, t_s, belief, compute_s)`` every decision.
    """
    env_kwargs = dict(env_kwargs or {})
    passes = plan_passes(agents, env_kwargs, all_options)
    records: list[list] = [[None] * len(scenarios) for _ in agents]
    made: dict[str, Trajectory] = {}
    groups: dict[float, list[int]] = {}  # one batched engine set per sensor-noise scale
    for i, s in enumerate(scenarios):
        groups.setdefault(float(s.noise_scale), []).append(i)
    batches = [
        np.asarray(idx[a : a + batch_size], dtype=np.int64)
        for idx in groups.values()
        for a in range(0, len(idx), batch_size)
    ]
    for p in passes:
        given = (trajectories or {}).get(p.key)
        share = 0.0 if given is not None else _SIMULATION_SHARE
        sim_cb = None if progress is None else (lambda x, w=share / len(passes): progress(x * w))
        score_cb = None if progress is None else (lambda x, w=(1.0 - share) / len(passes): progress(x * w))
        mine = [agents[j] for j in p.agents]
        reward = make_reward_config(p.env_kwargs.get("reward"))
        if given is None:
            warm_up(p.env_kwargs)  # compile time stays out of compute_s
        parts = []
        for idx in batches:
            if given is not None:
                traj = given.take(idx)
            else:
                traj = simulate(
                    [offset_scenario(scenarios[i], seed_offset) for i in idx], p.env_kwargs, progress=sim_cb
                )
            views = [agent_view(kw, traj) for kw in p.agent_env]
            cb = None if on_decision is None else (lambda j, *a, p=p: on_decision(p.agents[j], *a))
            for j, recs in zip(
                p.agents,
                score_agents(
                    mine, views, traj, reward, suite=suite, seed_offset=seed_offset, progress=score_cb, on_decision=cb
                ),
            ):
                for i, rec in zip(idx, recs):
                    records[j][i] = rec
            if keep:
                parts.append((idx, traj))
        if keep:
            made[p.key] = assemble(parts)
    return records, made


def run_episodes(
    agent,
    scenarios: list[ScenarioSpec],
    env_kwargs: dict | None = None,
    *,
    suite: str = "",
    seed_offset: int = 0,
    batch_size: int = 32,
    progress=None,
    on_decision=None,
) -> list[dict]:
    """Run ``agent`` on every scenario; returns the episode records (scenario order).

    ``progress(x)`` after every decision with the episodes' worth of work done since the last call
    (fractions); ``on_decision(scenario_id, t_s, belief, compute_s)`` for every decision of every
    episode (the belief vector the agent declared at decision time ``t_s`` and the time spent on
    this decision: its observation and its share of the agent's ``act``).
    """
    cb = None if on_decision is None else (lambda j, *a: on_decision(*a))
    records, _ = run_agents(
        [agent],
        scenarios,
        env_kwargs,
        suite=suite,
        seed_offset=seed_offset,
        batch_size=batch_size,
        progress=progress,
        on_decision=cb,
    )
    return records[0]


# ----------------------------------------------------------------------------- tasks
_AGENTS: dict[tuple, object] = {}  # agents loaded in this process (workers reuse theirs across tasks)


def _spec_stamp(spec: str) -> float:
    """The newest modification time of the files a spec loads (0 for names): a retrained model
    folder or an edited agent file is loaded anew."""
    from .agent_api import split_file_spec

    fs = split_file_spec(str(spec))
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


def evaluate_chunk(
    agent_specs: list[str],
    scenarios_dicts: list[dict],
    env_kwargs: dict,
    suite: str,
    seed_offset: int,
    batch_size: int,
    trajectories: dict | None = None,
    keep: bool = False,
    all_options: bool = False,
    progress=None,
) -> dict:
    """One task of a backend: every agent on a chunk of scenarios (given as dicts).

    Returns ``{"records": [records of each agent], "trajectories": {pass key: Trajectory}}`` (the
    trajectories with ``keep`` only).  ``progress`` counts episodes of all agents together."""
    agents = [cached_agent(s) for s in agent_specs]
    scs = [ScenarioSpec.from_dict(d) for d in scenarios_dicts]
    cb = None if progress is None else (lambda x, k=len(agents): progress(x * k))
    records, made = run_agents(
        agents,
        scs,
        env_kwargs,
        suite=suite,
        seed_offset=seed_offset,
        batch_size=batch_size,
        trajectories=trajectories,
        keep=keep,
        all_options=all_options,
        progress=cb,
    )
    return {"records": records, "trajectories": made}


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


def suite_caches(mode: str, cache_dir, suite, seed_offset: int, agents: list, env_kwargs: dict) -> dict:
    """The feature caches (:class:`~.feature_cache.SuiteCache`, by pass key) of ``agents`` on a suite
    and seed offset; none with ``mode`` ``off``.  A cache holds every observation option, so its
    parameters are those of a pass with all of them."""
    if mode == "off":
        return {}
    from .feature_cache import SuiteCache, cache_header

    scs = [offset_scenario(s, seed_offset) for s in suite.scenarios]
    return {
        p.key: SuiteCache(mode, cache_dir, cache_header(suite.name, suite["version"], seed_offset, p.env_kwargs, scs))
        for p in plan_passes(agents, env_kwargs, all_options=True)
    }


def chunk_tasks(caches: dict, todo_idx: np.ndarray, per: int) -> list[tuple[np.ndarray, dict]]:
    """The chunks of ``todo_idx`` (suite indices) and the cached trajectories each replays."""
    out = []
    for a in range(0, len(todo_idx), per):
        idx = todo_idx[a : a + per]
        out.append((idx, {k: c.trajectory.take(idx) for k, c in caches.items() if c.trajectory is not None}))
    return out


# ----------------------------------------------------------------------------- evaluate
def _open_partial(partial: Path, header: dict) -> dict[str, dict]:
    """The records kept in a partial log of this evaluation (a new log is started)."""
    done: dict[str, dict] = {}
    if not partial.exists():
        partial.parent.mkdir(parents=True, exist_ok=True)  # the CLI checked that at most this one level is new
        partial.write_text(json.dumps(header) + "\n")
        return done
    lines = partial.read_text().splitlines()
    try:
        old = json.loads(lines[0]) if lines else None
    except json.JSONDecodeError:
        old = None
    if old != header:
        from ..outputs import differing_fields

        raise ValueError(
            f"{partial} belongs to another evaluation ({differing_fields(old, header)}); rerun "
            "that command to finish it, remove the file, or choose another --out"
        )
    for ln in lines[1:]:
        try:
            rec = json.loads(ln)
        except json.JSONDecodeError:  # a line cut by an interruption: that episode reruns
            continue
        done[rec["scenario_id"]] = rec
    return done


def evaluate_agents(
    agent_specs: list[str],
    suite_name: str,
    outs: list[Path],
    *,
    workers: int = 1,
    seed_offset: int = 0,
    batch_size: int = 32,
    progress: bool = True,
    backend: "Backend | str | None" = None,
    ray_address: str | None = None,
    reward: "str | dict | None" = None,
    cache: str = "off",
    cache_dir=None,
) -> list[dict]:
    """Evaluate several agents on a suite in one pass over its episodes, resumably; returns the
    results object written to each ``outs[j]`` (as :func:`evaluate` writes it for one agent).

    ``backend``: a :class:`~.backends.Backend` or its name (default: ``process`` if
    ``workers > 1``, else ``serial``).  ``reward``: the reward to score (``v0``, ``v1`` or a config
    dict); default: the suite's ``env.reward``, else ``v1``.  A suite that fixes its reward refuses
    another one.  ``cache``: ``use`` (replay the suite's feature cache in ``cache_dir`` when there is one),
    ``write`` (simulate and write it) or ``off`` (:mod:`.feature_cache`)."""
    if not isinstance(backend, Backend):
        backend = Backend.make(backend, workers, ray_address)
    if not isinstance(batch_size, int) or batch_size < 1:
        raise ValueError(f"--batch-size must be a positive integer, got {batch_size!r}")
    if len(agent_specs) != len(outs) or not agent_specs:
        raise ValueError("evaluate_agents needs one output file per agent, and at least one agent")
    suite = load_suite(suite_name)
    specs = [resolve_agent_spec(a) for a in agent_specs]  # names stay names, paths become absolute
    if len(set(specs)) != len(specs) or len({Path(o).resolve() for o in outs}) != len(outs):
        raise ValueError("evaluate_agents: each agent and each output file once")
    agents = [cached_agent(s) for s in specs]  # fail early on a bad agent
    env_kwargs, reward_cfg = suite_env_kwargs(suite, reward)
    caches = suite_caches(cache, cache_dir, suite, seed_offset, agents, env_kwargs)
    outs = [Path(o) for o in outs]
    headers, partials, done = [], [], []
    for a, spec, out in zip(agents, agent_specs, outs):
        kw = dict(env_kwargs)
        kw.update(getattr(a, "env_kwargs", {}))  # options the agent needs (e.g. observe_sequential)
        header = {
            "agent": a.name,
            "agent_spec": str(spec),
            "suite": suite.name,
            "suite_version": suite["version"],
            "seed_offset": int(seed_offset),
            "env_id": env_id_for(reward_cfg),
            "env": kw,
        }
        if getattr(a, "training_seed", None) is not None:  # a learned agent: which of its trainings this is
            header["training_seed"] = int(a.training_seed)
        partial = out.with_name(out.name + ".partial.jsonl")
        done.append(_open_partial(partial, header))
        headers.append(header)
        partials.append(partial)
    ids = [s.scenario_id for s in suite.scenarios]
    need = np.array([any(i not in d for d in done) for i in ids], dtype=bool)
    for c in caches.values():
        need[c.missing()] = True  # episodes a feature cache being written has no trajectory of
    todo = np.flatnonzero(need)
    from ..progress import progress_bar

    if len(todo) and not (caches and all(c.trajectory is not None for c in caches.values())):
        warm_up(env_kwargs)  # before the bar (and before forking workers, which inherit the compiled code)
    n_done = len(ids) - len(todo)
    name = agents[0].name if len(agents) == 1 else f"{len(agents)} agents"
    bar = progress_bar(len(ids), n_done, f"{name} on {suite.name}", progress)
    chunks = chunk_tasks(caches, todo, chunk_size(len(todo), batch_size, backend.workers))
    keep = any(c.keep for c in caches.values())
    tasks = [
        (
            specs,
            [suite.scenarios[i].to_dict() for i in idx],
            env_kwargs,
            suite.name,
            seed_offset,
            batch_size,
            given or None,
            keep,
            cache == "write",
        )
        for idx, given in chunks
    ]
    finished = [0]

    def record(i, res):
        idx = chunks[i][0]
        for key, traj in res["trajectories"].items():
            caches[key].store(idx, traj)  # before the records: kept records always have their trajectory
        for j, recs in enumerate(res["records"]):
            with partials[j].open("a") as fh:
                for rec in recs:
                    fh.write(json.dumps(rec) + "\n")
                    done[j][rec["scenario_id"]] = rec
        finished[0] += len(idx)

    run_tasks_counted(
        backend,
        evaluate_chunk,
        tasks,
        bar=bar,
        on_result=record,
        settled=lambda: n_done + finished[0],
        per_episode=len(agents),
    )
    used = {k: str(c.path) for k, c in caches.items() if c.trajectory is not None}
    for c in caches.values():
        c.finish()
    results = []
    for header, partial, out, d in zip(headers, partials, outs, done):
        episodes = [d[i] for i in ids]
        result = dict(header)
        result.update(
            package_version=__version__,
            n_scenarios=len(episodes),
            **metric_blocks(episodes),
            episodes=episodes,
        )
        if used:
            result["feature_cache"] = sorted(used.values())
        tmp = out.with_name(out.name + ".tmp")
        if out.suffix == ".parquet":
            from .records import write_results_parquet

            write_results_parquet(tmp, result)
        else:
            tmp.write_text(json.dumps(result, separators=(",", ":")) + "\n")  # compact: episodes hold traces
        os.replace(tmp, out)
        partial.unlink()
        results.append(result)
    return results


def evaluate(agent_spec: str, suite_name: str, out: Path, **options) -> dict:
    """Evaluate an agent on a suite, resumably; returns the results object written to ``out``.

    ``options``: the keyword options of :func:`evaluate_agents` (``workers``, ``seed_offset``, ``batch_size``,
    ``progress``, ``backend``, ``ray_address``, ``reward``, ``cache``, ``cache_dir``).
    """
    return evaluate_agents([agent_spec], suite_name, [out], **options)[0]
