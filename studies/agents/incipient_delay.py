"""How fast the learned agents detect incipient faults, on held-in episodes only, against the reference.

    python -m studies.agents.incipient_delay
    python -m studies.agents.incipient_delay --agents reference training/models/classifier/seed0 --episodes 64

Never a suite: ``incipient`` episodes (process faults drifting in at 0.5-1.5x their detectability limit)
drawn like the robust training data (every sampler profile family, fuel settings 0.3-1.0) from a seed
no training or calibration spec uses (``--seed``, default 33), at the nominal sensor noise of
incipient-v1 (``--noise-scales``: others of the training grid 0.5-1.5x; the reference's thresholds
are set for the nominal noise, so above it its "detections" are false alarms).  Per agent and noise
scale: detection, the censored median detection delay, false alarms, and the paired median: the
agent's and the reference's median delay over the episodes both detect (incipient-v1's must-show
compares both medians with 0.5x the reference's).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from studies.agents.development import DEV_SPEC

__all__ = ["INCIPIENT_SPEC", "DEFAULT_AGENTS", "episode_delays", "delay_table", "main"]

INCIPIENT_SPEC = dict(
    DEV_SPEC, preset="incipient", config=dict(DEV_SPEC["config"], name="robust-incipient-development")
)
DEFAULT_AGENTS = (
    "reference",
    "training/models/classifier/seed0",
    "training/models/classifier/seed1",
    "training/models/classifier/seed2",
    "training/models/ppo/seed0",
    "training/models/ppo/seed1",
    "training/models/ppo/seed2",
    "classifier-v1",
)


def episode_delays(records: list[dict]) -> dict[str, tuple[float | None, int]]:
    """Per faulty episode: (detection delay [s] or None, false alarms before the onset); per fault-free
    episode: (None, false alarms)."""
    from marine_fdi_env.benchmark.metrics import episode_outcome

    out = {}
    for r in records:
        o = episode_outcome(r)
        out[r["scenario_id"]] = (o["detection_delay_s"], int(o["false_alarms"]))
    return out


def _median(v) -> float | None:
    return float(np.median(v)) if len(v) else None


def delay_table(delays: dict[str, dict], noise: dict[str, float], faulty: set[str]) -> list[dict]:
    """Rows (agent, noise scale or "all"): detection, censored median, false alarms, paired median vs
    ``delays["reference"]`` (when it is there) over the faulty episodes both detect."""
    ref = delays.get("reference")
    rows = []
    for agent, d in delays.items():
        scales = sorted(set(noise.values()))
        for scale in [None, *scales] if len(scales) > 1 else scales:
            ids = [s for s in d if scale is None or noise[s] == scale]
            fe = [s for s in ids if s in faulty]
            det = [d[s][0] for s in fe if d[s][0] is not None]
            censored = sorted(det) + [np.inf] * (len(fe) - len(det))
            med = _median(censored) if fe else None
            row = {
                "agent": agent,
                "noise": "all" if scale is None else f"{scale:g}x",
                "faulty": len(fe),
                "detection": len(det) / len(fe) if fe else None,
                "censored_median_s": None if med is None or not np.isfinite(med) else med,
                "false_alarms": sum(d[s][1] for s in ids),
                "episodes": len(ids),
            }
            if ref is not None and agent != "reference":
                both = [s for s in fe if d[s][0] is not None and ref[s][0] is not None]
                row["pairs"] = len(both)
                row["paired_median_s"] = _median([d[s][0] for s in both])
                row["reference_paired_median_s"] = _median([ref[s][0] for s in both])
            rows.append(row)
    return rows


def _fmt(v, unit: str = "") -> str:
    return "–" if v is None else f"{v:.1f}{unit}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m studies.agents.incipient_delay", description=__doc__.splitlines()[0])
    ap.add_argument("--agents", nargs="+", default=list(DEFAULT_AGENTS), help="agent names or model folders")
    ap.add_argument("--episodes", type=int, default=256)
    ap.add_argument("--seed", type=int, default=33)
    ap.add_argument("--noise-scales", type=float, nargs="+", default=[1.0], help="sensor-noise scales drawn from")
    ap.add_argument("--json", type=Path, help="also write the rows to this file")
    args = ap.parse_args(argv)
    from marine_fdi_env.benchmark.agent_api import load_agent
    from marine_fdi_env.benchmark.evaluate import run_episodes
    from marine_fdi_env.training.datasets import dataset_scenarios

    spec = dict(INCIPIENT_SPEC, episodes=args.episodes, seed=args.seed, noise_scales=args.noise_scales)
    scs = dataset_scenarios(spec)
    noise = {s.scenario_id: s.noise_scale for s in scs}
    faulty = {s.scenario_id for s in scs if s.faults}
    delays = {}
    for a in args.agents:
        recs = run_episodes(load_agent(a), scs, {"reward": "v1"}, suite="incipient-development")
        delays[a.replace("training/models/", "")] = episode_delays(recs)
    rows = delay_table(delays, noise, faulty)
    print(
        f"{len(scs)} held-in incipient episodes (seed {args.seed}), {len(faulty)} faulty\n\n"
        "| agent | noise | faulty | detection | censored median [s] | paired median: agent / reference [s] (pairs) "
        "| false alarms |\n|---|---|---:|---:|---:|---:|---:|"
    )
    for r in rows:
        paired = "–"
        if "pairs" in r:
            paired = f"{_fmt(r['paired_median_s'])} / {_fmt(r['reference_paired_median_s'])} ({r['pairs']})"
        det = "–" if r["detection"] is None else f"{100 * r['detection']:.1f} %"
        cens = "not reached" if r["censored_median_s"] is None and r["faulty"] else _fmt(r["censored_median_s"])
        print(
            f"| {r['agent']} | {r['noise']} | {r['faulty']} | {det} | {cens} | {paired} | "
            f"{r['false_alarms']} in {r['episodes']} |"
        )
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
