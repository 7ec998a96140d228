"""Training datasets: a spec (preset or scenario config, episodes, seed, optional sensor-noise
scales) -> its scenarios, exported once with ``marine-fdi dataset`` and kept in a cache folder
(:data:`CACHE`).

A spec is ``{"preset": NAME}`` or ``{"config": {...}}`` (a :class:`ScenarioConfig`), with
``episodes`` and ``seed``; ``noise_scales: [..]`` draws each episode's sensor-noise scale (the
multiplier of the table 6.3 bounds, the same for every sensor) uniformly from that grid, from a
stream of its own (the other draws of the episode are those of the spec without it); ``weight``
is the classifier's loss weight of its episodes.  :func:`for_training_seed` moves a spec's seed
with the training seed, so that another training seed also trains on other episodes.
"""

from __future__ import annotations

import hashlib
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

__all__ = [
    "CACHE",
    "scenario_config_of",
    "dataset_scenarios",
    "for_training_seed",
    "spec_name",
    "minari_id",
    "training_dataset",
]

CACHE = Path(__file__).resolve().parent / ".cache"


def scenario_config_of(spec: dict):
    """(name, ScenarioConfig) of a dataset spec: ``{"preset": NAME}``, ``{"config": {...}}``, or both
    (the preset with the fields the config names replaced)."""
    from dataclasses import asdict

    from marine_fdi_env.envs.scenario_sampler import ScenarioConfig, get_preset

    if "config" in spec:  # a scenario config (dict), over a named preset's fields if one is named
        fields = {
            k: (tuple(tuple(x) if isinstance(x, list) else x for x in v) if isinstance(v, list) else v)
            for k, v in spec["config"].items()
        }
        base = asdict(get_preset(spec["preset"])) if "preset" in spec else {}
        cfg = ScenarioConfig.from_dict(dict(base, **fields))
        return cfg.name, cfg
    return spec["preset"], get_preset(spec["preset"])


def spec_name(spec: dict) -> str:
    """A spec's short name: its config's name, else its preset."""
    return spec["config"]["name"] if "config" in spec and "name" in spec["config"] else spec["preset"]


def _noise_grid(spec: dict) -> list[float] | None:
    grid = spec.get("noise_scales")
    if grid is None:
        return None
    try:
        out = [float(x) for x in grid]
    except (TypeError, ValueError):
        out = []
    if not out or not all(np.isfinite(x) and x >= 0 for x in out):
        raise ValueError(
            f"dataset spec {spec_name(spec)!r}: noise_scales must be a non-empty list of numbers >= 0, got {grid!r}"
        )
    return out


def dataset_scenarios(spec: dict) -> list:
    """The scenarios of a dataset spec (``episodes`` drawn from ``SeedSequence(seed)``), as
    ``marine-fdi dataset --preset P --episodes N --seed S`` draws them; with ``noise_scales``,
    each episode's noise scale drawn from ``SeedSequence(seed).spawn(1)[0]``."""
    _, cfg = scenario_config_of(spec)
    n, s = int(spec["episodes"]), int(spec["seed"])
    ent = np.random.default_rng(np.random.SeedSequence(s)).integers(0, 2**63 - 1, size=n)
    scs = [cfg.sample(int(e), scenario_id=f"{cfg.name}/{s}/{i}") for i, e in enumerate(ent)]
    grid = _noise_grid(spec)
    if grid is not None:
        pick = np.random.default_rng(np.random.SeedSequence(s).spawn(1)[0]).integers(len(grid), size=n)
        scs = [replace(sc, noise_scale=grid[int(k)]) for sc, k in zip(scs, pick)]
    return scs


def for_training_seed(spec: dict, training_seed: int, stride: int) -> dict:
    """The spec a run with ``training_seed`` simulates: its seed moved by ``stride x training_seed``
    (``stride`` 0: the same episodes for every training seed)."""
    if not stride:
        return spec
    return dict(spec, seed=int(spec["seed"]) + int(stride) * int(training_seed))


def _cache_dir(spec: dict) -> Path:
    from marine_fdi_env._version import __version__

    key = {k: v for k, v in spec.items() if k != "weight"}
    digest = hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()[:10]
    return CACHE / f"{spec_name(spec)}_{int(spec['episodes'])}_{int(spec['seed'])}_{digest}_v{__version__}"


def _ensure_dataset(spec: dict, use_cache: bool, log=print) -> tuple[Path, float, bool]:
    """Export a dataset spec (or find it in the cache); returns (directory, CPU s of the export, fresh)."""
    from marine_fdi_env.benchmark.dataset import export_dataset

    preset, cfg = scenario_config_of(spec)
    d = _cache_dir(spec)
    meta = d / "cpu.json"
    if use_cache and meta.is_file() and (d / "dataset.npz").is_file():
        return d, float(json.loads(meta.read_text())["cpu_s"]), False
    c0 = time.process_time()
    if log:
        noise = f" at noise scales {spec['noise_scales']}" if "noise_scales" in spec else ""
        log(f"exporting dataset: {preset} x{spec['episodes']} (seed {spec['seed']}){noise}")
    export_dataset(dataset_scenarios(spec), d, {"scenario_config": cfg}, progress=False, force=True)
    cpu = time.process_time() - c0
    meta.write_text(json.dumps({"cpu_s": cpu}))
    return d, cpu, True


def minari_id(spec: dict) -> str:
    """The Minari dataset id of a dataset spec: ``marine_fdi/<name>-s<seed>-n<episodes>/null-v0``."""
    from marine_fdi_env.benchmark.minari_data import dataset_id_for

    return dataset_id_for(f"{spec_name(spec)}-s{int(spec['seed'])}-n{int(spec['episodes'])}")


def _minari_dataset(spec: dict, root: Path, log=print) -> tuple[dict, float, bool]:
    """A dataset spec as a Minari dataset under the datasets root ``root`` (exported once), read back
    with ``minari.load_dataset`` alone; returns (arrays, CPU s of the export, fresh)."""
    from marine_fdi_env.benchmark.dataset import export_dataset
    from marine_fdi_env.benchmark.minari_data import minari_arrays

    did = minari_id(spec)
    folder = Path(root) / did
    meta = folder / "cpu.json"
    fresh, cpu = not meta.is_file(), 0.0
    if fresh:
        _, cfg = scenario_config_of(spec)
        if log:
            log(f"exporting Minari dataset {did} under {root}")
        c0 = time.process_time()
        card = {
            "description": f"Training episodes of the dataset spec {json.dumps(spec, sort_keys=True)}",
            "command": "marine-fdi train --algo classifier --params data_source=minari minari_root=ROOT "
            "(marine_fdi_env.training.datasets)",
        }
        export_dataset(
            dataset_scenarios(spec),
            Path(root),
            {"scenario_config": cfg},
            progress=False,
            fmt="minari",
            force=True,
            dataset_id=did,
            card=card,
        )
        cpu = time.process_time() - c0
        meta.write_text(json.dumps({"cpu_s": cpu}))
    else:
        cpu = float(json.loads(meta.read_text())["cpu_s"])
    arrays = minari_arrays(root, did)
    return {k: arrays[k] for k in ("obs", "active", "valid")}, cpu, fresh


def _dataset(spec: dict, use_cache: bool, log=print, minari_root: "Path | None" = None) -> tuple[dict, float, bool]:
    """Export (or load from the cache) a preset dataset; returns (arrays, CPU s of the export, fresh).
    ``minari_root``: through a Minari dataset under that root instead (:func:`_minari_dataset`)."""
    from .classifier import load_dataset

    if minari_root is not None:
        return _minari_dataset(spec, Path(minari_root), log)
    d, cpu, fresh = _ensure_dataset(spec, use_cache, log)
    return load_dataset(d), cpu, fresh


def training_dataset(spec: dict, use_cache: bool = True, log=print) -> tuple[dict, float, bool]:
    """The arrays (``obs``, ``active``, ``valid``) of a dataset spec, exported once and then read from
    the cache; returns (arrays, CPU s of the export, whether it was exported now)."""
    return _dataset(spec, use_cache, log)
