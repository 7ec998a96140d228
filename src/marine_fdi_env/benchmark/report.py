"""Benchmark report: Markdown tables and plots from ``marine-fdi evaluate`` results files.

``marine-fdi report results*.json [--out DIR] [--no-plots]`` writes

* ``DIR/report.md``: the main table, one table per fault class, per suite a per-fault table
  (single-fault episodes: detection rate, isolation accuracy, median detection delay of each
  fault for each agent) and per suite and agent a confusion matrix of the final declaration
  against the truth (its non-zero cells, one row per true label);
* ``DIR/confusion.json``: the full confusion matrices (labels, counts, episodes per true label);
* with matplotlib: ``DIR/summary.png`` (detection rate, isolation accuracy and false-alarm
  episode rate per agent, one panel per suite), ``DIR/detection_delay.png`` (detection delays
  per agent, one panel per suite with faulty episodes) and ``DIR/confusion_<suite>.png`` (the
  confusion matrices as heat maps, one panel per agent).

Confusion matrix (decision: written here, not in the thesis).  Per episode, the *true* labels
are the faults active at the final decision time (the set the isolation accuracy compares
with; ``no fault`` when none is), the *declared* labels the final declared set, or ``unknown``
(the alarm is on, no fault named) or ``nothing`` (no alarm).  The episode adds 1 to every
(true, declared) pair: a single-fault episode to one cell, so the diagonal over a suite's
single-fault episodes is the isolation accuracy; an episode with two true and two declared
faults to four cells.

A results file is JSON ``{"agent", "suite", "suite_version", "metrics", "episodes", ...}``;
``metrics`` is recomputed from ``episodes`` when absent (see :mod:`.metrics`).  A learned agent
trained with several seeds has one results file per training seed (``training_seed``); the report
pools them into one row per suite and agent (its metrics over all their episodes), and every rate
carries its 95 % interval, a stratified bootstrap over episodes and training seeds
(:mod:`.uncertainty`).  With the null agent's and the oracle's results of a suite, ``report.md``
also gives each agent's normalised score per suite and their interquartile mean across suites,
with intervals, and ``scores.png`` plots them (:mod:`.report_scores`).
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping, Sequence

from ..engine.faults import FAULT_IDS
from ..errors import DataFileError
from ..jsonfile import read_json
from ..plotting import pyplot
from .metrics import FAULT_CLASSES, compute_metrics, episode_outcome

__all__ = [
    "load_results",
    "merge_seeds",
    "markdown_table",
    "write_report",
    "agent_sort_key",
    "fault_table",
    "confusion_matrix",
    "confusion_markdown",
    "NO_FAULT_LABEL",
    "UNKNOWN_LABEL",
    "NOTHING_LABEL",
    "report_pyplot",
]

_FIXED_FIRST = ("null", "random", "reference")
_FIXED_LAST = ("oracle",)
_DASH = "–"


# ----------------------------------------------------------------------------- loading


def _parquet_results(p: Path) -> list[dict]:
    """Results objects from a Parquet file: an evaluation's records, or a sweep's table (one
    object per agent x suite)."""
    from .records import read_records, sweep_results

    records, meta = read_records(p, keep_extra=True)
    if not records:
        raise DataFileError(f"{p}: no episode records: nothing to report")
    if meta.get("kind") == "marine-fdi sweep" or (records and "agent_spec" in records[0]):
        return sweep_results(records, str(p))
    for r in records:
        r.pop("agent_spec", None)
        r.pop("seed_offset", None)
    data = dict(meta, episodes=records, path=str(p))
    data.setdefault("agent", records[0]["agent"] if records else "")
    data.setdefault("suite", records[0]["suite"] if records else "")
    return [data]


def load_results(paths: Iterable[str | Path]) -> list[dict]:
    """Read results files; ``ValueError`` naming the path when missing or corrupt.

    A path is a JSON results file, a Parquet results file (``evaluate --out X.parquet``), or a
    sweep's table or folder (``marine-fdi sweep --out DIR``: one result per agent x suite).
    Each returned dict is the file's content plus ``"path"``; ``metrics`` is filled in from
    ``episodes`` when the file has none.
    """
    out = []
    for p in map(Path, paths):
        if p.is_dir() and (p / "episodes.parquet").is_file():
            p = p / "episodes.parquet"
        if not p.exists():
            raise ValueError(f"{p}: results file not found")
        if p.suffix == ".parquet":
            out += _parquet_results(p)
            continue
        data = read_json(p, "JSON results file")
        if not isinstance(data, dict):
            raise ValueError(f"{p}: results file must hold a JSON object")
        for key in ("agent", "suite"):
            if not isinstance(data.get(key), str):
                raise ValueError(f"{p}: field {key!r} missing or not a string")
        if "episodes" not in data:
            raise DataFileError(
                f"{p}: field 'episodes' is missing (a results file of 'marine-fdi evaluate' lists its episode records)"
            )
        episodes = data["episodes"]
        if not isinstance(episodes, list):
            raise DataFileError(f"{p}: field 'episodes' must be a list of episode records")
        if not episodes:
            raise DataFileError(f"{p}: field 'episodes' is empty: no episode to report (rerun 'marine-fdi evaluate')")
        metrics = data.get("metrics")
        try:
            if metrics is None:
                data["metrics"] = compute_metrics(episodes)
            elif not isinstance(metrics, dict):
                raise ValueError("field 'metrics' must be an object")
        except ValueError as e:
            raise ValueError(f"{p}: {e}") from None
        data["path"] = str(p)
        out.append(data)
    return out


def merge_seeds(results: Sequence[Mapping]) -> list[dict]:
    """One result per suite and agent: the results of an agent's training seeds (``training_seed``)
    pooled (episodes concatenated seed by seed, metrics recomputed), each with ``seed_results``, the
    results it pools in seed order; ``ValueError`` for two results of the same suite, agent and
    seed."""
    groups: dict[tuple[str, str], list[Mapping]] = {}
    seen: dict[tuple, str] = {}
    for r in results:
        key = (r["suite"], r["agent"], r.get("training_seed"))
        if key in seen:
            seed = "" if key[2] is None else f", training seed {key[2]}"
            raise ValueError(
                f"two results for suite {key[0]!r}, agent {key[1]!r}{seed}: {seen[key]} and {r.get('path', '?')}"
            )
        seen[key] = r.get("path", "?")
        groups.setdefault(key[:2], []).append(r)
    out = []
    for (suite, agent), rs in groups.items():
        rs = sorted(rs, key=lambda r: (r.get("training_seed") is None, r.get("training_seed") or 0))
        if len(rs) > 1 and any(r.get("training_seed") is None for r in rs):
            raise ValueError(
                f"suite {suite!r}, agent {agent!r}: several results, not all with a training_seed: "
                + ", ".join(str(r.get("path", "?")) for r in rs)
            )
        if len(rs) == 1:
            out.append(dict(rs[0], seed_results=[rs[0]]))
            continue
        episodes = [e for r in rs for e in r["episodes"]]
        out.append(
            dict(
                rs[0],
                episodes=episodes,
                metrics=compute_metrics(episodes),
                seed_results=list(rs),
                training_seeds=[r["training_seed"] for r in rs],
                path=", ".join(str(r.get("path", "?")) for r in rs),
            )
        )
    return out


def agent_sort_key(agent: str) -> tuple[int, str]:
    """null, random, reference first, then others alphabetically, oracle last."""
    a = agent.lower()
    if a in _FIXED_FIRST:
        return (_FIXED_FIRST.index(a), a)
    if a in _FIXED_LAST:
        return (len(_FIXED_FIRST) + 1 + _FIXED_LAST.index(a), a)
    return (len(_FIXED_FIRST), a)


def _sorted(results: Sequence[Mapping]) -> list[Mapping]:
    """The results with the seeds of each agent pooled (:func:`merge_seeds`), in table order."""
    if not all("seed_results" in r for r in results):
        results = merge_seeds(results)
    return sorted(results, key=lambda r: (_suite_sort_key(r["suite"]), agent_sort_key(r["agent"])))


def _suite_sort_key(suite: str) -> tuple:
    """Shipped suites in their documented order (thesis, single, multi, ...), then others by name."""
    from .suites import SUITE_NAMES

    return (SUITE_NAMES.index(suite), "") if suite in SUITE_NAMES else (len(SUITE_NAMES), suite)


# ----------------------------------------------------------------------------- formatting


def _f(fmt: Callable[[float], str]) -> Callable[[Any], str]:
    return lambda v: _DASH if v is None else fmt(float(v))


_pct = _f(lambda v: f"{100 * v:.1f} %")
_pct0 = _f(lambda v: f"{100 * v:.0f}")
_sec = _f(lambda v: f"{v:.1f}")
_rate = _f(lambda v: f"{v:.2f}")
_usps = _f(lambda v: f"{1e6 * v:.1f}")
_int = _f(lambda v: f"{int(v)}")


@dataclass(frozen=True)
class _Col:
    title: str
    key: str
    fmt: Callable[[Any], str]


COLUMNS: tuple[_Col, ...] = (
    _Col("Episodes", "n_episodes", _int),
    _Col("Detection", "detection_rate", _pct),
    _Col("Median det. delay [s]", "median_detection_delay_s", _sec),
    _Col("Censored median det. delay [s]", "median_detection_delay_censored_s", _sec),
    _Col("P90 det. delay [s]", "p90_detection_delay_s", _sec),
    _Col("Isolation acc.", "isolation_accuracy", _pct),
    _Col("Belief on truth", "belief_on_truth", _pct),
    _Col("Median iso. delay [s]", "median_isolation_delay_s", _sec),
    _Col("P90 iso. delay [s]", "p90_isolation_delay_s", _sec),
    _Col("False alarms [1/h]", "false_alarm_rate", _rate),
    _Col("FA episodes", "false_alarm_episode_rate", _pct),
    _Col("Mean return", "mean_return", _rate),
    _Col("Features [µs/sample]", "feature_compute_s_per_sample", _usps),
    _Col("Agent [µs/decision]", "agent_compute_s_per_decision", _usps),
)
# the DX 2025 metrics per decision (:func:`.metrics.dx_metrics`), beside ours in the main table
DX_COLUMNS: tuple[_Col, ...] = (
    _Col("DX TDR", "dx_true_detection_rate", _pct),
    _Col("DX FAR", "dx_false_alarm_rate", _pct),
    _Col("DX FIA", "dx_fault_isolation_accuracy", _pct),
)
_FA_COLUMNS = tuple(
    c
    for c in COLUMNS
    if c.key
    in (
        "n_episodes",
        "false_alarm_rate",
        "false_alarm_episode_rate",
        "mean_return",
        "feature_compute_s_per_sample",
        "agent_compute_s_per_decision",
    )
)


# the columns that carry a 95 % interval (the metrics of :data:`.uncertainty.RATE_METRICS`)
_INTERVAL_KEYS = (
    "detection_rate",
    "median_detection_delay_censored_s",
    "isolation_accuracy",
    "false_alarm_rate",
    "false_alarm_episode_rate",
    "mean_return",
    "dx_true_detection_rate",
    "dx_false_alarm_rate",
    "dx_fault_isolation_accuracy",
)


def _value(r: Mapping, key: str):
    """A metric of a result: ``metrics[key]``, or a DX metric (``dx_*``) from its ``dx_metrics`` or its
    episodes (results written before the DX metrics lack them)."""
    if not key.startswith("dx_"):
        return r.get("metrics", r).get(key)
    dx = r.get("dx_metrics")
    if dx is None and "episodes" in r:
        from .metrics import dx_metrics

        dx = dx_metrics(r["episodes"])
    return (dx or {}).get(key[3:])


def _with_interval(col: _Col, est) -> str:
    """``value (low–high)``; the bounds in the column's format without a unit."""
    text = col.fmt(est.value)
    if est.value is None or est.low is None or est.high is None:
        return text
    bound = (lambda v: col.fmt(v).replace(" %", "")) if col.fmt is _pct else col.fmt
    high = "∞" if est.high == float("inf") else bound(est.high)  # a censored delay whose bound is not reached
    return f"{text} ({bound(est.low)}–{high})"


def _interval_cells(r: Mapping, cols: Sequence[_Col]) -> list[str]:
    from .uncertainty import interval, outcomes

    o = outcomes([x["episodes"] for x in r.get("seed_results") or [r]])
    return [_with_interval(c, interval(o, c.key)) if c.key in _INTERVAL_KEYS else c.fmt(_value(r, c.key)) for c in cols]


def _table(rows: Sequence[tuple[str, str, Mapping]], cols: Sequence[_Col], intervals: bool = False) -> str:
    """Rows (suite, agent, result or metrics); with ``intervals`` the results' rate cells carry their
    95 % intervals and a column gives the number of training seeds."""
    head = ["Suite", "Agent", *(["Seeds"] if intervals else []), *(c.title for c in cols)]
    lines = [
        "| " + " | ".join(head) + " |",
        "|" + "|".join([" --- ", " --- "] + [" ---: "] * (len(cols) + int(intervals))) + "|",
    ]
    for suite, agent, r in rows:
        if intervals:
            cells = [suite, agent, str(len(r.get("seed_results") or [r])), *_interval_cells(r, cols)]
        else:
            cells = [suite, agent, *(c.fmt(_value(r, c.key)) for c in cols)]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def markdown_table(results: Sequence[Mapping], intervals: bool = False) -> str:
    """Main Markdown table: one row per (suite, agent), an agent's training seeds pooled; with
    ``intervals``, every rate with its 95 % interval (:mod:`.uncertainty`) and a seeds column."""
    return _table([(r["suite"], r["agent"], r) for r in _sorted(results)], COLUMNS + DX_COLUMNS, intervals)


def class_table(results: Sequence[Mapping], fault_class: str) -> str:
    """Markdown table of one fault class (``metrics["by_class"][fault_class]``)."""
    cols = _FA_COLUMNS if fault_class == "none" else COLUMNS
    rows = [(r["suite"], r["agent"], r["metrics"].get("by_class", {}).get(fault_class) or {}) for r in _sorted(results)]
    return _table(rows, cols)


# ----------------------------------------------------------------------------- per fault, confusion


def fault_table(results: Sequence[Mapping]) -> str:
    """Markdown table of one suite's single-fault episodes per fault id (``metrics["by_fault"]``):
    one row per fault, one column per agent, each cell "detection / isolation accuracy / median
    detection delay"; empty string when no result has single-fault episodes."""
    rs = _sorted(results)
    faults = [f for f in FAULT_IDS if any(f in (r["metrics"].get("by_fault") or {}) for r in rs)]
    if not faults:
        return ""
    lines = [
        "| Fault | Episodes | " + " | ".join(r["agent"] for r in rs) + " |",
        "| --- | ---: |" + " :---: |" * len(rs),
    ]
    for f in faults:
        cells, n = [], None
        for r in rs:
            m = (r["metrics"].get("by_fault") or {}).get(f)
            if not m:
                cells.append(_DASH)
                continue
            n = m.get("n_episodes") if n is None else n
            cells.append(
                f"{_pct0(m.get('detection_rate'))} / {_pct0(m.get('isolation_accuracy'))} / "
                f"{_sec(m.get('median_detection_delay_s'))}"
            )
        lines.append(f"| {f} | {_int(n)} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


NO_FAULT_LABEL = "no fault"  # true label of an episode with no fault active at its end
UNKNOWN_LABEL = "unknown"  # declared: alarm on, no fault named
NOTHING_LABEL = "nothing"  # declared: no alarm


_OUTCOMES: dict[int, tuple[Mapping, list[dict]]] = {}  # scored episodes of a result, while a report is written


def _outcomes(result: Mapping) -> list[dict]:
    """``episode_outcome`` of every episode of a result (scored once per report)."""
    hit = _OUTCOMES.get(id(result))
    if hit is None or hit[0] is not result:
        hit = _OUTCOMES[id(result)] = (result, [episode_outcome(e) for e in result["episodes"]])
    return hit[1]


def _result_labels(result: Mapping) -> list[tuple[list[str], list[str]]]:
    return [_episode_labels(ep, o) for ep, o in zip(result["episodes"], _outcomes(result))]


def _episode_labels(ep: Mapping, o: Mapping | None = None) -> tuple[list[str], list[str]]:
    """(true labels, declared labels) of one episode record (module docstring)."""
    o = episode_outcome(ep) if o is None else o
    true = list(o["final_true"]) or [NO_FAULT_LABEL]
    if o["final_declared"]:
        return true, list(o["final_declared"])
    changes = ep.get("declared_changes") or []
    alarm = bool(changes[-1][2]) if changes else False
    return true, [UNKNOWN_LABEL if alarm else NOTHING_LABEL]


def _label_order(labels: Iterable[str], extra: Sequence[str]) -> list[str]:
    order = {f: i for i, f in enumerate(list(FAULT_IDS) + list(extra))}
    return sorted(set(labels), key=lambda x: (order.get(x, len(order)), x))


def confusion_matrix(result: Mapping, rows: Sequence[str] | None = None, cols: Sequence[str] | None = None) -> dict:
    """``{"true": [...], "declared": [...], "counts": [[...]], "episodes": [...]}``: counts[i][j] =
    episodes (module docstring) with true label ``true[i]`` and declared label ``declared[j]``;
    episodes[i] = episodes with true label ``true[i]`` (a row of ``counts`` sums to more when
    episodes declared several faults).  ``rows``/``cols`` fix the labels (default: those that
    occur, faults in FAULT_IDS order)."""
    labels = _result_labels(result)
    pairs = []
    for t, d in labels:
        pairs += [(a, b) for a in t for b in d]
    rows = list(rows) if rows is not None else _label_order((a for a, _ in pairs), [NO_FAULT_LABEL])
    cols = list(cols) if cols is not None else _label_order((b for _, b in pairs), [UNKNOWN_LABEL, NOTHING_LABEL])
    ri, ci = {x: i for i, x in enumerate(rows)}, {x: j for j, x in enumerate(cols)}
    counts = [[0] * len(cols) for _ in rows]
    for a, b in pairs:
        counts[ri[a]][ci[b]] += 1
    episodes = [0] * len(rows)
    for t, _ in labels:
        for a in set(t):
            episodes[ri[a]] += 1
    return {"true": rows, "declared": cols, "counts": counts, "episodes": episodes}


def _suite_labels(rs: Sequence[Mapping]) -> tuple[list[str], list[str]]:
    """The true and declared labels occurring in any result of a suite (shared by its panels)."""
    t_all, d_all = [], []
    for r in rs:
        for t, d in _result_labels(r):
            t_all += t
            d_all += d
    return (_label_order(t_all, [NO_FAULT_LABEL]), _label_order(d_all, [UNKNOWN_LABEL, NOTHING_LABEL]))


def confusion_markdown(cm: Mapping) -> str:
    """A confusion matrix as a Markdown table of its non-zero cells: one row per true label with
    its number of episodes and "declared count" entries, the correct one in bold."""
    lines = ["| True | Episodes | Declared at the end (episodes) |", "| --- | ---: | --- |"]
    for i, t in enumerate(cm["true"]):
        row = cm["counts"][i]
        n = cm["episodes"][i] if "episodes" in cm else sum(row)
        cells = sorted(((c, d) for d, c in zip(cm["declared"], row) if c), key=lambda x: -x[0])
        text = ", ".join(
            (f"**{d}** {c}" if d == t or (t == NO_FAULT_LABEL and d == NOTHING_LABEL) else f"{d} {c}") for c, d in cells
        )
        lines.append(f"| {t} | {n} | {text} |")
    return "\n".join(lines) + "\n"


# ----------------------------------------------------------------------------- plots


def report_pyplot():
    """matplotlib's pyplot for the report's figures (a missing extra's message offers --no-plots)."""
    return pyplot("or pass --no-plots")


def _by_suite(results: Sequence[Mapping]) -> dict[str, list[Mapping]]:
    groups: dict[str, list[Mapping]] = {}
    for r in _sorted(results):
        groups.setdefault(r["suite"], []).append(r)
    return groups


def _has_faults(rs: Sequence[Mapping]) -> bool:
    return any(r["metrics"].get("n_faulty") or any(e.get("faults") for e in r["episodes"]) for r in rs)


def plot_detection_delays(results: Sequence[Mapping], path: Path) -> Path | None:
    """Detection delays per agent (box and points), one panel per suite that has faulty episodes
    (none is drawn for a fault-free suite such as nominal-v1); ``None`` when no suite has one.
    The delay axis is linear up to 1 s (the decision period) and logarithmic above."""
    plt = report_pyplot()
    groups = {s: rs for s, rs in _by_suite(results).items() if _has_faults(rs)}
    if not groups:
        return None
    fig, axes = plt.subplots(len(groups), 1, figsize=(9, 3.0 * len(groups) + 0.4), squeeze=False)
    for ax, (suite, rs) in zip(axes[:, 0], groups.items()):
        data = [[o["detection_delay_s"] for o in _outcomes(r) if o["detection_delay_s"] is not None] for r in rs]
        n_faulty = [r["metrics"].get("n_faulty") or 0 for r in rs]
        ax.boxplot(
            [d if d else [float("nan")] for d in data],
            showfliers=True,
            widths=0.5,
            medianprops={"color": "C1", "lw": 2},
            flierprops={"markersize": 3, "alpha": 0.5},
        )
        for i, d in enumerate(data, start=1):
            if not d:
                ax.text(i, 0.5, "no detection", ha="center", va="center", fontsize=8, color="0.4")
        ax.set_xticks(
            range(1, len(rs) + 1),
            [f"{r['agent']}\n{len(d)}/{n} detected" for r, d, n in zip(rs, data, n_faulty)],
            fontsize=8,
        )
        ax.set_yscale("symlog", linthresh=1.0)
        top = max([max(d) for d in data if d] + [1.0]) * 1.5
        ax.set_ylim(0, top)
        ticks = [t for t in (0, 0.5, 1, 3, 10, 30, 100, 300, 1000, 3000) if t <= top]
        ax.set_yticks(ticks, [f"{t:g}" for t in ticks])
        ax.minorticks_off()
        ax.set_title(f"suite {suite}: detection delay after the first fault onset", fontsize=10)
        ax.set_ylabel("delay [s]")
        ax.grid(axis="y", alpha=0.3, which="both")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


_BARS = (
    ("detection_rate", "detection rate"),
    ("isolation_accuracy", "isolation accuracy"),
    ("false_alarm_episode_rate", "episodes with a false alarm"),
)


def plot_summary(results: Sequence[Mapping], path: Path) -> Path:
    """Grouped bars of detection rate, isolation accuracy, false-alarm episodes (%), one panel per
    suite, each bar labelled with its value ("n/a" where undefined, e.g. detection on a
    fault-free suite); one legend above the panels, never over a bar."""
    plt = report_pyplot()
    groups = _by_suite(results)
    fig, axes = plt.subplots(len(groups), 1, figsize=(9, 2.9 * len(groups) + 0.6), squeeze=False)
    width = 0.8 / len(_BARS)
    handles = []
    for ax, (suite, rs) in zip(axes[:, 0], groups.items()):
        for j, (key, label) in enumerate(_BARS):
            xs = [i + (j - 1) * width for i in range(len(rs))]
            raw = [r["metrics"].get(key) for r in rs]
            vals = [0.0 if v is None else 100 * v for v in raw]
            bars = ax.bar(xs, vals, width, label=label, color=f"C{j}")
            if len(handles) < len(_BARS):
                handles.append(bars)
            for x, v, r in zip(xs, vals, raw):
                ax.text(
                    x,
                    v + 1.5,
                    "n/a" if r is None else f"{v:.0f}",
                    ha="center",
                    va="bottom",
                    fontsize=6.5,
                    color="0.45" if r is None else "0.1",
                )
        ax.set_xticks(range(len(rs)), [r["agent"] for r in rs], fontsize=9)
        ax.set_xlim(-0.6, max(len(rs), 2) - 0.4)
        ax.set_ylim(0, 115)
        ax.set_yticks(range(0, 101, 20))
        ax.set_ylabel("%")
        ax.set_title(
            f"suite {suite}" + ("" if _has_faults(rs) else " (fault-free: only false alarms apply)"), fontsize=10
        )
        ax.grid(axis="y", alpha=0.3)
    fig.legend(
        handles,
        [label for _, label in _BARS],
        loc="upper center",
        ncol=len(_BARS),
        fontsize=9,
        frameon=False,
        bbox_to_anchor=(0.5, 1.0),
    )
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.35 / fig.get_figheight()))
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_confusion(rs: Sequence[Mapping], path: Path) -> Path:
    """One suite's confusion matrices (module docstring) as heat maps, one panel per agent."""
    import numpy as np

    plt = report_pyplot()
    rows, cols = _suite_labels(rs)
    n = len(rs)
    ncol = min(3, n)
    nrow = -(-n // ncol)
    cell = 0.24
    w = cell * len(cols) + 0.4
    h = max(cell * len(rows) + 0.5, 1.4)  # a one-row matrix (a fault-free suite) still needs room for title and labels
    lab_w = 0.07 * max(len(x) for x in rows) + 0.6  # room for the y tick labels of the first column
    lab_h = 0.065 * max(len(x) for x in cols) + 0.5  # room for the x tick labels of the bottom row
    fig, axes = plt.subplots(nrow, ncol, figsize=(w * ncol + lab_w, h * nrow + lab_h + 0.3), squeeze=False)
    for k, ax in enumerate(axes.flat):
        if k >= n:
            ax.axis("off")
            continue
        cm = confusion_matrix(rs[k], rows, cols)
        c = np.array(cm["counts"], dtype=float)
        ax.imshow(np.where(c > 0, c, np.nan), cmap="Blues", aspect="auto", vmin=0, vmax=max(1.0, c.max()))
        for i in range(len(rows)):
            for j in range(len(cols)):
                if c[i, j]:
                    ax.text(
                        j,
                        i,
                        f"{int(c[i, j])}",
                        ha="center",
                        va="center",
                        fontsize=6,
                        color="white" if c[i, j] > 0.6 * c.max() else "black",
                    )
        bottom = k + ncol >= n  # tick labels on the outer panels only
        ax.set_xticks(range(len(cols)), cols if bottom else [], rotation=90, fontsize=6.5)
        ax.set_yticks(range(len(rows)), rows if k % ncol == 0 else [], fontsize=6.5)
        ax.hlines(np.arange(len(rows) + 1) - 0.5, -0.5, len(cols) - 0.5, color="0.9", lw=0.5)
        ax.vlines(np.arange(len(cols) + 1) - 0.5, -0.5, len(rows) - 0.5, color="0.9", lw=0.5)
        if bottom:
            ax.set_xlabel("declared at the end", fontsize=8)
        if k % ncol == 0:
            ax.set_ylabel("true", fontsize=8)
        ax.set_title(f"{rs[k]['agent']}", fontsize=9)
    fig.suptitle(f"suite {rs[0]['suite']}: final declaration vs truth (episodes)", fontsize=11)
    fig.tight_layout(rect=(0, 0, 1, 1 - 0.25 / fig.get_figheight()), h_pad=1.5)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def _file_stem(name: str) -> str:
    import re

    return re.sub(r"[^A-Za-z0-9._-]+", "_", Path(name).stem if name.endswith(".json") else name)


# ----------------------------------------------------------------------------- report


def write_report(paths: Iterable[str | Path], out_dir: str | Path, *, plots: bool = True) -> Path:
    """Write ``out_dir/report.md``, ``confusion.json`` (and the PNG plots); return the report path."""
    try:
        return _write_report(paths, out_dir, plots)
    finally:
        _OUTCOMES.clear()


def _write_report(paths, out_dir, plots: bool) -> Path:
    if plots:
        report_pyplot()  # a missing matplotlib is an error before any work
    results = load_results(list(paths))
    if not results:
        raise ValueError("no results files given")
    results = merge_seeds(results)  # one result per suite and agent, its training seeds pooled
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    groups = _by_suite(results)
    parts = [
        "# MarineFDI benchmark report\n",
        "Sources: " + ", ".join(f"`{r['path']}`" for r in _sorted(results)) + "\n",
        "## All episodes\n",
        "Every rate with its 95 % interval in parentheses: a percentile bootstrap over the episodes, stratified "
        "by fault class, and over the training seeds of a learned agent (Seeds: how many are pooled); where "
        "every resample agrees (e.g. no false alarm at all), the exact interval of one seed's episodes "
        "(Clopper-Pearson, Poisson).  `marine_fdi_env.benchmark.uncertainty`.\n",
        markdown_table(results, intervals=True),
    ]
    from .report_scores import plot_scores, scores_markdown

    agent_order = sorted({r["agent"] for r in results}, key=agent_sort_key)
    score_md = scores_markdown(results, agent_order)
    if score_md:
        parts += [
            "## Normalised scores\n",
            "Per suite, 100 (R - R_null) / (R_oracle - R_null) with R the mean return: the null agent scores 0, "
            "the oracle 100; suites where the two earn the same (fault-free ones) are not scored.  IQM: the "
            "interquartile mean over training seeds x suites.  95 % intervals in parentheses (the episodes "
            "resampled within each suite, the null and oracle returns on the same resamples).\n",
            score_md,
        ]
        if plots and plot_scores(results, out / "scores.png", agent_order) is not None:
            parts.append("![normalised scores](scores.png)\n")
    for cls in FAULT_CLASSES:
        if not any((r["metrics"].get("by_class", {}).get(cls) or {}).get("n_episodes") for r in results):
            continue  # no episode of this class in any results file
        title = "fault-free episodes" if cls == "none" else f"{cls} fault episodes"
        parts += [f"## {title[0].upper() + title[1:]}\n", class_table(results, cls)]
    per_fault = [(suite, fault_table(rs)) for suite, rs in groups.items()]
    if any(t for _, t in per_fault):
        parts += [
            "## Per fault\n",
            "Single-fault episodes of each suite, per fault and agent: detection rate [%] / "
            "isolation accuracy [%] / median detection delay [s].\n",
        ]
        for suite, table in per_fault:
            if table:
                parts += [f"### Suite {suite}\n", table]
    parts += [
        "## Confusion matrices\n",
        "Final declaration against the truth, per suite and agent: for each true label (the faults "
        "active at the end, or `no fault`) the declared labels (the final declared faults, `unknown`: "
        "alarm on and no fault named, `nothing`: no alarm) with the number of episodes; the correct one in bold.  An "
        "episode counts once per (true, declared) pair: an episode with two true faults is in two rows, one "
        "that declared two faults adds to two entries of its row (so a row's entries may sum to more than "
        "its episodes).  "
        "Full matrices: `confusion.json`" + (", heat maps: `confusion_<suite>.png`" if plots else "") + ".\n",
    ]
    matrices = []
    for suite, rs in groups.items():
        rows, cols = _suite_labels(rs)
        for r in rs:
            cm = confusion_matrix(r, rows, cols)
            matrices.append({"suite": suite, "agent": r["agent"], **cm})
            parts += [f"### Suite {suite}, agent {r['agent']}\n", confusion_markdown(cm)]
    (out / "confusion.json").write_text(json.dumps(matrices, indent=1) + "\n", encoding="utf-8")
    if plots:
        parts += ["## Plots\n", "![summary](summary.png)\n"]
        plot_summary(results, out / "summary.png")
        if plot_detection_delays(results, out / "detection_delay.png") is not None:
            parts.append("![detection delay](detection_delay.png)\n")
        for suite, rs in groups.items():
            name = f"confusion_{_file_stem(suite)}.png"
            plot_confusion(rs, out / name)
            parts.append(f"![confusion matrices, suite {suite}]({name})\n")
    envs = sorted({str(r.get("env_id", "?")) for r in results})
    parts.append(
        "Rates in %, delays in s (censored median: a missed fault counts as never detected; – when "
        "fewer than half are detected), false alarms per fault-free hour; mean return of the reward "
        f"scored ({', '.join(envs)}); features: the observation features every agent shares, in µs per "
        "sensor sample; agent: the agent's own decision, in µs per decision and engine (both measured "
        "at the evaluation's batch size); – = undefined. Definitions: `marine_fdi_env.benchmark.metrics`.\n"
    )
    report = out / "report.md"
    report.write_text("\n".join(parts), encoding="utf-8")
    return report
