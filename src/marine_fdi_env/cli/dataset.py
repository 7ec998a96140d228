"""``marine-fdi dataset``: features, labels and ground truth of episodes, for offline learners."""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path

import numpy as np

from ..benchmark.dataset import FORMATS, dataset_bytes, export_dataset
from ..benchmark.suites import load_suite
from ..costs import CostEstimate, check_memory, episode_cpu_s, say_cost
from ..envs.observation import feature_names
from ..envs.scenario_sampler import get_preset
from .common import CommandParser, add_force_option
from .failures import fail

EPISODE_DECISION_PERIOD_S = 1.0  # the environment's decision period, which the exported episodes keep


_HELP = """\
Runs the episodes of a frozen suite (--suite) or of a scenario preset (--preset, --episodes,
--seed) through the environment with a silent agent and writes, in the folder --out:

  dataset.npz      (--format npz, default) dense arrays, E episodes x T decisions x D features:
                     obs (E, T, D) float32    the observation at each decision
                     active (E, T, 26) bool   faults active at the decision time
                     valid (E, T) bool        False after an episode ended early (engine failure)
                     t_s (E, T) float64       decision times [s]
                     feature_names (D,), fault_ids (26,)
  dataset.parquet  (--format parquet) the same in long format: one row per valid decision with
                   the columns episode, scenario_id, step, t_s, one column per feature and one
                   bool column active.<fault id> per fault, plus no_fault
  scenarios.json   the scenarios with their ground truth, in episode order

With --format minari, --out is a Minari datasets root: the dataset goes to OUT/ID (--dataset-id,
default marine_fdi/<preset or suite>/null-v0), laid out so that MINARI_DATASETS_PATH=OUT and
minari.load_dataset(ID) open it, with a card (README.md), scenarios.json and manifest.json (the
sha256 of every decoded array).  --check OUT/ID checks the manifest against the data, and with
--regenerate simulates the dataset again from its seeds and compares (docs/minari.md).

Load either file with marine_fdi_env.benchmark.dataset.load_dataset(path) (the same arrays, bit for
bit).  Training data must not come from the evaluation suites: use --preset for training.

Episodes run in chunks of up to --batch-size (default 64); each finished chunk is kept in
OUT/dataset.partial/ until the dataset is written: after Ctrl-C (or a lost worker) the same
command resumes where it stopped, and says how many episodes it kept (none when Ctrl-C came
before the first chunk finished).  A folder that already holds a
finished dataset is not overwritten without --force.
"""


def build_parser() -> argparse.ArgumentParser:
    from ..benchmark.suites import SUITE_NAMES
    from ..envs.scenario_sampler import PRESETS
    from .common import add_backend_args, add_progress_option

    ap = CommandParser(
        prog="marine-fdi dataset",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description="Export observations, fault labels and ground truth of episodes for offline learning.",
        epilog=_HELP,
    )
    src = ap.add_mutually_exclusive_group(required=True)
    src.add_argument(
        "--check",
        type=Path,
        metavar="DIR",
        help="a Minari dataset written by --format minari (ROOT/ID): check its manifest against the data",
    )
    src.add_argument(
        "--suite",
        metavar="NAME|FILE.json",
        help=f"a frozen evaluation suite: {', '.join(SUITE_NAMES)}, or a suite JSON file",
    )
    src.add_argument(
        "--preset",
        metavar="NAME",
        help=f"a scenario preset (training data): {', '.join(PRESETS)}; with --episodes and --seed",
    )
    ap.add_argument(
        "--episodes",
        type=int,
        default=None,
        metavar="N",
        help="episodes drawn from --preset (default 256; not with --suite)",
    )
    ap.add_argument(
        "--seed",
        type=int,
        default=None,
        metavar="S",
        help="seed of the episodes drawn from --preset (default 0; not with --suite)",
    )
    ap.add_argument(
        "--out",
        type=Path,
        default=None,
        metavar="DIR",
        help="output folder (created, and its parent if missing; never more levels)",
    )
    ap.add_argument(
        "--format",
        choices=FORMATS,
        default="npz",
        help="npz (dense arrays, default), parquet (long format, one row per decision; needs pyarrow) or minari "
        "(a Minari dataset under the datasets root --out; needs minari)",
    )
    ap.add_argument(
        "--dataset-id",
        default=None,
        metavar="ID",
        help="the Minari dataset id (--format minari; default marine_fdi/<preset or suite>/null-v0)",
    )
    ap.add_argument(
        "--regenerate",
        action="store_true",
        help="with --check: simulate the dataset again from its seeds and compare the manifests",
    )
    ap.add_argument(
        "--observe-sensors", action="store_true", help="append the normalised sensor readings to the features"
    )
    add_force_option(ap, "overwrite a finished dataset in --out, or discard another export's kept chunks there")
    add_backend_args(ap, default_batch=64)
    add_progress_option(ap)
    return ap


def _kept(out: Path | None, scenarios: list | None) -> str:
    """What an interrupted export keeps, exactly: the episodes of its finished chunks, or nothing."""
    from ..benchmark.dataset import PARTIAL, kept_episodes

    n = kept_episodes(out) if out is not None else 0
    if n == 0:
        return "no chunk of episodes had finished, nothing is kept"
    total = f" of {len(scenarios)}" if scenarios else ""
    return f"the {n}{total} episodes of the finished chunks are kept in {out / PARTIAL}"


def dataset_main(argv=None) -> int:
    from ..errors import require_extra
    from ..outputs import prepare_out
    from .common import backend_from_args, interrupted, parse_cli

    ap = build_parser()
    args, code = parse_cli(ap, argv)
    if args is None:
        return code
    if args.check is not None:
        return _check_main(args)
    try:
        backend = backend_from_args(args)
        if args.out is None:
            raise ValueError("--out is required (the dataset's folder; with --format minari, a Minari datasets root)")
        if args.regenerate:
            raise ValueError("--regenerate goes with --check DIR (a Minari dataset to simulate again)")
        if args.dataset_id is not None and args.format != "minari":
            raise ValueError("--dataset-id names a Minari dataset: it goes with --format minari")
        if args.format == "minari":
            require_extra("minari", "--format minari")
        if args.suite and (args.episodes is not None or args.seed is not None):
            raise ValueError("--episodes and --seed draw episodes from a --preset; a --suite has its own episodes")
        episodes = 256 if args.episodes is None else args.episodes
        seed = 0 if args.seed is None else args.seed
        if args.format == "parquet":
            require_extra("pyarrow", "--format parquet")
        if args.suite:
            suite = load_suite(args.suite)
            scenarios, env_kwargs = suite.scenarios, dict(suite["env"])
        else:
            if episodes < 1:
                raise ValueError(f"--episodes must be >= 1, got {episodes}")
            if seed < 0:
                raise ValueError(f"--seed must be >= 0, got {seed}")
            cfg = get_preset(args.preset)
            T = int(round(cfg.duration_s / EPISODE_DECISION_PERIOD_S))
            check_memory(
                dataset_bytes(episodes, T, len(feature_names(args.observe_sensors))),
                f"a dataset of {episodes} episodes of {T} decisions",
                "--episodes",
            )
            ss = np.random.SeedSequence(seed)
            ent = np.random.default_rng(ss).integers(0, 2**63 - 1, size=episodes)
            scenarios = [cfg.sample(int(e), scenario_id=f"{cfg.name}/{seed}/{i}") for i, e in enumerate(ent)]
            env_kwargs = {"scenario_config": cfg}
        if args.observe_sensors:
            env_kwargs["observe_sensors"] = True
        dataset_id = card = None
        if args.format == "minari":
            from ..benchmark.minari_data import check_dataset_id, dataset_id_for

            source = Path(args.suite).stem if args.suite else args.preset
            dataset_id = check_dataset_id(args.dataset_id or dataset_id_for(source))
            what = f"suite {source}" if args.suite else f"preset {args.preset}, {episodes} episodes, seed {seed}"
            card = {
                "description": f"Episodes of MarineFDI-v1 ({what})",
                "command": shlex.join(["marine-fdi", "dataset"] + list(argv or [])),
                "n_features": len(feature_names(args.observe_sensors)),
            }
        out = prepare_out(args.out, "--out", is_dir=True)
        finished = [f.name for f in (out / "dataset.npz", out / "dataset.parquet") if f.is_file()]
        if dataset_id is not None:
            finished = [dataset_id] if (out / dataset_id).is_dir() else []
        if finished and not (out / "dataset.partial").is_dir() and not args.force:
            raise ValueError(
                f"--out {out} already holds a dataset ({', '.join(finished)}); pass --force to overwrite "
                "it, or choose another --out"
            )
        if args.force:
            for name in finished:
                if (out / name).is_dir():
                    import shutil

                    shutil.rmtree(out / name)
                else:
                    (out / name).unlink()
        T = max(int(round(sc.duration_s / EPISODE_DECISION_PERIOD_S)) for sc in scenarios)
        say_cost(
            "marine-fdi dataset",
            f"{len(scenarios)} episodes",
            CostEstimate(
                episode_cpu_s("null") * len(scenarios) * T / 300,
                dataset_bytes(len(scenarios), T, len(feature_names(args.observe_sensors))),
                backend.workers,
            ),
        )
        path = export_dataset(
            scenarios,
            out,
            env_kwargs,
            batch_size=args.batch_size,
            progress=not args.no_progress,
            backend=backend,
            fmt=args.format,
            force=args.force,
            dataset_id=dataset_id,
            card=card,
        )
    except ValueError as e:
        return fail("marine-fdi dataset", e)
    except KeyboardInterrupt:
        return interrupted("marine-fdi dataset", _kept(locals().get("out"), locals().get("scenarios")))
    if dataset_id is not None:
        print(
            f"wrote the Minari dataset {dataset_id} ({len(scenarios)} episodes) in {path}: "
            f"MINARI_DATASETS_PATH={out} and minari.load_dataset({dataset_id!r}) open it"
        )
        return 0
    print(f"wrote {path} and {out / 'scenarios.json'} ({len(scenarios)} episodes)")
    return 0


def _check_main(args) -> int:
    """``--check DIR [--regenerate]``: a Minari dataset's manifest against its data (and its seeds)."""
    import tempfile

    try:
        from ..benchmark.dataset import regenerate_minari
        from ..benchmark.minari_data import check_minari
        from ..errors import require_extra
        from ..jsonfile import read_json

        require_extra("minari", "--check")
        folder = args.check
        if not (folder / "manifest.json").is_file():
            raise ValueError(f"--check {folder}: no manifest.json (not a dataset written by --format minari)")
        dataset_id = str(read_json(folder / "manifest.json", "Minari dataset manifest").get("dataset_id", ""))
        root = folder.resolve().parents[dataset_id.count("/")]
        kept = check_minari(root, dataset_id)
        print(f"{dataset_id}: {kept['n_episodes']} episodes, every decoded array has the manifest's sha256")
        if args.regenerate:
            with tempfile.TemporaryDirectory() as tmp:
                regenerate_minari(root, dataset_id, tmp, progress=not args.no_progress)
            print(f"{dataset_id}: regenerated from its seeds, the same manifest ({kept['sha256'][:16]}...)")
    except ValueError as e:
        return fail("marine-fdi dataset", e)
    return 0
