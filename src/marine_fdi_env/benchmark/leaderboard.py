"""The leaderboard: a table built from entries (:mod:`.entries`) by ``marine-fdi leaderboard``.

One row per agent, its training seeds pooled (the entries of one agent name, one per training seed),
ranked by the interquartile mean of its normalised scores:

* the normalised score of each suite (D4RL style: ``null`` = 0, ``oracle`` = 100, from the mean
  ``MarineFDI-v1`` return; :func:`.uncertainty.normalised_score`), ``nominal-v1`` left out (null and
  oracle earn the same there);
* the IQM over training seeds x suites with its 95 % interval (:func:`.uncertainty.iqm_score`);
* the probability of improvement over ``reference`` (rliable's; :func:`.uncertainty.probability_of_improvement`);
* the DX 2025 metrics per decision over all suites' episodes (:func:`.metrics.dx_metrics`).

Every number comes from the entries' traces, never from their stored metrics (which ``verify``
checks against the same traces).  The block ends with two fingerprints: the sha256 of every file of
the entries it was built from and the sha256 of its own text, so that a stale table (entries added,
removed or changed since) or one edited by hand is found in a second (:func:`fingerprint_problem`,
``marine-fdi leaderboard --check --hashes-only``); ``--check`` alone builds the table again.  The
table needs the entries of ``null`` and ``oracle`` (the normalisers) and of ``reference``.
"""

from __future__ import annotations

import hashlib
import re
from pathlib import Path
from typing import Sequence

from .entries import ENTRY_FILE, WORK, read_entry, read_trace

__all__ = [
    "find_entries",
    "load_pooled",
    "leaderboard_block",
    "write_block",
    "entries_sha256",
    "fingerprint_problem",
    "BEGIN",
    "END",
    "REQUIRED",
]

BEGIN = "<!-- leaderboard:begin (marine-fdi leaderboard writes this block) -->"
END = "<!-- leaderboard:end -->"
REQUIRED = ("null", "oracle", "reference")
_PRINT = re.compile(r"<!-- entries sha256 ([0-9a-f]{64}); table sha256 ([0-9a-f]{64})[^>]*-->\n")


def find_entries(paths: Sequence["str | Path"]) -> list[Path]:
    """The entry folders among ``paths``: each an entry folder, or a folder of entry folders."""
    out: list[Path] = []
    for p in map(Path, paths):
        if (p / ENTRY_FILE).is_file():
            out.append(p)
        elif p.is_dir():
            subs = sorted(d for d in p.iterdir() if (d / ENTRY_FILE).is_file())
            if not subs:
                raise ValueError(f"{p}: neither an entry folder ({ENTRY_FILE}) nor a folder of entry folders")
            out += subs
        else:
            raise ValueError(f"{p}: no such entry folder")
    return out


def load_pooled(entry_dirs: Sequence[Path]) -> dict[str, dict]:
    """``{agent name: {"family", "seeds": [...], "entries": [...], "suites": {suite: [records of each
    seed]}}}``, the training seeds in order; ValueError when an agent's seeds cover other suites."""
    pooled: dict[str, dict] = {}
    for d in entry_dirs:
        e = read_entry(d)
        a = e["agent"]
        name = str(a.get("name"))
        p = pooled.setdefault(name, {"family": a.get("family"), "seeds": [], "entries": [], "traces": []})
        p["seeds"].append(a.get("training_seed"))
        p["entries"].append(d)
        p["traces"].append({b["name"]: read_trace(d, b)[0] for b in e["suites"]})
    for name, p in pooled.items():
        order = sorted(range(len(p["seeds"])), key=lambda i: (p["seeds"][i] is None, p["seeds"][i] or 0))
        if len(order) > 1 and any(p["seeds"][i] is None for i in order):
            raise ValueError(f"agent {name!r}: several entries, not all with a training seed: {p['entries']}")
        suites = [set(t) for t in p["traces"]]
        if any(s != suites[0] for s in suites):
            raise ValueError(f"agent {name!r}: its entries cover different suites ({p['entries']})")
        p["seeds"] = [p["seeds"][i] for i in order]
        p["entries"] = [p["entries"][i] for i in order]
        kept = p.pop("traces")
        traces = [kept[i] for i in order]
        p["suites"] = {s: [t[s] for t in traces] for s in traces[0]}
    missing = [n for n in REQUIRED if n not in pooled]
    if missing:
        raise ValueError(f"the leaderboard needs the entries of {', '.join(REQUIRED)}; missing: {', '.join(missing)}")
    return pooled


def _fmt(e, scale: float = 1.0, digits: int = 1) -> str:
    if e is None or e.value is None:
        return "–"
    v = f"{scale * e.value:.{digits}f}"
    if e.low is None or e.high is None:
        return v
    return f"{v} ({scale * e.low:.{digits}f}–{scale * e.high:.{digits}f})"


def _files(d: Path) -> list[Path]:
    """The files of an entry folder (an unfinished submit's ``.work`` aside), in a fixed order."""
    d = Path(d)
    return sorted(f for f in d.rglob("*") if f.is_file() and WORK not in f.relative_to(d).parts)


def _dir_bytes(d: Path) -> int:
    return sum(f.stat().st_size for f in _files(d))


def entries_sha256(entry_dirs: Sequence[Path]) -> str:
    """One sha256 of every file of the entries (by folder name, path in it and content)."""
    h = hashlib.sha256()
    for d in sorted(map(Path, entry_dirs), key=lambda d: d.name):
        for f in _files(d):
            h.update(f"{d.name}/{f.relative_to(d).as_posix()}\0{hashlib.sha256(f.read_bytes()).hexdigest()}\n".encode())
    return h.hexdigest()


def fingerprint_problem(text: str, entry_dirs: Sequence[Path]) -> str | None:
    """Whether the leaderboard block in ``text`` was written from these entries and not edited since,
    by its fingerprints alone (no table is built); the problem in one line, or None."""
    if BEGIN not in text or END not in text:
        return "no leaderboard markers: run marine-fdi leaderboard"
    block = text[text.index(BEGIN) : text.index(END)]
    m = _PRINT.search(block)
    if m is None:
        return "the table has no fingerprints (entries sha256, table sha256): rerun marine-fdi leaderboard"
    if hashlib.sha256(block[: m.start()].encode()).hexdigest() != m.group(2):
        return "the table is not the text marine-fdi leaderboard wrote (edited by hand): rerun marine-fdi leaderboard"
    if entries_sha256(entry_dirs) != m.group(1):
        return (
            f"the table is stale: its {len(entry_dirs)} entries are not those it was built from (an entry added, "
            "removed or changed since); rerun marine-fdi leaderboard and commit it"
        )
    return None


def leaderboard_block(entry_dirs: Sequence[Path], shown_root: Path | None = None) -> str:
    """The Markdown between the markers: the ranked table, the DX table and the entries."""
    from .metrics import scored_once

    with scored_once():
        return _block(entry_dirs, shown_root)


def _block(entry_dirs: Sequence[Path], shown_root: Path | None) -> str:
    from .suites import SUITE_NAMES
    from .uncertainty import interval, iqm_score, normalised_score, outcomes, probability_of_improvement

    pooled = load_pooled(entry_dirs)
    common = set.intersection(*(set(p["suites"]) for p in pooled.values()))
    suites = [s for s in SUITE_NAMES if s in common]
    o = {(a, s): outcomes(p["suites"][s]) for a, p in pooled.items() for s in suites}
    scored = [s for s in suites if abs(float(o[("oracle", s)].ret[0].mean() - o[("null", s)].ret[0].mean())) > 1e-9]
    rows = []
    for a, p in pooled.items():
        per = [(o[(a, s)], o[("null", s)], o[("oracle", s)]) for s in scored]
        iqm = iqm_score(per)
        poi = probability_of_improvement(
            [(o[(a, s)], o[("reference", s)], o[("null", s)], o[("oracle", s)]) for s in scored]
        )
        cells = [normalised_score(*t) for t in per]
        every = outcomes([[r for s in suites for r in p["suites"][s][k]] for k in range(len(p["seeds"]))])
        dx = [
            interval(every, m) for m in ("dx_true_detection_rate", "dx_false_alarm_rate", "dx_fault_isolation_accuracy")
        ]
        rows.append((a, p, iqm, poi, cells, dx))
    rows.sort(key=lambda r: (-(r[2].value if r[2].value is not None else -1e9), r[0]))
    seeds = lambda p: str(len(p["seeds"])) if p["seeds"][0] is not None else "1"  # noqa: E731
    head = (
        "| rank | agent | kind | seeds | normalised score, IQM | P(better than reference) | "
        + " | ".join(scored)
        + " |"
    )
    left = ", ".join(s for s in suites if s not in scored) or "no suite"
    lines = [
        BEGIN,
        "",
        f"Normalised score per suite (null = 0, oracle = 100, from the mean MarineFDI-v1 return; {left} "
        "left out: null and oracle earn the same there) and its interquartile mean over training seeds x suites; "
        "P(better than reference): rliable's probability of improvement over `reference` (per suite, the share of "
        "seed pairs whose score is higher, ties one half; averaged over the suites).  95 % intervals in "
        "parentheses: stratified bootstrap over episodes and training seeds (`marine_fdi_env.benchmark.uncertainty`).",
        "",
        head,
        "|---:|---|---|---:|---:|---:|" + "---:|" * len(scored),
    ]
    for k, (a, p, iqm, poi, cells, _) in enumerate(rows, 1):
        lines.append(
            f"| {k} | `{a}` | {p['family']} | {seeds(p)} | {_fmt(iqm)} | {_fmt(poi, digits=2)} | "
            + " | ".join(_fmt(c) for c in cells)
            + " |"
        )
    lines += [
        "",
        f"The DX 2025 metrics per decision over the episodes of all {len(suites)} suites ({', '.join(suites)}): "
        "true detection rate (TDR), false-alarm rate (FAR) and isolation accuracy (FIA, the mean share of belief "
        "on the true faults while the alarm is on); how they differ from the competition's: docs/submitting.md.",
        "",
        "| agent | seeds | DX TDR | DX FAR | DX FIA |",
        "|---|---:|---:|---:|---:|",
    ]
    for a, p, _, _, _, dx in rows:
        lines.append(
            f"| `{a}` | {seeds(p)} | "
            + " | ".join(_fmt(e, 100.0) + " %" if e.value is not None else "–" for e in dx)
            + " |"
        )
    total = sum(_dir_bytes(d) for p in pooled.values() for d in p["entries"])
    lines += [
        "",
        "| entry | agent | training seed | needs | package | episodes | size |",
        "|---|---|---:|---|---|---:|---:|",
    ]
    for a, p, *_ in rows:
        for d, s in zip(p["entries"], p["seeds"]):
            e = read_entry(d)
            shown = (
                d.name if shown_root is None else Path(d).resolve().relative_to(Path(shown_root).resolve()).as_posix()
            )
            lines.append(
                f"| [{d.name}]({shown}/{ENTRY_FILE}) | `{a}` | {'–' if s is None else s} | "
                f"{', '.join(e['agent'].get('needs') or []) or '–'} | {e['software'].get('marine-fdi-env', '?')} | "
                f"{sum(b['n_episodes'] for b in e['suites'])} | {_dir_bytes(d) / 1024:.0f} KiB |"
            )
    lines += [
        "",
        f"{sum(len(p['entries']) for p in pooled.values())} entries of {len(pooled)} agents, {total / 2**20:.1f} MiB "
        "on disk (gzip'd JSON traces).",
        "",
    ]
    text = "\n".join(lines) + "\n"
    table = hashlib.sha256(text.encode()).hexdigest()
    return (
        text
        + f"<!-- entries sha256 {entries_sha256(entry_dirs)}; table sha256 {table} (marine-fdi leaderboard --check "
        "--hashes-only compares them) -->\n" + END
    )


def write_block(path: Path, block: str) -> bool:
    """Put ``block`` between the markers of ``path`` (a new file holds a title and the block); whether
    the file changed."""
    path = Path(path)
    text = path.read_text(encoding="utf-8") if path.is_file() else f"# Leaderboard\n\n{BEGIN}\n{END}\n"
    if BEGIN not in text or END not in text:
        raise ValueError(f"{path}: no leaderboard markers ({BEGIN} ... {END}) to write between")
    a, b = text.index(BEGIN), text.index(END) + len(END)
    new = text[:a] + block + text[b:]
    if new == text:
        return False
    path.write_text(new, encoding="utf-8")
    return True
