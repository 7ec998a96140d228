"""Compare the learned diagnosers with the baselines on every frozen suite, under MarineFDI-v1.

    python -m studies.agents.compare                      # evaluate what is missing, write the reports
    python -m studies.agents.compare --force              # re-evaluate the learned agents
    python -m studies.agents.compare --force-baselines    # ... and null, random, reference, oracle too
    python -m studies.agents.compare --report-only        # only rewrite the reports and the README table
    python -m studies.agents.compare --probe transfer-v3 --agents classifier   # what makes a transfer suite hard
    python -m studies.agents.compare --force-baselines --backend ray --workers 2   # any backend

Runs ``marine-fdi evaluate`` (the same code, :func:`marine_fdi_env.benchmark.evaluate.evaluate_agents`:
each suite simulated once, every agent and training seed to evaluate scored on it in lockstep) with the
``MarineFDI-v1`` reward and a batch of 32 episodes (the batch size the compute columns are measured at),
writing ``docs/data/results/AGENT_SUITE.json`` (``AGENT_sSEED_SUITE.json`` per training seed); then writes
``docs/learned_agents.md`` (every metric on every suite with 95 % intervals, normalised scores, the
must-show checks, the seed-to-seed spread, the differences between agents, training compute and size
of each shipped model), the tables of ``docs/results.md`` (the main table is ``marine-fdi report``'s)
and the README's headline table (one row per agent), each between ``compare:`` markers.

Every row is named for what it is: ``classifier`` and ``ppo`` are the noise-invariant learned agents
(three training seeds each, pooled in every row; ``ppo`` starts from a supervised fit of its policy to
its training episodes' ground truth), ``ppo-v1`` and ``classifier-v1`` the first learned agents (one
seed, nominal noise only), kept as named baselines; ``classifier-v1+reference`` the hybrid that also
takes the reference diagnoser's alarm and isolation.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from functools import lru_cache
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
SEEDS = (0, 1, 2)  # the training seeds of the noise-invariant agents


def _seeded(folder: str) -> tuple[str, ...]:
    return tuple(f"{folder}/seed{s}" for s in SEEDS)


# display name -> evaluate --agent spec of each training seed (models by path relative to the repository root)
AGENTS: dict[str, tuple[str, ...]] = {
    "null": ("null",),
    "random": ("random",),
    "reference": ("reference",),
    "sequential": ("sequential",),
    "classifier": _seeded("training/models/classifier"),
    "ppo": _seeded("training/models/ppo"),
    "ppo-v1": ("training/models/ppo-v1",),
    "classifier-v1": ("training/models/classifier-v1",),
    "classifier-v1+reference": ("training/models/classifier-v1+reference",),
    "oracle": ("oracle",),
}
LEARNED = ("classifier", "ppo", "ppo-v1", "classifier-v1", "classifier-v1+reference")
ROBUST = ("classifier", "ppo")  # the agents the must-show checks are about (every training seed)
# what each row is, and whether it reads the reference diagnoser's conclusion (info["reference"])
WHAT = {
    "null": ("never declares anything", False),
    "random": ("declares a random hypothesis about once a minute", False),
    "reference": ("the thesis's diagnoser (19 modules, adaptive thresholds, minimal diagnoses)", True),
    "sequential": (
        "the sequential diagnoser: CUSUM tests on the reference's residuals, the same structural "
        "isolation; thresholds calibrated on its own fault-free runs, not on a suite",
        False,
    ),
    "classifier": (
        "supervised GRU on noise-invariant inputs (each residual over its noise level from the episode's "
        "first 4 s), trained over sensor noise 0.5-1.5x and all sampler profile families; alarm threshold and "
        "conformal isolation (abstains with `unknown` when its most probable fault set is less decisive than on "
        "95 % of held-in faulty episodes) calibrated on held-in episodes; 3 training seeds",
        False,
    ),
    "ppo": (
        "reinforcement learning (PPO on replayed episodes, reward MarineFDI-v1) on the same noise-invariant inputs "
        "and training episodes as `classifier`, started from a supervised fit of its policy to those episodes' "
        "ground truth; 3 training seeds",
        False,
    ),
    "ppo-v1": (
        "reinforcement learning (PPO) on the observation features, trained at nominal sensor noise only; one seed: "
        "a named baseline",
        False,
    ),
    "classifier-v1": (
        "supervised GRU on the observation features, trained at nominal sensor noise only; its own alarm and "
        "faults; one seed: a named baseline",
        False,
    ),
    "classifier-v1+reference": (
        "hybrid: classifier-v1 plus the reference's alarm and its isolation whenever it has one",
        True,
    ),
    "oracle": ("reads the ground truth: the ceiling", False),
}

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
    ("dx_true_detection_rate", "DX TDR", "pct"),
    ("dx_false_alarm_rate", "DX FAR", "pct"),
    ("dx_fault_isolation_accuracy", "DX FIA", "pct"),
)
# the DX 2025 metrics per decision (marine_fdi_env.benchmark.metrics.dx_metrics): computed from the stored
# episode records (results written before them lack a dx_metrics field)
DX = ("dx_true_detection_rate", "dx_false_alarm_rate", "dx_fault_isolation_accuracy")
WITH_INTERVAL = (
    "detection_rate",
    "median_detection_delay_censored_s",
    "isolation_accuracy",
    "false_alarm_rate",
    "false_alarm_episode_rate",
    "mean_return",
) + DX


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
        return "∞" if v == float("inf") else f"{v:.1f}"
    if kind == "us":
        return f"{1e6 * v:.1f}"
    return f"{v:.2f}"


def _fmt_est(e, kind: str) -> str:
    """``value (low–high)`` of an :class:`~marine_fdi_env.benchmark.uncertainty.Estimate`."""
    text = _fmt(e.value, kind)
    if e.value is None or e.low is None or e.high is None:
        return text
    bound = (lambda v: _fmt(v, kind).replace(" %", "")) if kind == "pct" else (lambda v: _fmt(v, kind))
    return f"{text} ({bound(e.low)}–{bound(e.high)})"


def _multi_seed(agent: str) -> bool:
    return len(AGENTS[agent]) > 1


def result_path(agent: str, suite: str, seed: int | None = None) -> Path:
    return RESULTS / (f"{agent}_{suite}.json" if seed is None else f"{agent}_s{seed}_{suite}.json")


def _result_paths(agent: str, suite: str) -> list[Path]:
    if _multi_seed(agent):
        return [result_path(agent, suite, s) for s in SEEDS]
    return [result_path(agent, suite)]


def run(
    agents: dict,
    suites,
    force: bool = False,
    force_baselines: bool = False,
    workers: int = 1,
    backend: str | None = None,
    ray_address: str | None = None,
    log=print,
) -> None:
    """Evaluate the missing results; ``force`` re-evaluates the learned agents (and the baselines
    too with ``force_baselines``: their results are shared with the README's baseline table).  Per
    suite, every agent to evaluate is scored on one simulation of its episodes."""
    for suite in suites:
        todo: dict[Path, tuple[str, str]] = {}  # output -> (agent, evaluate --agent spec)
        for name, specs in agents.items():
            for spec, out in zip(specs, _result_paths(name, suite)):
                again = force_baselines or (force and name in LEARNED)
                if out.is_file() and not again:
                    continue
                if "/" in spec and not (ROOT / spec / "agent.json").is_file():
                    log(f"skip {name}: {spec} not trained")
                    continue
                todo[out] = (name, spec)
        if not todo:
            continue
        t0 = time.perf_counter()
        fixed = _suite_reward(suite)
        evaluate_agents(
            [str(ROOT / spec) if "/" in spec else spec for _, spec in todo.values()],
            suite,
            list(todo),
            workers=workers,
            backend=backend,
            ray_address=ray_address,
            progress=False,
            batch_size=BATCH_SIZE,
            reward=None if fixed else REWARD,
        )
        for out, (name, spec) in todo.items():
            _relabel(out, name, spec)
        log(
            f"{suite:13s} {', '.join(sorted({n for n, _ in todo.values()}))}: {time.perf_counter() - t0:6.0f} s -> "
            f"{RESULTS.relative_to(ROOT)}/*_{suite}.json"
        )


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


# ----------------------------------------------------------------------------- loading and estimates
def _results(agent: str, suite: str) -> list[dict] | None:
    """The results of every training seed of ``agent`` on ``suite`` (None if one is missing)."""
    paths = _result_paths(agent, suite)
    if not all(p.is_file() for p in paths):
        return None
    return [json.loads(p.read_text()) for p in paths]


def _pooled(agent: str, suite: str) -> dict | None:
    """The results of ``agent`` on ``suite``, its training seeds pooled (as ``marine-fdi report``)."""
    from marine_fdi_env.benchmark.report import merge_seeds

    rs = _results(agent, suite)
    if rs is None:
        return None
    for k, r in enumerate(rs):
        if _multi_seed(agent):
            r.setdefault("training_seed", SEEDS[k])
    return merge_seeds(rs)[0]


def _load(agent: str, suite: str) -> dict | None:
    """The pooled metrics of ``agent`` on ``suite`` (None if a result is missing)."""
    r = _pooled(agent, suite)
    return None if r is None else r["metrics"]


@lru_cache(maxsize=None)
def _outcomes_cached(agent: str, suite: str, stamp: tuple):
    from marine_fdi_env.benchmark.uncertainty import outcomes

    return outcomes([r["episodes"] for r in _results(agent, suite)])


def _outcomes(agent: str, suite: str):
    paths = _result_paths(agent, suite)
    if not all(p.is_file() for p in paths):
        return None
    return _outcomes_cached(agent, suite, (str(RESULTS),) + tuple(p.stat().st_mtime_ns for p in paths))


def _est(agent: str, suite: str, metric: str):
    """``metric`` of ``agent`` on ``suite`` (``ALL``: every suite's episodes pooled) with its 95 % interval."""
    from marine_fdi_env.benchmark.uncertainty import interval

    o = _outcomes_all(agent) if suite == ALL else _outcomes(agent, suite)
    return None if o is None else interval(o, metric)


ALL = "all suites"


def _outcomes_all(agent: str):
    """The outcomes of ``agent`` over the episodes of every suite (one row per training seed)."""
    per = [_results(agent, s) for s in SUITE_NAMES]
    if any(r is None for r in per):
        return None
    return _all_cached(agent, tuple(p.stat().st_mtime_ns for s in SUITE_NAMES for p in _result_paths(agent, s)))


@lru_cache(maxsize=None)
def _all_cached(agent: str, stamp: tuple):
    from marine_fdi_env.benchmark.uncertainty import outcomes

    per = [_results(agent, s) for s in SUITE_NAMES]
    return outcomes([[e for r in per for e in r[k]["episodes"]] for k in range(len(per[0]))])


def _seed_values(agent: str, suite: str, metric: str) -> list:
    """The metric of each training seed alone (empty for a one-seed agent or a missing result)."""
    from marine_fdi_env.benchmark.uncertainty import interval, outcomes

    rs = _results(agent, suite)
    if rs is None or len(rs) < 2:
        return []
    return [interval(outcomes([r["episodes"]]), metric).value for r in rs]


def _spread(agent: str, suite: str, metric: str, kind: str) -> str:
    """The metric of each training seed alone: ``a / b / c``."""
    return " / ".join(_fmt(v, kind) for v in _seed_values(agent, suite, metric))


def _model_cfgs(name: str) -> list[dict]:
    """The config.json of every model of a learned agent (one per training seed)."""
    out = []
    for spec in AGENTS.get(name, ()):
        if "/" not in spec:
            return []
        d = ROOT / spec
        meta = d / "agent.json"
        if meta.is_file():
            model = (json.loads(meta.read_text()).get("kwargs") or {}).get("model")
            if model:
                d = (d / model).resolve()
        f = d / "config.json"
        if f.is_file():
            out.append(dict(json.loads(f.read_text()), _dir=str(d)))
    return out


def _dir_bytes(d: Path) -> int:
    return sum(f.stat().st_size for f in d.rglob("*") if f.is_file() and f.suffix != ".png")


# ----------------------------------------------------------------------------- tables
def suite_table(suite: str, agents) -> str:
    head = "| agent | seeds | " + " | ".join(t for _, t, _ in METRICS) + " |"
    sep = "|---|---:|" + "---:|" * len(METRICS)
    rows = [head, sep]
    for a in agents:
        m = _load(a, suite)
        if m is None:
            rows.append(f"| {a} | – | " + " | ".join("n/a" for _ in METRICS) + " |")
            continue
        cells = [
            _fmt_est(_est(a, suite, k), kind) if k in WITH_INTERVAL else _fmt(m.get(k), kind) for k, _, kind in METRICS
        ]
        rows.append(f"| {a} | {len(AGENTS[a])} | " + " | ".join(cells) + " |")
    return "\n".join(rows) + "\n"


SUMMARY_COLS = (
    ("single-v1", "isolation_accuracy", "pct", "single iso. acc."),
    ("multi-v1", "isolation_accuracy", "pct", "multi iso. acc."),
    ("incipient-v1", "median_detection_delay_censored_s", "sec", "incipient censored median det. delay [s]"),
    ("nominal-v1", "false_alarm_rate", "rate", "nominal FA [1/h]"),
    ("transfer-v2", "detection_rate", "pct", "transfer-v2 detection"),
    ("transfer-v2", "isolation_accuracy", "pct", "transfer-v2 iso. acc."),
    ("transfer-v2", "false_alarm_rate", "rate", "transfer-v2 FA [1/h]"),
    ("transfer-v3", "detection_rate", "pct", "transfer-v3 detection"),
    ("transfer-v3", "isolation_accuracy", "pct", "transfer-v3 iso. acc."),
    ("transfer-v3", "false_alarm_rate", "rate", "transfer-v3 FA [1/h]"),
    (ALL, "dx_true_detection_rate", "pct", "DX TDR, all suites"),
    (ALL, "dx_false_alarm_rate", "pct", "DX FAR, all suites"),
    (ALL, "dx_fault_isolation_accuracy", "pct", "DX FIA, all suites"),
)


def _training_minutes(a: str) -> str:
    cfgs = _model_cfgs(a)
    if not cfgs:
        return "–"
    v = [c["cpu_minutes"] for c in cfgs]
    return f"{v[0]:.1f}" if len(v) == 1 else f"{max(v):.1f} (max of {len(v)})"


def _cells(agent: str, cols) -> list[str]:
    """One table row's cells: each (suite, metric, format, title) of ``cols`` for ``agent``."""
    out = []
    for suite, key, kind, _ in cols:
        if suite == ALL or key in WITH_INTERVAL:
            e = _est(agent, suite, key)
            out.append("n/a" if e is None else _fmt_est(e, kind))
            continue
        m = _load(agent, suite)
        out.append("n/a" if m is None else _fmt(m.get(key), kind))
    return out


def compact_table(agents) -> str:
    """The headline metrics per agent with their 95 % intervals, the IQM of its normalised scores,
    training cost and size."""
    iqm = _scores()[1]
    head = (
        "| agent | reads the reference | seeds | "
        + " | ".join(c[3] for c in SUMMARY_COLS)
        + " | normalised score, IQM | training [CPU min] | model size |"
    )
    rows = [head, "|---|---|---:|" + "---:|" * (len(SUMMARY_COLS) + 3)]
    for a in agents:
        cells = ["yes" if WHAT[a][1] else "no", str(len(AGENTS[a]))]
        for suite, key, kind, _ in SUMMARY_COLS:
            e = _est(a, suite, key)
            cells.append("n/a" if e is None else _fmt_est(e, kind))
        e = iqm.get(a, {}).get("IQM")
        cells.append("n/a" if e is None else _fmt_est(e, "rate").replace(".00", ".0"))
        cfgs = _model_cfgs(a)
        cells.append(_training_minutes(a))
        cells.append(f"{_dir_bytes(Path(cfgs[0]['_dir'])) / 1024:.0f} KiB" if cfgs else "–")
        rows.append(f"| {a} | " + " | ".join(cells) + " |")
    return "\n".join(rows) + "\n"


def _scores() -> tuple[list[str], dict]:
    """(scored suites, {agent: {suite: Estimate, "IQM": Estimate}}) of every agent with all results."""
    from marine_fdi_env.benchmark.report_scores import scores

    pooled = [r for a in AGENTS for s in SUITE_NAMES if (r := _pooled(a, s)) is not None]
    return scores(pooled) if pooled else ([], {})


def scores_table() -> str:
    suites, table = _scores()
    if not suites:
        return "(no results)\n"
    rows = ["| agent | " + " | ".join(suites) + " | IQM across suites |", "|---|" + "---:|" * (len(suites) + 1)]
    for a in AGENTS:
        if a not in table:
            continue
        cells = [_fmt_est(table[a][s], "rate") if s in table[a] else "n/a" for s in suites]
        cells.append(_fmt_est(table[a]["IQM"], "rate") if "IQM" in table[a] else "n/a")
        rows.append(f"| {a} | " + " | ".join(cells).replace(".00", ".0") + " |")
    return "\n".join(rows) + "\n"


def _onset_delays(name: str, suite: str) -> dict | None:
    """Per faulty episode (of each training seed): detection delay [s] from the first onset (None: not
    detected), keyed (seed index, scenario id)."""
    rs = _results(name, suite)
    if rs is None:
        return None
    from marine_fdi_env.benchmark.metrics import episode_outcome

    return {
        (k, e["scenario_id"]): episode_outcome(e)["detection_delay_s"]
        for k, r in enumerate(rs)
        for e in r["episodes"]
        if e["faults"]
    }


def _median(v: list[float]) -> float:
    v = sorted(v)
    return (v[(len(v) - 1) // 2] + v[len(v) // 2]) / 2


def paired_incipient(a: str) -> dict | None:
    """Median detection delay of ``a`` and of the reference over the incipient-v1 episodes both
    detect (every training seed of ``a`` against the reference on the same episode)."""
    ref, mine = _onset_delays("reference", "incipient-v1"), _onset_delays(a, "incipient-v1")
    if not ref or not mine:
        return None
    pairs = [(d, ref[(0, sid)]) for (k, sid), d in mine.items() if d is not None and ref.get((0, sid)) is not None]
    if not pairs:
        return {"n": 0}
    m, r = _median([p[0] for p in pairs]), _median([p[1] for p in pairs])
    return {
        "n": len(pairs),
        "agent": m,
        "reference": r,
        "ratio": m / r if r else None,
        "earlier": sum(1 for x, y in pairs if x < y - 0.5),
        "later": sum(1 for x, y in pairs if x > y + 0.5),
    }


def _check(rows: list, name: str, agent: str, suite: str, metric: str, kind: str, ok) -> None:
    """One must-show row: a rate over training seeds is judged pooled, with its interval, every seed shown
    (and the seeds that alone would miss the target named)."""
    e = _est(agent, suite, metric)
    if e is None:
        return
    seeds = _seed_values(agent, suite, metric)
    short = [SEEDS[k] for k, v in enumerate(seeds) if v is None or not ok(v)]
    text = _fmt_est(e, kind) + (f"; seeds {_spread(agent, suite, metric, kind)}" if seeds else "")
    met = None if e.value is None else bool(ok(e.value))
    if e.value is not None and ok(e.value) and short:
        text += f" (seed {', '.join(map(str, short))} alone would not meet it)"
    rows.append((name, text, met))


def must_shows() -> list[tuple[str, str, bool | str | None]]:
    """The must-show checks of the learned agents, from the stored results: (check, measured with the
    95 % interval and each training seed's value, met by the pooled estimate; ``"reported"`` for a
    number shown beside a check, not judged).  The incipient check is the censored median; the paired
    median is reported beside it."""
    out: list[tuple[str, str, bool | None]] = []
    fmt = lambda v: "not reached" if v is None else f"{v:.1f} s"  # noqa: E731
    for a in ROBUST:
        for s in ("transfer-v2", "transfer-v3"):
            _check(out, f"{a}: {s} false alarms <= 0.5/h", a, s, "false_alarm_rate", "rate", lambda v: v <= 0.5)
            _check(out, f"{a}: {s} detection >= 90 %", a, s, "detection_rate", "pct", lambda v: v >= 0.9)
            _check(out, f"{a}: {s} isolation accuracy >= 50 %", a, s, "isolation_accuracy", "pct", lambda v: v >= 0.5)
        _check(
            out,
            f"{a}: single-v1 isolation accuracy >= 90 %",
            a,
            "single-v1",
            "isolation_accuracy",
            "pct",
            lambda v: v >= 0.9,
        )
        nom = _load(a, "nominal-v1")
        if nom is not None:
            spread = _spread(a, "nominal-v1", "false_alarm_rate", "rate")
            out.append(
                (
                    f"{a}: nominal-v1 0 false alarms (every seed)",
                    f"{nom['n_false_alarms']} false alarms in {len(AGENTS[a])} x {nom['n_episodes'] // len(AGENTS[a])} "
                    f"episodes; rate {_fmt_est(_est(a, 'nominal-v1', 'false_alarm_rate'), 'rate')}/h"
                    + (f"; seeds {spread}" if spread else ""),
                    nom["n_false_alarms"] == 0,
                )
            )
        inc, ref = (
            _est(a, "incipient-v1", "median_detection_delay_censored_s"),
            _est("reference", "incipient-v1", "median_detection_delay_censored_s"),
        )
        if inc is not None and ref is not None:
            c_me, c_ref = (v if v is not None and v != float("inf") else None for v in (inc.value, ref.value))
            ok = c_me is not None and (c_ref is None or c_me <= 0.5 * c_ref)
            spread = _spread(a, "incipient-v1", "median_detection_delay_censored_s", "sec")
            det, rdet = _load(a, "incipient-v1")["detection_rate"], _load("reference", "incipient-v1")["detection_rate"]
            out.append(
                (
                    f"{a}: incipient-v1 censored median detection delay <= 0.5 x reference's "
                    "(not reached counts as worse than any delay)",
                    (f"{_fmt_est(inc, 'sec')} s" if c_me is not None else "not reached")
                    + f" vs {fmt(c_ref)} (detection "
                    f"{100 * det:.0f} % vs {100 * rdet:.0f} %)" + (f"; seeds {spread}" if spread else ""),
                    ok,
                )
            )
            p = paired_incipient(a)
            if p and p["n"]:
                out.append(
                    (
                        f"{a}: incipient-v1 paired median detection delay vs reference (the {p['n']} "
                        "seed x episode pairs both detect; reported beside the censored median, not a check)",
                        f"{p['agent']:.1f} s vs {p['reference']:.1f} s (ratio {p['ratio']:.2f}; earlier on "
                        f"{p['earlier']}, later on {p['later']})",
                        "reported",
                    )
                )
        cfgs = _model_cfgs(a)
        if cfgs:
            v = [c["cpu_minutes"] for c in cfgs]
            data = [c.get("cpu_s_data", 0) / 60 for c in cfgs]
            out.append(
                (
                    f"{a}: training <= 30 CPU minutes per seed",
                    " / ".join(f"{x:.1f}" for x in v) + f" CPU min (seeds {', '.join(str(c['seed']) for c in cfgs)}; "
                    f"of which simulating the training episodes {' / '.join(f'{x:.1f}' for x in data)}; "
                    f"{cfgs[0]['machine']['cpus']} cores)",
                    max(v) <= 30.0,
                )
            )
    best = [
        (e.value, a)
        for a in ROBUST
        if (e := _est(a, "multi-v1", "isolation_accuracy")) is not None and e.value is not None
    ]
    if best:
        _, a = max(best)
        _check(
            out,
            f"best learned agent ({a}): multi-v1 isolation accuracy >= 50 %",
            a,
            "multi-v1",
            "isolation_accuracy",
            "pct",
            lambda v: v >= 0.5,
        )
    return out


# the pairs whose differences are shown, and the metrics of each suite compared
PAIRS = (
    ("classifier", "classifier-v1"),
    ("classifier", "ppo-v1"),
    ("classifier", "ppo"),
    ("ppo", "ppo-v1"),
    ("classifier", "reference"),
    ("classifier", "sequential"),
    ("classifier-v1", "ppo-v1"),
)
DIFF_COLS = (
    ("single-v1", "isolation_accuracy", "pct"),
    ("multi-v1", "isolation_accuracy", "pct"),
    ("incipient-v1", "detection_rate", "pct"),
    ("transfer-v1", "isolation_accuracy", "pct"),
    ("nominal-v1", "false_alarm_rate", "rate"),
    ("transfer-v2", "detection_rate", "pct"),
    ("transfer-v2", "isolation_accuracy", "pct"),
    ("transfer-v2", "false_alarm_rate", "rate"),
    ("transfer-v3", "detection_rate", "pct"),
    ("transfer-v3", "isolation_accuracy", "pct"),
    ("transfer-v3", "false_alarm_rate", "rate"),
)
_SHORT = {"detection_rate": "detection", "isolation_accuracy": "iso. acc.", "false_alarm_rate": "FA [1/h]"}


def differences_table() -> str:
    """A minus B on the same episodes with the 95 % interval of the difference; bold where the
    interval excludes 0 (only then does the text say that one beats the other)."""
    from marine_fdi_env.benchmark.uncertainty import difference

    rows = [
        "| A - B | " + " | ".join(f"{s} {_SHORT[m]}" for s, m, _ in DIFF_COLS) + " |",
        "|---|" + "---:|" * len(DIFF_COLS),
    ]
    for a, b in PAIRS:
        cells = []
        for s, m, kind in DIFF_COLS:
            oa, ob = _outcomes(a, s), _outcomes(b, s)
            if oa is None or ob is None:
                cells.append("n/a")
                continue
            d = difference(oa, ob, m)
            if d.value is None:
                cells.append("–")
                continue
            scale, unit = (100.0, "") if kind == "pct" else (1.0, "")
            text = f"{scale * d.value:+.1f} ({scale * d.low:+.1f}–{scale * d.high:+.1f}){unit}"
            cells.append(f"**{text}**" if d.low > 0 or d.high < 0 else text)
        rows.append(f"| {a} - {b} | " + " | ".join(cells) + " |")
    return "\n".join(rows) + "\n"


SPREAD_COLS = (("thesis-v1", "isolation_accuracy", "pct"),) + DIFF_COLS


def spread_table() -> str:
    """Each headline rate of every multi-seed agent, training seed by seed."""
    rows = [
        "| agent | " + " | ".join(f"{s} {_SHORT[m]}" for s, m, _ in SPREAD_COLS) + " |",
        "|---|" + "---:|" * len(SPREAD_COLS),
    ]
    for a in AGENTS:
        if not _multi_seed(a):
            continue
        rows.append(
            f"| {a} (seeds {', '.join(map(str, SEEDS))}) | "
            + " | ".join(_spread(a, s, m, k) or "n/a" for s, m, k in SPREAD_COLS)
            + " |"
        )
    return "\n".join(rows) + "\n"


def _group_table(suite: str, agents, key_of, title: str) -> str:
    """Per group of a suite's episodes (``key_of(episode)``): detection, isolation accuracy and
    false-alarm episodes of each agent (training seeds pooled)."""
    from marine_fdi_env.benchmark.metrics import compute_metrics

    groups: dict[str, dict[str, list]] = {}
    for a in agents:
        r = _pooled(a, suite)
        if r is None:
            continue
        for e in r["episodes"]:
            groups.setdefault(key_of(e), {}).setdefault(a, []).append(e)
    rows = [
        "| agent | "
        + " | ".join(f"{title} {g}: detection | {g}: isolation acc. | {g}: FA episodes" for g in sorted(groups))
        + " |",
        "|---|" + "---:|" * (3 * len(groups)),
    ]
    for a in agents:
        cells = []
        for g in sorted(groups):
            eps = groups[g].get(a)
            if not eps:
                cells += ["n/a"] * 3
                continue
            m = compute_metrics(eps)
            cells += [
                _fmt(m["detection_rate"], "pct"),
                _fmt(m["isolation_accuracy"], "pct"),
                f"{sum(1 for e in eps if compute_metrics([e])['n_false_alarms'])}/{len(eps)}",
            ]
        rows.append(f"| {a} | " + " | ".join(cells) + " |")
    return "\n".join(rows) + "\n"


def family_table(suite: str, agents) -> str:
    """Per profile family of a suite."""
    return _group_table(suite, agents, lambda e: e["profile"].split(":")[0], "family")


def noise_table(suite: str, agents) -> str:
    """Per sensor-noise scale of a suite (read from the suite's scenarios)."""
    from marine_fdi_env.benchmark.suites import load_suite

    noise = {s.scenario_id: s.noise_scale for s in load_suite(suite).scenarios}
    return _group_table(suite, agents, lambda e: f"{noise[e['scenario_id']]:g}x", "noise")


def _load_note() -> str:
    loads = []
    for f in RESULTS.glob("*.json"):
        v = json.loads(f.read_text()).get("load_average_1min")
        if v is not None:
            loads.append(v)
    if not loads:
        return "load average not recorded"
    return f"1-minute load average at the end of the runs {min(loads):.1f}-{max(loads):.1f} on 2 cores"


def _data_name(spec: dict) -> str:
    name = spec["config"]["name"] if "config" in spec and "name" in spec["config"] else spec["preset"]
    noise = " at noise " + "/".join(f"{x:g}" for x in spec["noise_scales"]) + "x" if "noise_scales" in spec else ""
    return f"{name} x{spec['episodes']} (seed {spec['seed']}){noise}"


def models_table() -> str:
    rows = [
        "| model | algorithm | training data | training [CPU min] | of which simulating the data | parameters | "
        "files | command |",
        "|---|---|---|---:|---:|---:|---:|---|",
    ]
    for a in LEARNED:
        if a.endswith("+reference"):
            continue
        for cfg in _model_cfgs(a):
            d = Path(cfg["_dir"]).relative_to(ROOT)
            datasets = cfg.get("datasets") or cfg["hyperparams"].get("datasets", [])
            data = ", ".join(_data_name(s) for s in datasets)
            if cfg["algo"] == "classifier":
                cal = cfg.get("calibration_sets") or [cfg["hyperparams"]["calibration"]]
                data += "; calibration: " + ", ".join(_data_name(s) for s in cal)
                algo = "GRU classifier (supervised)"
            else:
                data += f"; {cfg['n_timesteps']} decisions replayed"
                algo = f"PPO on {cfg['env_id']} ({cfg['action_mode']} actions)"
            rows.append(
                f"| `{d}` | {algo} | {data} | {cfg['cpu_minutes']:.1f} | {cfg.get('cpu_s_data', 0) / 60:.1f} | "
                f"{cfg.get('n_parameters', '–')} | {_dir_bytes(ROOT / d) / 1024:.0f} KiB | "
                f"`{_current_spelling(cfg['command'])}` |"
            )
    return "\n".join(rows) + "\n"


def agents_list() -> str:
    return (
        "\n".join(
            f"* `{a}`: {WHAT[a][0]}" + (' (reads `info["reference"]`)' if WHAT[a][1] and a != "reference" else "")
            for a in AGENTS
        )
        + "\n"
    )


def _must_show_block() -> list[str]:
    parts = [
        "| check | measured: pooled over the training seeds (95 % interval); each seed | met (pooled estimate) |",
        "|---|---|---|",
    ]
    for name, val, ok in must_shows():
        mark = "–" if ok is None else ok if isinstance(ok, str) else "yes" if ok else "NO"
        parts.append(f"| {name} | {val} | {mark} |")
    return parts


INTERVAL_NOTE = (
    "95 % intervals in parentheses: a percentile bootstrap (scipy.stats.bootstrap, 2000 resamples) over "
    "the episodes, stratified by fault class, and over the training seeds of a multi-seed agent; where "
    "every resample agrees (e.g. no false alarm at all) the exact interval of one seed's episodes "
    "(Clopper-Pearson; Poisson for rates per hour); `marine_fdi_env.benchmark.uncertainty`."
)


def write_report(path: Path = REPORT, notes: str = "") -> Path:
    agents = list(AGENTS)
    parts = [
        "# Learned diagnosers\n",
        "Generated by `python -m studies.agents.compare` from `docs/data/results/*.json` (`marine-fdi evaluate "
        f"--reward {REWARD} --batch-size {BATCH_SIZE}` of every agent and training seed on every suite, each "
        "suite simulated once and the agents scored on it in lockstep; transfer-v2 and -v3 fix v1 themselves). "
        "Agents (every row named for what it is):\n",
        agents_list(),
        f"{INTERVAL_NOTE}  A learned agent's row pools its training seeds (seeds 0-2: the same command, "
        "each seed training on episodes of its own).\n",
        "## Summary\n",
        compact_table(agents),
        "\nNormalised score: per suite 100 (R - R_null) / (R_oracle - R_null) with R the mean v1 return (null = 0, "
        "oracle = 100; nominal-v1 is not scored: null and oracle both earn 0 there), and its interquartile mean "
        "over training seeds x suites.\n",
        "\n## Normalised scores\n",
        scores_table(),
        "\nThe plot: `marine-fdi report docs/data/results/*.json --out docs/results_all` "
        "(`docs/results_all/scores.png`).\n",
        "\n## Must-show checks\n",
    ] + _must_show_block()
    parts += [
        "\n## Seed-to-seed spread\n",
        "Each training seed alone (seeds 0, 1, 2; same command, each on its own training episodes):\n",
        spread_table(),
        "\n## Differences between agents\n",
        "A minus B on the same episodes (percentage points for rates, 1/h for false alarms), with the 95 % "
        "interval of the difference (paired: the episodes resampled jointly, each agent's seeds independently); "
        "**bold** where the interval excludes 0.  Only a bold cell supports saying that one agent beats the "
        "other on that suite.\n",
        differences_table(),
        "\n## Shipped models\n",
        models_table(),
        "\nCPU minutes: process CPU time (all threads) of the training command on a 2-core machine shared with "
        "other jobs, including simulating the training episodes (the `marine-fdi dataset` exports; a cached "
        "export counts with the CPU time it took) and, for the classifier, the calibrations.\n",
    ]
    if notes:
        parts += ["\n", notes.strip() + "\n"]
    parts += [
        "\n## transfer-v2 by profile family\n",
        "Harbour telegraph steps and sea-state load fluctuation, both at sensor noise 0.7x (never in any "
        "training or calibration data):\n",
        family_table("transfer-v2", agents),
        "\n## transfer-v3 by sensor-noise scale\n",
        "Slow steaming at part load with waves (a profile family never in any training or calibration data) at "
        "sensor noise 1.3x and 0.6x:\n",
        noise_table("transfer-v3", agents),
    ]
    parts.append("\n## Every metric, every suite\n")
    parts.append(
        f"Compute: features = the observation features every agent shares, per sensor sample; agent = the "
        f"agent's own decision per decision and engine; both at a batch of {BATCH_SIZE} episodes on the shared "
        f"2-core machine ({_load_note()}): their spread between rows is the machine's load, not the agent.\n"
    )
    for s in SUITE_NAMES:
        parts += [f"\n### {s}\n", suite_table(s, agents)]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("\n".join(parts))
    return path


BEGIN, END = "<!-- compare:begin (python -m studies.agents.compare writes this block) -->", "<!-- compare:end -->"


def _all_files() -> list[Path]:
    return [p for s in SUITE_NAMES for a in AGENTS for p in _result_paths(a, s) if p.is_file()]


HEADLINE_COLS = (
    ("single-v1", "isolation_accuracy", "pct", "single-v1 isolation"),
    ("multi-v1", "isolation_accuracy", "pct", "multi-v1 isolation"),
    ("transfer-v3", "isolation_accuracy", "pct", "transfer-v3 isolation"),
    ("nominal-v1", "n_false_alarms", "int", "nominal-v1 false alarms"),
    (ALL, "dx_true_detection_rate", "pct", "DX TDR"),
    (ALL, "dx_false_alarm_rate", "pct", "DX FAR"),
    (ALL, "dx_fault_isolation_accuracy", "pct", "DX FIA"),
)
README_AGENTS = 9  # rows of the README's table (the hybrid classifier-v1+reference is in docs/results.md)


def _headline_cell(e, kind: str) -> str:
    """A compact cell of the README's table: a rate in % with its 95 % interval rounded outward to whole
    percent (``94.0 (90-98)``), a count as it is."""
    if e is None:
        return "n/a"
    if kind != "pct" or e.value is None or e.low is None or e.high is None:
        return _fmt_est(e, kind).replace(" %", "")
    return f"{100 * e.value:.1f} ({math.floor(100 * e.low + 1e-9):.0f}-{math.ceil(100 * e.high - 1e-9):.0f})"


HEADLINE_NOTE = (
    "Rates in % with 95 % intervals (rounded outward); isolation: the final declaration is exactly the active "
    "faults; DX: the DX 2025 competition's metrics per decision, all suites "
    "([submitting.md](docs/submitting.md#the-dx-metrics)); verified entries: [leaderboard](leaderboard/README.md)."
)


def headline_table(agents) -> str:
    """The README's table: one row per agent (at most 9), one headline metric per suite family and the DX
    metrics, each rate with its 95 % interval."""
    rows = [
        "| agent | seeds | " + " | ".join(c[3] for c in HEADLINE_COLS) + " |",
        "|---|---:|" + "---:|" * len(HEADLINE_COLS),
    ]
    for a in [a for a in agents if not a.endswith("+reference")][:README_AGENTS]:
        cells = []
        for suite, key, kind, _ in HEADLINE_COLS:
            if kind == "pct":
                cells.append(_headline_cell(_est(a, suite, key), kind))
            else:
                m = _load(a, suite)
                cells.append("n/a" if m is None else _fmt(m.get(key), kind))
        rows.append(f"| `{a}` | {len(AGENTS[a])} | " + " | ".join(cells) + " |")
    return "\n".join(rows) + "\n"


def readme_block() -> str:
    """The README's generated block: the headline table and where the rest is."""
    return "\n".join([BEGIN, HEADLINE_NOTE, "", headline_table(AGENTS), END])


def results_block() -> str:
    """docs/results.md's generated tables: ``marine-fdi report``'s main table, the summary and must-shows."""
    from marine_fdi_env.benchmark.report import load_results, markdown_table

    files = _all_files()
    results = load_results(files) if files else []
    parts = (
        [
            BEGIN,
            "",
            "Agents:\n",
            agents_list(),
            f"All suites, all agents, scored on MarineFDI-v1 (`marine-fdi report docs/data/results/*.json`; "
            f"compute at a batch of {BATCH_SIZE} episodes).  {INTERVAL_NOTE}\n",
            markdown_table(results, intervals=True) if results else "(no results)\n",
            "Headline numbers, normalised scores, training compute and size of the learned agents "
            "(`python -m studies.agents.compare`; more in docs/learned_agents.md):\n",
            compact_table(list(AGENTS)),
            "\nMust-show checks of the noise-invariant learned agents:\n",
        ]
        + _must_show_block()
        + ["", END]
    )
    return "\n".join(parts)


def write_block(path: Path, block: str) -> bool:
    """Replace the block between the compare markers of ``path``; False if it has none."""
    text = path.read_text()
    if BEGIN not in text or END not in text:
        return False
    a, b = text.index(BEGIN), text.index(END) + len(END)
    path.write_text(text[:a] + block + text[b:])
    return True


def transfer_probe(agent: str = "reference", suite: str = "transfer-v2", log=print) -> dict:
    """What makes a transfer suite hard for an agent: its scenarios as in the suite, at the training
    noise (1.0x), and with a constant profile at the profile's mean level at the suite's noise;
    detection, isolation accuracy, false alarms (a multi-seed agent: every training seed, pooled).
    Nothing is tuned on it: it splits the suite's conditions apart after the fact."""
    import re
    from dataclasses import replace

    from marine_fdi_env.benchmark.agent_api import load_agent
    from marine_fdi_env.benchmark.evaluate import run_episodes
    from marine_fdi_env.benchmark.metrics import compute_metrics
    from marine_fdi_env.benchmark.suites import load_suite

    scs = load_suite(suite).scenarios

    def level(p: str) -> float:
        m = re.search(r"u_mean=([0-9.]+)", p)
        return float(m.group(1)) if m else 0.65

    noise = "/".join(f"{x:g}" for x in sorted({s.noise_scale for s in scs}))
    variants = {
        f"as in the suite (noise {noise}x)": scs,
        "the same profiles at noise 1.0x": [replace(s, noise_scale=1.0) for s in scs],
        f"constant profile at the mean level, noise {noise}x": [
            replace(s, profile=f"constant:u0={level(s.profile)}") for s in scs
        ],
    }
    specs = AGENTS.get(agent, (agent,))
    out = {}
    for name, v in variants.items():
        recs = []
        for spec in specs:
            full = str(ROOT / spec) if "/" in spec else spec
            recs += run_episodes(load_agent(full), v, {"reward": REWARD}, suite=f"{suite}-probe")
        m = compute_metrics(recs)
        out[name] = m
        log(
            f"| {agent} | {name} | {_fmt(m['detection_rate'], 'pct')} | {_fmt(m['isolation_accuracy'], 'pct')} | "
            f"{m['n_false_alarms']} ({m['false_alarm_rate']:.2f}/h) |"
        )
    return out


NOTES_FILE = ROOT / "training" / "NOTES.md"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m studies.agents.compare", description=__doc__.splitlines()[0])
    ap.add_argument("--agents", nargs="*", default=list(AGENTS), choices=list(AGENTS))
    ap.add_argument("--suites", nargs="*", default=list(SUITE_NAMES))
    ap.add_argument("--force", action="store_true", help="re-evaluate the learned agents even when results exist")
    ap.add_argument("--force-baselines", action="store_true", help="re-evaluate null/random/reference/oracle too")
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument(
        "--backend",
        choices=("serial", "process", "ray"),
        default=None,
        help="where the chunks run (marine-fdi evaluate's --backend; default: process if --workers > 1)",
    )
    ap.add_argument("--ray-address", default=None, help="a Ray cluster to run on (marine-fdi evaluate's --ray-address)")
    ap.add_argument("--report-only", action="store_true")
    ap.add_argument(
        "--probe",
        choices=("transfer-v2", "transfer-v3"),
        default=None,
        help="only print what makes that transfer suite hard for the --agents (noise vs profiles)",
    )
    ap.add_argument(
        "--transfer-v2-probe",
        action="store_const",
        const="transfer-v2",
        dest="probe",
        help="the same as --probe transfer-v2",
    )
    args = ap.parse_args(argv)
    if args.probe:
        print("| agent | episodes | detection | isolation acc. | false alarms |\n|---|---|---:|---:|---:|")
        for a in args.agents:
            transfer_probe(a, args.probe)
        return 0
    if not args.report_only:
        t0 = time.perf_counter()
        run(
            {a: AGENTS[a] for a in args.agents},
            args.suites,
            force=args.force,
            force_baselines=args.force_baselines,
            workers=args.workers,
            backend=args.backend,
            ray_address=args.ray_address,
        )
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
