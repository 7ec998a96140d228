"""RL Zoo with the package's hyperparameters, trained, timed and scored against ``null`` (docs/rl_zoo.md).

    python benchmarks/rl_zoo.py [--seed 0] [--suite single-v1] [--logs DIR] [--write]
    python benchmarks/rl_zoo.py --score logs/ppo/MarineFDI-v1_1 --cpu-minutes M [--write]

1. runs ``python -m rl_zoo3.train --algo ppo --env MarineFDI-v1 --gym-packages marine_fdi_env --conf-file
   marine_fdi_env.training.zoo --seed SEED -f LOGS`` as docs/rl_zoo.md writes it and measures its CPU time
   (the child process, all threads) and wall time; ``--score RUN`` scores a run trained before instead
   (``--cpu-minutes``: its CPU time, e.g. from ``/usr/bin/time``);
2. evaluates the run folder (``marine-fdi evaluate --agent RUN``) and ``null`` on ``--suite``;
3. prints the run's detection and isolation with exact 95 % intervals and the per-episode return
   difference to ``null``, paired by episode, with a 95 % t interval (as ``benchmarks/sb3_readme.py``).

``--write`` keeps the output in ``docs/data/rl_zoo.json``.  The run "beats null" when the paired
interval lies above 0.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import emit  # noqa: E402
from sb3_readme import ROOT, paired_return, summary  # noqa: E402

COMMAND = (
    "python -m rl_zoo3.train --algo ppo --env MarineFDI-v1 --gym-packages marine_fdi_env "
    "--conf-file marine_fdi_env.training.zoo"
)


def train(seed: int, logs: Path) -> tuple[Path, float, float]:
    """Run RL Zoo as documented; (run folder, CPU minutes, wall minutes)."""
    cmd = [sys.executable, "-m", *COMMAND.split()[2:], "--seed", str(seed), "-f", str(logs)]
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    w0 = time.perf_counter()
    subprocess.run(cmd, check=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime + after.ru_stime) - (before.ru_utime + before.ru_stime)
    runs = sorted((logs / "ppo").glob("MarineFDI-v1_*"), key=lambda p: int(p.name.rsplit("_", 1)[1]))
    return runs[-1], cpu / 60.0, (time.perf_counter() - w0) / 60.0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0, help="RL Zoo's --seed (default 0)")
    ap.add_argument("--suite", default="single-v1", help="the suite to score on (default single-v1)")
    ap.add_argument("--logs", type=Path, default=None, help="RL Zoo's -f folder (default: a temporary one)")
    ap.add_argument("--score", type=Path, default=None, metavar="RUN", help="score this run folder, no training")
    ap.add_argument("--cpu-minutes", type=float, default=None, help="with --score: the run's training CPU time")
    ap.add_argument("--workers", type=int, default=1, help="evaluation workers")
    ap.add_argument("--write", action="store_true", help="keep the output in docs/data/rl_zoo.json")
    ap.add_argument("--json", action="store_true")
    args = ap.parse_args(argv)
    from marine_fdi_env.benchmark.evaluate import evaluate

    with tempfile.TemporaryDirectory() as tmp:
        here = Path(tmp)
        load0 = os.getloadavg()[0]
        if args.score is not None:
            run, cpu, wall = args.score.resolve(), args.cpu_minutes, None
        else:
            run, cpu, wall = train(args.seed, (args.logs or here / "logs").resolve())
        load1 = os.getloadavg()[0]
        agent = evaluate(str(run), args.suite, here / "zoo.json", workers=args.workers, progress=False)
        null = evaluate("null", args.suite, here / "null.json", workers=args.workers, progress=False)
    diff = paired_return(agent, null)
    out = {
        "command": f"{COMMAND} --seed {args.seed}",
        "hyperparameters": "training/hyperparams/zoo_ppo.yml (--conf-file marine_fdi_env.training.zoo)",
        "run": run.name,
        "training_cpu_minutes": None if cpu is None else round(cpu, 2),
        "training_wall_minutes": None if wall is None else round(wall, 2),
        "load_average_1min": [round(load0, 2), round(load1, 2)],
        "cpus": os.cpu_count(),
        "suite": agent["suite"],
        "agent": summary(agent),
        "null": summary(null),
        "return_minus_null": diff,
        "beats_null": bool(diff["ci95"][0] > 0),
    }
    if args.write:
        (ROOT / "docs" / "data" / "rl_zoo.json").write_text(json.dumps(out, indent=1) + "\n")
    emit(out, args.json)
    return 0


if __name__ == "__main__":
    sys.exit(main())
