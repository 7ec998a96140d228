"""The README's Stable-Baselines3 example, run verbatim, timed, and scored against ``null``.

    python benchmarks/sb3_readme.py [--seeds 0 1 2] [--suite single-v1] [--dev] [--record DIR] [--write]

1. runs the Python block between the README's ``sb3:`` markers as written, in a temporary folder, once per
   seed of ``--seeds`` (default 0: the block verbatim; seed k replaces the block's two ``seed=0``, the
   environment's and PPO's, by ``seed=k`` and changes nothing else), and measures each run's CPU time (this
   process, all threads: the batched environment's two threads, torch, SB3), wall time and the load average;
2. evaluates each saved agent (``my_ppo``) and ``null`` on ``--suite`` (default single-v1, the report set)
   and, with ``--dev``, on the development set the example's settings were chosen on (64 episodes of the
   ``default`` preset drawn with seed 4242, never a suite);
3. prints one JSON object: per seed the training CPU and wall minutes, the agent's detection rate and
   isolation accuracy with exact (Clopper-Pearson) 95 % intervals, false-alarm episodes, mean return, and
   the mean per-episode return difference (agent - null, paired by episode) with a 95 % t interval; then
   the range of each over the seeds.

``--record DIR`` keeps each seed's result in ``DIR/seed_K.json`` as soon as it is measured and reuses the
ones there, so a run cut short resumes and ``--write`` regenerates the summary from the kept results
(docs/data/sb3_readme/ holds the README's).  ``--write`` puts the summary into the README (between its
``sb3result:`` markers) and the whole output into ``docs/data/sb3_readme.json`` and ``docs/sb3.md``.  A
policy "beats null" when its paired return difference's interval lies above 0.  The comparison rows of
docs/sb3.md (``reference``, the shipped ``ppo``) are read from the results ``python -m studies.agents.compare``
wrote (docs/data/results/).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
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


def block_for_seed(block: str, seed: int) -> str:
    """The README block trained with ``seed``: its two ``seed=0`` (environment and PPO) become ``seed=SEED``."""
    if block.count("seed=0") != 2:
        raise SystemExit("the README's SB3 block must set seed=0 twice (SB3VecEnv and PPO) for --seeds")
    return block.replace("seed=0", f"seed={int(seed)}")


def run_seed(block: str, seed: int, suite: str, null: dict, here: Path, workers: int, dev: Path | None) -> dict:
    """Train the block with ``seed`` in ``here`` and score the agent against ``null`` (module docstring)."""
    from marine_fdi_env.benchmark.evaluate import evaluate

    load0 = os.getloadavg()[0]
    c0, w0 = time.process_time(), time.perf_counter()
    exec(compile(block_for_seed(block, seed), "README.md", "exec"), {"__name__": "__readme__"})  # noqa: S102
    cpu_s, wall_s = time.process_time() - c0, time.perf_counter() - w0
    load1 = os.getloadavg()[0]
    agent = evaluate(str(here / "my_ppo"), suite, here / f"agent_s{seed}.json", workers=workers, progress=False)
    diff = paired_return(agent, null["report"])
    out = {
        "seed": seed,
        "training_cpu_minutes": round(cpu_s / 60.0, 2),
        "training_wall_minutes": round(wall_s / 60.0, 2),
        "load_average_1min": [round(load0, 2), round(load1, 2)],
        "agent": summary(agent),
        "return_minus_null": diff,
        "beats_null": bool(diff["ci95"][0] > 0),
    }
    if dev is not None:
        a = evaluate(str(here / "my_ppo"), str(dev), here / f"agent_dev_s{seed}.json", workers=workers, progress=False)
        d = paired_return(a, null["development"])
        out["development"] = {"agent": summary(a), "return_minus_null": d, "beats_null": bool(d["ci95"][0] > 0)}
    return out


def recorded(folder: Path, seed: int, suite: str, dev: bool) -> dict | None:
    """The result of ``seed`` kept in ``folder`` (``--record``) for the same suite and development set, or None."""
    f = Path(folder) / f"seed_{seed}.json"
    if not f.is_file():
        return None
    rec = json.loads(f.read_text())
    if rec.get("suite") != suite or bool(rec.get("dev")) != bool(dev):
        return None
    return {k: v for k, v in rec.items() if k not in ("suite", "dev")}


def _span(values) -> list:
    return [min(values), max(values)]


def ranges(runs: list[dict]) -> dict:
    """The range over the seeds of each figure the README states."""
    return {
        "training_cpu_minutes": _span([r["training_cpu_minutes"] for r in runs]),
        "training_wall_minutes": _span([r["training_wall_minutes"] for r in runs]),
        "load_average_1min": _span([x for r in runs for x in r["load_average_1min"]]),
        "detection_rate": _span([r["agent"]["detection_rate"] for r in runs]),
        "detection_ci95": _span([x for r in runs for x in r["agent"]["detection_ci95"]]),
        "isolation_accuracy": _span([r["agent"]["isolation_accuracy"] for r in runs]),
        "isolation_ci95": _span([x for r in runs for x in r["agent"]["isolation_ci95"]]),
        "false_alarm_episodes": _span([r["agent"]["false_alarm_episodes"] for r in runs]),
        "return_minus_null": _span([r["return_minus_null"]["mean"] for r in runs]),
        "return_minus_null_ci95": _span([x for r in runs for x in r["return_minus_null"]["ci95"]]),
    }


def shipped_comparison(suite: str) -> dict:
    """``reference`` and the shipped ``ppo`` (each training seed) on ``suite``, from the results
    ``python -m studies.agents.compare`` wrote (docs/data/results/), with the ppo's training CPU minutes."""
    res = ROOT / "docs" / "data" / "results"
    out: dict = {}
    ref = res / f"reference_{suite}.json"
    if ref.is_file():
        out["reference"] = summary(json.loads(ref.read_text()))
    ppo = []
    for f in sorted(res.glob(f"ppo_s[0-9]_{suite}.json")):
        cfg = ROOT / "training" / "models" / "ppo" / f"seed{f.name[5]}" / "config.json"
        cpu = json.loads(cfg.read_text()).get("cpu_minutes") if cfg.is_file() else None
        ppo.append(dict(summary(json.loads(f.read_text())), training_cpu_minutes=cpu))
    if ppo:
        out["ppo"] = ppo
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", nargs="+", type=int, default=[0], help="train once per seed (default 0: verbatim)")
    ap.add_argument("--suite", default="single-v1", help="the suite to score on (default single-v1, the report set)")
    ap.add_argument("--dev", action="store_true", help="also score on the development set (module docstring)")
    ap.add_argument("--workers", type=int, default=1, help="evaluation workers (the training is always serial)")
    ap.add_argument(
        "--write", action="store_true", help="write README's summary, docs/sb3.md, docs/data/sb3_readme.json"
    )
    ap.add_argument("--check", action="store_true", help="exit 1 unless every seed's policy beats null on --suite")
    ap.add_argument("--json", action="store_true")
    ap.add_argument(
        "--record",
        type=Path,
        default=None,
        metavar="DIR",
        help="keep each seed's result in DIR/seed_K.json as it finishes and reuse the ones there (a long run "
        "resumes, and --write regenerates the summary from them)",
    )
    args = ap.parse_args(argv)
    from marine_fdi_env.benchmark.evaluate import evaluate, warm_up

    block = readme_block()
    kept = {s: recorded(args.record, s, args.suite, args.dev) for s in args.seeds} if args.record else {}
    null_file = args.record / f"null_{Path(args.suite).stem}.json" if args.record else None
    null_summary = json.loads(null_file.read_text()) if null_file is not None and null_file.is_file() else None
    if null_summary is None or any(kept.get(s) is None for s in args.seeds):
        with tempfile.TemporaryDirectory() as tmp:
            here = Path(tmp)
            old = Path.cwd()
            os.chdir(here)
            try:
                warm_up({})  # compilation is not training
                dev = dev_suite(here) if args.dev else None
                report = evaluate("null", args.suite, here / "null.json", workers=args.workers, progress=False)
                null = {"report": report}
                null_summary = summary(null["report"])
                if dev is not None:
                    null["development"] = evaluate("null", str(dev), here / "null_dev.json", workers=args.workers)
                if null_file is not None:
                    args.record.mkdir(parents=True, exist_ok=True)
                    null_file.write_text(json.dumps(null_summary, indent=1) + "\n")
                for seed in args.seeds:
                    if kept.get(seed) is not None:
                        continue
                    kept[seed] = run_seed(block, seed, args.suite, null, here, args.workers, dev)
                    shutil.rmtree(here / "my_ppo")  # the next seed's block saves its own
                    print(f"seed {seed}: {json.dumps(kept[seed])}", file=sys.stderr, flush=True)
                    if args.record:
                        rec = dict(kept[seed], suite=args.suite, dev=bool(args.dev))
                        (args.record / f"seed_{seed}.json").write_text(json.dumps(rec, indent=1) + "\n")
            finally:
                os.chdir(old)
    runs = [kept[s] for s in args.seeds]
    out = {
        "command": "python benchmarks/sb3_readme.py --seeds "
        + " ".join(str(s) for s in args.seeds)
        + f" --suite {args.suite}"
        + (" --dev" if args.dev else "")
        + (f" --record {args.record}" if args.record else ""),
        "suite": args.suite,
        "cpus": os.cpu_count(),
        "seeds": runs,
        "null": null_summary,
        "range": ranges(runs),
        "beats_null_every_seed": all(r["beats_null"] for r in runs),
        "comparison": shipped_comparison(args.suite),
    }
    if args.write:
        write(out)
    emit(out, args.json)
    return 1 if args.check and not out["beats_null_every_seed"] else 0


def _pct(v, ci) -> str:
    return "–" if v is None else f"{100 * v:.1f} % ({100 * ci[0]:.1f}-{100 * ci[1]:.1f} %)"


def _pct_span(span) -> str:
    lo, hi = (100 * span[0], 100 * span[1])
    return f"{lo:.1f} %" if f"{lo:.1f}" == f"{hi:.1f}" else f"{lo:.1f}-{hi:.1f} %"


def _num_span(span, fmt: str) -> str:
    a, b = format(span[0], fmt), format(span[1], fmt)
    return a if a == b else f"{a} to {b}" if fmt.startswith("+") else f"{a}-{b}"


def _seeds(out: dict) -> str:
    s = [str(r["seed"]) for r in out["seeds"]]
    return f"seed {s[0]}" if len(s) == 1 else "seeds " + ", ".join(s[:-1]) + " and " + s[-1]


def readme_line(out: dict) -> str:
    r, n = out["range"], len(out["seeds"])
    verdict = (
        ("each seed's" if n > 1 else "its") + " paired 95 % interval above 0"
        if out["beats_null_every_seed"]
        else "NOT above 0 for every seed"
    )
    load = r["load_average_1min"]
    return (
        f"{_seeds(out).capitalize()} on the shared 2-core machine (load average {load[0]:.1f}-{load[1]:.1f} at start "
        f"and end; other CPUs and loads differ): {_num_span(r['training_cpu_minutes'], '.1f')} CPU minutes; on "
        f"{out['suite']} ({out['null']['episodes']} episodes, not used to choose the settings) detection "
        f"{_pct_span(r['detection_rate'])}, isolation {_pct_span(r['isolation_accuracy'])} (95 % intervals within "
        f"{100 * r['isolation_ci95'][0]:.1f}-{100 * r['isolation_ci95'][1]:.1f} %), "
        f"{_num_span(r['false_alarm_episodes'], 'd')} false-alarm episodes, return over `null` "
        f"{_num_span(r['return_minus_null'], '+.2f')} per episode ({verdict}).  `{out['command']} --write` "
        "measures it ([docs/sb3.md](docs/sb3.md))."
    )


def write(out: dict) -> None:
    data = ROOT / "docs" / "data" / "sb3_readme.json"
    data.write_text(json.dumps(out, indent=1) + "\n")
    text = README.read_text(encoding="utf-8")
    begin = re.search(r"<!-- sb3result:begin[^>]*-->", text)
    end = text.index("<!-- sb3result:end -->")
    README.write_text(text[: begin.end()] + "\n" + readme_line(out) + "\n" + text[end:], encoding="utf-8")
    (ROOT / "docs" / "sb3.md").write_text(page(out), encoding="utf-8")


def page(out: dict) -> str:
    n = out["null"]
    rows = [
        "| seed | training CPU min | load average | detection | isolation | false-alarm episodes | "
        "mean return | return minus null's (95 % t interval) |",
        "|---:|---:|---|---:|---:|---:|---:|---:|",
    ]
    for r in out["seeds"]:
        a, d = r["agent"], r["return_minus_null"]
        rows.append(
            f"| {r['seed']} | {r['training_cpu_minutes']:.1f} | "
            f"{r['load_average_1min'][0]:.1f} → {r['load_average_1min'][1]:.1f} | "
            f"{_pct(a['detection_rate'], a['detection_ci95'])} | "
            f"{_pct(a['isolation_accuracy'], a['isolation_ci95'])} | "
            f"{a['false_alarm_episodes']} | {a['mean_return']:.2f} | {d['mean']:+.2f} ({d['ci95'][0]:+.2f} to "
            f"{d['ci95'][1]:+.2f}) |"
        )
    rows.append(
        f"| `null` | | | {_pct(n['detection_rate'], n['detection_ci95'])} | "
        f"{_pct(n['isolation_accuracy'], n['isolation_ci95'])} | {n['false_alarm_episodes']} | "
        f"{n['mean_return']:.2f} | |"
    )
    dev = [r for r in out["seeds"] if r.get("development")]
    dev_lines = []
    if dev:
        each = []
        for r in dev:
            da, dd = r["development"]["agent"], r["development"]["return_minus_null"]
            each.append(
                f"seed {r['seed']} isolation {_pct(da['isolation_accuracy'], da['isolation_ci95'])}, "
                f"return minus null's {dd['mean']:+.2f}"
            )
        dev_lines = ["On the development set (the same trained policies): " + "; ".join(each) + ".\n"]
    cmp = out.get("comparison") or {}
    cmp_text = ""
    if cmp.get("reference") or cmp.get("ppo"):
        parts = []
        if cmp.get("reference"):
            ref = cmp["reference"]
            parts.append(
                f"the `reference` itself isolates {_pct(ref['isolation_accuracy'], ref['isolation_ci95'])} (mean "
                f"return {ref['mean_return']:.2f})"
            )
        if cmp.get("ppo"):
            ppo = cmp["ppo"]
            iso = _pct_span(_span([p["isolation_accuracy"] for p in ppo]))
            cpu = [p["training_cpu_minutes"] for p in ppo if p.get("training_cpu_minutes") is not None]
            cost = f", {min(cpu):.1f}-{max(cpu):.1f} CPU minutes of training" if cpu else ""
            parts.append(
                f"the shipped `ppo` ({len(ppo)} training seeds{cost}, its own features and a supervised start, "
                f"[learned_agents.md](learned_agents.md)) {iso} (mean return "
                f"{min(p['mean_return'] for p in ppo):.2f}-{max(p['mean_return'] for p in ppo):.2f})"
            )
        cmp_text = (
            f"For comparison on {out['suite']} (the results `python -m studies.agents.compare` wrote, "
            f"[results.md](results.md)): " + "; ".join(parts) + ".  "
        )
    return "\n".join(
        [
            "# The README's Stable-Baselines3 example, measured\n",
            f"`{out['command']} --write` runs the README's PPO block verbatim once per seed (seed k in place of "
            "the block's two `seed=0`, nothing else changed), then evaluates each saved agent and `null` on "
            f"{out['suite']} ({n['episodes']} episodes, {n['faulty_episodes']} with faults).  The machine: "
            f"{out['cpus']} CPUs shared with other work (the load average at the start and the end of each "
            "training run is in the table; wall time on a shared machine says more about the others' work and is "
            "kept in docs/data/sb3_readme/ only); a faster or idle CPU takes less time, the numbers of a seed do "
            "not depend on it.  The example's settings were chosen on a development set (`--dev`: 64 episodes "
            f"of the `default` preset, seed 4242); {out['suite']} was not used to choose them.  Intervals: exact "
            "binomial 95 % for the rates, t for the paired return difference.\n",
            *rows,
            "",
            "A policy beats `null` when its paired interval lies above 0: "
            + ("every seed's does.\n" if out["beats_null_every_seed"] else "NOT every seed's does.\n"),
            *dev_lines,
            "Choices that favour this policy, said next to its numbers: it reads the reference diagnoser's "
            'conclusion (`reference_features=True`, as every agent may: `info["reference"]`), and it trains with '
            "a false alarm costing 10 instead of the scored 40 (it is scored on MarineFDI-v1's 40).  It trains on "
            "episodes drawn from the `default` preset, never on a suite.  " + cmp_text + "\n",
            "How the settings are chosen (training runs of 64 engines, scored only on the development set): "
            "PPO's defaults on the gated action with the reference's inputs (gamma 0.5, 64-step rollouts) settle "
            "on never raising the alarm: development return -2.01 after 328 k steps, that of `null`.  With the "
            "return normalised (`VecNormalize`), a learning rate of 1e-3, entropy 0.01 and a quiet initial "
            "policy, the training return is still below `null`'s after 430 k steps (stopped, not scored).  A "
            "false alarm at 10 while training makes trying the alarm affordable: the policy learns to follow the "
            "reference's detection and to name faults (development return +2.15 after 614 k steps, the "
            "`reference`'s +1.38).  The same without the quiet initial policy learns as fast (training "
            "return -0.9 against -0.5 at 348 k steps; stopped) and is the README's example, for 1 M steps.  One "
            "torch thread (`torch.set_num_threads(1)`): with torch's default two threads a run takes more CPU "
            "time for the same steps (8.5 CPU minutes before finishing 1.2 M steps, one measured run, stopped).  "
            "`ProgressLine` prints a line a minute; it reads the training and changes nothing in it.\n",
        ]
    )


if __name__ == "__main__":
    sys.exit(main())
