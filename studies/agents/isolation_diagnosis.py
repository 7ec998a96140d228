"""Where a classifier's detections and isolations go, on held-in episodes of its training distribution.

    python -m studies.agents.isolation_diagnosis training/models/classifier/seed0 \
        training/models/classifier/seed1 training/models/classifier/seed2

Never a suite: the episodes are the development episodes of :mod:`studies.agents.development` (drawn like
the robust training data from seed 31, which no training or calibration spec uses; 384 of them, the
cached export ``robust-development``), and the alarm's fault-free calibration episodes of the three
training seeds (seeds 25, 1025, 2025; each model calibrated on its own 256 only).  Per model:

* the outcome of its declaration at each faulty episode's last decision, by number of true faults:
  no alarm, ``unknown`` (the conformal rule abstains), the exact true set, one of the two true faults
  alone, anything else;
* how many exact sets the faults at or above its isolation threshold would give without the conformal
  abstention, and its per-fault recall (probability >= 0.5 at the last decision), on one- and
  two-fault episodes;
* with ``--alphas``, the same outcomes had its abstention quantile been calibrated at each of those
  levels on its own isolation-calibration episodes (seeds 26, 1026, 2026);
* its alarm threshold against the peaks of the "some fault" probability on fault-free episodes: the
  two highest on its own calibration episodes (the threshold is the highest + 0.5 log-odds), the
  highest on the other seeds' calibration episodes, and how many of those would raise a false alarm;
* the last and best validation loss of its learning curve.
"""

from __future__ import annotations

import argparse
import csv
import glob
import json
import sys
from pathlib import Path

import numpy as np

from studies.agents.development import DEV_SPEC
from studies.paths import REPO

__all__ = [
    "OUTCOMES",
    "DIAGNOSIS_SPEC",
    "ALARM_CALIBRATION_SEEDS",
    "ISOLATION_CALIBRATION_SEEDS",
    "outcome",
    "last_declarations",
    "diagnose",
    "main",
]

OUTCOMES = ("no alarm", "unknown", "exact set", "one of the two", "other")
DIAGNOSIS_SPEC = dict(DEV_SPEC, episodes=384, seed=31)
ALARM_CALIBRATION_SEEDS = (25, 1025, 2025)
ISOLATION_CALIBRATION_SEEDS = (26, 1026, 2026)


def outcome(alarm: bool, declared: np.ndarray, truth: np.ndarray) -> str:
    """The outcome (one of :data:`OUTCOMES`) of a final declaration (26 bool, empty for ``unknown``)
    against the true fault set (26 bool, non-empty)."""
    if not alarm:
        return "no alarm"
    if not declared.any():
        return "unknown"
    if np.array_equal(declared, truth):
        return "exact set"
    if truth.sum() == 2 and declared.sum() == 1 and (declared & truth).any():
        return "one of the two"
    return "other"


def last_declarations(agent, obs: np.ndarray, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(alarm (E,), declared faults (E, 26)) of ``agent`` at each episode's last valid decision, the agent
    run decision by decision on recorded observations (E, T, 115) as the benchmark runs it."""
    from marine_fdi_env.envs.hypotheses import N_HYPOTHESES, NO_FAULT, UNKNOWN

    e, t_len, _ = obs.shape
    last = valid.sum(axis=1) - 1
    out = np.zeros((e, N_HYPOTHESES), dtype=np.float32)
    agent.reset(list(range(e)))
    for t in range(t_len):
        b = agent.act(obs[:, t], {})
        out[last == t] = b[last == t]
    alarm = out[:, UNKNOWN] > 0.5
    faults = np.delete(out, [NO_FAULT, UNKNOWN], axis=1) > 0.5
    return alarm | faults.any(axis=1), faults


def _peaks(agent, obs: np.ndarray, valid: np.ndarray) -> np.ndarray:
    from marine_fdi_env.training.classifier import episode_scores
    from marine_fdi_env.training.features import transform_episodes

    p = episode_scores(agent.model, transform_episodes(agent.features, obs))
    return p, np.where(valid, p[..., -1], 0.0).max(axis=1)


def _logit(p) -> np.ndarray:
    p = np.clip(np.asarray(p, dtype=float), 1e-12, 1 - 1e-12)
    return np.log(p / (1 - p))


def _calibration_export(seed: int, kind: str = "alarm", episodes: int = 256) -> dict:
    from marine_fdi_env.training.classifier import load_dataset

    found = sorted(glob.glob(str(REPO / "training" / ".cache" / f"robust-{kind}-calibration_{episodes}_{seed}_*")))
    if not found:
        raise FileNotFoundError(
            f"no cached {kind}-calibration export of seed {seed} in training/.cache "
            "(made by marine-fdi train --algo classifier --hyperparams robust)"
        )
    return load_dataset(found[-1])


def _abstention_levels(
    agent, alarm: np.ndarray, p_last: np.ndarray, truth: np.ndarray, calibration: dict, alphas
) -> dict:
    """Outcomes of the final declarations (alarm (E,), fault probabilities (E, 26), true sets (E, 26)) had
    the model's abstention quantile been calibrated at each level of ``alphas`` on ``calibration`` (its
    isolation-calibration arrays); the alarm is the model's own."""
    from marine_fdi_env.training.classifier import calibrate_isolation, conformal_sets

    cal_probs = _peaks(agent, calibration["obs"], calibration["valid"])[0]
    out = {}
    for alpha in alphas:
        q = calibrate_isolation(cal_probs, calibration["active"], calibration["valid"], alpha)["quantile"]
        declared = conformal_sets(p_last, agent.isolation_threshold, q)
        row: dict = {"quantile": q}
        for k in (1, 2):
            counts = dict.fromkeys(OUTCOMES, 0)
            for i in np.flatnonzero(truth.sum(axis=1) == k):
                counts[outcome(bool(alarm[i]), declared[i], truth[i])] += 1
            row[f"{k} fault"] = counts
        out[alpha] = row
    return out


def diagnose(
    model_dir: str | Path,
    data: dict,
    calibration: dict[int, dict],
    isolation_calibration: dict[int, dict] | None = None,
    alphas=(),
) -> dict:
    """The module docstring's numbers for one model on the development arrays ``data`` and the alarm
    calibration arrays ``calibration`` (keyed by dataset seed); with ``alphas``, the outcomes at those
    abstention levels calibrated on its own isolation-calibration arrays in ``isolation_calibration`` (keyed
    by dataset seed)."""
    from marine_fdi_env.benchmark.agent_api import load_agent

    agent = load_agent(str(model_dir))
    obs, active, valid = data["obs"], data["active"], data["valid"]
    rows = np.arange(len(obs))
    last = valid.sum(axis=1) - 1
    truth = active[rows, last]
    n_true = truth.sum(axis=1)
    alarm, declared = last_declarations(agent, obs, valid)
    probs, _ = _peaks(agent, obs, valid)
    p_last = probs[rows, last, :-1]
    res: dict = {
        "model": str(model_dir),
        "alarm_threshold": agent.alarm_threshold,
        "quantile": agent.conformal_quantile,
        "training_seed": agent.training_seed,
    }
    for k in (1, 2):
        idx = np.flatnonzero(n_true == k)
        counts = dict.fromkeys(OUTCOMES, 0)
        for i in idx:
            counts[outcome(bool(alarm[i]), declared[i], truth[i])] += 1
        best = p_last[idx] >= agent.isolation_threshold
        res[f"{k} fault"] = {
            "episodes": int(len(idx)),
            "outcomes": counts,
            # the faults at or above the isolation threshold, declared without the conformal abstention
            "exact_without_abstention": int(np.sum(alarm[idx] & (best == truth[idx]).all(axis=1))),
            "recall": float(np.mean(p_last[idx][truth[idx]] >= 0.5)),
        }
    own_seed = ALARM_CALIBRATION_SEEDS[int(agent.training_seed)]
    own = np.sort(_peaks(agent, calibration[own_seed]["obs"], calibration[own_seed]["valid"])[1])[::-1]
    other = np.concatenate([_peaks(agent, c["obs"], c["valid"])[1] for s, c in calibration.items() if s != own_seed])
    res["alarm"] = {
        "threshold_logit": float(_logit(agent.alarm_threshold)),
        "own_top2_logit": [float(x) for x in _logit(own[:2])],
        "other_max_logit": float(_logit(other.max())),
        "other_false_alarms": int((other >= agent.alarm_threshold).sum()),
        "other_episodes": int(len(other)),
    }
    if alphas:
        own = isolation_calibration[ISOLATION_CALIBRATION_SEEDS[int(agent.training_seed)]]
        res["abstention_levels"] = _abstention_levels(agent, alarm, p_last, truth, own, alphas)
    with open(Path(model_dir) / "learning_curve.csv") as f:
        val = [float(r["val_loss"]) for r in csv.DictReader(f)]
    res["val_loss"] = {"epochs": len(val), "last": val[-1], "best": min(val), "best_epoch": int(np.argmin(val)) + 1}
    return res


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m studies.agents.isolation_diagnosis", description=__doc__.splitlines()[0]
    )
    ap.add_argument("models", nargs="+", help="model folders (e.g. training/models/classifier/seed1)")
    ap.add_argument(
        "--alphas", type=float, nargs="*", default=[], help="abstention levels to compare (e.g. 0.2 0.1 0.05)"
    )
    ap.add_argument("--json", type=Path, help="also write the numbers to this file")
    args = ap.parse_args(argv)
    from marine_fdi_env.training.datasets import _dataset

    data, _, _ = _dataset(DIAGNOSIS_SPEC, True, print)
    calibration = {s: _calibration_export(s) for s in ALARM_CALIBRATION_SEEDS}
    isolation = None
    if args.alphas:
        isolation = {s: _calibration_export(s, "isolation", 384) for s in ISOLATION_CALIBRATION_SEEDS}
    results = [
        diagnose(REPO / m if (REPO / m).exists() else m, data, calibration, isolation, args.alphas) for m in args.models
    ]
    print(
        "| model | faults (episodes) | " + " | ".join(OUTCOMES) + " | exact set without abstaining | per-fault recall |"
    )
    print("|---|---|" + "---:|" * (len(OUTCOMES) + 2))
    for r in results:
        for k in (1, 2):
            c = r[f"{k} fault"]
            cells = " | ".join(str(c["outcomes"][o]) for o in OUTCOMES)
            print(
                f"| {Path(r['model']).name} | {k} ({c['episodes']}) | {cells} | {c['exact_without_abstention']} | "
                f"{100 * c['recall']:.1f} % |"
            )
    print()
    print(
        "| model | alarm threshold [log-odds] | own calibration: two highest peaks | other seeds' calibration: "
        "highest peak | false alarms there | val. loss last / best (epoch) |"
    )
    print("|---|---:|---:|---:|---:|---:|")
    for r in results:
        a, v = r["alarm"], r["val_loss"]
        print(
            f"| {Path(r['model']).name} | {a['threshold_logit']:.2f} | {a['own_top2_logit'][0]:.2f}, "
            f"{a['own_top2_logit'][1]:.2f} | {a['other_max_logit']:.2f} | {a['other_false_alarms']} of "
            f"{a['other_episodes']} | {v['last']:.3f} / {v['best']:.3f} ({v['best_epoch']} of {v['epochs']}) |"
        )
    if args.alphas:
        print()
        print("| model | alpha | quantile | faults | unknown | exact set | one of the two | other |")
        print("|---|---:|---:|---|---:|---:|---:|---:|")
        for m, r in zip(args.models, results, strict=True):
            for a, v in r["abstention_levels"].items():
                for k in (1, 2):
                    c = v[f"{k} fault"]
                    print(
                        f"| {Path(m).name} | {a:g} | {v['quantile']:.3f} | {k} | {c['unknown']} | {c['exact set']} | "
                        f"{c['one of the two']} | {c['other']} |"
                    )
    if args.json:
        args.json.write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
