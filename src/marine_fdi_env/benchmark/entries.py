"""Entries anyone can submit and anyone can verify: ``marine-fdi submit`` and ``marine-fdi verify``.

An entry is a folder::

    DIR/entry.json               what was scored, on what, with what, and the metrics (below)
    DIR/traces/SUITE.json.gz     the per-episode records of ``marine-fdi evaluate`` on each suite
                                 (the declaration trace, the returns, the compute times), gzip'd JSON
    DIR/agent/                   a copy of a folder or file agent (shipped agents are found by name)

``entry.json`` holds ``format`` / ``format_version``; ``agent`` (:func:`.provenance.agent_identity`:
kind, family, name or files with their sha256, training seed, the extras it needs); ``declared``
(what the submitter states: the training data, notes); ``software`` (versions); ``command``; and per
suite (``suites``): its ``name``, ``version`` and content ``sha256`` (:func:`.provenance.suite_sha256`),
the environment it was scored on, the trace file and the sha256 of its decoded JSON, and
``metrics`` (:func:`.metrics.compute_metrics`), ``dx_metrics`` (:func:`.metrics.dx_metrics`) and
``intervals`` (:func:`.uncertainty.interval` of every :data:`.uncertainty.RATE_METRICS`), all
computed from the trace.  ``wall_clock`` (when and how long) is outside every check.

**What each check catches** (the threat model):

* the hashes catch corruption and name the provenance: a trace whose bytes changed, a suite file that
  is no longer the one scored (``suite single-v1: its content sha256 is ... here, the entry was
  scored on ...``), a model whose files are not those scored;
* recomputation (:func:`verify_entry`) catches an edited metric: every metric, DX metric and interval
  is recomputed from the trace and compared exactly; the trace's ground truth (faults, seeds,
  profiles) is compared with the suite's scenarios, so a trace cannot move the truth;
* only a rerun (:func:`rerun_entries`, ``verify --rerun``) catches an edited trace: the suites are
  simulated again, the agent replayed, and every record compared field by field, episode by episode.

The wall-clock fields of the records (:data:`.evaluate.WALL_CLOCK_FIELDS`) and the metrics made of
them (:data:`.evaluate.WALL_CLOCK_METRICS`) are recomputed from the trace like any other, but a
rerun does not compare them: they differ from run to run.

A suite change makes a new suite version (a new name, ``single-v2``): an entry names the version and
content it was scored on and stays valid for it; a suite file changed under the same name is refused.
"""

from __future__ import annotations

import gzip
import hashlib
import json
import math
import os
import shutil
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

from ..errors import DataFileError

__all__ = [
    "ENTRY_FILE",
    "FORMAT",
    "FORMAT_VERSION",
    "submit_entries",
    "read_entry",
    "read_trace",
    "verify_entry",
    "rerun_entries",
    "Verification",
    "suite_block",
    "record_differences",
]

ENTRY_FILE = "entry.json"
FORMAT = "marine-fdi entry"
FORMAT_VERSION = 1
TRACES = "traces"
WORK = ".work"  # finished suites and partial logs of an unfinished submit, inside DIR


@dataclass
class Verification:
    """The outcome of verifying one entry: ``problems`` (one line each; empty: it verifies) and what
    was checked (``checked``, lines for the record)."""

    entry: Path
    problems: list[str] = field(default_factory=list)
    checked: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.problems


# ----------------------------------------------------------------------------- traces
def _trace_bytes(records: Sequence[dict]) -> bytes:
    return json.dumps(list(records), sort_keys=True, separators=(",", ":")).encode()


def _write_trace(path: Path, records: Sequence[dict]) -> str:
    """Write the records gzip'd (no time stamp: the same records, the same file); the sha256 of the JSON."""
    data = _trace_bytes(records)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "wb") as raw, gzip.GzipFile(filename="", mode="wb", fileobj=raw, compresslevel=9, mtime=0) as gz:
        gz.write(data)
    os.replace(tmp, path)
    return hashlib.sha256(data).hexdigest()


def read_trace(entry_dir: Path, block: dict) -> tuple[list[dict], str]:
    """(records, sha256 of the decoded JSON) of a suite block's trace; DataFileError naming the file."""
    path = Path(entry_dir) / str(block.get("trace", ""))
    try:
        data = gzip.decompress(path.read_bytes())
        records = json.loads(data)
    except FileNotFoundError:
        raise DataFileError(f"{path}: the trace of suite {block.get('name')!r} is missing") from None
    except (OSError, EOFError, gzip.BadGzipFile, json.JSONDecodeError, UnicodeDecodeError) as e:
        raise DataFileError(f"{path}: not a readable gzip'd JSON trace ({e})") from None
    if not isinstance(records, list):
        raise DataFileError(f"{path}: a trace is a JSON list of episode records")
    return records, hashlib.sha256(data).hexdigest()


# ----------------------------------------------------------------------------- metrics of a trace
def _estimates(episode_lists: Sequence[Sequence[dict]]) -> dict:
    from .uncertainty import RATE_METRICS, interval, outcomes

    o = outcomes(episode_lists)
    return {m: interval(o, m).to_dict() for m in RATE_METRICS}


def _suite_scores(records: list[dict]) -> dict:
    """What an entry's suite block holds of its trace: ``metrics``, ``dx_metrics`` and ``intervals``."""
    from .metrics import metric_blocks

    return {**metric_blocks(records), "intervals": _estimates([records])}


def suite_block(suite, records: list[dict], trace: str, trace_sha256: str, env_id: str, env: dict) -> dict:
    """The block of ``entry.json`` for one suite: its identity, the trace and what it gives."""
    from .provenance import suite_sha256

    return {
        "name": suite.name,
        "version": suite["version"],
        "sha256": suite_sha256(suite),
        "n_episodes": len(records),
        "seed_offset": 0,
        "env_id": env_id,
        "env": env,
        "trace": trace,
        "trace_sha256": trace_sha256,
        **_suite_scores(records),
    }


# ----------------------------------------------------------------------------- submit
def _same(a, b) -> bool:
    """Exact equality of JSON values (NaN never occurs: metrics use None)."""
    return json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)


def _done_suite(work: Path, suite, spec: str) -> bool:
    """Whether ``work`` keeps the finished results of ``spec`` on ``suite`` (an interrupted submit's)."""
    f = work / f"{suite.name}.json"
    try:
        res = json.loads(f.read_text())
    except (OSError, json.JSONDecodeError):
        return False
    return (res.get("agent_spec"), res.get("suite"), res.get("suite_version")) == (spec, suite.name, suite["version"])


def submit_entries(
    specs: Sequence[str],
    suites: Sequence[str],
    outs: Sequence[Path],
    *,
    declared: dict | None = None,
    command: str = "",
    workers: int = 1,
    batch_size: int = 32,
    backend=None,
    progress: bool = True,
    log: Callable[[str], None] = print,
) -> list[dict]:
    """Score ``specs`` (one entry folder each, ``outs``) on ``suites`` and write their entries; the
    agents are scored together, in lockstep on one simulation of each suite.  Finished suites are kept
    in ``OUT/.work`` until the entry is written, so an interrupted submit resumes; returns the entries."""
    from .agent_api import load_agent, resolve_agent_spec
    from .backends import Backend
    from .evaluate import evaluate_agents
    from .provenance import agent_identity, copy_agent, software_versions
    from .suites import load_suite

    if len(specs) != len(outs) or not specs:
        raise ValueError("submit needs one output folder per agent, and at least one agent")
    if not suites:
        raise ValueError("--suites: name at least one suite")
    if not isinstance(backend, Backend):
        backend = Backend.make(backend, workers)
    resolved = [resolve_agent_spec(s) for s in specs]
    agents = [load_agent(s) for s in resolved]  # a bad agent fails before any work
    loaded = [load_suite(s) for s in suites]
    for s in loaded:
        from .suites import SUITE_NAMES

        if s.name not in SUITE_NAMES:
            raise ValueError(f"--suites: {s.name!r} is not a shipped suite; an entry is scored on the frozen suites")
    t0 = time.perf_counter()
    works = [Path(o) / WORK for o in outs]
    for w in works:
        w.mkdir(parents=True, exist_ok=True)
    for suite in loaded:
        todo = [j for j, w in enumerate(works) if not _done_suite(w, suite, resolved[j])]
        if todo:
            evaluate_agents(
                [resolved[j] for j in todo],
                suite.name,
                [works[j] / f"{suite.name}.json" for j in todo],
                workers=workers,
                batch_size=batch_size,
                progress=progress,
                backend=backend,
            )
    entries = []
    for j, (spec, out, agent) in enumerate(zip(specs, outs, agents)):
        out = Path(out)
        seed = getattr(agent, "training_seed", None)
        identity = dict(agent_identity(resolved[j], seed), name=agent.name)
        blocks = []
        for suite in loaded:
            res = json.loads((works[j] / f"{suite.name}.json").read_text())
            rel = f"{TRACES}/{suite.name}.json.gz"
            sha = _write_trace(out / rel, res["episodes"])
            blocks.append(suite_block(suite, res["episodes"], rel, sha, res["env_id"], res["env"]))
        entry = {
            "format": FORMAT,
            "format_version": FORMAT_VERSION,
            "agent": identity,
            "declared": dict(declared or {}),
            "software": software_versions(),
            "command": command or f"marine-fdi submit {spec} --out {out}",
            "suites": blocks,
            "wall_clock": {
                "created_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
                "submit_s": round(time.perf_counter() - t0, 1),
                "load_average_1min": round(os.getloadavg()[0], 2),
            },
        }
        copy_agent(resolved[j], identity, out)
        tmp = out / (ENTRY_FILE + ".tmp")
        tmp.write_text(json.dumps(entry, indent=1) + "\n")
        os.replace(tmp, out / ENTRY_FILE)
        shutil.rmtree(works[j], ignore_errors=True)
        entries.append(entry)
        if log:
            n = sum(b["n_episodes"] for b in blocks)
            log(f"wrote the entry {out} ({agent.name}: {len(blocks)} suites, {n} episodes)")
    return entries


# ----------------------------------------------------------------------------- verify
def read_entry(entry_dir: Path) -> dict:
    """``entry.json`` of an entry folder; DataFileError naming what is wrong."""
    from ..jsonfile import read_json

    f = Path(entry_dir) / ENTRY_FILE
    if not f.is_file():
        raise DataFileError(f"{entry_dir}: no {ENTRY_FILE} (not an entry folder written by marine-fdi submit)")
    entry = read_json(f, "entry")
    if not isinstance(entry, dict) or entry.get("format") != FORMAT:
        raise DataFileError(f"{f}: not an entry (format {FORMAT!r} expected)")
    if entry.get("format_version") != FORMAT_VERSION:
        raise DataFileError(f"{f}: format_version {entry.get('format_version')!r}; this version reads {FORMAT_VERSION}")
    for k in ("agent", "suites"):
        if k not in entry:
            raise DataFileError(f"{f}: field {k!r} is missing")
    return entry


def _first_difference(kept, now, path: str) -> str | None:
    """The first path where two JSON values differ: ``metrics.by_class.sensor.detection_rate: the entry
    says 0.5, its trace gives 0.6``."""
    if isinstance(kept, dict) and isinstance(now, dict):
        for k in list(now) + [k for k in kept if k not in now]:
            if k not in kept:
                return f"{path}.{k}: missing from the entry"
            if k not in now:
                return f"{path}.{k}: in the entry, not computed from its trace"
            d = _first_difference(kept[k], now[k], f"{path}.{k}")
            if d:
                return d
        return None
    if isinstance(kept, list) and isinstance(now, list) and len(kept) == len(now):
        for i, (a, b) in enumerate(zip(kept, now)):
            d = _first_difference(a, b, f"{path}[{i}]")
            if d:
                return d
        return None
    if _same(kept, now) or (_num(kept) and _num(now) and float(kept) == float(now)):
        return None
    return f"{path}: the entry says {_short(kept)}, the trace gives {_short(now)}"


def _num(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _short(v) -> str:
    text = json.dumps(v)
    return text if len(text) <= 80 else text[:77] + "..."


def _check_truth(records: list[dict], suite, name: str) -> str | None:
    """The trace's scenarios, seeds, profiles and faults against the suite's (the truth is not the trace's)."""
    ids = [s.scenario_id for s in suite.scenarios]
    got = [r.get("scenario_id") for r in records]
    if got != ids:
        first = next((i for i, (a, b) in enumerate(zip(got, ids)) if a != b), min(len(got), len(ids)))
        return (
            f"suite {name}: the trace holds {len(got)} episodes, the suite {len(ids)}; episode {first} is "
            f"{got[first] if first < len(got) else 'missing'!r}, the suite's "
            f"{ids[first] if first < len(ids) else '-'!r}"
        )
    for r, sc in zip(records, suite.scenarios):
        for key, want in (("faults", sc.truth()), ("seed", int(sc.noise_seed)), ("profile", sc.profile)):
            if not _same(r.get(key), want):
                return f"suite {name}: episode {sc.scenario_id}: {key} in the trace is not the suite's ground truth"
        if r.get("suite") != name:
            return f"suite {name}: episode {sc.scenario_id}: the record names suite {r.get('suite')!r}"
    return None


def verify_entry(entry_dir: Path, *, check_agent: bool = True, recompute: bool = True) -> Verification:
    """Check an entry without simulating: every hash, the ground truth of its traces, and every metric,
    DX metric and interval recomputed from its traces (module docstring).  ``check_agent``: also hash
    the agent's files where they are (the shipped model in this installation, the entry's copy).
    ``recompute=False`` (``verify --hashes-only``): the hashes alone (agent files, suites, traces),
    without reading the traces' records: corruption and provenance, not an edited metric."""
    from .metrics import scored_once

    with scored_once():
        return _verify_entry(Path(entry_dir), check_agent, recompute)


def _trace_sha256(entry_dir: Path, block: dict) -> str:
    """The sha256 of a trace's decoded JSON, without parsing it; DataFileError naming the file."""
    path = Path(entry_dir) / str(block.get("trace", ""))
    try:
        return hashlib.sha256(gzip.decompress(path.read_bytes())).hexdigest()
    except FileNotFoundError:
        raise DataFileError(f"{path}: the trace of suite {block.get('name')!r} is missing") from None
    except (OSError, EOFError, gzip.BadGzipFile) as e:
        raise DataFileError(f"{path}: not a readable gzip'd JSON trace ({e})") from None


def _verify_entry(entry_dir: Path, check_agent: bool, recompute: bool) -> Verification:
    from .agent_registry import models_dir
    from .metrics import validate_record
    from .provenance import AGENT_FOLDER, file_sha256, software_versions, suite_sha256
    from .suites import SUITE_NAMES, load_suite

    entry_dir = Path(entry_dir)
    v = Verification(entry_dir)
    try:
        entry = read_entry(entry_dir)
    except ValueError as e:
        v.problems.append(str(e))
        return v
    agent = entry["agent"]
    if check_agent and agent.get("kind") in ("shipped", "folder", "file"):
        if agent["kind"] == "shipped":
            root = models_dir()
            base = None if root is None else root / str(agent.get("folder", ""))
        else:
            base = entry_dir / (AGENT_FOLDER if agent["kind"] == "folder" else Path(agent["file"]).parent)
        files = agent.get("files") or {}
        if base is None or not base.is_dir():
            v.problems.append(f"agent {agent.get('name')!r}: its files are not here ({base})")
        else:
            for rel, sha in files.items():
                f = base / rel
                if not f.is_file():
                    v.problems.append(f"agent {agent.get('name')!r}: {rel} is missing from {base}")
                elif file_sha256(f) != sha:
                    v.problems.append(
                        f"agent {agent.get('name')!r}: {rel} in {base} is not the file scored (its sha256 differs): "
                        "the entry names another model"
                    )
            if not v.problems:
                v.checked.append(f"agent files: {len(files)} sha256")
    for block in entry["suites"]:
        name = str(block.get("name"))
        if name not in SUITE_NAMES:
            v.problems.append(f"suite {name!r}: not a shipped suite of this version ({', '.join(SUITE_NAMES)})")
            continue
        suite = load_suite(name)
        if block.get("version") != suite["version"]:
            v.problems.append(
                f"suite {name}: the entry names version {block.get('version')!r}, here {suite['version']}"
            )
            continue
        here = suite_sha256(suite)
        if block.get("sha256") != here:
            v.problems.append(
                f"suite {name}: its content sha256 is {here[:12]}... here, the entry was scored on "
                f"{str(block.get('sha256'))[:12]}...: the suite file changed (a changed suite is a new version)"
            )
            continue
        try:
            if recompute:
                records, sha = read_trace(entry_dir, block)
            else:
                sha = _trace_sha256(entry_dir, block)
        except ValueError as e:
            v.problems.append(str(e))
            continue
        if sha != block.get("trace_sha256"):
            v.problems.append(
                f"suite {name}: the trace {block.get('trace')} does not have the entry's sha256 (corrupt or edited)"
            )
            continue
        if not recompute:
            v.checked.append(f"{name}: suite and trace sha256")
            continue
        try:
            for r in records:
                validate_record(r)
        except ValueError as e:
            v.problems.append(f"suite {name}: {e}")
            continue
        bad = _check_truth(records, suite, name)
        if bad:
            v.problems.append(bad)
            continue
        if block.get("n_episodes") != len(records):
            v.problems.append(
                f"suite {name}: n_episodes: the entry says {block.get('n_episodes')}, the trace holds {len(records)}"
            )
            continue
        for key, now in _suite_scores(records).items():
            d = _first_difference(block.get(key), json.loads(json.dumps(now)), f"suite {name}: {key}")
            if d:
                v.problems.append(d)
                break
        else:
            v.checked.append(f"{name}: {len(records)} episodes, metrics recomputed")
    mine = software_versions()
    other = {k: (val, mine.get(k)) for k, val in (entry.get("software") or {}).items() if mine.get(k) != val}
    other.pop("platform", None)
    if other:
        v.notes.append(
            "made with other versions: " + ", ".join(f"{k} {a} (here {b})" for k, (a, b) in sorted(other.items()))
        )
    return v


# ----------------------------------------------------------------------------- rerun
def _strip_clock(x):
    from .evaluate import WALL_CLOCK_FIELDS, WALL_CLOCK_METRICS

    if isinstance(x, dict):
        return {k: _strip_clock(v) for k, v in x.items() if k not in WALL_CLOCK_FIELDS + WALL_CLOCK_METRICS}
    if isinstance(x, list):
        return [_strip_clock(v) for v in x]
    return x


_RERUN_FIELDS = ("declared_changes", "belief_on_truth", "return", "reward_terms", "terminated", "failure_reason")


def record_differences(kept: list[dict], now: list[dict], name: str, limit: int = 10) -> list[str]:
    """Per episode and field, what a rerun gives that the trace does not (wall-clock fields aside)."""
    out = []
    for a, b in zip(kept, now):
        a, b = _strip_clock(a), _strip_clock(b)
        for k in sorted(set(a) | set(b), key=lambda k: (k not in _RERUN_FIELDS, k)):
            if not _same(a.get(k), b.get(k)):
                out.append(
                    f"suite {name}: episode {b['scenario_id']}: {k}: trace {_short(a.get(k))}, rerun {_short(b.get(k))}"
                )
                if len(out) >= limit:
                    return out
    return out


def rerun_entries(
    entry_dirs: Sequence[Path],
    *,
    workers: int = 1,
    batch_size: int = 32,
    backend=None,
    progress: bool = True,
    scratch: Path | None = None,
    log: Callable[[str], None] | None = print,
) -> list[Verification]:
    """Simulate the suites of the entries again, replay their agents (together, in lockstep) and compare
    every record with the trace, field by field and episode by episode, and the metrics (wall-clock
    fields aside).  Each entry is first verified by recomputation (:func:`verify_entry`); an entry that
    does not verify is not rerun."""
    import tempfile

    from .backends import Backend
    from .evaluate import evaluate_agents
    from .provenance import agent_spec_of

    if not isinstance(backend, Backend):
        backend = Backend.make(backend, workers)
    checks = [verify_entry(Path(d)) for d in entry_dirs]
    entries = {Path(c.entry): read_entry(c.entry) for c in checks if c.ok}
    suites: dict[str, list[Path]] = {}
    for d, e in entries.items():
        for b in e["suites"]:
            suites.setdefault(b["name"], []).append(d)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(dir=scratch) as tmp:
        for suite, dirs in suites.items():
            specs = {}
            for d in dirs:  # one run per agent: two entries of one agent compare with the same rerun
                specs.setdefault(agent_spec_of(entries[d]["agent"], d), []).append(d)
            outs = [Path(tmp) / f"{i}_{suite}.json" for i in range(len(specs))]
            results = evaluate_agents(
                list(specs), suite, outs, workers=workers, batch_size=batch_size, progress=progress, backend=backend
            )
            for (spec, ds), res in zip(specs.items(), results):
                for d in ds:
                    c = next(c for c in checks if Path(c.entry) == d)
                    block = next(b for b in entries[d]["suites"] if b["name"] == suite)
                    kept, _ = read_trace(d, block)
                    diffs = record_differences(kept, res["episodes"], suite)
                    for key in ("metrics", "dx_metrics"):
                        m = _first_difference(
                            _strip_clock(block[key]), _strip_clock(res[key]), f"suite {suite}: rerun {key}"
                        )
                        if m and not diffs:
                            diffs.append(m)
                    if diffs:
                        c.problems.extend(diffs)
                    else:
                        c.checked.append(f"{suite}: rerun reproduces every record and metric (wall clock aside)")
    spent = time.perf_counter() - t0
    for c in checks:
        if c.entry in entries:
            c.notes.append(f"rerun of {len(suites)} suites took {spent:.0f} s of wall time")
    if log:
        log(f"reran {len(entries)} entries on {len(suites)} suites in {spent:.0f} s")
    return checks
