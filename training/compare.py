"""Compare the learned diagnosers with the baselines on every frozen suite.

    python -m training.compare                      # evaluate what is missing, write the report
    python -m training.compare --force              # re-evaluate the learned agents (ppo, classifier)
    python -m training.compare --report-only        # only rewrite docs/learned_agents.md

Runs ``marine-fdi evaluate`` (the same code, :func:`marine_fdi_env.envs.evaluate.evaluate`) for
each agent x suite, writing ``docs/data/results/AGENT_SUITE.json``, then writes
``docs/learned_agents.md``: every metric on every suite, the must-show checks, and the training
compute (CPU minutes) and size of each shipped model.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from marine_fdi_env.envs.evaluate import evaluate
from marine_fdi_env.envs.suites import SUITE_NAMES

__all__ = ["AGENTS", "main", "write_report"]

ROOT = Path(__file__).resolve().parent.parent
MODELS = ROOT / "training" / "models"
RESULTS = ROOT / "docs" / "data" / "results"
REPORT = ROOT / "docs" / "learned_agents.md"

# display name -> evaluate --agent spec (models by path relative to the repository root)
AGENTS = {
    "null": "null",
    "random": "random",
    "reference": "reference",
    "sequential": "sequential",
    "ppo": "training/models/ppo",
    "classifier": "training/models/classifier",
    "oracle": "oracle",
}

METRICS = (  # (key, title, format)
    ("n_episodes", "episodes", "int"),
    ("detection_rate", "detection", "pct"),
    ("median_detection_delay_s", "median det. delay [s]", "sec"),
    ("p90_detection_delay_s", "p90 det. delay [s]", "sec"),
    ("isolation_rate", "isolated (ever)", "pct"),
    ("isolation_accuracy", "isolation acc.", "pct"),
    ("median_isolation_delay_s", "median iso. delay [s]", "sec"),
    ("p90_isolation_delay_s", "p90 iso. delay [s]", "sec"),
    ("n_false_alarms", "false alarms", "int"),
    ("false_alarm_rate", "false alarms [1/h]", "rate"),
    ("false_alarm_episode_rate", "FA episodes", "pct"),
    ("belief_on_truth", "belief on truth", "rate"),
    ("mean_return", "mean return", "rate"),
    ("engine_failures", "engine failures", "int"),
    ("compute_s_per_sample", "compute [µs/sample]", "us"),
)


def _fmt(v, kind: str) -> str:
    if v is None:
        return "–"
    if kind == "int":
        return str(int(v))
    if kind == "pct":
        return f"{100 * v:.1f} %"
    if kind == "sec":
        return f"{v:.1f}"
    if kind == "us":
        return f"{1e6 * v:.1f}"
    return f"{v:.2f}"


def result_path(agent: str, suite: str) -> Path:
    return RESULTS / f"{agent}_{suite}.json"


LEARNED = ("ppo", "classifier")


def run(agents: dict, suites, force: bool = False, force_baselines: bool = False, workers: int = 1,
        log=print) -> None:
    """Evaluate the missing results; ``force`` re-evaluates the learned agents (and the baselines
    too with ``force_baselines``: their results are shared with the README's baseline table)."""
    for suite in suites:
        for name, spec in agents.items():
            out = result_path(name, suite)
            again = force_baselines or (force and name in LEARNED)
            if out.is_file() and not again:
                continue
            if "/" in spec and not (ROOT / spec / "agent.json").is_file():
                log(f"skip {name}: {spec} not trained")
                continue
            t0 = time.perf_counter()
            full = str(ROOT / spec) if "/" in spec else spec
            evaluate(full, suite, out, workers=workers, progress=False)
            _relabel(out, name, spec)
            log(f"{name:10s} {suite:13s} {time.perf_counter() - t0:6.0f} s -> {out.relative_to(ROOT)}")


def _relabel(out: Path, name: str, spec: str) -> None:
    """Store the agent spec relative to the repository (results must not carry local paths)."""
    data = json.loads(out.read_text())
    data["agent_spec"] = spec
    data["agent"] = name
    for e in data.get("episodes", []):
        e["agent"] = name
    out.write_text(json.dumps(data, separators=(",", ":")) + "\n")


def _load(agent: str, suite: str) -> dict | None:
    p = result_path(agent, suite)
    return json.loads(p.read_text())["metrics"] if p.is_file() else None


def _model_cfg(name: str) -> dict | None:
    f = ROOT / AGENTS[name] / "config.json"
    return json.loads(f.read_text()) if f.is_file() else None


def _dir_bytes(d: Path) -> int:
    return sum(f.stat().st_size for f in d.rglob("*") if f.is_file())


def suite_table(suite: str, agents) -> str:
    head = "| agent | " + " | ".join(t for _, t, _ in METRICS) + " |"
    sep = "|---|" + "---:|" * len(METRICS)
    rows = [head, sep]
    for a in agents:
        m = _load(a, suite)
        if m is None:
            rows.append(f"| {a} | " + " | ".join("n/a" for _ in METRICS) + " |")
            continue
        rows.append(f"| {a} | " + " | ".join(_fmt(m.get(k), kind) for k, _, kind in METRICS) + " |")
    return "\n".join(rows) + "\n"


def compact_table(agents) -> str:
    """Main table for the README: the headline metric of each suite per agent."""
    cols = [("thesis-v1", "isolation_accuracy", "pct"), ("single-v1", "isolation_accuracy", "pct"),
            ("multi-v1", "isolation_accuracy", "pct"), ("incipient-v1", "median_detection_delay_s", "sec"),
            ("incipient-v1", "detection_rate", "pct"), ("transfer-v1", "isolation_accuracy", "pct"),
            ("transfer-v1", "false_alarm_rate", "rate"), ("nominal-v1", "n_false_alarms", "int")]
    head = ("| agent | thesis iso. acc. | single iso. acc. | multi iso. acc. | incipient median det. delay [s] "
            "| incipient detection | transfer iso. acc. | transfer FA [1/h] | nominal false alarms | "
            "training [CPU min] | model size |")
    rows = [head, "|---|" + "---:|" * (len(cols) + 2)]
    for a in agents:
        cells = []
        for suite, key, kind in cols:
            m = _load(a, suite)
            cells.append("n/a" if m is None else _fmt(m.get(key), kind))
        cfg = _model_cfg(a) if "/" in AGENTS[a] else None
        if cfg:
            cells += [f"{cfg['cpu_minutes']:.1f}", f"{_dir_bytes(ROOT / AGENTS[a]) / 1024:.0f} KiB"]
        else:
            cells += ["–", "–"]
        rows.append(f"| {a} | " + " | ".join(cells) + " |")
    return "\n".join(rows) + "\n"


def must_shows() -> list[tuple[str, str, bool | None]]:
    out = []
    learned = [a for a in ("classifier", "ppo") if _load(a, "incipient-v1")]
    ref_inc = _load("reference", "incipient-v1")
    ref_nom = _load("reference", "nominal-v1")
    for a in learned:
        inc, nom = _load(a, "incipient-v1"), _load(a, "nominal-v1")
        if ref_inc and inc and inc["median_detection_delay_s"] is not None and ref_inc["median_detection_delay_s"]:
            r = inc["median_detection_delay_s"] / ref_inc["median_detection_delay_s"]
            out.append((f"{a}: incipient-v1 median detection delay <= 0.5 x reference",
                        f"{inc['median_detection_delay_s']:.1f} s vs {ref_inc['median_detection_delay_s']:.1f} s "
                        f"(ratio {r:.2f}; detection {100 * inc['detection_rate']:.0f} % vs "
                        f"{100 * ref_inc['detection_rate']:.0f} %)", r <= 0.5))
            paired = _paired_incipient(a)
            if paired:
                out.append(paired)
            c_ref, c_me = ref_inc.get("median_detection_delay_censored_s"), inc.get("median_detection_delay_censored_s")
            if "median_detection_delay_censored_s" in inc:
                fmt = lambda v: "not reached" if v is None else f"{v:.1f} s"  # noqa: E731
                out.append((f"{a}: (information) incipient-v1 median delay over all faulty episodes, a missed "
                            "fault counting as never detected", f"{fmt(c_me)} vs {fmt(c_ref)}", None))
        if ref_nom and nom:
            out.append((f"{a}: nominal-v1 false-alarm rate <= reference",
                        f"{nom['false_alarm_rate']:.2f}/h ({nom['n_false_alarms']} alarms) vs "
                        f"{ref_nom['false_alarm_rate']:.2f}/h", nom["false_alarm_rate"] <= ref_nom["false_alarm_rate"]))
        for s in ("single-v1", "multi-v1"):
            m, r = _load(a, s), _load("reference", s)
            if m and r:
                out.append((f"{a}: {s} isolation accuracy >= reference",
                            f"{100 * m['isolation_accuracy']:.1f} % vs {100 * r['isolation_accuracy']:.1f} %",
                            m["isolation_accuracy"] >= r["isolation_accuracy"]))
        cfg = _model_cfg(a)
        if cfg:
            out.append((f"{a}: training <= 30 CPU minutes", f"{cfg['cpu_minutes']:.1f} CPU min "
                        f"({cfg['machine']['cpus']} cores)", cfg["cpu_minutes"] <= 30.0))
    return out


def _onset_delays(name: str, suite: str) -> dict | None:
    """Per episode: detection delay [s] from the first onset (None: not detected after the onset)."""
    f = RESULTS / f"{name}_{suite}.json"
    if not f.is_file():
        return None
    out = {}
    for e in json.loads(f.read_text())["episodes"]:
        if not e["faults"]:
            continue
        on = min(x["onset_s"] for x in e["faults"])
        det = [c[0] for c in e["declared_changes"] if c[2] and c[0] >= on]
        out[e["scenario_id"]] = det[0] - on if det else None
    return out


def _paired_incipient(a: str):
    """The same comparison on the incipient-v1 episodes the reference detects (information only):
    the median over each agent's own detections rewards detecting fewer, easy faults."""
    ref, mine = _onset_delays("reference", "incipient-v1"), _onset_delays(a, "incipient-v1")
    if not ref or not mine:
        return None
    both = [k for k, v in ref.items() if v is not None]
    if not both:
        return None
    r = sorted(ref[k] for k in both)
    m = sorted(mine[k] if mine.get(k) is not None else float("inf") for k in both)
    med = lambda v: (v[(len(v) - 1) // 2] + v[len(v) // 2]) / 2  # noqa: E731
    earlier = sum(1 for k in both if mine.get(k) is not None and mine[k] < ref[k] - 0.5)
    later = sum(1 for k in both if mine.get(k) is None or mine[k] > ref[k] + 0.5)
    return (f"{a}: (information) incipient-v1 median delay on the {len(both)} episodes the reference detects",
            f"{med(m):.1f} s vs {med(r):.1f} s (ratio {med(m) / med(r):.2f}; earlier on {earlier}, later on {later})",
            None)


def _count_parameters(name: str):
    """Parameters of a shipped model whose config predates the count."""
    try:
        from marine_fdi_env.envs.agent_api import load_agent

        agent = load_agent(str(ROOT / AGENTS[name]))
        net = agent.model.policy if hasattr(agent.model, "policy") else agent.model
        return int(sum(p.numel() for p in net.parameters()))
    except Exception:  # noqa: BLE001 - the table shows a dash
        return "–"


def models_table() -> str:
    rows = ["| model | algorithm | training data | training [CPU min] | of which data export | parameters | "
            "files | command |", "|---|---|---|---:|---:|---:|---:|---|"]
    for a in AGENTS:
        if "/" not in AGENTS[a]:
            continue
        cfg = _model_cfg(a)
        if cfg is None:
            rows.append(f"| {a} | not trained | | | | | | |")
            continue
        if cfg["algo"] == "classifier":
            data = ", ".join(f"{d.get('preset') or d['config']['name']} x{d['episodes']} (seed {d['seed']}"
                             + (f", weight {d['weight']:g}" if "weight" in d else "") + ")"
                             for d in cfg["hyperparams"]["datasets"])
            c = cfg["hyperparams"]["calibration"]
            cname = c.get("preset") or c["config"]["name"]
            data += f"; threshold: {cname} x{c['episodes']} (seed {c['seed']})"
            data_min = f"{cfg['cpu_s_data'] / 60:.1f}"
            algo = "GRU classifier (supervised)"
        else:
            data = f"{cfg['scenario_config']} preset, {cfg['n_timesteps']} decisions"
            data_min = "(in the total)"
            algo = f"{cfg['algo']} ({cfg['action_mode']} actions)"
        n_par = cfg.get("n_parameters") or _count_parameters(a)
        rows.append(f"| `{AGENTS[a]}` | {algo} | {data} | {cfg['cpu_minutes']:.1f} | {data_min} | {n_par} | "
                    f"{_dir_bytes(ROOT / AGENTS[a]) / 1024:.0f} KiB | `{cfg['command']}` |")
    return "\n".join(rows) + "\n"


def write_report(path: Path = REPORT, notes: str = "") -> Path:
    agents = list(AGENTS)
    parts = ["# Learned diagnosers\n",
             "Generated by `python -m training.compare` from `docs/data/results/*.json` (one "
             "`marine-fdi evaluate` run per agent and suite). Agents: `null` (never declares), `random`, "
             "`reference` (the thesis diagnoser), `sequential` (CUSUM tests on the reference's residuals, "
             "docs/diagnosis.md), `ppo` (reinforcement learning, `training/models/ppo`), "
             "`classifier` (supervised GRU, `training/models/classifier`), `oracle` (reads the ground truth; "
             "the ceiling).\n",
             "## Summary\n", compact_table(agents),
             "\n## Must-show checks\n",
             "| check | measured | met |", "|---|---|---|"]
    for name, val, ok in must_shows():
        parts.append(f"| {name} | {val} | {'–' if ok is None else 'yes' if ok else 'NO'} |")
    parts += ["\n## Shipped models\n", models_table(),
              "\nCPU minutes: process CPU time (all threads) of the training command on a 2-core machine "
              "shared with other jobs, including simulating the training episodes (for the classifier: the "
              "`marine-fdi dataset` exports and the threshold calibration).\n"]
    if notes:
        parts += ["\n", notes.strip() + "\n"]
    parts.append("\n## Every metric, every suite\n")
    for s in SUITE_NAMES:
        parts += [f"\n### {s}\n", suite_table(s, agents)]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(parts))
    return path


NOTES_FILE = Path(__file__).resolve().parent / "NOTES.md"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m training.compare", description=__doc__.splitlines()[0])
    ap.add_argument("--agents", nargs="*", default=list(AGENTS), choices=list(AGENTS))
    ap.add_argument("--suites", nargs="*", default=list(SUITE_NAMES))
    ap.add_argument("--force", action="store_true", help="re-evaluate the learned agents even when results exist")
    ap.add_argument("--force-baselines", action="store_true", help="re-evaluate null/random/reference/oracle too")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--report-only", action="store_true")
    args = ap.parse_args(argv)
    if not args.report_only:
        run({a: AGENTS[a] for a in args.agents}, args.suites, force=args.force,
            force_baselines=args.force_baselines, workers=args.workers)
    notes = NOTES_FILE.read_text() if NOTES_FILE.is_file() else ""
    print(f"wrote {write_report(notes=notes)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
