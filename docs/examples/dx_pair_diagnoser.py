"""A small external diagnoser in the style of the LiU-ICE / DX'25 kits (docs/raw_data.md).

    python docs/examples/dx_pair_diagnoser.py RAW_DIR PRED_DIR

It knows nothing of this package: it reads ``RAW_DIR/manifest.json`` and each scenario's
``data/*.csv`` one sample at a time (``Input(sample)`` returns ``detection, isolation`` like the
kits' ``DiagnosisSystemClass``) and writes ``PRED_DIR/output_<data file>`` with the kits' row
format.  Score it with ``marine-fdi score-raw --suite NAME --predictions PRED_DIR --data RAW_DIR``.

Method: the engine has nine pairs of redundant sensors.  For each pair the difference of the
twins is pure sensor noise when both are healthy: the noise is uniform within +-b (b published in
the manifest, thesis table 6.3), so the difference has standard deviation b*sqrt(2/3) and its
mean over W samples b*sqrt(2/3)/sqrt(W).  The pair alarms (and stays alarmed) when that mean
leaves +-Z of its standard deviations.  Which twin is faulty: the one that moved further from its
slow baseline (an EWMA frozen at the alarm), since a change of the engine's state moves both.
Nothing is fitted to any suite; it cannot see process faults or S3.5 (no twin).
"""

from __future__ import annotations

import csv
import json
import math
import sys
import time
from collections import deque
from pathlib import Path

PAIRS = [
    ("S1.1", "S1.2"),
    ("S2.1", "S2.2"),
    ("S2.3", "S2.4"),
    ("S2.5", "S2.6"),
    ("S3.1", "S3.2"),
    ("S3.3", "S3.4"),
    ("S4.1", "S4.2"),
    ("S4.3", "S4.4"),
    ("S4.5", "S4.6"),
]
W = 100  # samples in the moving mean (1 s at 100 Hz)
Z = 6.0  # standard deviations of that mean: about 2e-9 per independent window fault-free
TAU = 3000  # samples of the slow baseline (30 s)


class PairDiagnoser:
    def __init__(self, noise_bounds: dict[str, float], fault_ids: list[str]):
        self.bound = noise_bounds
        self.fault_ids = fault_ids

    def Initialize(self) -> None:
        self.window = {p: deque(maxlen=W) for p in PAIRS}
        self.sum = {p: 0.0 for p in PAIRS}
        self.alarmed: dict[tuple, str] = {}  # pair -> the twin judged faulty
        self.slow: dict[str, float] = {}  # per sensor: slow baseline
        self.recent = {s: deque(maxlen=W) for p in PAIRS for s in p}

    def Input(self, sample: dict[str, float]) -> tuple[int, list[float]]:
        for s in self.recent:
            x = sample[s]
            self.recent[s].append(x)
            if not any(s in p for p in self.alarmed):
                self.slow[s] = x if s not in self.slow else self.slow[s] + (x - self.slow[s]) / TAU
        for p in PAIRS:
            if p in self.alarmed:
                continue
            d = sample[p[0]] - sample[p[1]]
            win = self.window[p]
            if len(win) == W:
                self.sum[p] -= win[0]
            win.append(d)
            self.sum[p] += d
            sigma = self.bound[p[0]] * math.sqrt(2.0 / 3.0) / math.sqrt(W)
            if len(win) == W and abs(self.sum[p] / W) > Z * sigma:
                moved = [abs(sum(self.recent[s]) / len(self.recent[s]) - self.slow[s]) / self.bound[s] for s in p]
                self.alarmed[p] = p[0] if moved[0] >= moved[1] else p[1]
        rank = [0.0] * (len(self.fault_ids) + 1)  # the 26 faults, then unknown
        if not self.alarmed:
            return 0, rank
        for p, faulty in self.alarmed.items():
            twin = p[1] if faulty == p[0] else p[0]
            rank[self.fault_ids.index(faulty)] += 0.8
            rank[self.fault_ids.index(twin)] += 0.2
        total = sum(rank)
        return 1, [r / total for r in rank]


def main(raw_dir: str, pred_dir: str) -> int:
    raw, pred = Path(raw_dir), Path(pred_dir)
    pred.mkdir(exist_ok=True)
    manifest = json.loads((raw / "manifest.json").read_text())
    bounds = {c["name"]: c["noise_bound"] for c in manifest["data_columns"] if "noise_bound" in c}
    header = manifest["output_columns"]
    diagnoser = PairDiagnoser(bounds, manifest["fault_ids"])
    for entry in manifest["scenarios"]:
        diagnoser.Initialize()
        with open(raw / entry["data_file"], newline="") as fin, open(pred / entry["output_file"], "w") as fout:
            reader = csv.reader(fin)
            names = next(reader)
            fout.write(",".join(header) + "\n")
            for row in reader:
                sample = dict(zip(names, map(float, row)))
                t0 = time.perf_counter()
                detection, isolation = diagnoser.Input(sample)
                elapsed = time.perf_counter() - t0
                fout.write(
                    "%f,%f,%d," % (sample["time"], elapsed, detection) + ",".join("%f" % r for r in isolation) + "\n"
                )
    print(f"wrote {len(manifest['scenarios'])} output files to {pred}")
    return 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:3]))
