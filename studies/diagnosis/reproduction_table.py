"""The reproduction table: each claim of :mod:`.thesis_claims` against the measurements of
:mod:`.reproduction`, per column, with a verdict and, where ours differs, its measured cause.

Verdicts (:data:`VERDICTS`): ``reproduced`` (a delay or limit within a factor 1.5 of the thesis's
either way, "almost immediately" within 1 s, a qualitative order or set equal), ``better`` (a delay
or limit below 1/1.5 of the thesis's, a diagnosis set tighter than the thesis's), ``worse`` (above 1.5x,
later than the words allow, a looser or different set, a spread at or above 0.003 s), ``not
reproduced`` (not detected within the thesis's 300 s run in most runs, or fired before the fault).
Medians are censored: a run without detection counts as later than every detection, so a median
"not reached" means most runs did not detect.  Intervals: 95 %, order statistics for medians
(exact binomial ranks), Clopper-Pearson for shares, Garwood for Poisson rates, percentile bootstrap
(:func:`scipy.stats.bootstrap`, seed 0) for standard deviations.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import stats

from marine_fdi_env.diagnosis.modules import MODULE_IDS, MODULES
from marine_fdi_env.engine.faults import PROCESS_FAULT_DEFAULTS

from .thesis_claims import THESIS_TEXT, ThesisClaim, claims, diagnoses

__all__ = ["VERDICTS", "Row", "rows_for", "write_table", "QUALITATIVE_DELAYS"]

VERDICTS = ("reproduced", "better", "worse", "not reproduced")
FACTOR = 1.5
AT_ONCE_S = 1.0
SPREAD_S = 0.003
DURATION_S = 300.0
# our reading of the thesis's words for a delay after the onset [s]: (earliest, latest) that reproduce it
QUALITATIVE_DELAYS = {
    "almost immediately": (0.0, AT_ONCE_S),
    "instantly": (0.0, AT_ONCE_S),
    "shortly after": (0.0, 30.0),
    "relatively short time": (0.0, 60.0),
    "around the middle of the simulation time": (80.0, 180.0),
    "far later stage": (60.0, 270.0),
}
DOC = Path("docs/reproduction.md")
DATA = Path("docs/data/reproduction.json")
CAUSES = Path("docs/data/reproduction_causes")


# ----------------------------------------------------------------------------- statistics
def median_ci(values) -> tuple[float, float, float]:
    """Censored median and its 95 % interval by order statistics (None/NaN/inf: not detected, later
    than any detection): (median, low, high), inf where not reached."""
    x = np.sort(np.array([math.inf if v is None or not math.isfinite(v) else float(v) for v in values]))
    n = len(x)
    if n == 0:
        return math.nan, math.nan, math.nan
    med = float(np.quantile(x, 0.5, method="inverted_cdf")) if n else math.nan
    lo_rank = int(stats.binom.ppf(0.025, n, 0.5))
    hi_rank = int(stats.binom.ppf(0.975, n, 0.5))
    lo = float(x[max(lo_rank - 1, 0)])
    hi = float(x[min(hi_rank, n - 1)])
    return med, lo, hi


def share_ci(k: int, n: int) -> tuple[float, float]:
    if n == 0:
        return math.nan, math.nan
    ci = stats.binomtest(k, n).proportion_ci(0.95, method="exact")
    return float(ci.low), float(ci.high)


def rate_ci(k: int, hours: float) -> tuple[float, float]:
    """Garwood's exact 95 % interval of a Poisson rate [1/h]."""
    lo = 0.0 if k == 0 else stats.chi2.ppf(0.025, 2 * k) / 2.0 / hours
    hi = stats.chi2.ppf(0.975, 2 * k + 2) / 2.0 / hours
    return float(lo), float(hi)


def std_ci(x) -> tuple[float, float, float]:
    x = np.asarray(x, dtype=float)
    s = float(np.std(x))
    if len(x) < 3 or s == 0.0:
        return s, s, s
    res = stats.bootstrap((x,), np.std, confidence_level=0.95, method="percentile", random_state=0, n_resamples=2000)
    return s, float(res.confidence_interval.low), float(res.confidence_interval.high)


def _fmt_s(v: float) -> str:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return "-"
    if math.isinf(v):
        return "not reached"
    return f"{v:.3g} s" if abs(v) < 100 else f"{v:.0f} s"


def _median_text(med, lo, hi, k, n) -> str:
    return f"{_fmt_s(med)} ({_fmt_s(lo)} to {_fmt_s(hi)}); {k}/{n} runs"


def ratio_verdict(ratio: float) -> str:
    if not math.isfinite(ratio):
        return "not reproduced"
    if ratio < 1.0 / FACTOR:
        return "better"
    return "reproduced" if ratio <= FACTOR else "worse"


def window_verdict(delay: float, lo: float, hi: float) -> str:
    if not math.isfinite(delay):
        return "not reproduced"
    if delay < lo:
        return "better"
    return "reproduced" if delay <= hi else "worse"


# ----------------------------------------------------------------------------- rows
@dataclass
class Row:
    """One claim (at one size) in one column."""

    claim: str
    section: str
    kind: str
    line: int
    what: str
    thesis: str
    size: str
    ours: str
    n: int
    ratio: float | None
    verdict: str
    detail: dict

    def to_dict(self) -> dict:
        d = dict(self.__dict__)
        if d["ratio"] is not None and not math.isfinite(d["ratio"]):
            d["ratio"] = None
        return d


def _own(sensor: str) -> str:
    return next(m.id for m in MODULES if m.checked_sensor == sensor)


def _delays(entry: dict, module: str | None) -> list:
    if module is None:
        return [None if t is None or t < 0 else t for t in entry["first_s"]]
    i = MODULE_IDS.index(module)
    return [None if r[i] is None or r[i] < 0 else r[i] for r in entry["modules_s"]]


def _early(entry: dict, module: str | None) -> int:
    if module is None:
        return sum(1 for t in entry["first_s"] if t is not None and t < 0)
    i = MODULE_IDS.index(module)
    return sum(1 for r in entry["modules_s"] if r[i] is not None and r[i] < 0)


def _delay_row(c: ThesisClaim, entry: dict, module, size_label: str, thesis_text: str, window=None, thesis_s=None):
    d = _delays(entry, module)
    n = len(d)
    k = sum(x is not None for x in d)
    early = _early(entry, module)
    med, lo, hi = median_ci(d)
    if early * 2 > n:
        verdict, ratio = "not reproduced", None
    elif thesis_s is not None and thesis_s > 0:
        ratio = med / thesis_s if math.isfinite(med) else math.inf
        verdict = ratio_verdict(ratio)
    else:
        ratio = None
        a, b = window if window else (0.0, AT_ONCE_S)
        verdict = window_verdict(med, a, b)
    ours = _median_text(med, lo, hi, k, n) + (f"; {early} fired before the onset" if early else "")
    return Row(
        claim=c.id,
        section=c.section,
        kind=c.kind,
        line=c.line,
        what=c.kind.replace("_", " ") + (f" {c.fault}" if c.fault else "") + (f" by {module}" if module else ""),
        thesis=thesis_text,
        size=size_label,
        ours=ours,
        n=n,
        ratio=ratio,
        verdict=verdict,
        detail={"median_s": med, "ci_s": [lo, hi], "detected": k, "early": early, "module": module},
    )


def _sensor_rows(col: dict) -> list[Row]:
    out = []
    for c in claims("sensor_detection"):
        labels = col["sensor"][c.fault]
        for label, entry in labels.items():
            size = (
                f"table 6.3: {entry['magnitude']:.4g}"
                if label == "table"
                else f"{c.size_pct_of_max:g} % of the maximum by the noise rule: {entry['magnitude']:.4g}"
            )
            out.append(_delay_row(c, entry, _own(c.fault), size, f"{c.value} (≤ {AT_ONCE_S:g} s)"))
    return out


def _process_rows(col: dict) -> list[Row]:
    out = []
    for c in claims("process_detection"):
        if c.fault is None:
            continue
        entry = col["process"][c.fault]["table"]
        size = f"table 6.4 (onset {entry['onset_s']:g} s)"
        if isinstance(c.value, (int, float)):
            out.append(_delay_row(c, entry, None, size, f"{c.value:g} s after the onset", thesis_s=float(c.value)))
        else:
            window = QUALITATIVE_DELAYS[str(c.value)]
            text = f"'{c.value}' (read as {window[0]:g}-{window[1]:g} s)"
            out.append(_delay_row(c, entry, None, size, text, window=window))
    return out


def _fired_modules(entry: dict, share: float = 0.5) -> set[str]:
    runs = entry["modules_s"]
    n = len(runs)
    return {
        m for i, m in enumerate(MODULE_IDS) if sum(1 for r in runs if r[i] is not None and r[i] >= 0) * 1.0 > share * n
    }


def _signature_rows(col: dict) -> list[Row]:
    out = []
    agent_of = {m.id: m.agent for m in MODULES}
    for c in claims("process_signature"):
        if c.fault is None:  # no propagation between agents
            moved = {}
            for f, labels in col["process"].items():
                fired = _fired_modules(labels["table"])
                own_agent = PROCESS_FAULT_DEFAULTS[f].subsystem
                other = sorted(m for m in fired if agent_of[m] != own_agent)
                if other:
                    moved[f] = other
            verdict = "reproduced" if not moved else "not reproduced"
            ours = "none" if not moved else "; ".join(f"{f}: {', '.join(ms)}" for f, ms in moved.items())
            out.append(
                Row(
                    c.id,
                    c.section,
                    c.kind,
                    c.line,
                    "no process fault seen by another agent",
                    str(c.value),
                    "table 6.4",
                    f"modules of another agent that fire in most runs: {ours}",
                    0,
                    None,
                    verdict,
                    {"propagated": moved},
                )  # fmt: skip
            )
            continue
        entry = col["process"][c.fault]["table"]
        fired = _fired_modules(entry)
        thesis = set(c.value)
        extra, missing = sorted(fired - thesis), sorted(thesis - fired)
        verdict = "reproduced" if not extra and not missing else "not reproduced"
        ours = ", ".join(sorted(fired)) or "none"
        if extra or missing:
            ours += f" (extra: {', '.join(extra) or '-'}; missing: {', '.join(missing) or '-'})"
        out.append(
            Row(
                c.id,
                c.section,
                c.kind,
                c.line,
                f"modules that detect {c.fault}",
                ", ".join(c.value),
                "table 6.4",
                ours + f"; fired in most of {len(entry['modules_s'])} runs",
                len(entry["modules_s"]),
                None,
                verdict,
                {"fired": sorted(fired), "extra": extra, "missing": missing},
            )  # fmt: skip
        )
    return out


def _scenario_module_entry(col: dict, scenario: str, onset: float) -> dict:
    runs = col["scenarios"][scenario]["runs"]
    return {
        "first_s": [None if r["first_s"] is None else r["first_s"] - onset for r in runs],
        "modules_s": [[None if t is None else t - onset for t in r["modules_s"]] for r in runs],
    }


def _event_rows(col: dict) -> list[Row]:
    out = []
    for c in claims("event_time"):
        entry = _scenario_module_entry(col, c.scenario, c.onset_s)
        thesis_delay = float(c.value) - float(c.onset_s)
        text = f"{float(c.value):g} s ({thesis_delay:g} s after the {c.fault} onset)"
        row = _delay_row(c, entry, c.module, f"{c.scenario} (table sizes)", text, thesis_s=thesis_delay or None)
        out.append(row)
    return out


def _order_rows(col: dict) -> list[Row]:
    out = []
    for c in claims("module_order"):
        runs = col["scenarios"][c.scenario]["runs"]
        n = len(runs)
        med = {}
        for i, m in enumerate(MODULE_IDS):
            t = [r["modules_s"][i] for r in runs]
            k = sum(x is not None for x in t)
            if k * 2 > n:
                med[m] = median_ci(t)[0]
        named = [m for g in c.value for m in g]
        missing = [m for m in named if m not in med]
        extra = sorted(m for m in med if m not in named)
        ok = not missing
        for a, b in zip(c.value[:-1], c.value[1:]):
            if any(m in med and x in med and med[m] > med[x] + AT_ONCE_S for m in a for x in b):
                ok = False
        ours = " < ".join(
            ", ".join(f"{m} {med[m]:.1f}" for m in sorted(g, key=lambda m: med[m]))
            for g in _groups(sorted(med, key=lambda m: med[m]), med)
        )
        verdict = "reproduced" if ok and not extra else "not reproduced"
        thesis = " < ".join(", ".join(g) for g in c.value)
        note = []
        if missing:
            note.append(f"never in most runs: {', '.join(missing)}")
        if extra:
            note.append(f"also fire: {', '.join(extra)}")
        out.append(
            Row(
                c.id,
                c.section,
                c.kind,
                c.line,
                f"module order in {c.scenario}",
                thesis,
                "table sizes",
                (ours or "none") + (f" ({'; '.join(note)})" if note else "") + f"; median firing times [s] of {n} runs",
                n,
                None,
                verdict,
                {"median_s": med, "missing": missing, "extra": extra},
            )  # fmt: skip
        )
    return out


def _groups(order: list[str], med: dict) -> list[list[str]]:
    groups: list[list[str]] = []
    for m in order:
        if groups and med[m] - med[groups[-1][0]] <= AT_ONCE_S:
            groups[-1].append(m)
        else:
            groups.append([m])
    return groups


def _compare_sets(ours: list, thesis: set) -> str:
    o = {frozenset(d) for d in ours}
    if o == thesis:
        return "equal"
    if o and o < thesis:
        return "tighter"
    if o > thesis:
        return "looser"
    return "different"


def _set_rows(col: dict, kind: str) -> list[Row]:
    out = []
    for c in claims(kind):
        runs = col["scenarios"][c.scenario]["runs"]
        thesis = {frozenset(d) for d in diagnoses(c)}
        key = "final" if kind == "final_set" else "interim"
        cats = [_compare_sets(r[key] or [], thesis) for r in runs]
        n = len(cats)
        counts = {k: cats.count(k) for k in ("equal", "tighter", "looser", "different")}
        top = max(counts, key=lambda k: (counts[k], k == "equal"))
        verdict = {"equal": "reproduced", "tighter": "better", "looser": "worse", "different": "not reproduced"}[top]
        at = "the end" if kind == "final_set" else f"{col['scenarios'][c.scenario]['interim_at_s']:g} s"
        example = next((r[key] for r, k in zip(runs, cats) if k == top), [])
        ours = ", ".join(f"{k} {v}/{n}" for k, v in counts.items() if v) + f"; e.g. {_set_text(example)}"
        out.append(
            Row(
                c.id,
                c.section,
                c.kind,
                c.line,
                f"diagnosis set of {c.scenario} at {at}",
                _set_text(sorted(map(sorted, thesis))),
                "table sizes",
                ours,
                n,
                None,
                verdict,
                {"counts": counts},
            )  # fmt: skip
        )
    return out


def _set_text(ds) -> str:
    if not ds:
        return "{}"
    ds = list(ds)
    shown = ", ".join("{" + ", ".join(d) + "}" for d in ds[:6])
    return shown + (f", ... ({len(ds)} in all)" if len(ds) > 6 else "")


def _spread_rows(col: dict) -> list[Row]:
    out = []
    for c in claims("kpi_spread"):
        entry = col["sensor"][c.fault]["table"]
        d = [x for x in _delays(entry, c.module) if x is not None]
        n = len(entry["modules_s"])
        early = _early(entry, c.module)
        own = c.module == _own(c.fault)
        if len(d) * 2 <= n or early * 2 > n:
            verdict, s, lo, hi = "not reproduced", math.nan, math.nan, math.nan
        else:
            s, lo, hi = std_ci(d)
            verdict = "reproduced" if s < SPREAD_S else "worse"
        ours = (
            f"{s:.3g} s ({lo:.3g} to {hi:.3g}); fired in {len(d)}/{n}"
            if not math.isnan(s)
            else f"fired in {len(d)}/{n}"
        )
        if early:
            ours += f"; {early} before the onset"
        out.append(
            Row(
                c.id,
                c.section,
                c.kind,
                c.line,
                f"spread of {c.module}'s delay for {c.fault}" + (" (own)" if own else ""),
                f"< {SPREAD_S:g} s",
                "table 6.3, K = 100 runs",
                ours,
                n,
                None,
                verdict,
                {"std_s": s, "ci_s": [lo, hi], "fired": len(d), "own": own},
            )  # fmt: skip
        )
    return out


def _limit_rows(col: dict) -> list[Row]:
    out = []
    for c in claims("min_detectable"):
        v = col["min_detectable"][c.fault]
        lim = v["limit"]
        thesis = float(c.value)
        ratio = lim / thesis if lim is not None else math.inf
        verdict = ratio_verdict(ratio)
        unit = v["unit"]
        ours = (
            f"{lim:.3g} {unit} (bracket {v['bracket'][0]:.3g}-{v['bracket'][1]:.3g})"
            if lim
            else v.get("note", "not found")
        )
        out.append(
            Row(
                c.id,
                c.section,
                c.kind,
                c.line,
                f"smallest {c.fault} detected in 300 s",
                f"{thesis:g} {c.unit}",
                f"constant fuel setting 1.0, every one of {v['seeds']} seeds",
                ours,
                v["seeds"],
                ratio,
                verdict,
                {"limit": lim, "bracket": v["bracket"]},
            )  # fmt: skip
        )
    return out


def _fa_rows(col: dict) -> list[Row]:
    out = []
    fa = col["false_alarms"]
    hours = fa["engine_hours"]
    k = fa["runs_with_false_alarm"]
    lo, hi = rate_ci(k, hours)
    for c in claims("false_alarms"):
        if c.scenario:  # before the first onset of an example
            runs = col["scenarios"][c.scenario]["runs"]
            first_on = min(f["onset_s"] for f in col["scenarios"][c.scenario]["faults"])
            bad = sum(1 for r in runs if r["first_s"] is not None and r["first_s"] < first_on)
            out.append(
                Row(
                    c.id,
                    c.section,
                    c.kind,
                    c.line,
                    f"nothing declared before the first onset of {c.scenario}",
                    str(c.value),
                    "table sizes",
                    f"{bad}/{len(runs)} runs detect before {first_on:g} s",
                    len(runs),
                    None,
                    "reproduced" if bad == 0 else "not reproduced",
                    {"early_runs": bad},
                )  # fmt: skip
            )
        elif c.fault:  # the process-fault run raised no alarm before the onset
            entry = col["process"][c.fault]["table"]
            bad = _early(entry, None)
            n = len(entry["first_s"])
            out.append(
                Row(
                    c.id,
                    c.section,
                    c.kind,
                    c.line,
                    f"no false alarm in the {c.fault} runs",
                    str(c.value),
                    "table 6.4",
                    f"{bad}/{n} runs detect before the onset",
                    n,
                    None,
                    "reproduced" if bad == 0 else "not reproduced",
                    {"early_runs": bad},
                )  # fmt: skip
            )
        else:
            mods = _fa_modules(c.id)
            alarms = [a for a in fa["alarms"] if mods is None or set(a["modules"]) & mods]
            kk = len(alarms) if mods is not None else k
            lo2, hi2 = rate_ci(kk, hours)
            scope = "any module" if mods is None else ", ".join(sorted(mods))
            out.append(
                Row(
                    c.id,
                    c.section,
                    c.kind,
                    c.line,
                    f"no false alarm ({scope})",
                    str(c.value),
                    "fault-free, five profile families, fuel settings 0.3-1.1",
                    f"{kk} runs with an alarm in {fa['runs']} ({hours:.0f} engine-hours): "
                    f"{kk / hours:.3g}/h ({lo2:.3g} to {hi2:.3g})",
                    fa["runs"],
                    None,
                    "reproduced" if kk == 0 else "not reproduced",
                    {"runs_with_alarm": kk, "per_hour": kk / hours, "ci_per_hour": [lo2, hi2]},
                )  # fmt: skip
            )
    del lo, hi
    return out


def _fa_modules(claim_id: str) -> set[str] | None:
    for var, mods in (("x1", {"M1.1", "M1.2"}), ("x3", {"M3.1", "M3.2"}), ("x4", {"M4.1", "M4.2"})):
        if claim_id.endswith("/" + var):
            return mods
    return None


def rows_for(col: dict) -> list[Row]:
    """Every claim's row(s) in one column, in the thesis's order."""
    return (
        _sensor_rows(col)
        + _process_rows(col)
        + _signature_rows(col)
        + _event_rows(col)
        + _order_rows(col)
        + _set_rows(col, "interim_set")
        + _set_rows(col, "final_set")
        + _spread_rows(col)
        + _limit_rows(col)
        + _fa_rows(col)
    )


# ----------------------------------------------------------------------------- output
def write_table(
    work_dir: Path, settings: dict, doc: Path = DOC, data: Path = DATA, readme: Path | None = Path("README.md")
) -> int:
    """Write docs/reproduction.md and docs/data/reproduction.json from the measured columns."""
    from .reproduction import COLUMNS, column_agent
    from .reproduction_causes_text import causes_for

    cols = {}
    for c in COLUMNS:
        p = work_dir / f"{c}.json"
        if p.exists():
            d = json.loads(p.read_text())
            if d.get("settings") == settings:
                cols[c] = d
    if "local" not in cols:
        print(f"no measured 'local' column in {work_dir} with these settings: measure it first")
        return 1
    table = {c: [r.to_dict() for r in rows_for(d)] for c, d in cols.items()}
    causes = causes_for(table, cols)
    for c, rows in table.items():
        for r in rows:
            r["cause"] = causes.get((c, r["claim"], r["size"]))
    counts = {c: {v: sum(r["verdict"] == v for r in rows) for v in VERDICTS} for c, rows in table.items()}
    out = {
        "settings": settings,
        "command": _command(settings),
        "thesis_text": str(THESIS_TEXT.name),
        "columns": {
            c: {"agent": column_agent(c), "options": cols[c]["options"], "cpu_s": cols[c]["cpu_s"]} for c in cols
        },
        "counts": counts,
        "suites": {c: cols[c]["suites"] for c in cols},
        "false_alarms": {c: _fa_summary(cols[c]["false_alarms"]) for c in cols},
        "rows": table,
    }
    data.parent.mkdir(parents=True, exist_ok=True)
    data.write_text(json.dumps(out, indent=1, default=_jsonable) + "\n")
    doc.write_text(_markdown(out))
    print(f"wrote {doc} and {data}")
    if readme is not None and readme.exists() and _write_readme_line(readme, out):
        print(f"wrote the reproduction line of {readme}")
    return 0


README_BEGIN = "<!-- reproduction:begin (python -m studies.diagnosis.reproduction --render-only) -->"
README_END = "<!-- reproduction:end -->"


def _write_readme_line(readme: Path, out: dict) -> bool:
    """The README's line on the reproduction, between its markers; False if it has none."""
    text = readme.read_text()
    if README_BEGIN not in text or README_END not in text:
        return False
    k = out["counts"]["local"]
    line = (
        f"The reference against the thesis, claim by claim: {k['reproduced']} of {sum(k.values())} rows reproduced, "
        f"{k['better']} better, {k['worse']} worse, {k['not reproduced']} not, each difference with its measured "
        "cause ([reproduction.md](docs/reproduction.md))."
    )
    head, rest = text.split(README_BEGIN, 1)
    _, tail = rest.split(README_END, 1)
    readme.write_text(f"{head}{README_BEGIN}\n{line}\n{README_END}{tail}")
    return True


def _jsonable(o):
    if isinstance(o, float) and not math.isfinite(o):
        return None
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    raise TypeError(type(o))


def _fa_summary(fa: dict) -> dict:
    k, h = fa["runs_with_false_alarm"], fa["engine_hours"]
    lo, hi = rate_ci(k, h)
    return {"runs": fa["runs"], "engine_hours": h, "runs_with_alarm": k, "per_hour": k / h, "ci_per_hour": [lo, hi]}


def _command(settings: dict) -> str:
    return (
        f"python -m studies.diagnosis.reproduction --seeds {settings['seeds']} --kpi-seeds {settings['kpi_seeds']} "
        f"--limit-seeds {settings['limit_seeds']} --hours {settings['hours']:g}"
    )


def _markdown(out: dict) -> str:
    from .reproduction_doc import markdown

    return markdown(out)
