"""The README's Stable-Baselines3 example, run verbatim, timed, and scored against ``null``.

    python benchmarks/sb3_readme.py [--suite single-v1] [--workers 2] [--write]

1. runs the Python block between the README's ``sb3:`` markers as written, in a temporary folder,
   and measures its CPU time (this process, all threads: the batched environment's two threads,
   torch, SB3) and wall time;
2. evaluates the agent it saved (``my_ppo``) and ``null`` on ``--suite`` (default single-v1, the
   report set) and, with ``--dev``, on the development set the example's settings were chosen on
   (64 episodes of the ``default`` preset drawn with seed 4242, never a suite);
3. prints one JSON object: training CPU minutes, the two agents' detection rate and isolation
   accuracy with exact (Clopper-Pearson) 95 % intervals, false-alarm episodes, mean return, and the
   mean per-episode return difference (agent - null, paired by episode) with a 95 % t interval.

``--write`` puts the summary into the README (between its ``sb3result:`` markers) and the whole
output into ``docs/data/sb3_readme.json`` and ``docs/sb3.md``.  The policy "beats null" when the
paired return difference's interval lies above 0.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy import stats

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import emit  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
DEV_SEED, DEV_EPISODES = 4242, 64


def readme_block() -> str:
    text = README.read_text(encoding="utf-8")
    m = re.search(r"<!-- sb3:begin[^>]*-->\s*```python\n(.*?)^```", text, flags=re.S | re.M)
    if m is None:
        raise SystemExit("README.md has no ```python block between <!-- sb3:begin ... --> and <!-- sb3:end -->")
    return m.group(1)


def dev_suite(folder: Path) -> Path:
    """The development set: ``DEV_EPISODES`` episodes of the ``default`` preset (seed ``DEV_SEED``)."""
    from marine_fdi_env.benchmark.suites import load_suite
    from marine_fdi_env.envs.scenario_sampler import get_preset

    cfg = get_preset("default")
    ent = np.random.default_rng(np.random.SeedSequence(DEV_SEED)).integers(0, 2**63 - 1, size=DEV_EPISODES)
    head = {k: v for k, v in load_suite("single-v1").items() if k != "scenarios"}
    head.update(
        name="dev-default",
        description=f"{DEV_EPISODES} episodes of the default preset, seed {DEV_SEED}",
        scenarios=[cfg.sample(int(e), scenario_id=f"dev/{i}").to_dict() for i, e in enumerate(ent)],
    )
    path = folder / "dev-default.json"
    path.write_text(json.dumps(head))
    return path


def exact_ci(k: int, n: int) -> list[float | None]:
    if n == 0:
        return [None, None]
    ci = stats.binomtest(k, n).proportion_ci(confidence_level=0.95, method="exact")
    return [round(float(ci.low), 4), round(float(ci.high), 4)]


def summary(result: dict) -> dict:
    m = result["metrics"]
    eps = result["episodes"]
    faulty = [e for e in eps if e["faults"]]
    n_det = round((m.get("detection_rate") or 0.0) * m.get("n_faulty", len(faulty)))
    n_iso = round((m.get("isolation_accuracy") or 0.0) * m.get("n_faulty", len(faulty)))
    n_f = int(m.get("n_faulty", len(faulty)))
    return {
        "agent": result["agent"],
        "episodes": len(eps),
        "faulty_episodes": n_f,
        "detection_rate": m.get("detection_rate"),
        "detection_ci95": exact_ci(n_det, n_f),
        "isolation_accuracy": m.get("isolation_accuracy"),
        "isolation_ci95": exact_ci(n_iso, n_f),
        "false_alarm_episodes": round((m.get("false_alarm_episode_rate") or 0.0) * len(eps)),
        "mean_return": m.get("mean_return"),
    }


def paired_return(agent: dict, null: dict) -> dict:
    a = {e["scenario_id"]: e["return"] for e in agent["episodes"]}
    d = np.array([a[e["scenario_id"]] - e["return"] for e in null["episodes"]])
    mean, se = float(d.mean()), float(d.std(ddof=1) / np.sqrt(len(d)))
    half = float(stats.t.ppf(0.975, len(d) - 1) * se)
    return {"mean": round(mean, 3), "ci95": [round(mean - half, 3), round(mean + half, 3)], "episodes": len(d)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--suite", default="single-v1", help="the suite to score on (default single-v1, the report set)")
    ap.add_argument("--dev", action="store_true", help="also score on the development set (module docstring)")
    ap.add_argument("--workers", type=int, default=1, help="evaluation workers (the training is always serial)")
    ap.add_argument(
        "--write", action="store_true", help="write README's summary, docs/sb3.md, docs/data/sb3_readme.json"
    )
    ap.add_argument("--check", action="store_true", help="exit 1 unless the policy beats null on --suite")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    from marine_fdi_env.benchmark.evaluate import evaluate, warm_up

    block = readme_block()
    with tempfile.TemporaryDirectory() as tmp:
        here = Path(tmp)
        old = Path.cwd()
        os.chdir(here)
        try:
            warm_up({})  # compilation is not training
            c0, w0 = time.process_time(), time.perf_counter()
            exec(compile(block, "README.md", "exec"), {"__name__": "__readme__"})  # noqa: S102 - the README's own code
            cpu_s, wall_s = time.process_time() - c0, time.perf_counter() - w0
            scored = {}
            for name, suite in [("report", args.suite)] + ([("development", str(dev_suite(here)))] if args.dev else []):
                agent = evaluate(
                    str(here / "my_ppo"), suite, here / f"agent_{name}.json", workers=args.workers, progress=False
                )
                null = evaluate("null", suite, here / f"null_{name}.json", workers=args.workers, progress=False)
                diff = paired_return(agent, null)
                scored[name] = {
                    "suite": agent["suite"],
                    "agent": summary(agent),
                    "null": summary(null),
                    "return_minus_null": diff,
                    "beats_null": bool(diff["ci95"][0] > 0),
                }
        finally:
            os.chdir(old)
    out = {
        "training_cpu_minutes": round(cpu_s / 60.0, 2),
        "training_wall_minutes": round(wall_s / 60.0, 2),
        **scored["report"],
        "development": scored.get("development"),
        "load_average_1min": round(os.getloadavg()[0], 2),
        "command": f"python benchmarks/sb3_readme.py --suite {args.suite}" + (" --dev" if args.dev else ""),
    }
    if args.write:
        write(out)
    emit(out, args.json)
    return 1 if args.check and not out["beats_null"] else 0


def _pct(v, ci) -> str:
    return "–" if v is None else f"{100 * v:.1f} % ({100 * ci[0]:.1f}-{100 * ci[1]:.1f} %)"


def _dev_line(out: dict) -> str:
    dev = out.get("development")
    if not dev:
        return ""
    a, d = dev["agent"], dev["return_minus_null"]
    return (
        "On the development set (the same trained policy): "
        f"detection {_pct(a['detection_rate'], a['detection_ci95'])}, "
        f"isolation {_pct(a['isolation_accuracy'], a['isolation_ci95'])}, {a['false_alarm_episodes']} false-alarm "
        f"episodes, return minus null's {d['mean']:+.3f} ({d['ci95'][0]:+.3f} to {d['ci95'][1]:+.3f}).\n"
    )


def write(out: dict) -> None:
    a, n, d = out["agent"], out["null"], out["return_minus_null"]
    line = (
        f"On {out['suite']} ({a['episodes']} episodes, never used to choose the settings) the policy trained in "
        f"{out['training_cpu_minutes']:.1f} CPU minutes detects {_pct(a['detection_rate'], a['detection_ci95'])} "
        f"of the faulty episodes and isolates {_pct(a['isolation_accuracy'], a['isolation_ci95'])} with "
        f"{a['false_alarm_episodes']} false-alarm episodes; its return exceeds `null`'s by {d['mean']:+.2f} per "
        f"episode (95 % interval {d['ci95'][0]:+.2f} to {d['ci95'][1]:+.2f}): "
        f"{'better than null' if out['beats_null'] else 'NOT better than null'}.  "
        f"`{out['command']} --write` measures it ([docs/sb3.md](docs/sb3.md))."
    )
    data = ROOT / "docs" / "data" / "sb3_readme.json"
    data.write_text(json.dumps(out, indent=1) + "\n")
    text = README.read_text(encoding="utf-8")
    begin = re.search(r"<!-- sb3result:begin[^>]*-->", text)
    end = text.index("<!-- sb3result:end -->")
    README.write_text(text[: begin.end()] + "\n" + line + "\n" + text[end:], encoding="utf-8")
    rows = [
        (
            "detection (faulty episodes)",
            _pct(a["detection_rate"], a["detection_ci95"]),
            _pct(n["detection_rate"], n["detection_ci95"]),
        ),
        (
            "isolation accuracy",
            _pct(a["isolation_accuracy"], a["isolation_ci95"]),
            _pct(n["isolation_accuracy"], n["isolation_ci95"]),
        ),
        ("false-alarm episodes", str(a["false_alarm_episodes"]), str(n["false_alarm_episodes"])),
        ("mean return (MarineFDI-v1)", f"{a['mean_return']:.2f}", f"{n['mean_return']:.2f}"),
    ]
    page = [
        "# The README's Stable-Baselines3 example, measured\n",
        f"`{out['command']} --write` runs the README's PPO block verbatim (training "
        f"{out['training_cpu_minutes']:.1f} CPU minutes, {out['training_wall_minutes']:.1f} wall minutes, load "
        f"average {out['load_average_1min']}), then evaluates the saved agent and `null` on {out['suite']} "
        f"({a['episodes']} episodes, {a['faulty_episodes']} with faults).  The example's settings were chosen "
        f"on a development set (`--dev`: {DEV_EPISODES} episodes of the `default` preset, seed {DEV_SEED}); "
        f"{out['suite']} was run once, to report.  Intervals: exact binomial 95 %.\n",
        "| metric | README PPO | null |",
        "|---|---:|---:|",
    ] + [f"| {r[0]} | {r[1]} | {r[2]} |" for r in rows]
    page += [
        "",
        f"Return minus null's, paired by episode: {d['mean']:+.3f} (95 % t interval {d['ci95'][0]:+.3f} to "
        f"{d['ci95'][1]:+.3f}, {d['episodes']} episodes): "
        f"{'better than null' if out['beats_null'] else 'not better than null'}.\n",
        _dev_line(out),
        "Choices that favour this policy, said next to its numbers: it reads the reference diagnoser's "
        'conclusion (`reference_features=True`, as every agent may: `info["reference"]`), and it trains with '
        "a false alarm costing 10 instead of the scored 40 (it is scored on MarineFDI-v1's 40).  It trains on "
        "episodes drawn from the `default` preset (PPO seed 0, environment seed 0), never on a suite.  For "
        "comparison on the same suite ([results.md](results.md)): the `reference` itself isolates 18.6 % "
        "(return 1.95), the shipped `ppo` (observation features only, 28 CPU minutes, "
        "[learned_agents.md](learned_agents.md)) 80.8 %.\n",
        "How the settings were found (training runs of 64 engines, scored only on the development set): "
        "PPO's defaults on the gated action with the reference's inputs (gamma 0.5, 64-step rollouts) settled "
        "on never raising the alarm: development return -2.01 after 328 k steps, that of `null`.  With the "
        "return normalised (`VecNormalize`), a learning rate of 1e-3, entropy 0.01 and a quiet initial "
        "policy, the training return was still below `null`'s after 430 k steps (stopped, not scored).  A "
        "false alarm at 10 while training made trying the alarm affordable: the policy learned to follow the "
        "reference's detection and to name faults (development return +2.15 after 614 k steps, the "
        "`reference`'s +1.38).  The same without the quiet initial policy learned as fast (training "
        "return -0.9 against -0.5 at 348 k steps; stopped) and is the README's example, for 1 M steps.  One "
        "torch thread: a first run with torch's default two threads had used 8.5 CPU minutes before "
        "finishing 1.2 M steps (stopped), this one 5.2 for 1 M.\n",
    ]
    (ROOT / "docs" / "sb3.md").write_text("\n".join(page), encoding="utf-8")


if __name__ == "__main__":
    sys.exit(main())
