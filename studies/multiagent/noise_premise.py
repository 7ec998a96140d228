"""The thesis's decision vector against the sensor noise: how often the fixed thresholds fire on fault-free
episodes at each noise scale of the decentralised teams' training conditions (docs/multiagent.md).

    python -m studies.multiagent.noise_premise --write    # docs/data/multiagent/noise_premise.json

The thesis's adaptive thresholds bound the residuals for sensor noise within its rated bounds (noise scale
1.0).  The learned teams train and calibrate their alarm on episodes at 0.5-1.5x (the ``classifier``'s
conditions, ``training/hyperparams/decentralised.yml``), the suites single-v1, multi-v1 and nominal-v1 run at
1.0x.  This counts, on the teams' own preset episodes (never a suite), per noise scale: the fault-free
episodes whose decision vector has a fired bit by their end, which is a false alarm of
``reference-distributed`` (it declares as soon as a bit fires: ``ThesisGlobal.belief``), and the faulty
episodes with a fired bit.  Reads the training cache (``training_dataset``: exported once).
"""

from __future__ import annotations

import argparse
import json

import numpy as np
from scipy.stats import binomtest

from marine_fdi_env.baselines.reference_distributed_agent import ThesisGlobal
from marine_fdi_env.envs.observation import feature_names
from marine_fdi_env.training.datasets import dataset_scenarios, training_dataset
from marine_fdi_env.training.decentralised_run import load_decentralised_hyperparams
from studies.paths import DOCS_DATA

OUT = DOCS_DATA / "multiagent" / "noise_premise.json"


def count(spec: dict) -> dict:
    """Per noise scale: fault-free episodes, those with a fired bit at their end, the same for faulty ones,
    and ``reference-distributed``'s false alarms (a non-nominal declaration at any decision of a fault-free
    episode)."""
    arr, _, _ = training_dataset(spec, True, log=None)
    noise = np.array([sc.noise_scale for sc in dataset_scenarios(spec)])
    names = feature_names(False)
    fired = [i for i, n in enumerate(names) if n.endswith(".fired")]
    bits = arr["obs"][..., fired] >= 0.5  # (E, T, 19)
    valid, faulty = arr["valid"], arr["active"].any(axis=(1, 2))
    last = valid.sum(axis=1) - 1
    at_end = bits[np.arange(len(bits)), last].any(axis=1)
    team = ThesisGlobal()
    declared = np.array(
        [any(team.belief(b).max() >= 0.5 for b in np.unique(bits[e, valid[e]], axis=0)) for e in range(len(bits))]
    )
    out = {}
    for s in np.unique(noise):
        m = noise == s
        ff, fy = m & ~faulty, m & faulty
        fa = int(declared[ff].sum())
        out[f"{s:g}"] = {
            "fault_free_episodes": int(ff.sum()),
            "fault_free_fired_at_end": int(at_end[ff].sum()),
            "reference_distributed_false_alarms": fa,
            "false_alarm_interval": list(binomtest(fa, int(ff.sum())).proportion_ci(0.95, method="exact"))
            if ff.any()
            else None,
            "faulty_episodes": int(fy.sum()),
            "faulty_fired_at_end": int(at_end[fy].sum()),
        }
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--write", action="store_true", help=f"write {OUT.relative_to(DOCS_DATA.parent.parent)}")
    args = ap.parse_args(argv)
    hp = load_decentralised_hyperparams("decentralised")
    specs = {"alarm calibration (fault-free)": hp["calibration"], "training: nominal preset": hp["datasets"][3]}
    specs["training: default preset"] = hp["datasets"][0]
    data = {name: {"spec": spec, "by_noise_scale": count(spec)} for name, spec in specs.items()}
    for name, d in data.items():
        print(name)
        for s, r in d["by_noise_scale"].items():
            print(
                f"  noise {s}x: fault-free {r['fault_free_fired_at_end']}/{r['fault_free_episodes']} fired, "
                f"reference-distributed false alarms {r['reference_distributed_false_alarms']}; "
                f"faulty {r['faulty_fired_at_end']}/{r['faulty_episodes']} fired"
            )
    if args.write:
        OUT.parent.mkdir(parents=True, exist_ok=True)
        OUT.write_text(json.dumps(data, indent=1) + "\n")


if __name__ == "__main__":
    main()
