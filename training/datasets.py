"""Training datasets: a spec (preset or scenario config, episodes, seed) -> its scenarios, exported
once with ``marine-fdi dataset`` and kept in a cache folder (:data:`CACHE`)."""

from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

__all__ = ["CACHE", "scenario_config_of", "dataset_scenarios"]

CACHE = Path(__file__).resolve().parent / ".cache"


def scenario_config_of(spec: dict):
    """(name, ScenarioConfig) of a dataset spec: ``{"preset": NAME}`` or ``{"config": {...}}``."""
    from marine_fdi_env.envs.scenario_sampler import ScenarioConfig, get_preset

    if "config" in spec:  # a scenario config (dict) instead of a named preset
        cfg = ScenarioConfig.from_dict({k: (tuple(tuple(x) if isinstance(x, list) else x for x in v)
                                            if isinstance(v, list) else v) for k, v in spec["config"].items()})
        return cfg.name, cfg
    return spec["preset"], get_preset(spec["preset"])


def dataset_scenarios(spec: dict) -> list:
    """The scenarios of a dataset spec (``episodes`` drawn from ``SeedSequence(seed)``), as
    ``marine-fdi dataset --preset P --episodes N --seed S`` draws them."""
    _, cfg = scenario_config_of(spec)
    n, s = int(spec["episodes"]), int(spec["seed"])
    ent = np.random.default_rng(np.random.SeedSequence(s)).integers(0, 2**63 - 1, size=n)
    return [cfg.sample(int(e), scenario_id=f"{cfg.name}/{s}/{i}") for i, e in enumerate(ent)]


def _ensure_dataset(spec: dict, use_cache: bool, log=print) -> tuple[Path, float, bool]:
    """Export a dataset spec (or find it in the cache); returns (directory, CPU s of the export, fresh)."""
    from marine_fdi_env._version import __version__
    from marine_fdi_env.benchmark.dataset import export_dataset

    preset, cfg = scenario_config_of(spec)
    n, s = int(spec["episodes"]), int(spec["seed"])
    d = CACHE / f"{preset}_{n}_{s}_v{__version__}"
    meta = d / "cpu.json"
    if use_cache and meta.is_file() and (d / "dataset.npz").is_file():
        return d, float(json.loads(meta.read_text())["cpu_s"]), False
    c0 = time.process_time()
    if log:
        log(f"exporting dataset: marine-fdi dataset --preset {preset} --episodes {n} --seed {s}")
    export_dataset(dataset_scenarios(spec), d, {"scenario_config": cfg}, progress=False)
    cpu = time.process_time() - c0
    meta.write_text(json.dumps({"cpu_s": cpu}))
    return d, cpu, True


def _dataset(spec: dict, use_cache: bool, log=print) -> tuple[dict, float, bool]:
    """Export (or load from the cache) a preset dataset; returns (arrays, CPU s of the export, fresh)."""
    from .classifier import load_dataset

    d, cpu, fresh = _ensure_dataset(spec, use_cache, log)
    return load_dataset(d), cpu, fresh
