"""Development check of a learned agent on held-out episodes of its own training distribution.

    python -m studies.agents.development --agent training/models/classifier/seed0
    python -m studies.agents.development --agent training/models/ppo-v1 --episodes 256 --seed 31

The noise-invariant agents were developed on these numbers, never on a frozen suite: episodes drawn
like the robust training data (every sampler profile family, fuel settings 0.3-1.0, 0-2 faults at
1-4x their limit, sensor-noise scales 0.5-1.5x) but from a seed no training or calibration spec
uses (``--seed``, default 31), scored per noise scale and overall (detection, isolation accuracy,
false alarms and false-alarm episodes among the fault-free ones).
"""

from __future__ import annotations

import argparse
import sys

from studies.paths import REPO

__all__ = ["DEV_SPEC", "development_metrics", "main"]

DEV_SPEC = {
    "preset": "default",
    "config": {
        "name": "robust-development",
        "profiles": [["constant", 1.0], ["step", 1.0], ["ramp", 1.0], ["random", 1.0], ["manoeuvring", 1.0]],
        "load_range": [0.3, 1.0],
    },
    "noise_scales": [0.5, 0.75, 1.0, 1.25, 1.5],
}


def development_metrics(agent_spec: str, episodes: int = 256, seed: int = 31) -> dict:
    """Metrics of ``agent_spec`` on ``episodes`` development episodes: ``{"all": ..., "noise 0.5x": ...}``."""
    from marine_fdi_env.benchmark.agent_api import load_agent
    from marine_fdi_env.benchmark.evaluate import run_episodes
    from marine_fdi_env.benchmark.metrics import compute_metrics
    from marine_fdi_env.training.datasets import dataset_scenarios

    scs = dataset_scenarios(dict(DEV_SPEC, episodes=episodes, seed=seed))
    recs = run_episodes(load_agent(agent_spec), scs, {"reward": "v1"}, suite="development")
    noise = {s.scenario_id: s.noise_scale for s in scs}
    out = {"all": compute_metrics(recs)}
    for ns in sorted(set(noise.values())):
        out[f"noise {ns:g}x"] = compute_metrics([r for r in recs if noise[r["scenario_id"]] == ns])
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m studies.agents.development", description=__doc__.splitlines()[0])
    ap.add_argument("--agent", required=True, help="a model folder (e.g. training/models/classifier/seed0)")
    ap.add_argument("--episodes", type=int, default=256)
    ap.add_argument("--seed", type=int, default=31, help="the development episodes' seed (no training spec uses it)")
    args = ap.parse_args(argv)
    spec = str(REPO / args.agent) if (REPO / args.agent).exists() else args.agent
    res = development_metrics(spec, args.episodes, args.seed)
    print(
        "| episodes | detection | isolation acc. | false alarms | FA episodes (fault-free) | censored median det. [s] |"
    )
    print("|---|---:|---:|---:|---:|---:|")
    for k, m in res.items():
        ff = m.get("by_class", {}).get("none") or {}
        fa_ff, n_ff = ff.get("false_alarm_episode_rate"), ff.get("n_episodes")
        cm = m["median_detection_delay_censored_s"]
        ff_text = "–" if fa_ff is None else f"{100 * fa_ff:.1f} % of {n_ff}"
        print(
            f"| {k} ({m['n_episodes']}) | {100 * (m['detection_rate'] or 0):.1f} % | "
            f"{100 * (m['isolation_accuracy'] or 0):.1f} % | {m['n_false_alarms']} ({m['false_alarm_rate']:.2f}/h) | "
            f"{ff_text} | {'–' if cm is None else f'{cm:.1f}'} |"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
