"""``MarineFDI-v0`` throughput benchmark.

    python benchmarks/env.py --json

prints one JSON object:

``vector_engine_samples_per_s_n1024``  ``MarineFDIVectorEnv(num_envs=1024, scenario_config="default")``
                                  stepped with random belief actions (``action_space.sample()``;
                                  the residual features are always computed): engine-samples/s =
                                  1024 x 100 samples per 1 s decision x steps / wall time of the
                                  ``env.step`` calls (the first reset and compilation excluded; best
                                  of ``--repeats`` runs of ``--vector-steps`` steps).  The default
                                  episodes last 300 s, so no sub-env autoresets in the timed steps.
                                  Target: >= 5e5.
``vector_decision_steps_per_s_n1024`` the same run in sub-env decisions per second (1024 x steps / s).
``vector_*_n1024_autoreset``      the same in steady state: ``--autoresets-per-step`` (default 4) slots
                                  autoreset in every timed step (a training run with 300 s episodes
                                  restarts 1024 / 300 = 3.4 per step): those slots run short,
                                  fault-free episodes of the preset's profiles ending at staggered
                                  decisions, then the preset's episodes.
``vector_step_s_n1024``           wall time of one vector ``step`` (the best run's mean).
``vector_breakdown_n1024``        shares of the vector step time (same timed runs; the methods
                                  wrapped with a timer, overhead < 1 us per call):

                                  * ``simulator``: ``env.batch.sim.advance`` (the engines and sensors),
                                  * ``diagnoser``: ``env.batch.diag.observe`` (the 19 monitoring
                                    modules: residuals and adaptive thresholds),
                                  * ``features``: the rest of ``EpisodeBatch.advance`` (observation
                                    features from residuals, failure bookkeeping),
                                  * ``scoring``: ``EpisodeBatch.score`` (per-sub-env reward terms,
                                    declared sets, a Python loop over the 1024 slots),
                                  * ``infos``: the rest of ``step`` (checking the action, per-slot
                                    truncation checks, 1024 info dicts merged by Gymnasium's
                                    ``_add_info``);

                                  ``seconds`` holds the absolute time per step of each part,
                                  ``cpu_us_per_engine_sample`` the CPU time (both threads) of each
                                  part per engine-sample: less sensitive to other load than wall
                                  time (but not immune: a shared core also runs slower).
``vector_*_n1024_sequential``     with ``--observe-sequential``: the first run with the sequential
                                  diagnoser's observation features (its cost is part of ``features``).
``single_env_decision_steps_per_s``  one ``MarineFDIEnv(scenario_config="default")``: decisions per
                                  second of wall time over ``--episodes`` full 300-decision episodes
                                  with random actions, resets included (after one warm-up reset).
                                  Target: >= 200.
``single_env_engine_samples_per_s``  the same in engine-samples/s (x 100).
``python``, ``numpy``, ``cpu_count``  the platform; ``load_average_1min`` before the run (the
                                  diagnoser uses two threads: other processes on a 2-core machine
                                  slow every number down).

With ``--profile`` it also prints (to stderr) the top cProfile entries of one vector step.
"""

from __future__ import annotations

import argparse
import cProfile
import io
import os
import pstats
import sys
import time
from collections import defaultdict
from dataclasses import replace

import numpy as np
from _report import emit  # noqa: E402  (benchmarks/ is the script directory)

import marine_fdi_env  # noqa: F401  (registers the environment)
from marine_fdi_env.envs.fdi_env import MarineFDIEnv
from marine_fdi_env.envs.vector import MarineFDIVectorEnv

PRESET = "default"


class _Timers:
    """Wraps bound methods of an instance with accumulating wall-clock and CPU-time timers (CPU
    time of the whole process, so both worker threads count)."""

    def __init__(self) -> None:
        self.seconds: dict[str, float] = defaultdict(float)
        self.cpu: dict[str, float] = defaultdict(float)

    def wrap(self, obj, method: str, key: str) -> None:
        inner = getattr(obj, method)
        seconds, cpu = self.seconds, self.cpu

        def timed(*args, **kwargs):
            t0, c0 = time.perf_counter(), time.process_time()
            try:
                return inner(*args, **kwargs)
            finally:
                seconds[key] += time.perf_counter() - t0
                cpu[key] += time.process_time() - c0

        setattr(obj, method, timed)

    def reset(self) -> None:
        self.seconds.clear()
        self.cpu.clear()


def _staggered_scenarios(env: MarineFDIVectorEnv, seed: int, first_end: int, steps: int, per_step: int) -> list:
    """The preset's scenarios for every slot, except that ``per_step`` slots end (fault-free, same
    profile) at each of the decisions first_end .. first_end + steps - 1, so each of the steps after
    them autoresets that many slots (a vector env in steady state autoresets N / 300 slots per step)."""
    rng = np.random.default_rng(seed)
    scenarios = [env.scenario_config.sample(int(rng.integers(0, 2**63 - 1))) for _ in range(env.num_envs)]
    for k in range(steps):
        for j in range(per_step):
            i = k * per_step + j
            scenarios[i] = replace(scenarios[i], faults=(), magnitude_scales=(), duration_s=float(first_end + k))
    return scenarios


def vector_throughput(
    n: int,
    steps: int,
    repeats: int,
    seed: int = 0,
    profile: bool = False,
    autoresets_per_step: int = 0,
    observe_sequential: bool = False,
) -> dict:
    env = MarineFDIVectorEnv(num_envs=n, scenario_config=PRESET, observe_sequential=observe_sequential)
    env.action_space.seed(seed)
    warm = 2  # steps before timing: the first scoring and infos
    options = None
    if autoresets_per_step:
        options = {"scenarios": _staggered_scenarios(env, seed, warm, steps * repeats, autoresets_per_step)}
    env.reset(seed=seed, options=options)
    for _ in range(warm):
        env.step(env.action_space.sample())
    timers = _Timers()
    b = env.batch
    timers.wrap(b.sim, "advance", "simulator")
    timers.wrap(b.diag, "observe", "diagnoser")
    timers.wrap(b, "advance", "batch_advance")
    timers.wrap(b, "score", "scoring")
    samples = b.period_samples
    best = None
    for _ in range(repeats):
        actions = [env.action_space.sample() for _ in range(steps)]
        timers.reset()
        t0, c0 = time.perf_counter(), time.process_time()
        for a in actions:
            env.step(a)
        wall, cpu_total = time.perf_counter() - t0, time.process_time() - c0
        if best is None or wall < best[0]:
            best = (wall, dict(timers.seconds), dict(timers.cpu), cpu_total)
    wall, sec, cpu, cpu_total = best
    tag = f"n{n}" + ("_autoreset" if autoresets_per_step else "") + ("_sequential" if observe_sequential else "")
    parts = {
        "simulator": sec["simulator"],
        "diagnoser": sec["diagnoser"],
        "features": sec["batch_advance"] - sec["simulator"] - sec["diagnoser"],
        "scoring": sec["scoring"],
    }
    parts["infos"] = wall - sum(parts.values())
    cpu_parts = {
        "simulator": cpu["simulator"],
        "diagnoser": cpu["diagnoser"],
        "features": cpu["batch_advance"] - cpu["simulator"] - cpu["diagnoser"],
        "scoring": cpu["scoring"],
    }
    cpu_parts["infos"] = cpu_total - sum(cpu_parts.values())
    per_sample = n * samples * steps
    out = {
        f"vector_engine_samples_per_s_{tag}": round(n * samples * steps / wall, 1),
        f"vector_decision_steps_per_s_{tag}": round(n * steps / wall, 1),
        f"vector_step_s_{tag}": round(wall / steps, 4),
        f"vector_breakdown_{tag}": {
            "share": {k: round(v / wall, 3) for k, v in parts.items()},
            "seconds": {k: round(v / steps, 4) for k, v in parts.items()},
            "cpu_us_per_engine_sample": {k: round(1e6 * v / per_sample, 3) for k, v in cpu_parts.items()},
        },
    }
    if profile:
        pr = cProfile.Profile()
        a = env.action_space.sample()
        pr.enable()
        env.step(a)
        pr.disable()
        s = io.StringIO()
        pstats.Stats(pr, stream=s).sort_stats("tottime").print_stats(25)
        print(s.getvalue(), file=sys.stderr)
    return out


def single_env_throughput(episodes: int, seed: int = 0) -> dict:
    env = MarineFDIEnv(scenario_config=PRESET)
    env.action_space.seed(seed)
    env.reset(seed=seed)  # warm-up (compilation, nominal readings)
    steps = 0
    t0 = time.perf_counter()
    for _ in range(episodes):
        env.reset()
        done = False
        while not done:
            _, _, term, trunc, _ = env.step(env.action_space.sample())
            steps += 1
            done = term or trunc
    wall = time.perf_counter() - t0
    return {
        "single_env_decision_steps_per_s": round(steps / wall, 1),
        "single_env_engine_samples_per_s": round(steps * env.batch.period_samples / wall, 1),
        "single_env_steps_timed": steps,
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--json", action="store_true", help="print one JSON object")
    ap.add_argument("--num-envs", type=int, default=1024)
    ap.add_argument("--vector-steps", type=int, default=8, help="timed vector steps per repeat")
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--episodes", type=int, default=3, help="full single-env episodes timed")
    ap.add_argument("--profile", action="store_true", help="cProfile one vector step (to stderr)")
    ap.add_argument(
        "--observe-sequential",
        action="store_true",
        help="also time the vector env with observe_sequential=True (the sequential diagnoser's features)",
    )
    ap.add_argument(
        "--autoresets-per-step",
        type=int,
        default=4,
        help="slots autoreset in each step of the steady-state run (N / 300 s episodes: 3.4 at N=1024)",
    )
    args = ap.parse_args(argv)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else None
    out = {}
    out.update(vector_throughput(args.num_envs, args.vector_steps, args.repeats, profile=args.profile))
    out.update(
        vector_throughput(args.num_envs, args.vector_steps, args.repeats, autoresets_per_step=args.autoresets_per_step)
    )
    if args.observe_sequential:
        out.update(vector_throughput(args.num_envs, args.vector_steps, args.repeats, observe_sequential=True))
    out.update(single_env_throughput(args.episodes))
    out.update(
        {
            "preset": PRESET,
            "targets": {f"vector_engine_samples_per_s_n{args.num_envs}": 5e5, "single_env_decision_steps_per_s": 200},
            "numpy": np.__version__,
            "python": sys.version.split()[0],
            "cpu_count": os.cpu_count(),
            "load_average_1min": load,
        }
    )
    emit(out, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
