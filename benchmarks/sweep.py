"""The benchmark table's cost: one agent, every agent, every suite, and a new agent on a cache.

    python benchmarks/sweep.py --json                  # about 3 minutes on 2 idle cores
    python benchmarks/sweep.py --json --skip-full      # without the full sweep

Runs the real commands (``marine-fdi ...`` in a subprocess each, in a temporary folder; numba's
cache is warmed first so no compilation is timed) in one run, so ratios compare runs under the
same load, and prints one JSON object (wall times in seconds; ``cpu_s``: CPU time of the command
and its worker processes; ``load_*``: the 1-minute load average before and after each command,
from ``os.getloadavg``):

``one_agent_s``        ``marine-fdi evaluate --agent reference --suite single-v1 --workers W --cache off``
``every_agent_s``      ``marine-fdi sweep --agents all --suites single-v1 --workers W --cache off``
``every_over_one``     their ratio (the issue's target: <= 2)
``full_sweep_s``       ``marine-fdi sweep --agents all --suites all --workers W --cache off`` (target <= 120 s)
``cache_write_s``      ``marine-fdi evaluate --agent null --suite single-v1 --workers W --cache write``
``new_agent_cached_s`` ``marine-fdi evaluate --agent docs/examples/fired_modules_agent.py:FiredModulesAgent
                       --suite single-v1`` on that cache (an agent no other command ran; target <= 10 s)
``eight_over_one``     with ``--marginal``: ``marine-fdi sweep --agents EIGHT --suites single-v1`` over one agent,
                       EIGHT the agents registered when the 2x target was set (:data:`EIGHT`)
``marginal``           with ``--marginal``: per agent registered since, the CPU and wall seconds it adds to the
                       eight on single-v1 (``sweep --agents EIGHT AGENT`` minus ``sweep --agents EIGHT``)

With ``--repeats R`` the one/every pair runs R times, alternating (``every_over_one`` is the median
ratio).  ``episodes``: the episodes each command scored (agent x episode).  Load from other jobs on
a shared machine slows every number; compare ratios within one run.

``--other-src DIR`` also runs the one/every pair with another version of the package, alternating
with this one (``other_*``; e.g. ``mkdir -p /tmp/before && git archive ca28256 src | tar -x -C
/tmp/before`` and ``--other-src /tmp/before/src``; that version is given no ``--cache`` option).  For
that version's own agents too, archive ``training`` and ``baselines`` with ``src`` and move them into
``/tmp/before/src/marine_fdi_env/`` (otherwise the installed ones are imported).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from _report import emit  # noqa: E402  (benchmarks/ is the script directory)

ROOT = Path(__file__).resolve().parents[1]
# the agents registered when the "every agent <= 2x one agent" target was set
EIGHT = ("null", "random", "reference", "sequential", "ppo-v1", "classifier-v1", "classifier-v1+reference", "oracle")
NEW_AGENT = f"{ROOT / 'docs' / 'examples' / 'fired_modules_agent.py'}:FiredModulesAgent"


def _run(args: list[str], cwd: Path, src: Path | None = None) -> dict:
    """Wall time and load of one ``marine-fdi`` command (it must succeed); ``src``: run that version
    of the package (without ``--cache`` options)."""
    env = dict(os.environ)
    if src is not None:
        env["PYTHONPATH"] = os.pathsep.join([str(src)] + [p for p in [env.get("PYTHONPATH")] if p])
        args = [a for i, a in enumerate(args) if a != "--cache" and (i == 0 or args[i - 1] != "--cache")]
    load0 = os.getloadavg()[0]
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-m", "marine_fdi_env.cli", *args, "--no-progress"],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
    )
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if proc.returncode != 0:
        raise SystemExit(f"marine-fdi {' '.join(args)} failed:\n{proc.stderr}")
    cpu = (r1.ru_utime + r1.ru_stime) - (r0.ru_utime + r0.ru_stime)
    return {
        "wall_s": round(wall, 2),
        "cpu_s": round(cpu, 2),
        "load_before": round(load0, 2),
        "load_after": round(os.getloadavg()[0], 2),
    }


def _marginal(tmp: Path, w: list[str], one_s: float) -> dict:
    """The eight agents of the 2x target on single-v1, and what each later agent adds to them."""
    from marine_fdi_env.benchmark.agent_registry import list_agents

    def sweep(agents, out):
        return _run(["sweep", "--agents", *agents, "--suites", "single-v1", "--out", out, "--cache", "off", *w], tmp)

    eight = sweep(EIGHT, "eight")
    later = [e.name for e in list_agents() if e.available and e.name not in EIGHT]
    marginal = {}
    for k, name in enumerate(later):
        r = sweep((*EIGHT, name), f"eight_plus_{k}")
        marginal[name] = {
            "cpu_s": round(r["cpu_s"] - eight["cpu_s"], 2),
            "wall_s": round(r["wall_s"] - eight["wall_s"], 2),
            "load_before": r["load_before"],
        }
    return {"eight_agents": eight, "eight_over_one": round(eight["wall_s"] / one_s, 2), "marginal": marginal}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=1, help="runs of the one-agent / every-agent pair")
    ap.add_argument("--skip-full", action="store_true", help="leave out the full sweep")
    ap.add_argument(
        "--marginal",
        action="store_true",
        help="also the eight agents of the 2x target over one agent, and each later agent's marginal cost",
    )
    ap.add_argument("--keep", type=Path, default=None, help="run in this folder and keep it (default: a temporary one)")
    ap.add_argument(
        "--other-src",
        type=Path,
        default=None,
        metavar="DIR",
        help="also time the one/every pair with the package in DIR (another version), alternating",
    )
    args = ap.parse_args(argv)
    w = ["--workers", str(args.workers)]
    tmp = args.keep or Path(tempfile.mkdtemp(prefix="marine-fdi-sweep-bench-"))
    tmp.mkdir(parents=True, exist_ok=True)
    try:
        versions = [None] + ([args.other_src.resolve()] if args.other_src else [])
        for src in versions:  # compile a cold numba cache of each version outside the timings
            _run(
                [
                    "evaluate",
                    "--agent",
                    "null",
                    "--suite",
                    "thesis-v1",
                    "--out",
                    "warm.json",
                    "--cache",
                    "off",
                    "--force",
                ],
                tmp,
                src,
            )
        out: dict = {"workers": args.workers, "cpu_count": os.cpu_count(), "python": platform.python_version()}
        one, every, other_one, other_every = [], [], [], []
        for r in range(args.repeats):
            for src, o, e in ((None, one, every), (versions[-1], other_one, other_every))[: len(versions)]:
                tag = "" if src is None else "other-"
                o.append(
                    _run(
                        [
                            "evaluate",
                            "--agent",
                            "reference",
                            "--suite",
                            "single-v1",
                            "--out",
                            f"{tag}one{r}.json",
                            "--cache",
                            "off",
                            *w,
                        ],
                        tmp,
                        src,
                    )
                )
                e.append(
                    _run(
                        [
                            "sweep",
                            "--agents",
                            "all",
                            "--suites",
                            "single-v1",
                            "--out",
                            f"{tag}every{r}",
                            "--cache",
                            "off",
                            *w,
                        ],
                        tmp,
                        src,
                    )
                )
        if other_one:
            out.update(
                other_src=str(versions[-1]),
                other_one_agent=other_one,
                other_every_agent=other_every,
                other_every_over_one=round(
                    statistics.median(e["wall_s"] / o["wall_s"] for o, e in zip(other_one, other_every)), 2
                ),
            )
        n_agents = len(json.loads((tmp / "every0" / "sweep.json").read_text())["agents"])
        out.update(
            one_agent=one,
            every_agent=every,
            n_agents=n_agents,
            one_agent_s=statistics.median(x["wall_s"] for x in one),
            every_agent_s=statistics.median(x["wall_s"] for x in every),
            every_over_one=round(statistics.median(e["wall_s"] / o["wall_s"] for o, e in zip(one, every)), 2),
            episodes={"one_agent": 156, "every_agent": 156 * n_agents},
        )
        if args.marginal:
            out.update(_marginal(tmp, w, out["one_agent_s"]))
        if not args.skip_full:
            full = _run(["sweep", "--agents", "all", "--suites", "all", "--out", "full", "--cache", "off", *w], tmp)
            run = json.loads((tmp / "full" / "sweep.json").read_text())
            out.update(full_sweep=full, full_sweep_s=full["wall_s"], episodes_full=run["episodes_run"])
        out["cache_write"] = _run(
            ["evaluate", "--agent", "null", "--suite", "single-v1", "--out", "null.json", "--cache", "write", *w], tmp
        )
        out["cache_write_s"] = out["cache_write"]["wall_s"]
        cache = sorted((tmp / "results" / "cache").glob("single-v1_*.parquet"))
        out["cache_bytes"] = cache[0].stat().st_size if cache else None
        out["new_agent_cached"] = _run(
            ["evaluate", "--agent", NEW_AGENT, "--suite", "single-v1", "--out", "new.json"], tmp
        )
        out["new_agent_cached_s"] = out["new_agent_cached"]["wall_s"]
        if not json.loads((tmp / "new.json").read_text()).get("feature_cache"):
            raise SystemExit("the new agent was not scored on the cache")
    finally:
        if args.keep is None:
            shutil.rmtree(tmp, ignore_errors=True)
    emit(out, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
