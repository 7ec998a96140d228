"""``marine-fdi sweep``: every agent on every suite (and seed offset), on any backend, resumably.

    marine-fdi sweep --agents reference classifier --suites thesis-v1 single-v1 [--seed-offsets 0 1]
                     --backend ray --out DIR

The grid's episodes run as chunks (one suite, one seed offset, up to ``--batch-size`` episodes,
every agent) on the backend, all at once, so a cluster is kept busy: a chunk's episodes are
simulated once and every agent is scored on them in lockstep (:mod:`.evaluate`, :mod:`.lockstep`).
With ``--cache write`` the suites' trajectories are kept as feature caches, and later sweeps and
evaluations (``--cache use``, the default) score agents on them without simulating
(:mod:`.feature_cache`).  Every finished chunk's episode records are appended to
``DIR/sweep.partial.jsonl`` at once: an interrupted sweep (Ctrl-C, a lost node, a killed job)
loses only the chunks in flight and the same command resumes it.  When the grid is complete the
command writes

* ``DIR/episodes.parquet``: one row per episode (:mod:`.records`; with the columns
  ``agent_spec`` and ``seed_offset``), every cell of this sweep and of earlier complete sweeps
  into the same folder;
* ``DIR/metrics.json``: the metrics (:mod:`.metrics`) per agent x suite, pooled over the seed
  offsets, and ``DIR/metrics.md``, the same as a Markdown table;
* ``DIR/sweep.json``: how this run went (backend, workers, wall time, load average before and
  after, episodes run by this invocation, the feature caches read and written).

``marine-fdi report DIR`` reads the table.  ``--agents all`` is every named agent
(``marine-fdi agents``), ``--suites all`` every shipped suite.  Results are those of ``marine-fdi
evaluate`` for each cell, bit for bit except the wall-clock ``compute_s`` (tested).
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np

from .._version import __version__
from .backends import Backend, chunk_size, run_tasks_counted
from .evaluate import cached_agent, chunk_tasks, evaluate_chunk, suite_caches, suite_env_kwargs
from .records import sweep_results  # noqa: F401 - part of this module's API
from .suites import SUITE_NAMES, load_suite

__all__ = ["run_sweep", "sweep_results", "kept_episodes"]

PARTIAL = "sweep.partial.jsonl"
TABLE = "episodes.parquet"


def _expand_agents(agents: list[str]) -> list[str]:
    from .agent_registry import list_agents

    out: list[str] = []
    for a in agents:
        for x in [e.name for e in list_agents()] if a == "all" else [a]:
            if x not in out:
                out.append(x)
    return out


def _expand_suites(suites: list[str]) -> list[str]:
    out: list[str] = []
    for s in suites:
        for x in SUITE_NAMES if s == "all" else [s]:
            if x not in out:
                out.append(x)
    return out


def _key(rec: dict) -> tuple:
    return (rec["agent_spec"], rec["suite"], int(rec["seed_offset"]), rec["scenario_id"])


def kept_episodes(out_dir: "str | Path") -> int:
    """Episode records an unfinished sweep in ``out_dir`` holds (a rerun does not redo them)."""
    try:
        lines = (Path(out_dir) / PARTIAL).read_text().splitlines()
    except OSError:
        return 0
    n = 0
    for ln in lines[1:]:  # the first line is the grid
        try:
            json.loads(ln)
            n += 1
        except json.JSONDecodeError:
            pass
    return n


def _load_partial(path: Path, header: dict) -> dict[tuple, dict]:
    lines = path.read_text().splitlines()
    try:
        old = json.loads(lines[0]) if lines else None
    except json.JSONDecodeError:
        old = None
    if old is None or old.get("grid") != header["grid"]:
        from ..outputs import differing_fields

        what = differing_fields((old or {}).get("grid"), header["grid"], "grid" if old is None else "")
        raise ValueError(
            f"{path} belongs to another sweep ({what}); rerun that command to finish it, or remove the file"
        )
    done = {}
    for ln in lines[1:]:
        try:
            rec = json.loads(ln)
        except json.JSONDecodeError:  # a line cut by an interruption: that episode reruns
            continue
        done[_key(rec)] = rec
    return done


def run_sweep(
    agents: list[str],
    suites: list[str],
    seed_offsets: list[int],
    out_dir: "str | Path",
    *,
    backend: Backend | None = None,
    batch_size: int = 32,
    progress: bool = True,
    cache: str = "off",
    cache_dir=None,
) -> dict:
    """Run (or resume, or extend) a sweep into ``out_dir``; returns the contents of metrics.json.

    ``cache``: ``use`` (score on the suites' feature caches in ``cache_dir`` where there are),
    ``write`` (simulate and write them) or ``off`` (:mod:`.feature_cache`)."""
    from ..progress import progress_bar
    from .records import read_records, write_records

    backend = backend or Backend()
    if not isinstance(batch_size, int) or batch_size < 1:
        raise ValueError(f"--batch-size must be a positive integer, got {batch_size!r}")
    agents, suites = _expand_agents(list(agents)), _expand_suites(list(suites))
    offsets = list(dict.fromkeys(int(k) for k in seed_offsets))
    if not agents or not suites or not offsets:
        raise ValueError("a sweep needs at least one agent, one suite and one seed offset")
    from .agent_api import resolve_agent_spec

    specs = {a: resolve_agent_spec(a) for a in agents}
    loaded = {a: cached_agent(specs[a]) for a in agents}  # fail early on a bad agent
    suite_objs = {s: load_suite(s) for s in suites}
    out_dir = Path(out_dir)
    header = {"kind": "marine-fdi sweep", "grid": {"agents": agents, "suites": suites, "seed_offsets": offsets}}
    out_dir.mkdir(parents=True, exist_ok=True)
    partial, table = out_dir / PARTIAL, out_dir / TABLE

    earlier: dict[tuple, dict] = {}
    if table.exists():
        recs, _ = read_records(table, keep_extra=True)
        earlier = {_key(r): r for r in recs}
    if partial.exists():
        done = _load_partial(partial, header)
    else:
        partial.write_text(json.dumps(header) + "\n")
        done = {}
    cells = [(a, s, k) for a in agents for s in suites for k in offsets]
    for a, s, k in cells:  # a complete cell of an earlier sweep in this folder is reused
        keys = [(a, suite_objs[s].name, k, sc.scenario_id) for sc in suite_objs[s].scenarios]
        if all(key in earlier for key in keys):
            for key in keys:
                done.setdefault(key, earlier[key])
    total = sum(len(suite_objs[s].scenarios) for _, s, _ in cells)
    # one task per chunk of a suite and seed offset, with every agent that misses one of its episodes
    tasks, plan, all_caches = [], [], []
    for s in suites:
        suite = suite_objs[s]
        env_kwargs = suite_env_kwargs(suite)[0]
        for k in offsets:
            caches = suite_caches(cache, cache_dir, suite, k, [loaded[a] for a in agents], env_kwargs)
            all_caches += caches.values()
            lacks = np.array(
                [[(a, suite.name, k, sc.scenario_id) not in done for a in agents] for sc in suite.scenarios], dtype=bool
            ).reshape(len(suite.scenarios), len(agents))
            need = lacks.any(axis=1)
            for c in caches.values():
                need[c.missing()] = True  # episodes a feature cache being written has no trajectory of
            todo = np.flatnonzero(need)
            for idx, given in chunk_tasks(caches, todo, chunk_size(len(todo), batch_size, backend.workers)):
                run = [a for a, m in zip(agents, lacks[idx].any(axis=0)) if m] or agents
                tasks.append(
                    (
                        [specs[a] for a in run],
                        [suite.scenarios[i].to_dict() for i in idx],
                        env_kwargs,
                        suite.name,
                        k,
                        batch_size,
                        given or None,
                        any(c.keep for c in caches.values()),
                        cache == "write",
                    )
                )
                plan.append((run, k, idx, caches))
    n_before = len(done)
    if tasks and not (all_caches and all(c.trajectory is not None for c in all_caches)):
        from .evaluate import warm_up

        warm_up(tasks[0][2])  # compile a cold cache once, here, before the bar and the workers
    bar = progress_bar(total, n_before, "sweep", progress)

    def keep(i, res):
        run, k, idx, caches = plan[i]
        for key, traj in res["trajectories"].items():
            caches[key].store(idx, traj)  # before the records: kept records always have their trajectory
        with partial.open("a") as fh:
            for a, recs in zip(run, res["records"]):
                for rec in recs:
                    rec = dict(rec, agent_spec=a, seed_offset=k)
                    fh.write(json.dumps(rec) + "\n")
                    done[_key(rec)] = rec

    load0, t0 = os.getloadavg(), time.perf_counter()
    run_tasks_counted(backend, evaluate_chunk, tasks, bar=bar, on_result=keep, settled=lambda: len(done))
    wall = time.perf_counter() - t0
    load1 = os.getloadavg()
    read = sorted({str(c.path) for c in all_caches if c.trajectory is not None})
    written = [str(p) for p in (c.finish() for c in all_caches) if p is not None]

    # the table: this grid in grid order, then the other cells of earlier sweeps in this folder
    grid_keys = [(a, suite_objs[s].name, k, sc.scenario_id) for a, s, k in cells for sc in suite_objs[s].scenarios]
    records = [done[key] for key in grid_keys]
    in_grid = set(grid_keys)
    records += [r for key, r in earlier.items() if key not in in_grid]
    info = {
        "kind": "marine-fdi sweep",
        "package_version": __version__,
        "grid": header["grid"],
        "suites": {o.name: {"version": o["version"], "env": o["env"]} for o in suite_objs.values()},
    }
    tmp = table.with_name(TABLE + ".tmp")
    write_records(tmp, records, info, extra=("agent_spec", "seed_offset"))
    os.replace(tmp, table)
    results = sweep_results(records)
    metrics = {"sweep": info, "results": [{k: v for k, v in r.items() if k != "episodes"} for r in results]}
    (out_dir / "metrics.json").write_text(json.dumps(metrics, indent=1) + "\n")
    from .report import markdown_table

    (out_dir / "metrics.md").write_text(markdown_table(results))
    run = {
        "backend": backend.name,
        "workers": backend.workers,
        "ray_address": backend.ray_address,
        "batch_size": batch_size,
        "wall_s": wall,
        "episodes_run": len(done) - n_before,
        "episodes_resumed": n_before,
        "load_average_before": list(load0),
        "load_average_after": list(load1),
        "cpu_count": os.cpu_count(),
        "agents": {a: loaded[a].name for a in agents},
        "cache": cache,
        "caches_read": read,
        "caches_written": written,
    }
    (out_dir / "sweep.json").write_text(json.dumps(run, indent=1) + "\n")
    partial.unlink()
    metrics["run"] = run
    metrics["table"] = results
    return metrics
