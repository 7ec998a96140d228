"""What message ``reference`` itself would need: its evidence, sent by the locals, on the budget axis.

The ``reference`` agent's decision (the sized cells, :mod:`marine_fdi_env.diagnosis.sized_decision`) at a
decision time t reads, per module m: whether it has fired (D^(l), eq. 5.19), its first detection time
T_D(m) and its running peak ratio q_m = max |r|/threshold, which only matters through the size bands it
selects (``q_m`` against the measured thresholds of m: :meth:`SizedCells.bands`).  So the evidence a
local must send per module and decision is

* the decision bit (1 bit),
* T_D(m) to the sample: the sample of the period in which the module first fired (ceil(log2(B)) bits,
  B = 100 samples per period; the global knows the period from the bit's first arrival),
* the index of q_m among the sorted thresholds of m's band boundaries (ceil(log2(L_m + 1)) bits, L_m
  distinct boundaries),

a fixed-size message of :func:`evidence_bits` bits per decision.  :func:`check` verifies on the suites'
episodes that this evidence suffices: at every decision the global diagnoses recomputed from it alone
(sized conflicts and minimal hitting sets, :func:`sized_conflicts`) equal the reference diagnoser's.

    python -m studies.multiagent.reference_message --suites thesis-v1 single-v1 multi-v1 --write
"""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np

from marine_fdi_env.benchmark.suites import SUITE_NAMES, load_suite
from marine_fdi_env.diagnosis.decision import minimal_hitting_sets
from marine_fdi_env.diagnosis.modules import MODULE_IDS
from marine_fdi_env.diagnosis.sized_cells import load_sized_cells
from marine_fdi_env.diagnosis.sized_decision import sized_conflicts
from marine_fdi_env.diagnosis.structure import fault_signature_matrix
from marine_fdi_env.engine.faults import FAULT_IDS
from marine_fdi_env.envs.core import EpisodeBatch
from marine_fdi_env.multiagent.budgets import BUDGETS
from studies.paths import REPO

OUT = REPO / "docs" / "data" / "multiagent" / "reference_message.json"
PERIOD_SAMPLES = 100  # decision period / sample time (1 s / 0.01 s)


def boundaries() -> list[np.ndarray]:
    """Per module, the sorted distinct finite peak thresholds of its supported faults' size bands."""
    cells = load_sized_cells()
    thr, sup = cells.threshold, fault_signature_matrix()[0]
    out = []
    for m in range(len(MODULE_IDS)):
        v = thr[:, m, :][:, sup[m]]
        out.append(np.unique(v[np.isfinite(v)]))
    return out


def evidence_bits() -> dict:
    """Bits per decision of the reference's evidence in fixed-size messages (module docstring), per local."""
    levels = boundaries()
    t_bits = math.ceil(math.log2(PERIOD_SAMPLES))
    per_module = [1 + t_bits + math.ceil(math.log2(len(b) + 1)) for b in levels]
    float_format = len(MODULE_IDS) * (1 + 2 * 32)
    return {
        "per_module_bits": dict(zip(MODULE_IDS, per_module)),
        "quantised_bits_per_decision": int(sum(per_module)),
        "float_bits_per_decision": float_format,
        "t_d_bits": t_bits,
        "levels": {m: int(len(b)) for m, b in zip(MODULE_IDS, levels)},
        "named_budgets": {k: b.bits_per_decision for k, b in BUDGETS.items()},
    }


def quantised_peaks(peaks: np.ndarray, levels: list[np.ndarray]) -> np.ndarray:
    """Each module's running peak as the global rebuilds it from the level index sent: just above the
    largest boundary it has passed (0 below all): the same size bands as the exact peak."""
    out = np.zeros_like(peaks)
    for m, b in enumerate(levels):
        k = np.searchsorted(b, peaks[:, m], side="left")  # boundaries strictly below the peak
        out[:, m] = np.where(k > 0, np.nextafter(b[np.maximum(k - 1, 0)], np.inf), 0.0)
    return out


def check(suite: str, batch: int = 64) -> dict:
    """Decisions of ``suite`` at which the diagnoses rebuilt from the evidence equal the reference's."""
    cells, support, levels = load_sized_cells(), fault_signature_matrix()[0], boundaries()
    scs = load_suite(suite).scenarios
    agree = total = detected = 0
    mismatched: list[str] = []
    for a in range(0, len(scs), batch):
        part = scs[a : a + batch]
        scales = sorted({s.noise_scale for s in part})
        for scale in scales:
            group = [s for s in part if s.noise_scale == scale]
            b = EpisodeBatch(len(group), reward=None, noise_scale=scale)
            b.start(range(len(group)), group)
            b.advance()
            live = np.ones(len(group), dtype=bool)
            while live.any():
                slots = np.flatnonzero(live)
                det, diag = b.declarations("reference", "sized", slots)
                fv = b.diag.first_violation[slots]
                fired = ~np.isnan(fv)
                q = quantised_peaks(b.diag.peak_run[slots], levels)
                for j, i in enumerate(slots):
                    total += 1
                    if not fired[j].any():
                        agree += int(not det[j])
                        continue
                    detected += 1
                    conf, _ = sized_conflicts(
                        fired[j], np.where(fired[j], fv[j], np.nan), q[j], float(b.t[i]), cells, support
                    )
                    sets = [{FAULT_IDS[k] for k in range(len(FAULT_IDS)) if c >> k & 1} for c in conf]
                    mine = {tuple(sorted(d)) for d in minimal_hitting_sets(sets, max_cardinality=2)}
                    ok = mine == {tuple(d) for d in diag[j]}
                    agree += int(ok)
                    if not ok and len(mismatched) < 5:
                        mismatched.append(f"{group[i].scenario_id} t={b.t[i]:.0f}: {sorted(mine)} vs {diag[j]}")
                ended = slots[b.failed[slots] | (b.t[slots] >= b.durations[slots] - 1e-9)]
                live[ended] = False
                going = np.flatnonzero(live)
                if len(going):
                    for f in b.advance(going):
                        live[f] = False
    return {"decisions": total, "detected_decisions": detected, "agree": agree, "examples": mismatched}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--suites", nargs="*", default=list(SUITE_NAMES))
    ap.add_argument("--write", action="store_true", help=f"write {OUT.relative_to(REPO)}")
    args = ap.parse_args(argv)
    out = {"bits": evidence_bits(), "checks": {}}
    c0 = time.process_time()
    for s in args.suites:
        out["checks"][s] = r = check(s)
        print(f"{s}: {r['agree']} of {r['decisions']} decisions agree ({r['detected_decisions']} after detection)")
        for e in r["examples"]:
            print("   ", e)
    out["cpu_s"] = round(time.process_time() - c0, 1)
    print(json.dumps(out["bits"], indent=1)[:600])
    if args.write:
        OUT.parent.mkdir(parents=True, exist_ok=True)
        OUT.write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
