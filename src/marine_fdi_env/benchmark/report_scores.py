"""Normalised scores of the report: per suite (null = 0, oracle = 100) and the interquartile mean
across suites, with 95 % intervals (:mod:`.uncertainty`); a Markdown table and a plot.

Only suites with the null agent's and the oracle's results, on which the two earn different
returns, are scored (``nominal-v1`` is not: neither raises an alarm).  The inputs are results
pooled per suite and agent (:func:`.report.merge_seeds`, each with ``seed_results``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Mapping, Sequence

from .uncertainty import Estimate, iqm_score, normalised_score, outcomes

__all__ = ["scores", "scores_markdown", "plot_scores", "NORMALISERS"]

NORMALISERS = ("null", "oracle")


def _outcomes(r: Mapping):
    return outcomes([x["episodes"] for x in r.get("seed_results") or [r]])


def scores(results: Sequence[Mapping]) -> tuple[list[str], dict[str, dict[str, Estimate]]]:
    """(scored suites, {agent: {suite: score, ..., "IQM": interquartile mean}}) of pooled results."""
    by_suite: dict[str, dict[str, Mapping]] = {}
    from .suites import SUITE_NAMES

    for r in sorted(
        results,
        key=lambda r: (SUITE_NAMES.index(r["suite"]) if r["suite"] in SUITE_NAMES else len(SUITE_NAMES), r["suite"]),
    ):
        by_suite.setdefault(r["suite"], {})[r["agent"]] = r
    table: dict[str, dict[str, Estimate]] = {}
    parts: dict[str, list] = {}
    suites = []
    for suite, rs in by_suite.items():
        if not all(n in rs for n in NORMALISERS):
            continue
        null, oracle = _outcomes(rs["null"]), _outcomes(rs["oracle"])
        if abs(float(oracle.ret[0].mean() - null.ret[0].mean())) <= 1e-9:
            continue
        suites.append(suite)
        for agent, r in rs.items():
            o = _outcomes(r)
            table.setdefault(agent, {})[suite] = normalised_score(o, null, oracle)
            parts.setdefault(agent, []).append((o, null, oracle))
    for agent, p in parts.items():
        if len(p) == len(suites):
            table[agent]["IQM"] = iqm_score(p)
    return suites, table


def _cell(e: Estimate | None) -> str:
    if e is None or e.value is None:
        return "–"
    if e.low is None or e.high is None:
        return f"{e.value:.1f}"
    return f"{e.value:.1f} ({e.low:.1f}–{e.high:.1f})"


def scores_markdown(results: Sequence[Mapping], order: Sequence[str] | None = None) -> str:
    """Markdown table: one row per agent, its normalised score on every scored suite and the IQM
    across them, each with its 95 % interval; empty string when no suite can be scored."""
    suites, table = scores(results)
    if not suites:
        return ""
    agents = [a for a in (order or table) if a in table]
    lines = ["| Agent | " + " | ".join(suites) + " | IQM across suites |", "| --- |" + " ---: |" * (len(suites) + 1)]
    for a in agents:
        lines.append(
            f"| {a} | " + " | ".join(_cell(table[a].get(s)) for s in suites) + f" | {_cell(table[a].get('IQM'))} |"
        )
    return "\n".join(lines) + "\n"


def plot_scores(results: Sequence[Mapping], path: Path, order: Sequence[str] | None = None) -> Path | None:
    """Per agent, the IQM of its normalised scores with its 95 % interval (bar and error bar) and
    its score on each suite (points); ``None`` when no suite can be scored."""
    from ..plotting import pyplot

    suites, table = scores(results)
    if not suites:
        return None
    agents = [a for a in (order or table) if a in table and "IQM" in table[a]]
    plt = pyplot("or pass --no-plots")
    fig, ax = plt.subplots(figsize=(9, 0.45 * len(agents) + 1.6))
    for i, a in enumerate(agents):
        e = table[a]["IQM"]
        ax.barh(i, e.value, color="C0", alpha=0.35, height=0.6)
        if e.low is not None:
            ax.errorbar(e.value, i, xerr=[[e.value - e.low], [e.high - e.value]], color="C0", capsize=3, lw=1.5)
        for k, s in enumerate(suites):
            v = table[a].get(s)
            if v is not None and v.value is not None:
                ax.plot(
                    v.value,
                    i + (k - (len(suites) - 1) / 2) * 0.07,
                    "o",
                    ms=3.5,
                    color=f"C{k + 1}",
                    label=s if i == 0 else None,
                )
    ax.set_yticks(range(len(agents)), agents, fontsize=9)
    ax.invert_yaxis()
    ax.axvline(0, color="0.5", lw=0.8)
    ax.axvline(100, color="0.5", lw=0.8, ls="--")
    ax.set_xlabel(
        "normalised score (null = 0, oracle = 100): bar = IQM across suites with its 95 % interval, points = suites",
        fontsize=8,
    )
    ax.legend(fontsize=7, ncol=min(4, len(suites)), loc="lower right", frameon=False)
    ax.grid(axis="x", alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
