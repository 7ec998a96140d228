"""Feature caches: the trajectories of a suite (every observation and info an agent sees) as a
versioned Parquet table, so that agents are scored on them without simulating.

    marine-fdi sweep --agents all --suites all --cache write --out runs/all    # simulate, keep them
    marine-fdi evaluate --agent my_agent.py:Mine --suite single-v1              # scored on the cache

**Where.**  ``--cache-dir`` (default ``results/cache`` under the working folder, beside
``evaluate``'s ``results/``): one file per suite, seed offset and environment,
``SUITE_oOFFSET_KEY.parquet`` (KEY: 10 hex digits of the hash of the parameters below).  While a
run writes one, its finished chunks wait in ``SUITE_oOFFSET_KEY.parts/`` (an interrupted run
resumes them); the file is assembled when every episode is in.

**When.**  ``--cache use`` (default): the file of the run's parameters is read when it exists, else
the episodes are simulated (nothing is written).  ``--cache write``: simulate and (re)write it;
such a pass computes every observation option (``observe_sensors`` and ``observe_sequential``), so
one cache serves every agent.  ``--cache off``: caches are neither read nor written.

**What.**  One row per decision: ``episode`` (int32, the suite index), ``step`` (int32), ``t_s``
and ``feature_s`` (float64: decision time and the wall time spent on its observation), ``obs``
(fixed-size list of float32, the columns of ``feature_names``), and per cell set C of the
diagnosers (``cell_sets``: all three in a cache) ``reference_detected_C`` (bool),
``reference_diagnoses_C`` (JSON string, dictionary-encoded), the same two for ``sequential``.  The
metadata (key ``marine_fdi``) holds the header (below), the feature names, the cell sets, the
decision period, per episode its scenario (seed offset applied), number of decisions, engine
failure and feature time, and ``checksum``: the SHA-256 of all of that and of every column's
values.  The header's ``format`` (:data:`FORMAT`) numbers this layout; a file of another format
is refused.

**Refused, never used silently.**  The header records the code that made the cache (package
version, SHA-256 of the source and data of the simulator, the diagnosers and the environment:
``engine/``, ``diagnosis/``, ``envs/``, ``_jit.py``, ``data/params``, ``data/diagnosis``,
``data/env``; the numpy, numba and Python versions) and its parameters (suite name, version and
scenarios, seed offset, environment arguments but the reward, which no trajectory depends on).
A cache whose header differs from the run's, whose checksum does not match its content, or that is
not a feature cache at all stops the command with one line naming the file and what differs
(:class:`~marine_fdi_env.errors.DataFileError`); remove it, rebuild it with ``--cache write``, or
pass ``--cache off``.
"""

from __future__ import annotations

import hashlib
import json
import os
import platform
import shutil
from functools import lru_cache
from pathlib import Path

import numpy as np

from .._version import __version__
from ..envs.scenario_sampler import ScenarioSpec
from ..envs.trajectory import Trajectory, assemble
from ..errors import DataFileError, MissingExtra
from ..jsonfile import json_safe

__all__ = [
    "CACHE_MODES",
    "DEFAULT_CACHE_DIR",
    "FORMAT",
    "code_version",
    "cache_header",
    "cache_path",
    "write_trajectory",
    "read_trajectory",
    "cached_indices",
    "SuiteCache",
]

CACHE_MODES = ("use", "write", "off")
DEFAULT_CACHE_DIR = Path("results") / "cache"
FORMAT = 2
KIND = "marine-fdi feature cache"
META_KEY = b"marine_fdi"
_SOURCES = ("engine", "diagnosis", "envs", "_jit.py", "data/params", "data/diagnosis", "data/env")


def _pyarrow(what: str):
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        raise MissingExtra("pyarrow", what) from None
    return pa, pq


@lru_cache(maxsize=1)
def _source_sha256() -> str:
    root = Path(__file__).resolve().parent.parent
    h = hashlib.sha256()
    for name in _SOURCES:
        p = root / name
        files = sorted(f for f in p.rglob("*") if f.is_file() and f.suffix in (".py", ".json")) if p.is_dir() else [p]
        for f in files:
            h.update(f.relative_to(root).as_posix().encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest()


def code_version() -> dict:
    """The code a trajectory depends on: package version, source hash, numpy/numba/Python versions."""
    import numba

    return {
        "package": __version__,
        "source_sha256": _source_sha256(),
        "numpy": np.__version__,
        "numba": numba.__version__,
        "python": platform.python_version(),
    }


def cache_header(
    suite_name: str, suite_version, seed_offset: int, env_kwargs: dict, scenarios: list[ScenarioSpec]
) -> dict:
    """The header a cache of these episodes (seed offset applied) on this environment must carry."""
    env = {k: json_safe(v, nonfinite="keep") for k, v in sorted(env_kwargs.items()) if k != "reward"}
    scen = hashlib.sha256(json.dumps([s.to_dict() for s in scenarios], sort_keys=True).encode()).hexdigest()
    return {
        "kind": KIND,
        "format": FORMAT,
        "code": code_version(),
        "params": {
            "suite": suite_name,
            "suite_version": suite_version,
            "seed_offset": int(seed_offset),
            "n_episodes": len(scenarios),
            "scenarios_sha256": scen,
            "env": env,
        },
    }


def cache_path(cache_dir: "str | Path", header: dict) -> Path:
    """The file of a cache with this header in ``cache_dir`` (named by suite, seed offset and parameters)."""
    p = header["params"]
    key = hashlib.sha256(json.dumps(p, sort_keys=True).encode()).hexdigest()[:10]
    stem = Path(str(p["suite"])).stem
    return Path(cache_dir) / f"{stem}_o{p['seed_offset']}_{key}.parquet"


# ----------------------------------------------------------------------------- one table
def _dumps(d) -> str:
    return json.dumps(d, separators=(",", ":"))


def _columns(idx: np.ndarray, traj: Trajectory) -> dict:
    """The table's columns (numpy arrays; diagnoses as JSON strings) of a trajectory's decisions."""
    d = traj.n_decisions
    jj = np.repeat(np.arange(traj.n), d)
    kk = np.concatenate([np.arange(x) for x in d]) if traj.n else np.zeros(0, dtype=np.int64)
    cols = {
        "episode": idx[jj].astype(np.int32),
        "step": kk.astype(np.int32),
        "t_s": traj.t[kk, jj],
        "feature_s": traj.feature_s[kk, jj],
        "obs": np.ascontiguousarray(traj.obs[kk, jj], dtype=np.float32),
    }
    diagnosers = ("reference", "sequential") if traj.observe_sequential else ("reference",)
    for name in diagnosers:
        det, diag = getattr(traj, f"{name}_detected"), getattr(traj, f"{name}_diagnoses")
        for c, cells in enumerate(traj.cell_sets):
            cols[f"{name}_detected_{cells}"] = det[kk, jj, c]
            cols[f"{name}_diagnoses_{cells}"] = [_dumps(x) for x in diag[kk, jj, c]]
    return cols


def _checksum(cols: dict, meta: dict) -> str:
    h = hashlib.sha256(json.dumps(meta, sort_keys=True).encode())
    for name, v in cols.items():
        h.update(name.encode() + b"\0")
        h.update("\n".join(v).encode() if isinstance(v, list) else np.ascontiguousarray(v).tobytes())
    return h.hexdigest()


def write_trajectory(path: "str | Path", idx, traj: Trajectory, header: dict) -> Path:
    """Write the episodes ``idx`` (suite indices) of a cache with ``header`` to ``path`` (atomically)."""
    pa, pq = _pyarrow("a feature cache")
    idx = np.asarray(idx, dtype=np.int64)
    cols = _columns(idx, traj)
    meta = {
        "header": header,
        "feature_names": list(traj.feature_names),
        "cell_sets": list(traj.cell_sets),
        "decision_period_s": traj.decision_period_s,
        "period_samples": traj.period_samples,
        "observe_sequential": traj.observe_sequential,
        "episodes": [
            {
                "index": int(e),
                "scenario": sc.to_dict(),
                "n_decisions": int(traj.n_decisions[j]),
                "terminated": bool(traj.terminated[j]),
                "failure": traj.failures[j],
                "failure_step": int(traj.failure_step[j]),
                "compute_s": float(traj.compute_s[j]),
            }
            for j, (e, sc) in enumerate(zip(idx.tolist(), traj.scenarios))
        ],
    }
    meta["checksum"] = _checksum(cols, meta)
    D = len(traj.feature_names)
    arrays = {}
    for name, v in cols.items():
        if name == "obs":
            arrays[name] = pa.FixedSizeListArray.from_arrays(pa.array(v.reshape(-1)), D)
        elif isinstance(v, list):
            arrays[name] = pa.array(v, pa.string()).dictionary_encode()
        else:
            arrays[name] = pa.array(v)
    table = pa.table(arrays).replace_schema_metadata({META_KEY: json.dumps(meta).encode()})
    path = Path(path)
    tmp = path.with_name(path.name + ".tmp")
    pq.write_table(table, str(tmp), compression="zstd")
    os.replace(tmp, path)
    return path


def _refuse(path: Path, what: str) -> DataFileError:
    return DataFileError(f"{path}: {what}; remove it, rebuild it with --cache write, or pass --cache off")


def _check_header(path: Path, old, header: dict) -> None:
    from ..outputs import differing_fields

    if not isinstance(old, dict) or old.get("kind") != KIND:
        raise _refuse(path, "not a feature cache")
    if old.get("format") != header["format"]:
        raise _refuse(path, f"feature cache of format {old.get('format')!r}, this code reads {header['format']}")
    if old.get("code") != header["code"]:
        raise _refuse(
            path, f"feature cache made by other code ({differing_fields(old.get('code'), header['code'], 'code')})"
        )
    if old.get("params") != header["params"]:
        raise _refuse(
            path,
            "feature cache made with other parameters ("
            f"{differing_fields(old.get('params'), header['params'], 'params')})",
        )


def _metadata(path: Path, read) -> tuple[object, dict]:
    pa, _ = _pyarrow("a feature cache")
    try:
        obj = read(str(path))
        schema = obj if isinstance(obj, pa.Schema) else obj.schema
        meta = json.loads(schema.metadata[META_KEY])
        meta["header"]
    except (OSError, pa.ArrowException, KeyError, TypeError, ValueError) as e:
        raise _refuse(path, f"not a readable feature cache ({type(e).__name__}: {e})") from None
    return obj, meta


def cached_indices(path: "str | Path", header: dict) -> np.ndarray:
    """The suite indices of the episodes in a cache file (its header checked, not its content)."""
    _, pq = _pyarrow("a feature cache")
    path = Path(path)
    _, meta = _metadata(path, pq.read_schema)
    _check_header(path, meta["header"], header)
    return np.array([e["index"] for e in meta["episodes"]], dtype=np.int64)


def read_trajectory(path: "str | Path", header: dict) -> tuple[np.ndarray, Trajectory]:
    """(suite indices, trajectory) of a cache file; :class:`DataFileError` if it was made by other
    code or with other parameters than ``header`` says, or its checksum does not match."""
    pa, pq = _pyarrow("a feature cache")
    path = Path(path)
    table, meta = _metadata(path, pq.read_table)
    _check_header(path, meta["header"], header)
    cols: dict = {}
    for name in table.column_names:
        col = table.column(name).combine_chunks()
        if pa.types.is_dictionary(col.type):
            words = np.array(col.dictionary.to_pylist(), dtype=object)
            cols[name] = words[col.indices.to_numpy(zero_copy_only=False)].tolist()
        elif pa.types.is_fixed_size_list(col.type):
            cols[name] = col.flatten().to_numpy().reshape(len(col), col.type.list_size)
        elif pa.types.is_string(col.type):
            cols[name] = col.to_pylist()
        else:
            cols[name] = col.to_numpy(zero_copy_only=False)
    stored = meta.pop("checksum", None)
    if stored != _checksum(cols, meta):
        raise _refuse(path, "feature cache whose checksum does not match its content (damaged or edited)")
    return _trajectory(cols, meta)


def _parse(strings: list[str]) -> np.ndarray:
    memo: dict[str, object] = {}
    out = np.empty(len(strings), dtype=object)
    for j, s in enumerate(strings):
        v = memo.get(s)
        if v is None:
            v = memo[s] = json.loads(s)
        out[j] = v
    return out


def _trajectory(cols: dict, meta: dict) -> tuple[np.ndarray, Trajectory]:
    eps = meta["episodes"]
    idx = np.array([e["index"] for e in eps], dtype=np.int64)
    local = {int(e): j for j, e in enumerate(idx.tolist())}
    n = len(eps)
    n_dec = np.array([e["n_decisions"] for e in eps], dtype=np.int64)
    S = int(n_dec.max(initial=1))
    jj = np.array([local[int(e)] for e in cols["episode"].tolist()], dtype=np.int64)
    kk = cols["step"].astype(np.int64)

    def grid(v, dtype, fill, shape=()):
        out = np.full((S, n) + shape, fill, dtype=dtype)
        out[kk, jj] = v
        return out

    cell_sets = tuple(meta["cell_sets"])

    def conclusions(name: str) -> tuple[np.ndarray, np.ndarray] | tuple[None, None]:
        if name == "sequential" and not meta["observe_sequential"]:
            return None, None
        det = np.stack([grid(cols[f"{name}_detected_{c}"], bool, False) for c in cell_sets], axis=-1)
        diag = np.empty(det.shape, dtype=object)
        for j, c in enumerate(cell_sets):
            diag[..., j] = grid(_parse(cols[f"{name}_diagnoses_{c}"]), object, None)
        return det, diag

    ref, seq = conclusions("reference"), conclusions("sequential")
    traj = Trajectory(
        scenarios=[ScenarioSpec.from_dict(e["scenario"]) for e in eps],
        feature_names=tuple(meta["feature_names"]),
        cell_sets=cell_sets,
        decision_period_s=float(meta["decision_period_s"]),
        period_samples=int(meta["period_samples"]),
        obs=grid(cols["obs"], np.float32, 0.0, (len(meta["feature_names"]),)),
        t=grid(cols["t_s"], float, 0.0),
        feature_s=grid(cols["feature_s"], float, 0.0),
        reference_detected=ref[0],
        reference_diagnoses=ref[1],
        sequential_detected=seq[0],
        sequential_diagnoses=seq[1],
        n_decisions=n_dec,
        terminated=np.array([e["terminated"] for e in eps], dtype=bool),
        failures=[e["failure"] for e in eps],
        failure_step=np.array([e["failure_step"] for e in eps], dtype=np.int64),
        compute_s=np.array([e["compute_s"] for e in eps], dtype=float),
    )
    return idx, traj


# ----------------------------------------------------------------------------- a suite's cache in a run
class SuiteCache:
    """The feature cache of one suite, seed offset and environment in a run with ``mode``.

    ``use``: :attr:`trajectory` is the cache's (None without a file).  ``write``: chunks are kept
    as parts (:meth:`store`) and assembled into the file by :meth:`finish` once complete;
    :meth:`missing` says which episodes have no part yet (they must be simulated)."""

    def __init__(self, mode: str, cache_dir: "str | Path | None", header: dict) -> None:
        if mode not in CACHE_MODES:
            raise ValueError(f"--cache must be one of {', '.join(CACHE_MODES)}, got {mode!r}")
        self.mode, self.header = mode, header
        self.path = cache_path(cache_dir or DEFAULT_CACHE_DIR, header)
        self.parts_dir = self.path.with_suffix(".parts")
        self.trajectory: Trajectory | None = None
        self.n = int(header["params"]["n_episodes"])
        self._have = np.zeros(self.n, dtype=bool)
        if mode == "use" and self.path.is_file():
            idx, traj = read_trajectory(self.path, header)
            if sorted(idx.tolist()) != list(range(self.n)):
                raise _refuse(self.path, f"feature cache of {len(idx)} episodes, the suite has {self.n}")
            self.trajectory = traj.take(np.argsort(idx)) if np.any(idx != np.arange(self.n)) else traj
        elif mode == "write":
            try:
                for f in sorted(self.parts_dir.glob("part_*.parquet")):
                    self._have[cached_indices(f, header)] = True
            except DataFileError:  # parts of other code or parameters: this run rebuilds them
                shutil.rmtree(self.parts_dir)
                self._have[:] = False
            self.parts_dir.mkdir(parents=True, exist_ok=True)

    @property
    def keep(self) -> bool:
        return self.mode == "write"

    def missing(self) -> np.ndarray:
        """Episodes (suite indices) without a kept part (``write``; none otherwise)."""
        return np.flatnonzero(~self._have) if self.keep else np.zeros(0, dtype=np.int64)

    def store(self, idx, traj: Trajectory) -> None:
        """Keep the trajectory of the episodes ``idx`` (suite indices) as a part."""
        idx = np.asarray(idx, dtype=np.int64)
        write_trajectory(self.parts_dir / f"part_{int(idx.min()):06d}_{len(idx)}.parquet", idx, traj, self.header)
        self._have[idx] = True

    def finish(self) -> Path | None:
        """Assemble the parts into the cache file when every episode has one; the file, else None."""
        if not self.keep or not self._have.all():
            return None
        parts = [read_trajectory(f, self.header) for f in sorted(self.parts_dir.glob("part_*.parquet"))]
        seen = np.zeros(self.n, dtype=bool)
        unique = []
        for idx, traj in parts:  # a chunk that ran twice (a resumed run) counts once
            keep = ~seen[idx]
            if keep.any():
                unique.append((idx[keep], traj.take(np.flatnonzero(keep))))
                seen[idx[keep]] = True
        write_trajectory(self.path, np.arange(self.n), assemble(unique), self.header)
        shutil.rmtree(self.parts_dir, ignore_errors=True)
        return self.path
