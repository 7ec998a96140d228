"""Minari datasets: ``marine-fdi dataset --format minari --out ROOT`` (Farama's offline-RL format).

ROOT is laid out as a Minari datasets root, so that with ``MINARI_DATASETS_PATH=ROOT``
``minari.load_dataset(ID)`` opens the dataset (``ID`` like ``marine_fdi/default/null-v0``:
namespace ``marine_fdi``, the preset or suite, the policy that acted, the version)::

    ROOT/marine_fdi/default/null-v0/data/        Minari's own files (the ``arrow`` backend)
    ROOT/marine_fdi/default/null-v0/README.md    the dataset card: what, how made, the command, the manifest hash
    ROOT/marine_fdi/default/null-v0/manifest.json  sha256 of every decoded array of every episode
    ROOT/marine_fdi/default/null-v0/scenarios.json the scenarios with their ground truth and seeds

One Minari episode per scenario, one step per decision (``MarineFDI-v1``, one decision a second):

==================  ===================  ==================================================
field               shape, dtype         meaning
==================  ===================  ==================================================
``observations``    (T+1, D) float32     the observation before each decision, then the last one
``actions``         (T, 28) float32      the belief declared: all zero (the silent ``null`` agent)
``rewards``         (T,) float64         the ``MarineFDI-v1`` reward of each decision
``terminations``    (T,) bool            the engine failed (left its operating range)
``truncations``     (T,) bool            the episode's duration ran out
``infos/active``    (T+1, 26) bool       the faults active at each observation (FAULT_IDS order)
``infos/t_s``       (T+1,) float64       the time of each observation [s]
==================  ===================  ==================================================

Each episode's metadata holds its ``seed`` (the noise seed) and ``options`` (``{"scenario": ...}``:
the scenario, as ``env.reset(options=...)`` takes it, so the episode can be replayed); the dataset's
metadata holds the environment's spec (``MarineFDI-v1`` with the preset's scenario config).

**Manifest.**  ``manifest.json`` holds the sha256 of each decoded array (dtype, shape and bytes) of
every episode, read back through ``minari``, and the sha256 of them all: :func:`check_minari`
recomputes it (a changed file fails, naming the episode and field), and
:func:`.dataset.regenerate_minari` simulates the dataset again from the seeds in ``scenarios.json`` and
compares the manifests (the same seeds give the same arrays, bit for bit).  Hashing the decoded
arrays, not the files, keeps the check independent of how Arrow lays out its files.

Minari is an optional dependency (``pip install 'marine-fdi-env[minari]'``), imported only here.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import warnings
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

import numpy as np

from .._version import __version__
from ..engine.faults import FAULT_IDS

__all__ = [
    "NAMESPACE",
    "POLICY",
    "minari",
    "dataset_id_for",
    "check_dataset_id",
    "work_dir",
    "write_minari",
    "minari_manifest",
    "check_minari",
    "kept_manifest",
    "manifest_difference",
    "minari_arrays",
    "datasets_path",
]

NAMESPACE = "marine_fdi"
POLICY = "null"  # the agent whose actions a dataset holds: the silent one (the data do not depend on it)
MANIFEST = "manifest.json"
FIELDS = ("observations", "actions", "rewards", "terminations", "truncations", "infos/active", "infos/t_s")
_ID = re.compile(r"^[A-Za-z0-9_]+(/[A-Za-z0-9_.+-]+)+-v[0-9]+$")


def minari():
    """The ``minari`` module; a one-line error naming the extra when it is not installed."""
    from ..errors import require_extra

    require_extra("minari", "--format minari")
    import minari as m

    return m


def dataset_id_for(source: str, policy: str = POLICY, version: int = 0) -> str:
    """``marine_fdi/<preset or suite>/<policy>-v<version>``."""
    return f"{NAMESPACE}/{source}/{policy}-v{int(version)}"


def check_dataset_id(dataset_id: str | None) -> str:
    """``dataset_id`` if it is a Minari id with a namespace (``marine_fdi/default/null-v0``), else a ValueError."""
    if not isinstance(dataset_id, str) or not _ID.match(dataset_id):
        raise ValueError(
            f"--dataset-id must look like {dataset_id_for('PRESET')} (namespace/name-vN; letters, digits, "
            f"'_', '.', '+', '-'), got {dataset_id!r}"
        )
    return dataset_id


def work_dir(root: Path, dataset_id: str) -> Path:
    """Where an export keeps its finished chunks until the dataset is written (a hidden folder of
    ROOT, which Minari does not list)."""
    return Path(root) / ".partial" / check_dataset_id(dataset_id).replace("/", "__")


@contextmanager
def datasets_path(root: "str | Path") -> Iterator[None]:
    """``MINARI_DATASETS_PATH`` set to ``root`` inside the block (Minari reads it at every call)."""
    saved = os.environ.get("MINARI_DATASETS_PATH")
    os.environ["MINARI_DATASETS_PATH"] = str(Path(root).resolve())
    try:
        yield
    finally:
        if saved is None:
            os.environ.pop("MINARI_DATASETS_PATH", None)
        else:
            os.environ["MINARI_DATASETS_PATH"] = saved


def _env_spec(env_kwargs: dict):
    """The ``MarineFDI-v1`` spec with the dataset's environment arguments (JSON-ready)."""
    from dataclasses import replace

    import gymnasium

    from ..envs import ENV_ID_V1, register_envs

    register_envs()
    kwargs = {k: (v.to_dict() if hasattr(v, "to_dict") else v) for k, v in env_kwargs.items()}
    kwargs["reward"] = "v1"
    return replace(gymnasium.spec(ENV_ID_V1), kwargs=kwargs)


def _episodes(arrays: dict, scenarios) -> Iterator[dict]:
    """The Minari episode buffers' fields of every scenario, from the dense arrays of an export."""
    for e, sc in enumerate(scenarios):
        n = int(arrays["valid"][e].sum())
        yield {
            "id": e,
            "seed": int(sc.noise_seed),
            "options": {"scenario": sc.to_dict()},
            "observations": np.concatenate([arrays["obs"][e, :n], arrays["obs_final"][e][None]]),
            "actions": np.zeros((n, 28), dtype=np.float32),
            "rewards": arrays["reward"][e, :n].astype(np.float64),
            "terminations": arrays["ended"][e, :n, 0].copy(),
            "truncations": arrays["ended"][e, :n, 1].copy(),
            "infos": {
                "active": np.concatenate([arrays["active"][e, :n], arrays["active_final"][e][None]]),
                # a list: Minari 0.5 stores a 1-d info array with a shape it cannot read back
                "t_s": [float(x) for x in arrays["t_s"][e, :n]] + [float(arrays["t_final"][e])],
            },
        }


def write_minari(
    arrays: dict, scenarios, root: Path, dataset_id: str, env_kwargs: dict, truth: dict, card: dict
) -> Path:
    """Write the dataset ``dataset_id`` under the Minari root ``root`` from an export's dense arrays
    (:func:`~.dataset.export_dataset` with ``fmt="minari"``), with its card, its ground truth
    (``truth``: the environment and the scenarios) and its manifest; returns its folder."""
    m = minari()
    from minari.data_collector.episode_buffer import EpisodeBuffer

    folder = Path(root) / check_dataset_id(dataset_id)
    if folder.exists():
        shutil.rmtree(folder)  # the caller checked --force
    buffers = [EpisodeBuffer(**ep) for ep in _episodes(arrays, scenarios)]
    text = _card_text(dataset_id, card, len(buffers), int(sum(len(b.rewards) for b in buffers)))
    with datasets_path(root), warnings.catch_warnings(), _size_once():
        warnings.simplefilter("ignore")  # Minari's advice to add a code permalink and author e-mail
        ds = m.create_dataset_from_buffers(
            dataset_id,
            buffers,
            env=_env_spec(env_kwargs),
            algorithm_name=f"{POLICY} (the silent agent: declares nothing)",
            author="marine_fdi_env",
            code_permalink=f"marine-fdi-env {__version__}: {card.get('command', 'marine-fdi dataset')}",
            description=text,
            data_format="arrow",
            requirements=[f"marine-fdi-env=={__version__}"],
        )
    ds.storage.update_metadata({"dataset_size": ds.storage.get_size()})
    (folder / "scenarios.json").write_text(json.dumps(truth, indent=1) + "\n")
    manifest = minari_manifest(root, dataset_id)
    manifest["made_with"] = dict(card, package_version=__version__, minari_version=m.__version__)
    (folder / MANIFEST).write_text(json.dumps(manifest, indent=1) + "\n")
    (folder / "README.md").write_text(text + f"\nManifest sha256 (decoded arrays): `{manifest['sha256']}`\n")
    return folder


@contextmanager
def _size_once() -> Iterator[None]:
    """Minari 0.5 measures the dataset's size on disk (a walk over all its files) after every episode it
    writes, which makes writing n episodes take time in n^2; inside the block the walk is skipped (the
    size is measured once, after the last episode)."""
    from minari.dataset.minari_storage import MinariStorage

    real = MinariStorage.get_size
    MinariStorage.get_size = lambda self: 0.0
    try:
        yield
    finally:
        MinariStorage.get_size = real


def _card_text(dataset_id: str, card: dict, n_episodes: int, n_steps: int) -> str:
    return "\n".join(
        [
            f"# {dataset_id}",
            "",
            f"{card.get('description', 'Episodes of MarineFDI-v1')}: {n_episodes} episodes, {n_steps} decisions "
            f"(one a second), the silent `{POLICY}` agent acting.  Observations: the {card.get('n_features', '')} "
            "features of MarineFDI-v1; actions: the declared belief over the 26 faults, no_fault and unknown (all 0 "
            "here); rewards: MarineFDI-v1's; infos: `active` (the faults active at each observation, in "
            "marine_fdi_env.engine.faults.FAULT_IDS order) and `t_s` (its time).  Each episode's metadata holds "
            "its seed and scenario (`options`); `scenarios.json` holds them all with their ground truth.",
            "",
            f"Made with `{card.get('command', 'marine-fdi dataset --format minari')}` (marine-fdi-env "
            f"{__version__}); the same command makes the same arrays, bit for bit (`manifest.json`).  Training "
            "data must not come from the evaluation suites.",
            "",
        ]
    )


def _hash(a) -> str:
    a = np.ascontiguousarray(np.asarray(a))
    h = hashlib.sha256(f"{a.dtype.str}|{a.shape}|".encode())
    h.update(a.tobytes())
    return h.hexdigest()


def _fields(ep) -> dict:
    return {
        "observations": ep.observations,
        "actions": ep.actions,
        "rewards": ep.rewards,
        "terminations": ep.terminations,
        "truncations": ep.truncations,
        "infos/active": ep.infos["active"],
        "infos/t_s": ep.infos["t_s"],
    }


def _open(root: "str | Path", dataset_id: str):
    m = minari()
    folder = Path(root) / check_dataset_id(dataset_id)
    if not (folder / "data").is_dir():
        raise ValueError(f"{folder}: no Minari dataset {dataset_id!r} under the root {root}")
    with datasets_path(root):
        return m.load_dataset(dataset_id)


def minari_manifest(root: "str | Path", dataset_id: str) -> dict:
    """``{"dataset_id", "n_episodes", "episodes": [{"id", "scenario_id", "sha256": {field: hex}}],
    "sha256"}`` of the arrays ``minari.load_dataset`` decodes (module docstring)."""
    ds = _open(root, dataset_id)
    meta = {int(m["id"]): m for m in ds.storage.get_episode_metadata(range(ds.total_episodes))}
    episodes = []
    total = hashlib.sha256()
    for ep in ds.iterate_episodes():
        hashes = {k: _hash(v) for k, v in _fields(ep).items()}
        sid = ((meta.get(int(ep.id)) or {}).get("options") or {}).get("scenario", {}).get("scenario_id")
        episodes.append({"id": int(ep.id), "scenario_id": sid, "sha256": hashes})
        total.update(json.dumps(hashes, sort_keys=True).encode())
    return {"dataset_id": dataset_id, "n_episodes": len(episodes), "episodes": episodes, "sha256": total.hexdigest()}


def manifest_difference(kept: dict, now: dict, where: str) -> str | None:
    """What first differs between two manifests (an episode and a field), or None."""
    if kept.get("n_episodes") != now["n_episodes"]:
        return f"{where}: {kept.get('n_episodes')} episodes in the manifest, {now['n_episodes']} decoded"
    for a, b in zip(kept.get("episodes") or [], now["episodes"]):
        for f in FIELDS:
            if a.get("sha256", {}).get(f) != b["sha256"][f]:
                return f"{where}: episode {b['id']} ({b['scenario_id']}): {f} differs from the manifest's sha256"
    if kept.get("sha256") != now["sha256"]:
        return f"{where}: the manifest's total sha256 differs"
    return None


def kept_manifest(root: "str | Path", dataset_id: str) -> dict:
    from ..jsonfile import read_json

    f = Path(root) / check_dataset_id(dataset_id) / MANIFEST
    if not f.is_file():
        raise ValueError(f"{f}: no manifest (not written by marine-fdi dataset --format minari)")
    return read_json(f, "Minari dataset manifest")


def check_minari(root: "str | Path", dataset_id: str) -> dict:
    """The dataset's manifest after checking that the decoded arrays still have its hashes; a
    ValueError naming the episode and field that differ."""
    kept = kept_manifest(root, dataset_id)
    bad = manifest_difference(kept, minari_manifest(root, dataset_id), f"{Path(root) / dataset_id}")
    if bad:
        raise ValueError(bad)
    return kept


def minari_arrays(root: "str | Path", dataset_id: str) -> dict:
    """The dense arrays of ``marine-fdi dataset`` (``obs`` (E, T, D), ``active`` (E, T, 26), ``valid``
    (E, T), ``t_s`` (E, T)) of a Minari dataset, read with ``minari.load_dataset`` alone: the
    observation and the faults before each decision."""
    ds = _open(root, dataset_id)
    eps = list(ds.iterate_episodes())
    if not eps:
        raise ValueError(f"{dataset_id}: no episodes")
    T = max(len(ep.actions) for ep in eps)
    D = eps[0].observations.shape[1]
    out = {
        "obs": np.zeros((len(eps), T, D), dtype=np.float32),
        "active": np.zeros((len(eps), T, len(FAULT_IDS)), dtype=bool),
        "valid": np.zeros((len(eps), T), dtype=bool),
        "t_s": np.zeros((len(eps), T)),
    }
    for e, ep in enumerate(sorted(eps, key=lambda x: int(x.id))):
        n = len(ep.actions)
        out["obs"][e, :n] = ep.observations[:n]
        out["active"][e, :n] = ep.infos["active"][:n]
        out["valid"][e, :n] = True
        out["t_s"][e, :n] = ep.infos["t_s"][:n]
    return out
