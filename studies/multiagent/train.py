"""Train the learned decentralised teams of the multi-agent track for one seed, every message budget on
one simulation of the training episodes (``training/hyperparams/decentralised.yml``).

    python -m studies.multiagent.train --seed 0 --out training/models   # dec-classifier-BUDGET/seed0, every budget
    python -m studies.multiagent.train --seed 0 --entry thesis_locals --out training/models   # dec-global-decision
    python -m studies.multiagent.train --seed 0 --out /tmp/x --params epochs=1 --episodes-scale 0.05   # a smoke run
    python -m studies.multiagent.train --recalibrate training/models/dec-classifier-decision/seed*   # isolation only
    python -m studies.multiagent.train --out training/models --thesis-pairs training/models/dec-global-rated-decision/s*
    # -> dec-global-rated-decision+thesis-pairs/seedS: the same teams, the thesis's logic for pairs (nothing trained)
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import yaml

from marine_fdi_env.training.decentralised_run import (
    derive_thesis_pairs,
    load_decentralised_hyperparams,
    recalibrate_isolation,
    train_decentralised_run,
)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--seed", type=int, default=None, help="the training seed (required unless --recalibrate)")
    ap.add_argument(
        "--recalibrate", nargs="*", type=Path, default=None, help="model folders: calibrate their isolation again"
    )
    ap.add_argument(
        "--thesis-pairs",
        nargs="*",
        type=Path,
        default=None,
        help="dec-global model folders: save each with the thesis's logic for fault pairs under --out",
    )
    ap.add_argument("--out", type=Path, default=None, help="the models folder (default: nothing saved)")
    ap.add_argument(
        "--entry",
        default="decentralised",
        help="the entry of decentralised.yml (thesis_locals: a learned global on the thesis's locals)",
    )
    ap.add_argument("--budgets", nargs="*", default=None, help="default: the entry's budgets")
    ap.add_argument("--params", nargs="*", default=[], help="key=value overrides (YAML values)")
    ap.add_argument("--episodes-scale", type=float, default=1.0, help="scale every dataset's episodes (smoke runs)")
    args = ap.parse_args(argv)
    hp = load_decentralised_hyperparams(args.entry)
    for kv in args.params:
        k, _, v = kv.partition("=")
        hp[k] = yaml.safe_load(v)
    if args.episodes_scale != 1.0:
        for key in ("datasets",):
            hp[key] = [dict(s, episodes=max(8, int(s["episodes"] * args.episodes_scale))) for s in hp[key]]
        for key in ("calibration", "isolation_calibration"):
            hp[key] = dict(hp[key], episodes=max(8, int(hp[key]["episodes"] * args.episodes_scale)))
    if args.thesis_pairs is not None:
        if args.out is None:
            ap.error("--thesis-pairs needs --out")
        command = "python -m studies.multiagent.train " + " ".join(argv if argv is not None else sys.argv[1:])
        for folder in args.thesis_pairs:
            derive_thesis_pairs(folder, args.out, command=command)
        return
    if args.recalibrate is not None:
        for folder in args.recalibrate:
            recalibrate_isolation(folder, hp)
        return
    if args.seed is None:
        ap.error("--seed is required")
    command = "python -m studies.multiagent.train " + " ".join(argv if argv is not None else sys.argv[1:])
    for cfg in train_decentralised_run(args.seed, hp, args.out, budgets=args.budgets, command=command):
        print(f"{cfg['name']} seed {cfg['seed']}: {cfg['cpu_minutes']:.2f} CPU min ({cfg['cpu_s_data']:.0f} s data)")


if __name__ == "__main__":
    main()
