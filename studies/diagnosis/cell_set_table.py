"""The three cell sets side by side (docs/diagnosis_results.md): per diagnoser and cell set, the
thesis's examples, the held-out certainty grid and every frozen suite in one table.

:func:`summarize_results` condenses ``marine-fdi evaluate`` results files of the agents
``reference``, ``reference-grid``, ``reference-thesis`` (and the ``sequential`` ones) into
``docs/data/cell_sets.json``; :func:`cell_set_table` renders that file with the certainty reports
(``docs/data/certainty_*.json``) and the scenario checks (``docs/data/*_scenarios*.json``).
Rates carry their exact (Clopper-Pearson) 95 % interval.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

from scipy import stats

from marine_fdi_env.diagnosis.cell_sets import CELL_SETS, DEFAULT_CELLS

__all__ = ["summarize_results", "cell_set_table", "wrong_isolations", "SUITE_ORDER", "proportion_ci95"]

SUITE_ORDER = ("thesis-v1", "single-v1", "multi-v1", "incipient-v1", "transfer-v1", "transfer-v2", "nominal-v1")
_PREFIX = {"reference": "diagnoser", "sequential": "sequential"}
_EXAMPLES = ("thesis-6.4.1", "thesis-6.4.2", "thesis-6.4.3", "thesis-6.4.4")


def proportion_ci95(k: int, n: int) -> tuple[float, float]:
    """Two-sided 95 % Clopper-Pearson interval of k successes in n trials (NaN when n = 0)."""
    if n == 0:
        return math.nan, math.nan
    ci = stats.binomtest(k, n).proportion_ci(0.95, method="exact")
    return float(ci.low), float(ci.high)


def wrong_isolations(results: dict) -> dict:
    """Per fault, in the single-fault episodes of a results file (``marine-fdi evaluate``): episodes,
    those where the agent ever declared a set without the true fault (``anytime``) and those where
    its last declaration lacks it (``end``)."""
    from marine_fdi_env.engine.faults import FAULT_IDS

    per = {}
    for e in results["episodes"]:
        if len(e["faults"]) != 1:
            continue
        f = e["faults"][0]["id"]
        p = per.setdefault(f, {"episodes": 0, "anytime": 0, "end": 0})
        p["episodes"] += 1
        p["anytime"] += int(any(decl and f not in decl for _, decl, _ in e["declared_changes"]))
        last = e["declared_changes"][-1][1] if e["declared_changes"] else []
        p["end"] += int(bool(last) and f not in last)
    return {f: per[f] for f in FAULT_IDS if f in per}


def summarize_results(results: list[dict]) -> dict:
    """{agent: {suite: summary}} of evaluate results dicts: faulty episodes, correct final isolations,
    detection rate, fault-free episodes with a false alarm and single-fault wrong isolations
    (declared without the true fault, ever / at the end)."""
    out: dict = {}
    for r in results:
        m = r["metrics"]
        n_faulty = int(m["n_faulty"])
        acc = m.get("isolation_accuracy")
        n_free = int(m["n_episodes"]) - n_faulty
        fa = m.get("false_alarm_episode_rate")
        wrong = wrong_isolations(r).values()
        ever, end = sum(p["anytime"] for p in wrong), sum(p["end"] for p in wrong)
        out.setdefault(r["agent"], {})[r["suite"]] = {
            "faulty_episodes": n_faulty,
            "isolated": None if acc is None else int(round(acc * n_faulty)),
            "detection_rate": m.get("detection_rate"),
            "fault_free_episodes": n_free,
            "false_alarm_episodes": None if fa is None else int(round(fa * n_free)),
            "wrong_isolations_ever": ever,
            "wrong_isolations_end": end,
        }
    return out


def _agent(diagnoser: str, cells: str) -> str:
    return diagnoser if cells == DEFAULT_CELLS else f"{diagnoser}-{cells}"


def _load(path: Path):
    return json.loads(path.read_text()) if path.exists() else None


def _rate(k, n) -> str:
    if k is None or not n:
        return "–"
    lo, hi = proportion_ci95(k, n)
    return f"{100 * k / n:.1f} % ({100 * lo:.0f}-{100 * hi:.0f})"


def cell_set_table(data_dir: Path = Path("docs/data")) -> list[str]:
    """Markdown lines of the comparison table (empty when docs/data/cell_sets.json is missing)."""
    summary = _load(data_dir / "cell_sets.json")
    if summary is None:
        return []
    agents = summary["agents"]
    head = ["diagnoser", "cells"]
    head += [
        "6.4.1-6.4.4: injected set among the final minimal diagnoses",
        "6.4.2, 6.4.3: unique",
        "runs over the thesis's candidate count (4, 1, 1, 9)",
        "held-out grid: wrong isolations / detected runs",
        "held-out grid: isolated at the end",
    ]
    head += [f"{s} isolation acc." for s in SUITE_ORDER if s != "nominal-v1"]
    head += ["single-v1 wrong isolations ever / at the end", "nominal-v1 episodes with a false alarm"]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for diagnoser in ("reference", "sequential"):
        cert = _load(data_dir / f"certainty_{diagnoser}.json")
        for cells in CELL_SETS:
            tail = "" if cells == DEFAULT_CELLS else f"_{cells}"
            sc = _load(data_dir / f"{_PREFIX[diagnoser]}_scenarios{tail}.json")
            row = [diagnoser, cells]
            if sc:
                res = sc["result"]
                row.append(", ".join(f"{res[e]['injected_in_diagnoses_runs']}/{res[e]['seeds']}" for e in _EXAMPLES))
                row.append(", ".join(f"{res[e]['unique_runs']}/{res[e]['seeds']}" for e in _EXAMPLES[1:3]))
                row.append(", ".join(str(res[e]["seeds"] - res[e]["within_thesis_count_runs"]) for e in _EXAMPLES))
            else:
                row += ["–"] * 3
            if cert and cells in cert["result"]:
                per = cert["result"][cells].values()
                det = sum(p["detected"] for p in per)
                row.append(f"{sum(p['wrong'] for p in per)} / {det}")
                row.append(_rate(sum(p["isolated_end"] for p in per), det))
            else:
                row += ["–", "–"]
            a = agents.get(_agent(diagnoser, cells), {})
            for s in SUITE_ORDER:
                if s == "nominal-v1":
                    continue
                v = a.get(s)
                row.append(_rate(v["isolated"], v["faulty_episodes"]) if v else "–")
            v = a.get("single-v1")
            row.append(f"{v['wrong_isolations_ever']} / {v['wrong_isolations_end']}" if v else "–")
            v = a.get("nominal-v1")
            row.append(f"{v['false_alarm_episodes']} / {v['fault_free_episodes']}" if v else "–")
            lines.append("| " + " | ".join(row) + " |")
    return lines
