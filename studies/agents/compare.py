"""Compare the learned diagnosers with the baselines on every frozen suite, under MarineFDI-v1.

    python -m studies.agents.compare                      # evaluate what is missing, write the reports
    python -m studies.agents.compare --force              # re-evaluate the learned agents
    python -m studies.agents.compare --force-baselines    # ... and null, random, reference, oracle too
    python -m studies.agents.compare --report-only        # only rewrite docs/learned_agents.md, docs/results.md, the README table
    python -m studies.agents.compare --force-baselines --backend ray --workers 2   # any backend

Runs ``marine-fdi evaluate`` (the same code, :func:`marine_fdi_env.benchmark.evaluate.evaluate_agents`:
each suite simulated once, every agent to evaluate scored on it in lockstep) with the ``MarineFDI-v1``
reward and a batch of 32 episodes (the batch size the compute columns are measured at), writing
``docs/data/results/AGENT_SUITE.json``; then writes
``docs/learned_agents.md`` (every metric on every suite, the must-show checks, training compute
and size of each shipped model), the tables of ``docs/results.md`` (the main table is ``marine-fdi
report``'s) and the README's headline table (one row per agent), each between ``compare:`` markers.

Every row is named for what it is: ``classifier`` is the supervised network alone (its own alarm
and faults), ``classifier+reference`` the hybrid that also takes the reference diagnoser's alarm
and isolation; ``ppo`` is reinforcement learning on the observation features only.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

from marine_fdi_env.benchmark.evaluate import evaluate_agents
from marine_fdi_env.benchmark.suites import SUITE_NAMES
from studies.paths import REPO

__all__ = ["AGENTS", "main", "write_report", "must_shows"]

ROOT = REPO
MODELS = ROOT / "training" / "models"
RESULTS = ROOT / "docs" / "data" / "results"
REPORT = ROOT / "docs" / "learned_agents.md"
README = ROOT / "README.md"
RESULTS_PAGE = ROOT / "docs" / "results.md"
BATCH_SIZE = 32  # episodes advanced together: the compute columns are measured at this batch size
REWARD = "v1"

# display name -> evaluate --agent spec (models by path relative to the repository root)
AGENTS = {
    "null": "null",
    "random": "random",
    "reference": "reference",
    "sequential": "sequential",
    "ppo": "training/models/ppo",
    "classifier": "training/models/classifier",
    "classifier+reference": "training/models/classifier+reference",
    "oracle": "oracle",
}
LEARNED = ("ppo", "classifier", "classifier+reference")
# what each row is, and whether it reads the reference diagnoser's conclusion (info["reference"])
WHAT = {
    "null": ("never declares anything", False),
    "random": ("declares a random hypothesis about once a minute", False),
    "reference": ("the thesis's diagnoser (19 modules, adaptive thresholds, minimal diagnoses)", True),
    "sequential": ("the sequential diagnoser: CUSUM tests on the reference's residuals, the same structural "
                   "isolation; thresholds calibrated on its own fault-free runs, not on a suite", False),
    "ppo": ("reinforcement learning (PPO), observation features only", False),
    "classifier": ("supervised GRU, observation features only: its own alarm and faults", False),
    "classifier+reference": ("hybrid: the classifier plus the reference's alarm and its isolation whenever it "
                             "has one", True),
    "oracle": ("reads the ground truth: the ceiling", False),
}
MODEL_DIRS = {"ppo": "training/models/ppo", "classifier": "training/models/classifier",
              "classifier+reference": "training/models/classifier"}

METRICS = (  # (key, title, format)
    ("n_episodes", "episodes", "int"),
    ("detection_rate", "detection", "pct"),
    ("median_detection_delay_s", "median det. delay [s]", "sec"),
    ("median_detection_delay_censored_s", "censored median det. delay [s]", "sec"),
    ("p90_detection_delay_s", "p90 det. delay [s]", "sec"),
    ("isolation_rate", "isolated (ever)", "pct"),
    ("isolation_accuracy", "isolation acc.", "pct"),
    ("median_isolation_delay_s", "median iso. delay [s]", "sec"),
    ("p90_isolation_delay_s", "p90 iso. delay [s]", "sec"),
    ("n_false_alarms", "false alarms", "int"),
    ("false_alarm_rate", "false alarms [1/h]", "rate"),
    ("false_alarm_episode_rate", "FA episodes", "pct"),
    ("belief_on_truth", "belief on truth", "rate"),
    ("mean_return", "mean return (v1)", "rate"),
    ("engine_failures", "engine failures", "int"),
    ("feature_compute_s_per_sample", "features [µs/sample]", "us"),
    ("agent_compute_s_per_decision", "agent [µs/decision]", "us"),
)


def _current_spelling(command: str) -> str:
    """A recorded training command as it is typed today (``marine-fdi train``)."""
    for old in ("python -m training.train", "python -m marine_fdi_env.training.train"):
        command = command.replace(old, "marine-fdi train")
    return command


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


def run(agents: dict, suites, force: bool = False, force_baselines: bool = False, workers: int = 1,
        backend: str | None = None, ray_address: str | None = None, log=print) -> None:
    """Evaluate the missing results; ``force`` re-evaluates the learned agents (and the baselines
    too with ``force_baselines``: their results are shared with the README's baseline table).  Per
    suite, every agent to evaluate is scored on one simulation of its episodes."""
    for suite in suites:
        todo = {}
        for name, spec in agents.items():
            again = force_baselines or (force and name in LEARNED)
            if result_path(name, suite).is_file() and not again:
                continue
            if "/" in spec and not (ROOT / spec / "agent.json").is_file():
                log(f"skip {name}: {spec} not trained")
                continue
            todo[name] = spec
        if not todo:
            continue
        t0 = time.perf_counter()
        fixed = _suite_reward(suite)
        evaluate_agents([str(ROOT / spec) if "/" in spec else spec for spec in todo.values()], suite,
                        [result_path(name, suite) for name in todo], workers=workers, backend=backend,
                        ray_address=ray_address, progress=False, batch_size=BATCH_SIZE,
                        reward=None if fixed else REWARD)
        for name, spec in todo.items():
            _relabel(result_path(name, suite), name, spec)
        log(f"{suite:13s} {', '.join(todo)}: {time.perf_counter() - t0:6.0f} s -> "
            f"{RESULTS.relative_to(ROOT)}/*_{suite}.json")


def _suite_reward(suite: str):
    from marine_fdi_env.benchmark.suites import load_suite

    return load_suite(suite)["env"].get("reward")


def _relabel(out: Path, name: str, spec: str) -> None:
    """Store the agent spec relative to the repository (results must not carry local paths), and the
    machine's 1-minute load average when the run ended (the compute columns depend on it)."""
    data = json.loads(out.read_text())
    data["agent_spec"] = spec
    data["agent"] = name
    data["load_average_1min"] = round(os.getloadavg()[0], 2)
    for e in data.get("episodes", []):
        e["agent"] = name
    out.write_text(json.dumps(data, separators=(",", ":")) + "\n")


def _load(agent: str, suite: str) -> dict | None:
    p = result_path(agent, suite)
    return json.loads(p.read_text())["metrics"] if p.is_file() else None


def _model_cfg(name: str) -> dict | None:
    d = MODEL_DIRS.get(name)
    f = ROOT / d / "config.json" if d else None
    return json.loads(f.read_text()) if f is not None and f.is_file() else None


def _dir_bytes(d: Path) -> int:
    return sum(f.stat().st_size for f in d.rglob("*") if f.is_file() and f.suffix != ".png")


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


SUMMARY_COLS = (("thesis-v1", "isolation_accuracy", "pct", "thesis iso. acc."),
                ("single-v1", "isolation_accuracy", "pct", "single iso. acc."),
                ("multi-v1", "isolation_accuracy", "pct", "multi iso. acc."),
                ("incipient-v1", "detection_rate", "pct", "incipient detection"),
                ("incipient-v1", "median_detection_delay_censored_s", "sec", "incipient censored median det. delay [s]"),
                ("transfer-v1", "isolation_accuracy", "pct", "transfer-v1 iso. acc."),
                ("transfer-v2", "detection_rate", "pct", "transfer-v2 detection"),
                ("transfer-v2", "isolation_accuracy", "pct", "transfer-v2 iso. acc."),
                ("transfer-v2", "false_alarm_rate", "rate", "transfer-v2 FA [1/h]"),
                ("nominal-v1", "n_false_alarms", "int", "nominal false alarms"),
                ("single-v1", "feature_compute_s_per_sample", "us", "features [µs/sample]"),
                ("single-v1", "agent_compute_s_per_decision", "us", "agent [µs/decision]"))


def _cells(agent: str, cols) -> list[str]:
    """One table row's cells: each (suite, metric, format, title) of ``cols`` for ``agent``."""
    out = []
    for suite, key, kind, _ in cols:
        m = _load(agent, suite)
        out.append("n/a" if m is None else _fmt(m.get(key), kind))
    return out


def compact_table(agents) -> str:
    """The headline metric of each suite per agent, compute, training cost and size."""
    head = ("| agent | reads the reference | " + " | ".join(c[3] for c in SUMMARY_COLS)
            + " | training [CPU min] | model size |")
    rows = [head, "|---|---|" + "---:|" * (len(SUMMARY_COLS) + 2)]
    for a in agents:
        cells = ["yes" if WHAT[a][1] else "no"] + _cells(a, SUMMARY_COLS)
        cfg = _model_cfg(a)
        if cfg:
            cells += [f"{cfg['cpu_minutes']:.1f}", f"{_dir_bytes(ROOT / MODEL_DIRS[a]) / 1024:.0f} KiB"]
        else:
            cells += ["–", "–"]
        rows.append(f"| {a} | " + " | ".join(cells) + " |")
    return "\n".join(rows) + "\n"


def _onset_delays(name: str, suite: str) -> dict | None:
    """Per faulty episode: detection delay [s] from the first onset (None: not detected)."""
    f = result_path(name, suite)
    if not f.is_file():
        return None
    from marine_fdi_env.benchmark.metrics import episode_outcome

    return {e["scenario_id"]: episode_outcome(e)["detection_delay_s"] for e in json.loads(f.read_text())["episodes"]
            if e["faults"]}


def _median(v: list[float]) -> float:
    v = sorted(v)
    return (v[(len(v) - 1) // 2] + v[len(v) // 2]) / 2


def paired_incipient(a: str) -> dict | None:
    """Median detection delay of ``a`` and of the reference over the incipient-v1 episodes both
    detect (the issue's ruling: reported beside the censored median, both count)."""
    ref, mine = _onset_delays("reference", "incipient-v1"), _onset_delays(a, "incipient-v1")
    if not ref or not mine:
        return None
    both = [k for k in ref if ref[k] is not None and mine.get(k) is not None]
    if not both:
        return {"n": 0}
    r, m = _median([ref[k] for k in both]), _median([mine[k] for k in both])
    return {"n": len(both), "agent": m, "reference": r, "ratio": m / r if r else None,
            "earlier": sum(1 for k in both if mine[k] < ref[k] - 0.5),
            "later": sum(1 for k in both if mine[k] > ref[k] + 0.5)}


def must_shows() -> list[tuple[str, str, bool | None]]:
    """The issue's must-show checks, from the stored results."""
    out = []
    fmt = lambda v: "not reached" if v is None else f"{v:.1f} s"  # noqa: E731
    ref = {s: _load("reference", s) for s in ("single-v1", "multi-v1", "incipient-v1", "nominal-v1")}
    # the pure RL agent
    a = "ppo"
    for s in ("single-v1", "multi-v1"):
        m = _load(a, s)
        if m and ref[s]:
            out.append((f"ppo (pure RL): {s} isolation accuracy >= reference",
                        f"{100 * m['isolation_accuracy']:.1f} % vs {100 * ref[s]['isolation_accuracy']:.1f} %",
                        m["isolation_accuracy"] >= ref[s]["isolation_accuracy"]))
    m = _load(a, "nominal-v1")
    if m:
        out.append(("ppo (pure RL): 0 false alarms on nominal-v1", f"{m['n_false_alarms']} false alarms",
                    m["n_false_alarms"] == 0))
    cfg = _model_cfg(a)
    if cfg:
        out.append(("ppo (pure RL): trained in <= 30 CPU minutes",
                    f"{cfg['cpu_minutes']:.1f} CPU min ({cfg['machine']['cpus']} cores; of which simulating the "
                    f"training episodes {cfg.get('cpu_s_data', 0) / 60:.1f})", cfg["cpu_minutes"] <= 30.0))
    # the learned agents without reference inputs
    for a in ("classifier", "ppo"):
        inc, nom = _load(a, "incipient-v1"), _load(a, "nominal-v1")
        if inc and ref["incipient-v1"]:
            c_me, c_ref = inc.get("median_detection_delay_censored_s"), ref["incipient-v1"].get(
                "median_detection_delay_censored_s")
            ok = c_me is not None and (c_ref is None or c_me <= 0.5 * c_ref)
            out.append((f"{a}: incipient-v1 censored median detection delay <= 0.5 x reference "
                        "(reference not reached counts as worse)",
                        f"{fmt(c_me)} vs {fmt(c_ref)} (detection {100 * inc['detection_rate']:.0f} % vs "
                        f"{100 * ref['incipient-v1']['detection_rate']:.0f} %)", ok))
            p = paired_incipient(a)
            if p and p["n"]:
                out.append((f"{a}: incipient-v1 paired median detection delay <= 0.5 x reference (the {p['n']} "
                            "episodes both detect)",
                            f"{p['agent']:.1f} s vs {p['reference']:.1f} s (ratio {p['ratio']:.2f}; earlier on "
                            f"{p['earlier']}, later on {p['later']})", p["ratio"] is not None and p["ratio"] <= 0.5))
            elif p is not None:
                out.append((f"{a}: incipient-v1 paired median detection delay <= 0.5 x reference",
                            "no episode detected by both", False))
        if nom and ref["nominal-v1"]:
            out.append((f"{a}: nominal-v1 false-alarm rate <= reference",
                        f"{nom['false_alarm_rate']:.2f}/h ({nom['n_false_alarms']} alarms) vs "
                        f"{ref['nominal-v1']['false_alarm_rate']:.2f}/h",
                        nom["false_alarm_rate"] <= ref["nominal-v1"]["false_alarm_rate"]))
    return out


def family_table(suite: str, agents) -> str:
    """Per profile family of a suite: detection, isolation accuracy and false-alarm episodes."""
    from marine_fdi_env.benchmark.metrics import compute_metrics

    fams: dict[str, dict[str, list]] = {}
    for a in agents:
        f = result_path(a, suite)
        if not f.is_file():
            continue
        for e in json.loads(f.read_text())["episodes"]:
            fams.setdefault(e["profile"].split(":")[0], {}).setdefault(a, []).append(e)
    rows = ["| agent | " + " | ".join(f"{fam}: detection | {fam}: isolation acc. | {fam}: FA episodes"
                                      for fam in sorted(fams)) + " |",
            "|---|" + "---:|" * (3 * len(fams))]
    for a in agents:
        cells = []
        for fam in sorted(fams):
            eps = fams[fam].get(a)
            if not eps:
                cells += ["n/a"] * 3
                continue
            m = compute_metrics(eps)
            cells += [_fmt(m["detection_rate"], "pct"), _fmt(m["isolation_accuracy"], "pct"),
                      f"{sum(1 for e in eps if compute_metrics([e])['n_false_alarms'])}/{len(eps)}"]
        rows.append(f"| {a} | " + " | ".join(cells) + " |")
    return "\n".join(rows) + "\n"


def _load_note() -> str:
    loads = []
    for f in RESULTS.glob("*.json"):
        v = json.loads(f.read_text()).get("load_average_1min")
        if v is not None:
            loads.append(v)
    if not loads:
        return "load average not recorded; the published run had 5-6 on 2 cores: other jobs shared the machine"
    return f"1-minute load average at the end of the runs {min(loads):.1f}-{max(loads):.1f} on 2 cores"


def _count_parameters(name: str):
    try:
        from marine_fdi_env.benchmark.agent_api import load_agent

        agent = load_agent(str(ROOT / AGENTS[name]))
        net = agent.model.policy if hasattr(agent.model, "policy") else agent.model
        return int(sum(p.numel() for p in net.parameters()))
    except Exception:  # noqa: BLE001 - the table shows a dash
        return "–"


def models_table() -> str:
    rows = ["| model | algorithm | training data | training [CPU min] | of which simulating the data | parameters | "
            "files | command |", "|---|---|---|---:|---:|---:|---:|---|"]
    for a, d in MODEL_DIRS.items():
        if a == "classifier+reference":
            continue
        cfg = _model_cfg(a)
        if cfg is None:
            rows.append(f"| `{d}` | not trained | | | | | | |")
            continue
        if cfg["algo"] == "classifier":
            data = ", ".join(_data_name(s) for s in cfg["hyperparams"]["datasets"])
            data += f"; threshold: {_data_name(cfg['hyperparams']['calibration'])}"
            algo = "GRU classifier (supervised)"
        else:
            data = ", ".join(_data_name(s) for s in cfg.get("datasets", [])) or f"{cfg['scenario_config']} preset"
            data += f"; {cfg['n_timesteps']} decisions replayed"
            algo = f"PPO on {cfg['env_id']} ({cfg['action_mode']} actions)"
        n_par = cfg.get("n_parameters") or _count_parameters(a)
        rows.append(f"| `{d}` | {algo} | {data} | {cfg['cpu_minutes']:.1f} | {cfg.get('cpu_s_data', 0) / 60:.1f} | "
                    f"{n_par} | {_dir_bytes(ROOT / d) / 1024:.0f} KiB | `{_current_spelling(cfg['command'])}` |")
    return "\n".join(rows) + "\n"


def _data_name(spec: dict) -> str:
    name = spec.get("preset") or spec["config"]["name"]
    return f"{name} x{spec['episodes']} (seed {spec['seed']})"


def agents_list() -> str:
    return "\n".join(f"* `{a}`: {WHAT[a][0]}" + (" (reads `info[\"reference\"]`)" if WHAT[a][1] and a != "reference"
                                                 else "") for a in AGENTS) + "\n"


def write_report(path: Path = REPORT, notes: str = "") -> Path:
    agents = list(AGENTS)
    parts = ["# Learned diagnosers\n",
             "Generated by `python -m studies.agents.compare` from `docs/data/results/*.json` (`marine-fdi evaluate "
             f"--reward {REWARD} --batch-size {BATCH_SIZE}` of every agent on every suite, each suite simulated once "
             "and the agents scored on it in lockstep; transfer-v2 fixes v1 itself). "
             "Agents (every row named for what it is):\n", agents_list(),
             "## Summary\n", compact_table(agents),
             "\nCompute: features = the observation features (the 19 modules' residuals and thresholds) every agent "
             "shares, per sensor sample; agent = the agent's own decision per decision and engine; both measured "
             f"at a batch of {BATCH_SIZE} episodes on the shared 2-core machine (single-v1 runs; {_load_note()}).  "
             "The features column is the same work for every agent: its spread between rows is the machine's "
             "load, not the agent.\n",
             "\n## Must-show checks\n",
             "| check | measured | met |", "|---|---|---|"]
    for name, val, ok in must_shows():
        parts.append(f"| {name} | {val} | {'–' if ok is None else 'yes' if ok else 'NO'} |")
    parts += ["\n## Shipped models\n", models_table(),
              "\nCPU minutes: process CPU time (all threads) of the training command on a 2-core machine shared with "
              "other jobs, including simulating the training episodes (the `marine-fdi dataset` exports; a cached "
              "export counts with the CPU time it took) and, for the classifier, the threshold calibration.\n"]
    if notes:
        parts += ["\n", notes.strip() + "\n"]
    parts += ["\n## transfer-v2 by profile family\n",
              "Harbour telegraph steps and sea-state load fluctuation, both at sensor noise 0.7x (never in any "
              "training or calibration data):\n", family_table("transfer-v2", agents)]
    parts.append("\n## Every metric, every suite\n")
    for s in SUITE_NAMES:
        parts += [f"\n### {s}\n", suite_table(s, agents)]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(parts))
    return path


BEGIN, END = "<!-- compare:begin (python -m studies.agents.compare writes this block) -->", "<!-- compare:end -->"


HEADLINE_COLS = (("single-v1", "isolation_accuracy", "pct", "single-v1 isolation"),
                 ("multi-v1", "isolation_accuracy", "pct", "multi-v1 isolation"),
                 ("incipient-v1", "detection_rate", "pct", "incipient-v1 detection"),
                 ("transfer-v2", "isolation_accuracy", "pct", "transfer-v2 isolation"),
                 ("nominal-v1", "n_false_alarms", "int", "nominal-v1 false alarms"),
                 ("single-v1", "agent_compute_s_per_decision", "us", "agent [µs/decision]"))


def headline_table(agents) -> str:
    """The README's table: one row per agent (at most 8), one headline metric per suite family."""
    rows = ["| agent | " + " | ".join(c[3] for c in HEADLINE_COLS) + " |", "|---|" + "---:|" * len(HEADLINE_COLS)]
    for a in list(agents)[:8]:
        rows.append(f"| `{a}` | " + " | ".join(_cells(a, HEADLINE_COLS)) + " |")
    return "\n".join(rows) + "\n"


def readme_block() -> str:
    """The README's generated block: the headline table and where the rest is."""
    return "\n".join([BEGIN, "", headline_table(AGENTS), END])


def results_block() -> str:
    """docs/results.md's generated tables: ``marine-fdi report``'s main table, the summary and must-shows."""
    from marine_fdi_env.benchmark.report import load_results, markdown_table

    files = [result_path(a, s) for s in SUITE_NAMES for a in AGENTS if result_path(a, s).is_file()]
    parts = [BEGIN, "",
             "Agents:\n", agents_list(),
             f"All suites, all agents, scored on MarineFDI-v1 (`marine-fdi report docs/data/results/*.json`; "
             f"compute at a batch of {BATCH_SIZE} episodes):\n",
             markdown_table(load_results(files)) if files else "(no results)\n",
             "Headline numbers, training compute and size of the learned agents:\n", compact_table(list(AGENTS)),
             "\nMust-show checks of the learned agents:\n",
             "| check | measured | met |", "|---|---|---|"]
    for name, val, ok in must_shows():
        parts.append(f"| {name} | {val} | {'–' if ok is None else 'yes' if ok else 'NO'} |")
    parts += ["", END]
    return "\n".join(parts)


def write_block(path: Path, block: str) -> bool:
    """Replace the block between the compare markers of ``path``; False if it has none."""
    text = path.read_text()
    if BEGIN not in text or END not in text:
        return False
    a, b = text.index(BEGIN), text.index(END) + len(END)
    path.write_text(text[:a] + block + text[b:])
    return True


def transfer_v2_probe(agent: str = "reference", log=print) -> dict:
    """What makes transfer-v2 hard for an agent: its scenarios as in the suite, at the training noise
    (1.0x), and with a constant profile at the suite's noise (0.7x); detection, isolation, false alarms."""
    import re
    from dataclasses import replace

    from marine_fdi_env.benchmark.agent_api import load_agent
    from marine_fdi_env.benchmark.evaluate import run_episodes
    from marine_fdi_env.benchmark.metrics import compute_metrics
    from marine_fdi_env.benchmark.suites import load_suite

    scs = load_suite("transfer-v2").scenarios

    def level(p: str) -> float:
        m = re.search(r"u_mean=([0-9.]+)", p)
        return float(m.group(1)) if m else 0.65

    variants = {"as in the suite (held-out profiles, noise 0.7x)": scs,
                "the same profiles at noise 1.0x": [replace(s, noise_scale=1.0) for s in scs],
                "constant profile at the mean level, noise 0.7x": [replace(s, profile=f"constant:u0={level(s.profile)}")
                                                                   for s in scs]}
    spec = str(ROOT / AGENTS[agent]) if "/" in AGENTS.get(agent, "") else agent
    out = {}
    for name, v in variants.items():
        m = compute_metrics(run_episodes(load_agent(spec), v, {"reward": REWARD}, suite="transfer-v2-probe"))
        out[name] = m
        log(f"{agent} | {name} | detection {_fmt(m['detection_rate'], 'pct')} | isolation "
            f"{_fmt(m['isolation_accuracy'], 'pct')} | false alarms {m['n_false_alarms']}")
    return out


NOTES_FILE = ROOT / "training" / "NOTES.md"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m studies.agents.compare", description=__doc__.splitlines()[0])
    ap.add_argument("--agents", nargs="*", default=list(AGENTS), choices=list(AGENTS))
    ap.add_argument("--suites", nargs="*", default=list(SUITE_NAMES))
    ap.add_argument("--force", action="store_true", help="re-evaluate the learned agents even when results exist")
    ap.add_argument("--force-baselines", action="store_true", help="re-evaluate null/random/reference/oracle too")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--backend", choices=("serial", "process", "ray"), default=None,
                    help="where the chunks run (marine-fdi evaluate's --backend; default: process if --workers > 1)")
    ap.add_argument("--ray-address", default=None, help="a Ray cluster to run on (marine-fdi evaluate's --ray-address)")
    ap.add_argument("--report-only", action="store_true")
    ap.add_argument("--transfer-v2-probe", action="store_true",
                    help="only print what makes transfer-v2 hard for the --agents (noise vs profiles)")
    args = ap.parse_args(argv)
    if args.transfer_v2_probe:
        for a in args.agents:
            transfer_v2_probe(a)
        return 0
    if not args.report_only:
        t0 = time.perf_counter()
        run({a: AGENTS[a] for a in args.agents}, args.suites, force=args.force,
            force_baselines=args.force_baselines, workers=args.workers, backend=args.backend,
            ray_address=args.ray_address)
        print(f"evaluated in {time.perf_counter() - t0:.0f} s (1-minute load average now {os.getloadavg()[0]:.1f})")
    notes = NOTES_FILE.read_text() if NOTES_FILE.is_file() else ""
    print(f"wrote {write_report(notes=notes)}")
    if write_block(README, readme_block()):
        print(f"wrote the headline table of {README}")
    if write_block(RESULTS_PAGE, results_block()):
        print(f"wrote the tables of {RESULTS_PAGE}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
