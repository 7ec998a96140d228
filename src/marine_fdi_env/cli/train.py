"""``marine-fdi train``: train a learned agent (needs the ``train`` extra; :mod:`marine_fdi_env.training.train`)."""

from __future__ import annotations

import argparse
import shlex
import sys
from pathlib import Path

import numpy as np

from ..envs.fdi_env import ENV_ID
from ..errors import require_extra
from .common import parse_cli

__all__ = ["train_main"]


# ----------------------------------------------------------------------------- CLI
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
    ap = argparse.ArgumentParser(prog="marine-fdi train", description="Train a learned diagnoser for MarineFDI-v1 / "
                                 "MarineFDI-v0 (RL Zoo style): the model, config.json with the exact command, "
                                 "learning_curve.csv and agent.json go to --out.")
    ap.add_argument("--algo", choices=("ppo", "ppo_lstm", "classifier"), required=True)
    ap.add_argument("--seed", type=int, default=0, help="random seed; negative: draw one (logged)")
    ap.add_argument("--env", default=ENV_ID)
    ap.add_argument("--hyperparams", default=None, metavar="ENTRY",
                    help="the entry of training/hyperparams/ALGO.yml to train (default: the --env id; "
                         "'robust': the noise-invariant agents)")
    ap.add_argument("--out", type=Path, default=None, help="run directory (default training/logs/ALGO_sSEED)")
    ap.add_argument("--n-timesteps", type=int, default=None, help="override the PPO budget")
    ap.add_argument("--params", nargs="*", default=[], help="hyperparameter overrides key=value")
    ap.add_argument("--no-cache", action="store_true", help="simulate the training datasets again (classifier, "
                                                             "replayed PPO) instead of using training/.cache")
    args, code = parse_cli(ap, argv)
    if args is None:
        return code
    try:
        require_extra("torch", "marine-fdi train")
        require_extra("stable_baselines3", "marine-fdi train")
        from ..training.train import HERE, train_agent

        over = _parse_params(args.params)
        if args.n_timesteps is not None:
            over["n_timesteps"] = args.n_timesteps
    except ValueError as e:
        print(f"marine-fdi train: error: {e}", file=sys.stderr)
        return 2
    seed = args.seed
    if seed < 0:
        seed = int(np.random.SeedSequence().entropy % (2**31))
        print(f"drew seed {seed}")
    out = args.out or HERE / "logs" / f"{args.algo}_s{seed}"
    # the command that makes the model (--no-cache only re-exports the same data: not recorded)
    cmd = ["marine-fdi", "train"] + [a for a in argv if a != "--no-cache"]
    if args.seed < 0:
        cmd = [a if a != str(args.seed) else str(seed) for a in cmd]
    try:
        cfg = train_agent(args.algo, seed, out, env_id=args.env, overrides=over, use_cache=not args.no_cache,
                          command=shlex.join(cmd), seed_drawn=args.seed < 0, hyperparams=args.hyperparams)
    except ValueError as e:
        print(f"marine-fdi train: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("marine-fdi train: interrupted", file=sys.stderr)
        return 130
    print(f"saved {out} (seed {seed}, {cfg['cpu_minutes']} CPU minutes)")
    return 0
