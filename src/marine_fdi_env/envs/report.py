"""Benchmark report: Markdown tables and plots from ``marine-fdi evaluate`` results files.

``marine-fdi report results*.json [--out DIR] [--no-plots]`` writes ``DIR/report.md`` (main
table, one table per fault class) and, with matplotlib, ``DIR/detection_delay.png`` (box plot of
detection delays per agent, one panel per suite) and ``DIR/summary.png`` (detection rate,
isolation accuracy and false-alarm episode rate per agent, one panel per suite).

A results file is JSON ``{"agent", "suite", "suite_version", "metrics", "episodes", ...}``;
``metrics`` is recomputed from ``episodes`` when absent (see :mod:`.metrics`).
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping, Sequence

from .jsonfile import read_json
from .metrics import FAULT_CLASSES, compute_metrics, episode_outcome

__all__ = ["load_results", "markdown_table", "write_report", "report_main", "agent_sort_key"]

_FIXED_FIRST = ("null", "random", "reference")
_FIXED_LAST = ("oracle",)
_DASH = "–"


# ----------------------------------------------------------------------------- loading

def _parquet_results(p: Path) -> list[dict]:
    """Results objects from a Parquet file: an evaluation's records, or a sweep's table (one
    object per agent x suite)."""
    from .records import read_records

    records, meta = read_records(p, keep_extra=True)
    if meta.get("kind") == "marine-fdi sweep" or (records and "agent_spec" in records[0]):
        from .sweep import sweep_results

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
        episodes = data.setdefault("episodes", [])
        if not isinstance(episodes, list):
            raise ValueError(f"{p}: field 'episodes' must be a list")
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


def agent_sort_key(agent: str) -> tuple[int, str]:
    """null, random, reference first, then others alphabetically, oracle last."""
    a = agent.lower()
    if a in _FIXED_FIRST:
        return (_FIXED_FIRST.index(a), a)
    if a in _FIXED_LAST:
        return (len(_FIXED_FIRST) + 1 + _FIXED_LAST.index(a), a)
    return (len(_FIXED_FIRST), a)


def _sorted(results: Sequence[Mapping]) -> list[Mapping]:
    seen: dict[tuple[str, str], str] = {}
    for r in results:
        key = (r["suite"], r["agent"])
        if key in seen:
            raise ValueError(f"two results for suite {key[0]!r}, agent {key[1]!r}: "
                             f"{seen[key]} and {r.get('path', '?')}")
        seen[key] = r.get("path", "?")
    return sorted(results, key=lambda r: (_suite_sort_key(r["suite"]), agent_sort_key(r["agent"])))


def _suite_sort_key(suite: str) -> tuple:
    """Shipped suites in their documented order (thesis, single, multi, ...), then others by name."""
    from .suites import SUITE_NAMES

    return (SUITE_NAMES.index(suite), "") if suite in SUITE_NAMES else (len(SUITE_NAMES), suite)


# ----------------------------------------------------------------------------- formatting

def _f(fmt: Callable[[float], str]) -> Callable[[Any], str]:
    return lambda v: _DASH if v is None else fmt(float(v))


_pct = _f(lambda v: f"{100 * v:.1f} %")
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
_FA_COLUMNS = tuple(c for c in COLUMNS if c.key in ("n_episodes", "false_alarm_rate",
                                                    "false_alarm_episode_rate", "mean_return",
                                                    "feature_compute_s_per_sample",
                                                    "agent_compute_s_per_decision"))


def _table(rows: Sequence[tuple[str, str, Mapping]], cols: Sequence[_Col]) -> str:
    head = ["Suite", "Agent", *(c.title for c in cols)]
    lines = ["| " + " | ".join(head) + " |",
             "|" + "|".join([" --- ", " --- "] + [" ---: "] * len(cols)) + "|"]
    for suite, agent, m in rows:
        cells = [suite, agent, *(c.fmt(m.get(c.key)) for c in cols)]
        lines.append("| " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def markdown_table(results: Sequence[Mapping]) -> str:
    """Main Markdown table: one row per (suite, agent)."""
    return _table([(r["suite"], r["agent"], r["metrics"]) for r in _sorted(results)], COLUMNS)


def class_table(results: Sequence[Mapping], fault_class: str) -> str:
    """Markdown table of one fault class (``metrics["by_class"][fault_class]``)."""
    cols = _FA_COLUMNS if fault_class == "none" else COLUMNS
    rows = [(r["suite"], r["agent"], r["metrics"].get("by_class", {}).get(fault_class) or {})
            for r in _sorted(results)]
    return _table(rows, cols)


# ----------------------------------------------------------------------------- plots

def _pyplot():
    try:
        import matplotlib
    except ImportError:
        raise RuntimeError("plots need matplotlib: pip install 'marine-fdi-env[plots]' "
                           "(or pass --no-plots)") from None
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def _by_suite(results: Sequence[Mapping]) -> dict[str, list[Mapping]]:
    groups: dict[str, list[Mapping]] = {}
    for r in _sorted(results):
        groups.setdefault(r["suite"], []).append(r)
    return groups


def plot_detection_delays(results: Sequence[Mapping], path: Path) -> Path:
    """Box plot of detection delays per agent, one panel per suite."""
    plt = _pyplot()
    groups = _by_suite(results)
    fig, axes = plt.subplots(len(groups), 1, figsize=(8, 3.2 * len(groups)), squeeze=False)
    for ax, (suite, rs) in zip(axes[:, 0], groups.items()):
        data = [[d for d in (episode_outcome(e)["detection_delay_s"] for e in r["episodes"])
                 if d is not None] for r in rs]
        ax.boxplot(data, showfliers=True)
        ax.set_xticks(range(1, len(rs) + 1), [f"{r['agent']}\n(n={len(d)})" for r, d in zip(rs, data)],
                      rotation=30, ha="right")
        ax.set_title(f"suite {suite}: detection delay")
        ax.set_ylabel("delay [s]")
        ax.set_ylim(bottom=0)
        ax.grid(axis="y", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


_BARS = (("detection_rate", "detection rate"), ("isolation_accuracy", "isolation accuracy"),
         ("false_alarm_episode_rate", "episodes with false alarm"))


def plot_summary(results: Sequence[Mapping], path: Path) -> Path:
    """Grouped bars of detection rate, isolation accuracy, false-alarm episodes (%)."""
    plt = _pyplot()
    groups = _by_suite(results)
    fig, axes = plt.subplots(len(groups), 1, figsize=(8, 3.2 * len(groups)), squeeze=False)
    width = 0.8 / len(_BARS)
    for ax, (suite, rs) in zip(axes[:, 0], groups.items()):
        for j, (key, label) in enumerate(_BARS):
            vals = [100 * (r["metrics"].get(key) or 0.0) for r in rs]
            ax.bar([i + (j - 1) * width for i in range(len(rs))], vals, width, label=label)
        ax.set_xticks(range(len(rs)), [r["agent"] for r in rs], rotation=30, ha="right")
        ax.set_xlim(-0.6, max(len(rs), 2) - 0.4)
        ax.set_ylim(0, 105)
        ax.set_ylabel("%")
        ax.set_title(f"suite {suite}")
        ax.grid(axis="y", alpha=0.3)
        ax.legend(fontsize="small", loc="upper left")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    return path


# ----------------------------------------------------------------------------- report

def write_report(paths: Iterable[str | Path], out_dir: str | Path, *, plots: bool = True) -> Path:
    """Write ``out_dir/report.md`` (and the PNG plots); return the report path."""
    results = load_results(list(paths))
    if not results:
        raise ValueError("no results files given")
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    parts = ["# MarineFDI benchmark report\n",
             "Sources: " + ", ".join(f"`{r['path']}`" for r in _sorted(results)) + "\n",
             "## All episodes\n", markdown_table(results)]
    for cls in FAULT_CLASSES:
        if not any((r["metrics"].get("by_class", {}).get(cls) or {}).get("n_episodes")
                   for r in results):
            continue   # no episode of this class in any results file
        title = "fault-free episodes" if cls == "none" else f"{cls} fault episodes"
        parts += [f"## {title[0].upper() + title[1:]}\n", class_table(results, cls)]
    if plots:
        plot_detection_delays(results, out / "detection_delay.png")
        plot_summary(results, out / "summary.png")
        parts += ["## Plots\n", "![detection delay](detection_delay.png)\n",
                  "![summary](summary.png)\n"]
    envs = sorted({str(r.get("env_id", "?")) for r in results})
    parts.append("Rates in %, delays in s (censored median: a missed fault counts as never detected; – when "
                 "fewer than half are detected), false alarms per fault-free hour; mean return of the reward "
                 f"scored ({', '.join(envs)}); features: the observation features every agent shares, in µs per "
                 "sensor sample; agent: the agent's own decision, in µs per decision and engine (both measured "
                 "at the evaluation's batch size); – = undefined. Definitions: `marine_fdi_env.envs.metrics`.\n")
    report = out / "report.md"
    report.write_text("\n".join(parts), encoding="utf-8")
    return report


def build_report_parser(prog: str = "marine-fdi report") -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog=prog, description="Markdown report and plots from results files.")
    p.add_argument("results", nargs="+",
                   help="results files written by 'marine-fdi evaluate' (.json or .parquet), or sweep folders "
                        "('marine-fdi sweep --out DIR') or their episodes.parquet")
    p.add_argument("--out", default="report", help="output directory (default: ./report)")
    p.add_argument("--no-plots", action="store_true", help="skip the PNG plots (no matplotlib needed)")
    return p


def report_main(argv: Sequence[str] | None = None) -> int:
    """``marine-fdi report results*.json [--out DIR] [--no-plots]``; returns the exit code."""
    args = build_report_parser().parse_args(argv)
    try:
        path = write_report(args.results, args.out, plots=not args.no_plots)
    except (ValueError, RuntimeError, OSError) as e:
        print(f"marine-fdi report: error: {e}", file=sys.stderr)
        return 2
    print(path)
    return 0
