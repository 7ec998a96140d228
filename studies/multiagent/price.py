"""The price of decentralisation: centralised learned vs decentralised learned vs the thesis's distributed
scheme vs ``reference``, on every frozen suite, at each message budget (docs/multiagent.md).

    python -m studies.multiagent.price --evaluate --cache-dir /tmp/cache   # score what is missing, then the report
    python -m studies.multiagent.price                                      # the report from the stored results

``--evaluate`` runs ``marine-fdi evaluate``'s code (:func:`~marine_fdi_env.benchmark.evaluate.evaluate_agents`:
each suite simulated once, or read from its feature cache, every agent scored on it in lockstep; MarineFDI-v1,
batches of 32) for ``reference-distributed`` and every training seed of ``dec-classifier-BUDGET``, writing
``docs/data/multiagent/results/AGENT[_sSEED]_SUITE.json``.  The centralised rows (``reference``,
``classifier``, ``ppo``: every training seed) are the stored results of ``python -m studies.agents.compare``
(``docs/data/results``), scored on the same episodes, so every difference is paired.  Intervals:
:mod:`marine_fdi_env.benchmark.uncertainty` (stratified bootstrap over episodes and training seeds).
Writes ``docs/data/multiagent/price.json``, the figure ``docs/figures/multiagent/isolation_vs_budget.png``
and the tables of docs/multiagent.md between its ``price:`` markers.
"""

from __future__ import annotations

import argparse
import json
import math
import re
from pathlib import Path

from marine_fdi_env.benchmark.evaluate import evaluate_agents
from marine_fdi_env.benchmark.suites import SUITE_NAMES
from marine_fdi_env.benchmark.uncertainty import difference, interval, outcomes
from marine_fdi_env.multiagent.budgets import BUDGETS
from studies.paths import REPO

HERE = REPO / "docs" / "data" / "multiagent"
RESULTS = HERE / "results"
CENTRAL = REPO / "docs" / "data" / "results"
PAGE = REPO / "docs" / "multiagent.md"
FIGURE = REPO / "docs" / "figures" / "multiagent" / "isolation_vs_budget.png"
MESSAGE = HERE / "reference_message.json"
SEEDS = (0, 1, 2)
DEC = "dec-classifier"
GLOBAL = "dec-global-decision"  # the thesis's locals, a learned global (decision budget)
# the decision-budget teams trained and calibrated within the sensors' rated noise (0.5-1.0x; noise_premise.py)
RATED = {"dec-global-rated-decision": GLOBAL, "dec-classifier-rated-decision": "dec-classifier-decision"}
# the rated learned global with the thesis's logic where it names a fault pair (a combination: named for both)
HYBRID = "dec-global-rated-decision+thesis-pairs"

# the headline metric of each suite (the README's), and the metric's column title
HEADLINE = {
    "thesis-v1": ("isolation_accuracy", "thesis-v1 iso."),
    "single-v1": ("isolation_accuracy", "single-v1 iso."),
    "multi-v1": ("isolation_accuracy", "multi-v1 iso."),
    "incipient-v1": ("detection_rate", "incipient-v1 det."),
    "transfer-v1": ("isolation_accuracy", "transfer-v1 iso."),
    "nominal-v1": ("false_alarm_episode_rate", "nominal-v1 FA episodes"),
    "transfer-v2": ("isolation_accuracy", "transfer-v2 iso."),
    "transfer-v3": ("isolation_accuracy", "transfer-v3 iso."),
}


def dec_name(budget: str) -> str:
    return f"{DEC}-{budget}"


def rows() -> list[tuple[str, str, str, tuple[Path, ...]]]:
    """(row, information structure, bits per decision, result files' stems per seed) of every row."""
    dec = [
        (
            dec_name(b),
            "decentralised, learned",
            str(BUDGETS[b].bits_per_decision),
            tuple(f"{dec_name(b)}_s{s}" for s in SEEDS),
        )
        for b in BUDGETS
    ]
    msg = json.loads(MESSAGE.read_text())["bits"]["quantised_bits_per_decision"] if MESSAGE.is_file() else None
    return [
        ("reference-distributed", "distributed (thesis)", "19", ("reference-distributed",)),
        (GLOBAL, "thesis's locals, learned global", "19", tuple(f"{GLOBAL}_s{s}" for s in SEEDS)),
        *dec,
        *(
            (name, f"{info}; trained at noise 0.5-1.0x", "19", tuple(f"{name}_s{s}" for s in SEEDS))
            for name, info in zip(RATED, ("thesis's locals, learned global", "decentralised, learned"))
        ),
        (
            HYBRID,
            "thesis's locals, learned global + the thesis's logic for pairs; trained at noise 0.5-1.0x",
            "19",
            tuple(f"{HYBRID}_s{s}" for s in SEEDS),
        ),
        ("reference", "centralised evidence", f"{msg} (its evidence)" if msg else "-", ("reference",)),
        ("classifier", "centralised, learned", "all features", tuple(f"classifier_s{s}" for s in SEEDS)),
        ("ppo", "centralised, learned", "all features", tuple(f"ppo_s{s}" for s in SEEDS)),
    ]


def _file(stem: str, suite: str) -> Path:
    base = RESULTS if stem.startswith((DEC, "dec-global", "reference-distributed")) else CENTRAL
    return base / f"{stem}_{suite}.json"


def evaluate_missing(cache_dir: Path | None, workers: int = 1) -> None:
    specs = {"reference-distributed": "reference-distributed"}
    for name in (GLOBAL, *(dec_name(b) for b in BUDGETS), *RATED, HYBRID):
        for s in SEEDS:
            specs[f"{name}_s{s}"] = str(REPO / "training" / "models" / name / f"seed{s}")
    RESULTS.mkdir(parents=True, exist_ok=True)
    for suite in SUITE_NAMES:
        todo = [
            (stem, spec)
            for stem, spec in specs.items()
            if not _file(stem, suite).is_file() and (stem == "reference-distributed" or Path(spec).is_dir())
        ]
        if not todo:
            continue
        print(f"{suite}: {len(todo)} agents", flush=True)
        evaluate_agents(
            [spec for _, spec in todo],
            suite,
            [_file(stem, suite) for stem, _ in todo],
            batch_size=32,
            reward="v1",
            progress=False,
            workers=workers,
            # the first pass simulates and keeps each suite's features; later passes read them
            cache="off" if cache_dir is None else "use" if any(cache_dir.glob(f"{suite}_o0_*.parquet")) else "write",
            cache_dir=cache_dir,
        )


def _episodes(stem: str, suite: str) -> list[dict] | None:
    f = _file(stem, suite)
    return json.loads(f.read_text())["episodes"] if f.is_file() else None


def load_outcomes() -> dict:
    out = {}
    for name, _, _, stems in rows():
        for suite in SUITE_NAMES:
            eps = [_episodes(s, suite) for s in stems]
            if all(e is not None for e in eps):
                out[(name, suite)] = outcomes(eps)
    return out


def _fmt(e, pct: bool) -> str:
    if e.value is None:
        return "–"
    k = 100.0 if pct else 1.0
    lo = "" if e.low is None else f" ({k * e.low:.1f}–{k * e.high:.1f})"
    return f"{k * e.value:.1f}{' %' if pct else ''}{lo}"


def _fmt_diff(e) -> str:
    if e.value is None:
        return "–"
    txt = f"{100 * e.value:+.1f} ({100 * e.low:+.1f}–{100 * e.high:+.1f})"
    return f"**{txt}**" if e.low > 0 or e.high < 0 else txt


def report() -> dict:
    outs = load_outcomes()
    table, data = [], {"rows": {}, "differences": {}}
    head = "| agent | information | bits per decision | seeds | " + " | ".join(t for _, t in HEADLINE.values()) + " |"
    table += [head, "|" + "---|" * 4 + "---:|" * len(HEADLINE)]
    for name, info, bits, stems in rows():
        cells, rec = [], {}
        for suite, (metric, _) in HEADLINE.items():
            o = outs.get((name, suite))
            if o is None:
                cells.append("–")
                continue
            e = interval(o, metric)
            rec[suite] = {"metric": metric, **e.to_dict()}
            cells.append(_fmt(e, True))
        data["rows"][name] = {"information": info, "bits_per_decision": bits, "seeds": len(stems), "suites": rec}
        table.append(f"| `{name}` | {info} | {bits} | {len(stems)} | " + " | ".join(cells) + " |")
    # paired differences: every decentralised row against the distributed scheme and the centralised learned rows
    pairs = [
        (a, ref)
        for a in (GLOBAL, *map(dec_name, BUDGETS), *RATED, HYBRID)
        for ref in ("reference-distributed", "classifier", "ppo")
    ]
    pairs += list(RATED.items())  # the rated noise range against the same team trained at 0.5-1.5x
    pairs += [(HYBRID, "dec-global-rated-decision")]  # what the thesis's logic for pairs adds
    pairs += [("reference-distributed", "reference")]
    diff = ["| A - B | " + " | ".join(t for _, t in HEADLINE.values()) + " |", "|---|" + "---:|" * len(HEADLINE)]
    for a, b in pairs:
        cells = []
        for suite, (metric, _) in HEADLINE.items():
            oa, ob = outs.get((a, suite)), outs.get((b, suite))
            if oa is None or ob is None:
                cells.append("–")
                continue
            e = difference(oa, ob, metric)
            data["differences"].setdefault(f"{a} - {b}", {})[suite] = {"metric": metric, **e.to_dict()}
            cells.append(_fmt_diff(e))
        diff.append(f"| `{a}` - `{b}` | " + " | ".join(cells) + " |")
    HERE.mkdir(parents=True, exist_ok=True)
    (HERE / "price.json").write_text(json.dumps(data, indent=1) + "\n")
    _write_page("price", "\n".join(table))
    _write_page("differences", "\n".join(diff))
    figure(data)
    return data


def _write_page(marker: str, body: str) -> None:
    if not PAGE.is_file():
        return
    text = PAGE.read_text()
    begin = f"<!-- {marker}:begin (python -m studies.multiagent.price writes this block) -->"
    end = f"<!-- {marker}:end -->"
    pat = re.compile(re.escape(begin) + ".*?" + re.escape(end), re.S)
    if not pat.search(text):
        return
    PAGE.write_text(pat.sub(lambda _: f"{begin}\n\n{body}\n\n{end}", text))


def figure(data: dict) -> None:
    from marine_fdi_env.plotting import pyplot

    plt = pyplot()
    msg = json.loads(MESSAGE.read_text())["bits"]["quantised_bits_per_decision"] if MESSAGE.is_file() else None
    fig, axes = plt.subplots(1, 2, figsize=(10, 4.8), sharey=True)
    for ax, suite in zip(axes, ("single-v1", "multi-v1")):

        def point(name, x, style, label):
            r = data["rows"].get(name, {}).get("suites", {}).get(suite)
            if not r or r["value"] is None:
                return
            ax.errorbar(
                [x],
                [100 * r["value"]],
                yerr=[[100 * (r["value"] - r["low"])], [100 * (r["high"] - r["value"])]],
                fmt=style,
                capsize=3,
                label=label,
            )

        xs = [BUDGETS[b].bits_per_decision for b in BUDGETS]
        ys = [data["rows"].get(dec_name(b), {}).get("suites", {}).get(suite, {}).get("value") for b in BUDGETS]
        if all(y is not None for y in ys):
            ax.plot(xs, [100 * y for y in ys], "-", color="C0", alpha=0.5)
        for b in BUDGETS:
            point(dec_name(b), BUDGETS[b].bits_per_decision, "o", f"{DEC} ({b})")
        point("reference-distributed", 19 * 0.93, "s", "reference-distributed")  # beside the other 19-bit rows
        point(GLOBAL, 19 * 1.08, "^", GLOBAL)  # beside the other 19-bit rows
        for (name, style), x in zip(zip((*RATED, HYBRID), ("v", "P", "X")), (19 * 1.16, 19 * 1.25, 19 * 1.35)):
            point(name, x, style, f"{name} (noise 0.5-1.0x)")
        if msg:
            point("reference", msg, "D", "reference (its evidence)")
        for name, style in (("classifier", "--"), ("ppo", ":")):
            r = data["rows"].get(name, {}).get("suites", {}).get(suite)
            if r and r["value"] is not None:
                ax.axhline(100 * r["value"], ls=style, color="grey", label=f"{name} (centralised)")
        ax.set_xscale("log")
        ax.set_xlabel("message budget [bits per decision, all locals]")
        ax.set_title(f"{suite}: isolation accuracy (95 % intervals)")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("isolation accuracy [%]")
    handles, labels = axes[1].get_legend_handles_labels()
    fig.legend(handles, labels, fontsize=7, loc="lower center", ncol=4, frameon=False)
    fig.tight_layout(rect=(0, 0.16, 1, 1))
    FIGURE.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(FIGURE, dpi=110)
    plt.close(fig)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--evaluate", action="store_true", help="score the missing results first")
    ap.add_argument("--cache-dir", type=Path, default=None, help="feature caches of the suites (written if absent)")
    ap.add_argument("--workers", type=int, default=1)
    args = ap.parse_args(argv)
    if args.evaluate:
        evaluate_missing(args.cache_dir, args.workers)
    data = report()
    for name, r in data["rows"].items():
        s = r["suites"]
        txt = ", ".join(
            f"{k} {100 * v['value']:.1f}" for k, v in s.items() if v["value"] is not None and not math.isnan(v["value"])
        )
        print(f"{name}: {txt}")


if __name__ == "__main__":
    main()
