"""``marine-fdi dataset``: features, labels and ground truth of episodes, for offline learners.

Runs episodes of a frozen suite (``--suite NAME``) or of a scenario preset (``--preset NAME
--episodes N --seed S``; training data must not come from the evaluation suites) through the
environment with a silent agent, and writes ``OUT_DIR/dataset.npz`` (``--format npz``, default):

=================  ==================  =====================================================
array              shape, dtype        meaning
=================  ==================  =====================================================
``obs``            (E, T, D) float32   the environment's observation at each decision
``active``         (E, T, 26) bool     faults active at the decision time (FAULT_IDS order)
``valid``          (E, T) bool         False after an episode ended early (engine failure)
``t_s``            (E, T) float64      decision times [s]
``feature_names``  (D,) str
``fault_ids``      (26,) str
=================  ==================  =====================================================

or ``OUT_DIR/dataset.parquet`` (``--format parquet``), the same in long format: one row per
valid decision with the columns ``episode`` (int32, index into the scenarios), ``scenario_id``,
``step`` (int32, decision index), ``t_s`` (float64), one float32 column per feature (named as
in ``feature_names``), one bool column ``active.<fault id>`` per fault and ``no_fault`` (no
fault active); the table's metadata (key ``marine_fdi``) holds the feature names, the fault ids,
the environment and the scenarios with their ground truth.  :func:`load_dataset` returns the
same arrays, bit for bit, from either file (tested).

Both formats come with ``OUT_DIR/scenarios.json`` (the scenarios with their ground truth, same
order).  Labels for a classifier: ``active`` (multi-label), or "no fault" where ``active`` is all
False.

Episodes run in chunks on a backend (``--backend serial|process|ray``, :mod:`.backends`); the
arrays do not depend on the backend, the number of workers or the batch size.  Finished chunks
are kept in ``OUT_DIR/dataset.partial/`` until the dataset is written, so an interrupted export
resumes where it stopped.
"""

from __future__ import annotations

import hashlib
import json
import shutil
from pathlib import Path

import numpy as np

from ..engine.faults import FAULT_IDS
from ..envs.scenario_sampler import ScenarioSpec, with_noise_scale
from ..envs.vector import MarineFDIVectorEnv

__all__ = [
    "export_dataset",
    "regenerate_minari",
    "load_dataset",
    "dataset_chunk",
    "dataset_bytes",
    "kept_episodes",
    "FORMATS",
    "PARTIAL",
]

PARTIAL = "dataset.partial"  # the folder of finished chunks inside OUT_DIR, until the dataset is written

FORMATS = ("npz", "parquet", "minari")
_COL = {f: j for j, f in enumerate(FAULT_IDS)}


SCENARIO_BYTES = 4000  # one drawn scenario in memory and in scenarios.json (its faults, profile, truth)


def dataset_bytes(n_episodes: int, n_decisions: int, n_features: int) -> int:
    """Bytes of a dense dataset held in memory while it is written: obs (float32), the 26 fault
    flags and ``valid`` (bool), ``t_s`` (float64) per decision, and each episode's scenario."""
    return n_episodes * (n_decisions * (4 * n_features + len(FAULT_IDS) + 1 + 8) + SCENARIO_BYTES)


def _n_decisions(scenarios, env_kwargs) -> int:
    return max(int(round(s.duration_s / env_kwargs.get("decision_period_s", 1.0))) for s in scenarios)


def dataset_chunk(scenario_dicts: list[dict], env_kwargs: dict, T: int, progress=None) -> dict:
    """One task: observations, labels and decision times of a chunk of episodes (arrays over the chunk)."""
    chunk = [ScenarioSpec.from_dict(d) for d in scenario_dicts]
    n = len(chunk)
    scales = {float(s.noise_scale) for s in chunk}
    if len(scales) != 1:
        raise ValueError(f"a dataset chunk must share one sensor-noise scale, got {sorted(scales)}")
    venv = MarineFDIVectorEnv(num_envs=n, **with_noise_scale(env_kwargs, scales.pop()))
    obs, infos = venv.reset(options={"scenarios": chunk})
    D = obs.shape[1]
    obs_all = np.zeros((n, T, D), dtype=np.float32)
    valid = np.zeros((n, T), dtype=bool)
    active = np.zeros((n, T, len(FAULT_IDS)), dtype=bool)
    t_all = np.zeros((n, T))
    reward = np.zeros((n, T))
    ended = np.zeros((n, T, 2), dtype=bool)  # terminated, truncated at each decision
    final = np.zeros((n, D), dtype=np.float32)  # the observation the last step returned, its time and faults
    t_final = np.zeros(n)
    active_final = np.zeros((n, len(FAULT_IDS)), dtype=bool)
    live = np.ones(n, dtype=bool)
    k = 0
    while live.any() and k < T:
        rows = np.flatnonzero(live)
        obs_all[rows, k] = obs[live]
        valid[rows, k] = True
        for i in rows:
            t_all[i, k] = infos["t_s"][i]
            for f in infos["active_faults"][i]:
                active[i, k, _COL[f]] = True
        obs, rew, term, trunc, infos = venv.step(np.zeros((n, 28), dtype=np.float32))
        reward[rows, k] = rew[rows]
        ended[rows, k, 0], ended[rows, k, 1] = term[rows], trunc[rows]
        final[rows] = obs[rows]
        active_final[rows] = False
        for i in rows:
            t_final[i] = infos["t_s"][i]
            for f in infos["active_faults"][i]:
                active_final[i, _COL[f]] = True
        before = int(live.sum())
        live &= ~(term | trunc)
        k += 1
        if progress is not None:  # episodes' worth of work: a decision of each live one, the rest of ended ones
            progress(before / T + float(np.sum((~live[rows])) * (T - k)) / T)
    return {
        "obs": obs_all,
        "active": active,
        "valid": valid,
        "t_s": t_all,
        "reward": reward,
        "ended": ended,
        "obs_final": final,
        "t_final": t_final,
        "active_final": active_final,
        "feature_names": np.array(venv.feature_names),
    }


def _env_json(env_kwargs: dict) -> dict:
    return {k: (v.to_dict() if hasattr(v, "to_dict") else v) for k, v in env_kwargs.items()}


def export_dataset(
    scenarios: list[ScenarioSpec],
    out_dir: Path,
    env_kwargs: dict | None = None,
    batch_size: int = 64,
    progress: bool = True,
    backend=None,
    fmt: str = "npz",
    force: bool = False,
    dataset_id: str | None = None,
    card: dict | None = None,
) -> Path:
    """Write the dataset of ``scenarios`` to ``out_dir`` (resumably); returns the dataset file (the
    dataset's folder ``out_dir/dataset_id`` for ``fmt`` ``minari``, ``out_dir`` being a Minari
    datasets root: :mod:`.minari_data`, with ``card`` for its dataset card).

    ``force``: discard the kept chunks of another export in ``out_dir`` instead of refusing
    (a finished dataset in ``out_dir`` is the caller's to check: :func:`dataset_main` asks for
    ``--force``)."""
    from ..progress import progress_bar
    from .backends import Backend, chunk_size, run_tasks_counted

    env_kwargs = dict(env_kwargs or {})
    if fmt not in FORMATS:
        raise ValueError(f"--format must be one of {', '.join(FORMATS)}, got {fmt!r}")
    if not scenarios:
        raise ValueError("no scenarios to export")
    backend = backend if isinstance(backend, Backend) else Backend.make(backend)
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    root = out_dir
    if fmt == "minari":  # finished chunks in a hidden folder of the root (Minari creates the dataset's own)
        from .minari_data import work_dir

        env_kwargs["reward"] = env_kwargs.get("reward") or "v1"  # the rewards a Minari dataset holds

        out_dir = work_dir(root, str(dataset_id))
        out_dir.mkdir(parents=True, exist_ok=True)
    T = _n_decisions(scenarios, env_kwargs)
    E = len(scenarios)
    env_json = _env_json(env_kwargs)
    scen_json = [dict(s.to_dict(), truth=s.truth()) for s in scenarios]
    key = hashlib.sha256(json.dumps({"env": env_json, "scenarios": scen_json}, sort_keys=True).encode()).hexdigest()
    part_dir = out_dir / PARTIAL
    head = json.loads(
        json.dumps(
            {
                "key": key,
                "env": env_json,
                "n_episodes": E,  # as stored (lists, not tuples)
                "scenario_ids": [s.scenario_id for s in scenarios],
            }
        )
    )
    if force:
        _discard_other(part_dir, key)
    stored = _stored_chunks(part_dir, head)
    done = np.zeros(E, dtype=bool)
    for idx, _ in stored:
        done[idx] = True
    todo = np.flatnonzero(~done)
    per = chunk_size(len(todo), batch_size, backend.workers)
    groups: dict[float, list[int]] = {}  # one batched engine set per sensor-noise scale
    for j in todo:
        groups.setdefault(float(scenarios[j].noise_scale), []).append(int(j))
    plan = [np.asarray(idx[i : i + per], dtype=np.int64) for idx in groups.values() for i in range(0, len(idx), per)]
    tasks = [([scenarios[j].to_dict() for j in idx], env_kwargs, T) for idx in plan]
    if len(todo):
        from .evaluate import warm_up

        warm_up(env_kwargs)  # compile a cold cache once, here, before the bar and the workers
    bar = progress_bar(E, int(done.sum()), "dataset", progress)

    def keep(i, arrays):
        idx = plan[i]
        f = part_dir / f"chunk_{int(idx[0]):06d}_{len(idx)}.npz"
        tmp = f.with_name(f.stem + ".tmp.npz")
        np.savez(tmp, index=idx, **arrays)
        tmp.replace(f)
        stored.append((idx, f))
        done[idx] = True

    run_tasks_counted(backend, dataset_chunk, tasks, bar=bar, on_result=keep, settled=lambda: float(done.sum()))
    arrays = _assemble(stored, E, T, full=fmt == "minari")
    if fmt == "minari":
        from .minari_data import write_minari

        truth = {"env": env_json, "scenarios": scen_json}
        path = write_minari(arrays, scenarios, root, str(dataset_id), env_kwargs, truth, card or {})
        shutil.rmtree(out_dir, ignore_errors=True)  # the finished chunks
        try:
            out_dir.parent.rmdir()  # the hidden folder of chunks, when no other export is unfinished
        except OSError:
            pass
        return path
    if fmt == "npz":
        path = out_dir / "dataset.npz"
        np.savez_compressed(path, **arrays, fault_ids=np.array(FAULT_IDS))
    else:
        path = out_dir / "dataset.parquet"
        _write_parquet(path, arrays, scenarios, {"env": env_json, "scenarios": scen_json})
    (out_dir / "scenarios.json").write_text(json.dumps({"env": env_json, "scenarios": scen_json}, indent=1) + "\n")
    shutil.rmtree(part_dir, ignore_errors=True)
    return path


def kept_episodes(out_dir: "str | Path") -> int:
    """Episodes of an unfinished export in ``out_dir`` whose chunk finished (a rerun does not redo them)."""
    n = 0
    for f in (Path(out_dir) / PARTIAL).glob("chunk_*_*.npz"):
        if not f.name.endswith(".tmp.npz"):
            n += int(f.stem.rsplit("_", 1)[1])
    return n


def _read_head(part_dir: Path) -> dict | None:
    try:
        old = json.loads((part_dir / "header.json").read_text())
    except (OSError, json.JSONDecodeError):
        return None
    return old if isinstance(old, dict) else None


def _discard_other(part_dir: Path, key: str) -> None:
    """Remove the kept chunks of an export of other scenarios (``--force``)."""
    if part_dir.is_dir() and (_read_head(part_dir) or {}).get("key") != key:
        shutil.rmtree(part_dir)


def _mismatch(old: dict | None, new: dict) -> str:
    """What differs between the kept export's header and this one's, naming the field."""
    from ..outputs import differing_fields

    if old is None or "env" not in old:
        return "an unreadable or older header"
    if old.get("env") != new["env"]:
        return differing_fields(old["env"], new["env"], "env")
    if old.get("n_episodes") != new["n_episodes"]:
        return f"number of episodes: {old.get('n_episodes')} there, {new['n_episodes']} here"
    ids_old, ids_new = old.get("scenario_ids") or [], new["scenario_ids"]
    for i, (a, b) in enumerate(zip(ids_old, ids_new)):
        if a != b:
            return f"scenario {i}: {a!r} there, {b!r} here"
    return "the scenarios (same ids, other faults, profiles or seeds)"


def _stored_chunks(part_dir: Path, head_now: dict) -> list[tuple[np.ndarray, Path]]:
    """Chunks kept by an interrupted export of the same scenarios (a new export starts the folder)."""
    head = part_dir / "header.json"
    if part_dir.is_dir() and head.is_file():
        old = _read_head(part_dir)
        if (old or {}).get("key") != head_now["key"]:
            raise ValueError(
                f"{part_dir} holds the unfinished export of other episodes ({_mismatch(old, head_now)}); "
                "rerun that command to finish it, pass --force to discard it, or choose another --out"
            )
        out = []
        for f in sorted(part_dir.glob("chunk_*.npz")):
            if f.name.endswith(".tmp.npz"):
                continue
            try:
                with np.load(f) as z:
                    out.append((z["index"].copy(), f))
            except (OSError, ValueError, KeyError):  # cut by an interruption: that chunk reruns
                continue
        return out
    part_dir.mkdir(exist_ok=True)
    head.write_text(json.dumps(head_now) + "\n")
    return []


_FULL = {"reward": ((), np.float64), "ended": ((2,), bool)}  # the arrays only a Minari dataset keeps
_FINAL = ("obs_final", "t_final", "active_final")


def _assemble(stored, E: int, T: int, full: bool = False) -> dict:
    """The arrays of the kept chunks; ``full``: also each decision's reward, whether the episode ended
    there (terminated, truncated), and each episode's last observation."""
    arrays = None
    for idx, f in stored:
        with np.load(f) as z:
            if arrays is None:
                D = z["obs"].shape[2]
                arrays = {
                    "obs": np.zeros((E, T, D), dtype=np.float32),
                    "active": np.zeros((E, T, len(FAULT_IDS)), bool),
                    "valid": np.zeros((E, T), dtype=bool),
                    "t_s": np.zeros((E, T)),
                    "feature_names": z["feature_names"],
                }
                if full:
                    arrays.update({k: np.zeros((E, T) + tail, dtype=dt) for k, (tail, dt) in _FULL.items()})
                    arrays["obs_final"] = np.zeros((E, D), dtype=np.float32)
                    arrays["t_final"] = np.zeros(E)
                    arrays["active_final"] = np.zeros((E, len(FAULT_IDS)), dtype=bool)
            for k in ("obs", "active", "valid", "t_s") + (tuple(_FULL) + _FINAL if full else ()):
                arrays[k][idx] = z[k]
    return arrays


# ----------------------------------------------------------------------------- parquet
def _write_parquet(path: Path, arrays: dict, scenarios, meta: dict) -> None:
    from .records import META_KEY, pyarrow

    pa, pq = pyarrow()
    e_idx, k_idx = np.nonzero(arrays["valid"])
    names = [str(x) for x in arrays["feature_names"]]
    cols = {
        "episode": pa.array(e_idx.astype(np.int32)),
        "scenario_id": pa.array([scenarios[e].scenario_id for e in e_idx], pa.string()).dictionary_encode(),
        "step": pa.array(k_idx.astype(np.int32)),
        "t_s": pa.array(arrays["t_s"][e_idx, k_idx]),
    }
    obs = arrays["obs"][e_idx, k_idx]
    for j, n in enumerate(names):
        cols[n] = pa.array(obs[:, j])
    act = arrays["active"][e_idx, k_idx]
    for j, f in enumerate(FAULT_IDS):
        cols[f"active.{f}"] = pa.array(act[:, j])
    cols["no_fault"] = pa.array(~act.any(axis=1))
    table = pa.table(cols)
    meta = dict(
        meta,
        feature_names=names,
        fault_ids=list(FAULT_IDS),
        n_episodes=len(scenarios),
        n_decisions=int(arrays["valid"].shape[1]),
    )
    table = table.replace_schema_metadata({META_KEY: json.dumps(meta).encode()})
    pq.write_table(table, str(path), compression="zstd")


def load_dataset(path: "str | Path") -> dict:
    """The arrays of the module docstring's table from ``dataset.npz`` or ``dataset.parquet`` (or a
    folder holding one); the same arrays, bit for bit, from either format."""
    p = Path(path)
    if p.is_dir():
        cands = [p / "dataset.npz", p / "dataset.parquet"]
        found = [c for c in cands if c.is_file()]
        if not found:
            raise ValueError(f"{p}: no dataset.npz or dataset.parquet in this folder")
        p = found[0]
    if not p.is_file():
        raise ValueError(f"{p}: no such dataset file")
    if p.suffix == ".npz":
        try:
            with np.load(p) as z:
                return {k: z[k] for k in ("obs", "active", "valid", "t_s", "feature_names", "fault_ids")}
        except (OSError, ValueError, KeyError) as e:
            raise ValueError(f"{p}: not a dataset file ({e})") from None
    from .records import META_KEY, pyarrow

    pa, pq = pyarrow()
    try:
        table = pq.read_table(str(p))
        meta = json.loads(table.schema.metadata[META_KEY])
    except (OSError, pa.ArrowException, KeyError, TypeError, json.JSONDecodeError) as e:
        raise ValueError(f"{p}: not a dataset file ({e})") from None
    names, fids = meta["feature_names"], meta["fault_ids"]
    E, T, D = int(meta["n_episodes"]), int(meta["n_decisions"]), len(names)
    e = table.column("episode").to_numpy()
    k = table.column("step").to_numpy()
    obs = np.zeros((E, T, D), dtype=np.float32)
    for j, n in enumerate(names):
        obs[e, k, j] = table.column(n).to_numpy()
    active = np.zeros((E, T, len(fids)), dtype=bool)
    for j, f in enumerate(fids):
        active[e, k, j] = table.column(f"active.{f}").to_numpy(zero_copy_only=False)
    valid = np.zeros((E, T), dtype=bool)
    valid[e, k] = True
    t_s = np.zeros((E, T))
    t_s[e, k] = table.column("t_s").to_numpy()
    return {
        "obs": obs,
        "active": active,
        "valid": valid,
        "t_s": t_s,
        "feature_names": np.array(names),
        "fault_ids": np.array(fids),
    }


def regenerate_minari(root: "str | Path", dataset_id: str, scratch: "str | Path", progress: bool = False) -> dict:
    """Simulate the dataset again from its ``scenarios.json`` (seeds, scenarios, environment) into the
    Minari root ``scratch`` and compare the manifests; returns the manifest, or a ValueError naming
    what differs."""
    from ..envs.scenario_sampler import ScenarioSpec
    from ..jsonfile import read_json
    from .minari_data import kept_manifest, manifest_difference, minari_manifest

    kept = kept_manifest(root, dataset_id)
    truth = read_json(Path(root) / dataset_id / "scenarios.json", "dataset scenarios")
    scenarios = [ScenarioSpec.from_dict({k: v for k, v in s.items() if k != "truth"}) for s in truth["scenarios"]]
    export_dataset(
        scenarios,
        Path(scratch),
        dict(truth["env"]),
        progress=progress,
        fmt="minari",
        force=True,
        dataset_id=dataset_id,
        card=dict(kept.get("made_with") or {}),
    )
    bad = manifest_difference(kept, minari_manifest(scratch, dataset_id), f"{dataset_id} regenerated from its seeds")
    if bad:
        raise ValueError(bad)
    return kept
