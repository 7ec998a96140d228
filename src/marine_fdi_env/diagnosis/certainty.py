"""Which cells of the fault signature matrix *surely* fire: the thesis's '1' versus '*'.

The structure (:mod:`marine_fdi_env.diagnosis.structure`) tells which faults *can* violate each
ARR.  Exoneration ("a module that has not fired clears the faults it would surely have seen") also
needs the cells that fire for sure.  The thesis marks them '1' in tables 6.5-6.8 from its
simulations; we measure them the same way, reproducibly: every single fault at its default
magnitude (tables 6.3, 6.4), ``n_seeds`` noise seeds, a constant and a manoeuvring profile, 300 s
after onset; a cell is sure when the module fired in every run.  The result is shipped as
``data/diagnosis/sure_cells.json`` with the settings that produced it; regenerate with

    python -m marine_fdi_env.diagnosis.certainty --seeds 50

The cells are valid for faults at least as large as those defaults; a smaller fault can leave a
"sure" module silent and be exonerated by mistake (the same limitation as the thesis's tables).
"""

from __future__ import annotations

import argparse
import json
import sys
from functools import lru_cache
from importlib import resources
from pathlib import Path

import numpy as np

from ..faults import FAULT_IDS, PROCESS_FAULT_DEFAULTS, FaultSpec
from .modules import MODULE_IDS
from .structure import fault_signature_matrix

__all__ = ["sure_cells", "settle_times", "grace_times", "measure_sure_cells", "SURE_CELLS_FILE"]

SURE_CELLS_FILE = "sure_cells.json"
SENSOR_ONSET_S = 30.0
PROFILES = ("constant", "manoeuvring")


def _onset(fault_id: str) -> float:
    return PROCESS_FAULT_DEFAULTS[fault_id].onset_s if fault_id in PROCESS_FAULT_DEFAULTS else SENSOR_ONSET_S


def measure_sure_cells(n_seeds: int = 50, duration_s: float = 300.0, params: str = "thesis-12v28",
                       first_seed: int = 1000, progress: bool = True) -> dict:
    """Fire counts of every (module, fault) cell over single-fault runs; see module docstring."""
    from .kpis import diagnose_batch

    counts = np.zeros((len(MODULE_IDS), len(FAULT_IDS)), dtype=int)
    times = [[[] for _ in FAULT_IDS] for _ in MODULE_IDS]  # detection delays per cell
    runs = 0
    iterator = PROFILES
    if progress:
        from tqdm import tqdm

        iterator = tqdm(PROFILES, desc="sure cells", unit="profile")
    for prof in iterator:
        seeds = [first_seed + s * len(FAULT_IDS) + j for s in range(n_seeds) for j in range(len(FAULT_IDS))]
        sched = [[FaultSpec(f, _onset(f))] for _ in range(n_seeds) for f in FAULT_IDS]
        # module firing times do not depend on the decision logic: plain consistency, no sure cells
        reps = diagnose_batch(sched, seeds, prof, duration_s, exoneration="none", params=params)
        for k, rep in enumerate(reps):
            j = k % len(FAULT_IDS)
            for i, m in enumerate(MODULE_IDS):
                t = rep["module_detection_times_s"][m]
                if t is not None:
                    counts[i, j] += 1
                    times[i][j].append(float(t) - _onset(FAULT_IDS[j]))
        runs += n_seeds
    # spread of the firing times of the sure modules of each fault, per run: the settle time the
    # temporal check of the diagnosis must allow
    spread = []
    lag = np.zeros((len(MODULE_IDS), len(FAULT_IDS)))  # max delay of a sure module after the first one
    for j in range(len(FAULT_IDS)):
        sure = [i for i in range(len(MODULE_IDS)) if counts[i, j] == runs]
        if len(sure) < 2:
            spread.append(0.0)
            continue
        t = np.array([times[i][j] for i in sure])  # (sure modules, runs)
        spread.append(float((t.max(axis=0) - t.min(axis=0)).max()))
        lag[sure, j] = (t - t.min(axis=0)).max(axis=1)
    return {
        "module_ids": list(MODULE_IDS),
        "fault_ids": list(FAULT_IDS),
        "runs_per_fault": runs,
        "fire_counts": counts.tolist(),
        "sure_spread_s": spread,
        "sure_lag_s": lag.tolist(),
        "settings": {"n_seeds": n_seeds, "profiles": list(PROFILES), "duration_s": duration_s, "params": params,
                     "first_seed": first_seed, "sensor_onset_s": SENSOR_ONSET_S,
                     "magnitudes": "defaults of tables 6.3 (sensor offsets) and 6.4 (process faults)"},
        "command": "python -m marine_fdi_env.diagnosis.certainty --seeds %d" % n_seeds,
    }


@lru_cache(maxsize=1)
def _data() -> dict:
    path = resources.files("marine_fdi_env") / "data" / "diagnosis" / SURE_CELLS_FILE
    data = json.loads(path.read_text())
    if data["module_ids"] != list(MODULE_IDS) or data["fault_ids"] != list(FAULT_IDS):
        raise ValueError(f"{SURE_CELLS_FILE} does not match the current module or fault ids; regenerate it")
    return data


# An abrupt sensor fault surely fires a module only if it does so promptly: a module that fired in
# every run but up to minutes after the others did so by chance of the noise (e.g. M3.3 for S2.1,
# which may as well stay silent in a shorter run).
SENSOR_MAX_LAG_S = 30.0


def sure_cells() -> np.ndarray:
    """Bool (19, 26): cells that fired in every measured run, within the structural support; for
    sensor faults also within ``SENSOR_MAX_LAG_S`` of the fault's first sure module in every run."""
    data = _data()
    counts = np.asarray(data["fire_counts"])
    support, _, _ = fault_signature_matrix()
    sure = (counts == data["runs_per_fault"]) & support
    lag = np.asarray(data.get("sure_lag_s", np.zeros(sure.shape)), dtype=float)
    is_sensor = np.array([f not in PROCESS_FAULT_DEFAULTS for f in FAULT_IDS])
    return sure & ~(is_sensor[None, :] & (lag > SENSOR_MAX_LAG_S))


def grace_times(margin_s: float = 2.0, factor: float = 1.5) -> np.ndarray:
    """Grace periods (19, 26): how long after a fault's first fired module a silent sure module is
    still awaited before it exonerates the fault (its measured largest lag behind the fault's first
    sure module x ``factor`` + ``margin_s``)."""
    data = _data()
    lag = np.asarray(data.get("sure_lag_s", np.zeros((len(MODULE_IDS), len(FAULT_IDS)))), dtype=float)
    return factor * lag + margin_s


def settle_times(margin_s: float = 2.0, factor: float = 1.5) -> np.ndarray:
    """Per-fault settle times (26,) for the temporal check: the largest spread measured between the
    first and the last of a fault's sure modules, times ``factor`` plus ``margin_s``; process faults
    (incipient, their spread grows with the fault's size) get no temporal constraint (inf)."""
    spread = np.asarray(_data().get("sure_spread_s", [0.0] * len(FAULT_IDS)), dtype=float)
    out = factor * spread + margin_s
    for j, f in enumerate(FAULT_IDS):
        if f in PROCESS_FAULT_DEFAULTS:
            out[j] = np.inf
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="Measure which signature cells surely fire and write the data file.")
    ap.add_argument("--seeds", type=int, default=50, help="noise seeds per profile (default 50)")
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[1] / "data" / "diagnosis"
                    / SURE_CELLS_FILE)
    args = ap.parse_args(argv)
    if args.seeds < 1:
        ap.error("--seeds must be >= 1")
    data = measure_sure_cells(args.seeds)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(data, indent=1) + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
