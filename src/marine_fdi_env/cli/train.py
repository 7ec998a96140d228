"""``marine-fdi train``: train a learned agent (needs the ``train`` extra; :mod:`marine_fdi_env.training.train`)."""

from __future__ import annotations

import shlex
import sys
from pathlib import Path

import numpy as np

from ..envs.fdi_env import ENV_ID, ENV_ID_V1
from ..errors import UsageError, require_extra
from ..outputs import prepare_out
from .common import CommandParser, add_force_option, parse_cli
from .failures import fail

__all__ = ["train_main"]

TRAINED_FILES = ("config.json", "model.pt", "model.zip")  # what a finished run leaves in its folder


# ----------------------------------------------------------------------------- CLI
def shipped_training_config(algo: str, entry: str | None = None) -> dict | None:
    """The config of a shipped model trained like ``marine-fdi train --algo ALGO [--hyperparams ENTRY]``
    (a model folder or one training seed of it; the first in name order), or None."""
    from ..benchmark.agent_registry import models_dir
    from ..jsonfile import read_json

    root = models_dir()
    if root is None:
        return None
    for f in sorted(root.glob("*/config.json")) + sorted(root.glob("*/*/config.json")):
        cfg = read_json(f, "model config")
        if cfg.get("algo") == algo and cfg.get("hyperparams_entry") == entry:
            return cfg
    return None


def say_training_cost(algo: str, n_timesteps: int | None, entry: str | None = None) -> None:
    """The expected training time, from the shipped model trained with the same algorithm and
    hyperparameter entry (its measured CPU minutes, scaled by the PPO budget), said before training."""
    from ..costs import CostEstimate, say_cost

    cfg = shipped_training_config(algo, entry)
    if cfg is None:
        return
    minutes = float(cfg.get("cpu_minutes") or 0.0)
    if n_timesteps and cfg.get("n_timesteps"):
        data = float(cfg.get("cpu_s_data") or 0.0) / 60.0  # simulating the episodes does not scale with the budget
        minutes = data + (minutes - data) * n_timesteps / float(cfg["n_timesteps"])
    say_cost(
        "marine-fdi train",
        f"training {algo} (from the shipped model's measured CPU time, simulating its "
        "training episodes included; less when they are cached)",
        CostEstimate(60.0 * minutes),
    )


def _parse_params(items: list[str]) -> dict:
    import yaml

    out = {}
    for it in items or []:
        k, sep, v = it.partition("=")
        if not sep:
            raise ValueError(f"--params entries must look like key=value, got {it!r}")
        out[k] = yaml.safe_load(v)
    return out


def train_main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    ap = CommandParser(
        prog="marine-fdi train",
        description="Train a learned diagnoser for MarineFDI-v1 / "
        "MarineFDI-v0 (RL Zoo style): the model, config.json with the exact command, "
        "learning_curve.csv and agent.json go to --out.",
    )
    ap.add_argument("--algo", choices=("ppo", "ppo_lstm", "classifier"), required=True)
    ap.add_argument("--seed", type=int, default=0, help="random seed; negative: draw one (logged)")
    ap.add_argument(
        "--env",
        default=ENV_ID,
        metavar="ID",
        help=f"environment id: the entry of training/hyperparams/ALGO.yml and the reward trained on (default "
        f"{ENV_ID}; {ENV_ID_V1}: the reward derived from the metrics)",
    )
    ap.add_argument(
        "--hyperparams",
        default=None,
        metavar="ENTRY",
        help="the entry of training/hyperparams/ALGO.yml to train (default: the --env id; "
        "'robust': the noise-invariant agents)",
    )
    ap.add_argument("--out", type=Path, default=None, help="run directory (default training/logs/ALGO_sSEED)")
    ap.add_argument(
        "--n-timesteps", type=int, default=None, metavar="N", help="override the PPO budget (a positive integer)"
    )
    ap.add_argument("--params", nargs="*", default=[], help="hyperparameter overrides key=value")
    ap.add_argument(
        "--no-cache",
        action="store_true",
        help="simulate the training datasets again (classifier, replayed PPO) instead of using training/.cache",
    )
    add_force_option(ap, "overwrite a trained model in the run directory (without it: an error)")
    args, code = parse_cli(ap, argv)
    if args is None:
        return code
    try:
        require_extra("torch", "marine-fdi train")
        require_extra("stable_baselines3", "marine-fdi train")
        from ..training.train import HERE, load_hyperparams, train_agent

        over = _parse_params(args.params)
        if args.n_timesteps is not None:
            if args.n_timesteps < 1:
                raise UsageError(f"--n-timesteps must be a positive integer, got {args.n_timesteps}")
            over["n_timesteps"] = args.n_timesteps
        load_hyperparams(args.algo, args.hyperparams or args.env, over)  # its checks, before any work
        if args.out is not None:
            prepare_out(args.out, "--out", is_dir=True, create=False)
        seed = args.seed
        if seed < 0:
            seed = int(np.random.SeedSequence().entropy % (2**31))
            print(f"drew seed {seed}")
        out = args.out or HERE / "logs" / f"{args.algo}_s{seed}"
        trained = [f for f in TRAINED_FILES if (Path(out) / f).is_file()]
        if trained and not args.force:
            raise UsageError(
                f"--out {out} already holds a trained model ({', '.join(trained)}); pass --force to overwrite it, "
                "or choose another --out"
            )
    except ValueError as e:
        return fail("marine-fdi train", e)
    # the command that makes the model (--no-cache only re-exports the same data, --force only allows the
    # overwrite: neither is recorded)
    cmd = ["marine-fdi", "train"] + [a for a in argv if a not in ("--no-cache", "--force")]
    if args.seed < 0:
        cmd = [a if a != str(args.seed) else str(seed) for a in cmd]
    say_training_cost(args.algo, over.get("n_timesteps"), args.hyperparams)
    try:
        cfg = train_agent(
            args.algo,
            seed,
            out,
            env_id=args.env,
            overrides=over,
            use_cache=not args.no_cache,
            command=shlex.join(cmd),
            seed_drawn=args.seed < 0,
            hyperparams=args.hyperparams,
        )
    except ValueError as e:
        return fail("marine-fdi train", e)
    except KeyboardInterrupt:
        print("marine-fdi train: interrupted", file=sys.stderr)
        return 130
    print(f"saved {out} (seed {seed}, {cfg['cpu_minutes']} CPU minutes)")
    return 0
