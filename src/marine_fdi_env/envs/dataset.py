"""``marine-fdi dataset``: features, labels and ground truth of episodes, for offline learners.

Runs episodes of a frozen suite (``--suite NAME``) or of a scenario preset (``--preset NAME
--episodes N --seed S``; training data must not come from the evaluation suites) through the
environment with a silent agent, and writes ``OUT_DIR/dataset.npz``:

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

and ``OUT_DIR/scenarios.json`` (the scenarios with their ground truth, same order).  Labels for a
classifier: ``active`` (multi-label), or "no fault" where ``active`` is all False.  The format is
npz (numpy only); Parquet would add a dependency for no gain on dense tensors.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from ..faults import FAULT_IDS
from .scenario_sampler import ScenarioSpec, get_preset
from .suites import load_suite
from .vector import MarineFDIVectorEnv

__all__ = ["export_dataset", "dataset_main"]


def export_dataset(scenarios: list[ScenarioSpec], out_dir: Path, env_kwargs: dict | None = None,
                   batch_size: int = 64, progress: bool = True) -> Path:
    env_kwargs = dict(env_kwargs or {})
    if not scenarios:
        raise ValueError("no scenarios to export")
    T = max(int(round(s.duration_s / env_kwargs.get("decision_period_s", 1.0))) for s in scenarios)
    obs_all = valid = active = t_all = None
    names: list[str] = []
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=len(scenarios), desc="dataset", unit="episode", file=sys.stderr)
    groups: dict[float, list[int]] = {}  # one batched engine set per sensor-noise scale
    for i, sc in enumerate(scenarios):
        groups.setdefault(float(sc.noise_scale), []).append(i)
    chunks = [(ns, idx[k:k + batch_size]) for ns, idx in groups.items() for k in range(0, len(idx), batch_size)]
    for noise_scale, part in chunks:
        chunk = [scenarios[i] for i in part]
        n = len(chunk)
        kw = dict(env_kwargs)
        if noise_scale != get_preset(kw.get("scenario_config", "default")).noise_scale:
            from dataclasses import replace

            kw["scenario_config"] = replace(get_preset(kw.get("scenario_config", "default")), noise_scale=noise_scale)
        venv = MarineFDIVectorEnv(num_envs=n, **kw)
        obs, infos = venv.reset(options={"scenarios": chunk})
        if obs_all is None:
            D = obs.shape[1]
            names = list(venv.feature_names)
            obs_all = np.zeros((len(scenarios), T, D), dtype=np.float32)
            valid = np.zeros((len(scenarios), T), dtype=bool)
            active = np.zeros((len(scenarios), T, len(FAULT_IDS)), dtype=bool)
            t_all = np.zeros((len(scenarios), T))
        live = np.ones(n, dtype=bool)
        k = 0
        col = {f: j for j, f in enumerate(FAULT_IDS)}
        rows_of = np.asarray(part, dtype=np.int64)
        while live.any() and k < T:
            rows = rows_of[live]
            obs_all[rows, k] = obs[live]
            valid[rows, k] = True
            for i in np.flatnonzero(live):
                t_all[rows_of[i], k] = infos["t_s"][i]
                for f in infos["active_faults"][i]:
                    active[rows_of[i], k, col[f]] = True
            obs, _, term, trunc, infos = venv.step(np.zeros((n, 28), dtype=np.float32))
            live &= ~(term | trunc)
            k += 1
        if bar is not None:
            bar.update(n)
    if bar is not None:
        bar.close()
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(out_dir / "dataset.npz", obs=obs_all, active=active, valid=valid, t_s=t_all,
                        feature_names=np.array(names), fault_ids=np.array(FAULT_IDS))
    (out_dir / "scenarios.json").write_text(json.dumps(
        {"env": {k: (v.to_dict() if hasattr(v, "to_dict") else v) for k, v in env_kwargs.items()}, "scenarios": [dict(s.to_dict(), truth=s.truth()) for s in scenarios]}, indent=1) + "\n")
    return out_dir / "dataset.npz"


def dataset_main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="marine-fdi dataset", description=__doc__.splitlines()[0])
    src = ap.add_mutually_exclusive_group(required=True)
    src.add_argument("--suite", help="a frozen suite (evaluation data)")
    src.add_argument("--preset", help="a scenario preset (training data), with --episodes and --seed")
    ap.add_argument("--episodes", type=int, default=256)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--out", type=Path, required=True, help="output directory")
    ap.add_argument("--observe-sensors", action="store_true", help="append the normalised sensor features")
    ap.add_argument("--no-progress", action="store_true")
    try:
        args = ap.parse_args(argv)
    except SystemExit as e:
        return e.code if isinstance(e.code, int) else 0
    try:
        if args.suite:
            suite = load_suite(args.suite)
            scenarios, env_kwargs = suite.scenarios, dict(suite["env"])
        else:
            if args.episodes < 1:
                raise ValueError(f"--episodes must be >= 1, got {args.episodes}")
            cfg = get_preset(args.preset)
            ss = np.random.SeedSequence(args.seed)
            ent = np.random.default_rng(ss).integers(0, 2**63 - 1, size=args.episodes)
            scenarios = [cfg.sample(int(e), scenario_id=f"{cfg.name}/{args.seed}/{i}") for i, e in enumerate(ent)]
            env_kwargs = {"scenario_config": cfg}
        if args.observe_sensors:
            env_kwargs["observe_sensors"] = True
        path = export_dataset(scenarios, args.out, env_kwargs, progress=not args.no_progress)
    except ValueError as e:
        print(f"marine-fdi dataset: error: {e}", file=sys.stderr)
        return 2
    print(f"wrote {path} and {args.out / 'scenarios.json'} ({len(scenarios)} episodes)")
    return 0
