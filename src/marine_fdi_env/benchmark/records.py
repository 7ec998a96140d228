"""Episode records (the metrics' input, :mod:`.metrics`) as Parquet tables, and back.

One row per episode; the columns are the record's fields with their natural Arrow types::

    scenario_id, suite, agent, profile: string     seed, n_samples: int64
    duration_s, decision_period_s, compute_s, return: double      terminated: bool
    failure_reason: string (null when the episode was not terminated)
    faults: list<struct<id, class: string, onset_s, magnitude: double, end_s: double (null: permanent)>>
    declared_changes: list<struct<t_s: double, declared: list<string>, alarm: bool>>
    belief_on_truth: list<struct<t_s, share: double>>      reward_terms: map<string, double>

plus, in a sweep, ``agent_spec`` (string) and ``seed_offset`` (int64).  Doubles are stored
exactly, so :func:`table_to_records` gives back records equal to the originals and the metrics
computed from them are the same bit for bit (tested).  The table's metadata key ``marine_fdi``
holds JSON (an evaluation's header and metrics, a sweep's description).

Parquet needs pyarrow, an optional dependency (``pip install 'marine-fdi-env[parquet]'``).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Iterable, Mapping

from ..errors import MissingExtra

__all__ = [
    "episode_record",
    "pyarrow",
    "records_to_table",
    "table_to_records",
    "write_records",
    "read_records",
    "write_results_parquet",
    "read_results_parquet",
    "sweep_results",
]

META_KEY = b"marine_fdi"
_EXTRA = {"agent_spec": "string", "seed_offset": "int64"}


# record fields that older results do not have (null in the table, left out of a record read back)
_OPTIONAL = {"feature_compute_s": "float64", "agent_compute_s": "float64", "n_decisions": "int64"}


def episode_record(
    sc,
    suite: str,
    agent: str,
    *,
    duration_s: float,
    decision_period_s: float,
    n_samples: int,
    declared_changes: list,
    belief_on_truth: list,
    failure: Mapping | None,
    terminated: bool | None = None,
    compute_s: float | None = None,
    ret: float = 0.0,
    reward_terms: Mapping[str, float] | None = None,
    split: tuple[float, float, int] | None = None,
) -> dict:
    """The record of one episode of scenario ``sc`` (a :class:`~marine_fdi_env.envs.scenario_sampler.ScenarioSpec`),
    its fields in their order.  ``failure``: the engine failure of the episode (its ``reason`` is the record's
    ``failure_reason`` when the episode is ``terminated``, by default when there is a failure); ``ret``: the
    return; ``split``: ``(feature_compute_s, agent_compute_s, n_decisions)``, the optional fields, whose two
    times add up to ``compute_s`` when it is not given."""
    if terminated is None:
        terminated = failure is not None
    if compute_s is None:
        compute_s = float(split[0] + split[1])
    rec = {
        "scenario_id": sc.scenario_id,
        "suite": suite,
        "seed": int(sc.noise_seed),
        "agent": agent,
        "profile": sc.profile,
        "duration_s": duration_s,
        "decision_period_s": decision_period_s,
        "n_samples": n_samples,
        "faults": sc.truth(),
        "declared_changes": declared_changes,
        "belief_on_truth": belief_on_truth,
        "terminated": terminated,
        "failure_reason": (failure or {}).get("reason") or None if terminated else None,
        "compute_s": compute_s,
        "return": ret,
        "reward_terms": dict(reward_terms or {}),
    }
    if split is not None:
        rec.update(zip(_OPTIONAL, split))
    return rec


def pyarrow():
    """``(pyarrow, pyarrow.parquet)``; :class:`~marine_fdi_env.errors.MissingExtra` naming the extra when missing."""
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        raise MissingExtra("pyarrow", "reading or writing Parquet") from None
    return pa, pq


def _schema(pa, extra: Iterable[str] = ()):
    fault = pa.struct(
        [
            ("id", pa.string()),
            ("class", pa.string()),
            ("onset_s", pa.float64()),
            ("magnitude", pa.float64()),
            ("end_s", pa.float64()),
        ]
    )
    change = pa.struct([("t_s", pa.float64()), ("declared", pa.list_(pa.string())), ("alarm", pa.bool_())])
    share = pa.struct([("t_s", pa.float64()), ("share", pa.float64())])
    fields = [
        ("scenario_id", pa.string()),
        ("suite", pa.string()),
        ("agent", pa.string()),
        *((k, getattr(pa, _EXTRA[k])()) for k in extra),
        ("seed", pa.int64()),
        ("profile", pa.string()),
        ("duration_s", pa.float64()),
        ("decision_period_s", pa.float64()),
        ("n_samples", pa.int64()),
        ("faults", pa.list_(fault)),
        ("declared_changes", pa.list_(change)),
        ("belief_on_truth", pa.list_(share)),
        ("terminated", pa.bool_()),
        ("failure_reason", pa.string()),
        ("compute_s", pa.float64()),
        ("return", pa.float64()),
        ("reward_terms", pa.map_(pa.string(), pa.float64())),
        *((k, getattr(pa, t)()) for k, t in _OPTIONAL.items()),
    ]
    return pa.schema(fields)


def records_to_table(records: list[Mapping], metadata: dict | None = None, extra: Iterable[str] = ()):
    """A pyarrow Table of episode records (``extra``: sweep columns present in every record)."""
    pa, _ = pyarrow()
    extra = tuple(extra)
    for k in extra:
        if k not in _EXTRA:
            raise ValueError(f"unknown extra column {k!r}; allowed: {', '.join(_EXTRA)}")
    schema = _schema(pa, extra)
    rows = []
    for r in records:
        row = {f.name: r.get(f.name) for f in schema}
        row["declared_changes"] = [{"t_s": c[0], "declared": list(c[1]), "alarm": c[2]} for c in r["declared_changes"]]
        bot = r.get("belief_on_truth")
        row["belief_on_truth"] = None if bot is None else [{"t_s": t, "share": v} for t, v in bot]
        row["reward_terms"] = list(r["reward_terms"].items())
        rows.append(row)
    table = pa.Table.from_pylist(rows, schema=schema)
    if metadata is not None:
        table = table.replace_schema_metadata({META_KEY: json.dumps(metadata).encode()})
    return table


def table_to_records(table, keep_extra: bool = False) -> list[dict]:
    """The episode records of a table written by :func:`records_to_table`."""
    out = []
    for row in table.to_pylist():
        rec = dict(row)
        rec["declared_changes"] = [[c["t_s"], list(c["declared"]), c["alarm"]] for c in row["declared_changes"]]
        bot = row.get("belief_on_truth")
        if bot is None:
            rec.pop("belief_on_truth", None)
        else:
            rec["belief_on_truth"] = [[b["t_s"], b["share"]] for b in bot]
        rec["reward_terms"] = dict(row["reward_terms"])
        rec["faults"] = [dict(f) for f in row["faults"]]
        for k in _OPTIONAL:
            if rec.get(k, 0) is None:
                rec.pop(k)
        if not keep_extra:
            for k in _EXTRA:
                rec.pop(k, None)
        out.append(rec)
    return out


def table_metadata(table) -> dict:
    meta = table.schema.metadata or {}
    return json.loads(meta[META_KEY]) if META_KEY in meta else {}


def write_records(
    path: "str | Path", records: list[Mapping], metadata: dict | None = None, extra: Iterable[str] = ()
) -> Path:
    _, pq = pyarrow()
    pq.write_table(records_to_table(records, metadata, extra), str(path), compression="zstd")
    return Path(path)


def read_records(path: "str | Path", keep_extra: bool = False) -> tuple[list[dict], dict]:
    """(records, metadata) of a Parquet file of episode records; ``ValueError`` naming the file."""
    pa, pq = pyarrow()
    try:
        table = pq.read_table(str(path))
    except (OSError, pa.ArrowException) as e:
        raise ValueError(f"{path}: not a readable Parquet file ({e})") from None
    missing = [
        n for n in ("scenario_id", "agent", "suite", "declared_changes", "faults") if n not in table.column_names
    ]
    if missing:
        raise ValueError(f"{path}: not a table of episode records (no column {missing[0]!r})")
    return table_to_records(table, keep_extra), table_metadata(table)


def write_results_parquet(path: "str | Path", result: Mapping) -> Path:
    """An evaluation's results (header, metrics, episodes) as a Parquet table of its episodes."""
    meta = {k: v for k, v in result.items() if k != "episodes"}
    return write_records(path, result["episodes"], meta)


def read_results_parquet(path: "str | Path") -> dict:
    """The results object (as :func:`write_results_parquet` got it) of a Parquet results file."""
    records, meta = read_records(path)
    out = dict(meta)
    out["episodes"] = records
    return out


def sweep_results(records: list[dict], source: str = "") -> list[dict]:
    """Results objects (as ``marine-fdi evaluate`` writes them) per agent x suite, pooled over
    the seed offsets, from sweep records (with ``agent_spec`` and ``seed_offset``)."""
    from .metrics import metric_blocks

    groups: dict[tuple, list[dict]] = {}
    for r in records:
        groups.setdefault((r.get("agent_spec", r["agent"]), r["suite"]), []).append(r)
    out = []
    for (spec, suite), recs in groups.items():
        offsets = sorted({int(r.get("seed_offset", 0)) for r in recs})
        clean = [{k: v for k, v in r.items() if k not in ("agent_spec", "seed_offset")} for r in recs]
        out.append(
            {
                "agent": recs[0]["agent"],
                "agent_spec": spec,
                "suite": suite,
                "seed_offsets": offsets,
                "n_episodes": len(recs),
                **metric_blocks(clean),
                "episodes": clean,
                "path": f"{source}[{spec} on {suite}]" if source else f"{spec} on {suite}",
            }
        )
    return out
