"""Calibration of the ``sequential`` diagnoser (:mod:`marine_fdi_env.diagnosis.sequential`):

    python -m studies.diagnosis.sequential_calibration record --set calibration --hours 100
    python -m studies.diagnosis.sequential_calibration record --set validation --hours 200
    python -m studies.diagnosis.sequential_calibration fit        # -> data/diagnosis/sequential.json
    python -m studies.diagnosis.sequential_calibration check      # false alarms on the validation set

``record`` simulates fault-free engines with the reference diagnoser's residual generators and
keeps, per run, the 1 s block means of the 19 residuals and of the fuel setting, and the first
worst-case violation of every module (``--out-dir``, default ``results/sequential_calibration``,
one npz per set; not shipped: about 30 MB per 100 h).  Runs draw their profile uniformly from the
five families (constant, step, ramp, random, manoeuvring) with fuel settings in [0.3, 1.1] and
300 s length; the calibration and validation sets use disjoint seeds (entropy 7e9 + i and
8e9 + i; the suites and the KPI commands use seeds below 1e8).

``fit`` (calibration set only): per module the mean and spread of the block means at fuel-setting
nodes 0.3, 0.4, ..., 1.1 (blocks within ±0.05 of a node, after the warm-up), the pause region
(M3.1-M3.4 where the measured x3/x4 exceeds ``--r-max``, see
:mod:`~marine_fdi_env.diagnosis.sequential`), the CUSUM reference
k, and the threshold h: the per-run maximum of max(S+, S-) over the calibration runs has an
exponential tail (the CUSUM of increments with negative drift -k, Siegmund's approximation); we
fit it on the largest 10 % of the runs and take the h at which a run exceeds it with probability
p* = (1 false alarm / 200 h) x (300 s / 3600 s) / 19 modules / 3 (a factor 3 of margin).
The receiver test (:mod:`~marine_fdi_env.diagnosis.incipient_glr`, the GLR for a (t - τ)² shift of
M3.1 + M3.2 pooled, paused where those tests pause and where the transient gate closes) gets its
threshold the same way from the per-run peaks of its statistic, at the same p* (it is a 20th test:
the budget spent rises by 1/19, still a factor 2.85 below the target), never below 1.2x the
largest calibration peak.
``check`` (validation set only): runs the same tests (and the worst-case violations, which the
sequential decision ORs in) and counts the runs with an alarm (the receiver test's without its
common-shift condition, which can only remove alarms).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from marine_fdi_env.diagnosis.agent import ReferenceDiagnoser
from marine_fdi_env.diagnosis.incipient_glr import (
    GATE_DELTA,
    GATE_TAU_S,
    ORDER,
    WINDOW_BLOCKS,
    glr_polynomial,
    transient_gate,
)
from marine_fdi_env.diagnosis.modules import MODULE_IDS
from marine_fdi_env.diagnosis.sequential import CALIBRATION_FILE, Z_CAP, pressure_ratio
from marine_fdi_env.engine.simulator import Simulator
from studies.paths import PACKAGE_DATA

__all__ = [
    "profile_for",
    "record",
    "fit",
    "cusum_offline",
    "check",
    "normalise_blocks",
    "tail_threshold",
    "warm_blocks",
    "pooled_pair",
    "receiver_peaks",
    "glr_threshold",
    "SETS",
    "RECEIVER_MODULES",
]

N_MODULES = len(MODULE_IDS)
PARAMS = "thesis-12v28"
DURATION_S = 300.0
BLOCK_S = 1.0
FAMILIES = ("constant", "step", "ramp", "random", "manoeuvring")
LOAD_RANGE = (0.3, 1.1)
SETS = {"calibration": 7_000_000_000, "validation": 8_000_000_000}
U_NODES = tuple(round(0.3 + 0.1 * i, 1) for i in range(9))
NODE_HALF_WIDTH = 0.05
K_DEFAULT = 0.5
# observers' start-up transients: the charge-air observer (gain 0.38/s, table 6.1) settles in about
# 15 s, the others within a few seconds (measured: calibration report "warmup")
WARMUP_S = {m: (20.0 if m in ("M4.1", "M4.2") else 5.0) for m in MODULE_IDS}
# pressure ratio x3/x4 above which a test pauses (see the sequential module's docstring): the
# receiver and turbine-inlet residuals near x3/x4 = 1
PAUSED_MODULES = ("M3.1", "M3.2", "M3.3", "M3.4")
RECEIVER_MODULES = ("M3.1", "M3.2")
R_MAX_DEFAULT = 0.9
FA_TARGET_PER_H = 1.0 / 200.0
FA_MARGIN = 3.0
TAIL_FRACTION = 0.10
BATCH = 256


def profile_for(entropy: int, duration_s: float = DURATION_S) -> tuple[str, int]:
    """(profile spec, noise seed) of calibration run ``entropy``: one of the five families, uniform,
    with its parameters (as the environment's scenario sampler draws them, fuel settings in
    ``LOAD_RANGE``)."""
    r = np.random.default_rng(int(entropy))
    fam = FAMILIES[int(r.integers(0, len(FAMILIES)))]
    lo, hi = LOAD_RANGE
    D = duration_s
    u0, u1 = (round(float(x), 4) for x in r.uniform(lo, hi, size=2))
    if fam == "constant":
        spec = f"constant:u0={u0}"
    elif fam == "step":
        spec = f"step:u0={u0},u1={u1},t={round(float(r.uniform(0.1, 0.9) * D), 2)}"
    elif fam == "ramp":
        a, b = sorted(float(x) for x in r.uniform(0.05, 0.95, size=2) * D)
        spec = f"ramp:u0={u0},u1={u1},t0={round(a, 2)},t1={round(max(b, a + 10.0), 2)}"
    elif fam == "random":
        spec = f"random:seed={int(r.integers(0, 2**31))},u_min={lo},u_max={hi}"
    else:
        spec = f"manoeuvring:scale={round(float(r.uniform(0.9, 1.05)), 4)}"
    return spec, int(r.integers(0, 2**62))


def record(
    n_runs: int,
    entropy0: int,
    duration_s: float = DURATION_S,
    faults=None,
    profiles=None,
    seeds=None,
    progress: bool = True,
) -> dict:
    """Block means of the residuals of ``n_runs`` runs (see module docstring).  ``faults``: None
    (fault-free) or one schedule per run; ``profiles``/``seeds``: override the drawn ones."""
    drawn = [profile_for(entropy0 + i, duration_s) for i in range(n_runs)]
    profiles = [p for p, _ in drawn] if profiles is None else list(profiles)
    seeds = [s for _, s in drawn] if seeds is None else list(seeds)
    faults = [[] for _ in range(n_runs)] if faults is None else list(faults)
    block = int(round(BLOCK_S / 0.01))
    nb = int(round(duration_s / BLOCK_S))
    BM = np.empty((n_runs, nb, N_MODULES), dtype=np.float32)
    UB = np.empty((n_runs, nb), dtype=np.float32)
    RB = np.empty((n_runs, nb), dtype=np.float32)
    first = np.full((n_runs, N_MODULES), np.nan)
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=n_runs, desc="recording", unit="run", file=sys.stderr)
    for a in range(0, n_runs, BATCH):
        b = min(n_runs, a + BATCH)
        sim = Simulator(PARAMS, b - a, seeds=seeds[a:b], faults=faults[a:b], profiles=profiles[a:b])
        agent = ReferenceDiagnoser(PARAMS, n_engines=b - a, dt=sim.dt, exoneration="none")
        agent.observe(sim.y[:, None, :], sim.u[:, None])  # the t = 0 reading starts the observers
        # blocks t = 0.01 .. 1.00 s, 1.01 .. 2.00 s, ...: as in the environment, whose first
        # decision period starts after the t = 0 reading
        for j in range(nb):
            blk = sim.advance(block)
            out = agent.observe(blk.measurements, blk.u)
            BM[a:b, j] = out.residuals.mean(axis=1)
            UB[a:b, j] = blk.u.mean(axis=1)
            RB[a:b, j] = pressure_ratio(blk.measurements).mean(axis=1)
        first[a:b] = agent.first_violation
        if bar is not None:
            bar.update(b - a)
    if bar is not None:
        bar.close()
    return {
        "block_means": BM,
        "u": UB,
        "ratio": RB,
        "first_violation": first,
        "profiles": np.array(profiles),
        "seeds": np.array(seeds, dtype=np.int64),
        "entropy0": entropy0,
        "duration_s": duration_s,
    }


def warm_blocks(warmup_s) -> np.ndarray:
    return np.array([int(math.ceil(w / BLOCK_S - 1e-9)) for w in warmup_s])


def normalise_blocks(BM, UB, nodes, mean, scale):
    """z (runs, blocks, 19) of block means with the interpolated normalisation (as the online kernel)."""
    mu = np.stack([np.interp(UB, nodes, mean[m]) for m in range(N_MODULES)], axis=-1)
    sc = np.stack([np.interp(UB, nodes, scale[m]) for m in range(N_MODULES)], axis=-1)
    z = (BM - mu) / sc
    return np.clip(np.nan_to_num(z, nan=0.0), -Z_CAP, Z_CAP)


def pooled_pair(z, RB, warm, r_max, modules=RECEIVER_MODULES):
    """(p, paused) (runs, blocks): the normalised sum of the ``modules``' block z (runs, blocks, 19),
    0 where their tests pause (warm-up ``warm`` (19,) blocks, pressure ratio RB above r_max (19,))."""
    idx = [MODULE_IDS.index(m) for m in modules]
    paused = np.asarray(RB, dtype=np.float64) > max(float(r_max[i]) for i in idx)
    paused[:, : max(int(warm[i]) for i in idx)] = True
    p = np.where(paused, 0.0, z[:, :, idx].sum(axis=2) / math.sqrt(len(idx)))
    return p, paused


def receiver_peaks(
    z,
    UB,
    RB,
    warm,
    r_max,
    order=ORDER,
    window=WINDOW_BLOCKS,
    gate_tau_s=GATE_TAU_S,
    gate_delta=GATE_DELTA,
    modules=RECEIVER_MODULES,
) -> np.ndarray:
    """(runs,) largest receiver-test statistic of each recorded run (pause region and transient gate
    as online; without the common-shift condition); ``modules``: the chains pooled (one: that chain alone)."""
    p, paused = pooled_pair(z, RB, warm, r_max, modules)
    paused = paused | transient_gate(UB, BLOCK_S, gate_tau_s, gate_delta)
    return glr_polynomial(np.where(paused, 0.0, p), order, window, paused).max(axis=1)


def glr_threshold(peaks: np.ndarray, p_target: float) -> tuple[float, float, float]:
    """(h, tail-fit h, tail slope) of a GLR statistic from its fault-free per-run peaks: the h a run
    exceeds with probability ``p_target`` by the exponential tail of peak²/2 (the log-likelihood
    ratio), never below 1.2x the largest peak."""
    h2, theta, _ = tail_threshold(np.asarray(peaks) ** 2 / 2.0, p_target)
    h_tail = math.sqrt(2.0 * h2)
    return max(h_tail, 1.2 * float(np.max(peaks))), h_tail, theta


def cusum_offline(z, k, h, warm_blocks, RB=None, r_max=None):
    """CUSUM over normalised block means z (runs, blocks, 19): returns (first alarm block (runs, 19),
    -1 if none; per-run maximum of max(S+, S-) after the warm-up (runs, 19)); with the blocks'
    pressure ratios RB (runs, blocks) and r_max (19,) the tests pause above r_max."""
    R, B, M = z.shape
    sp = np.zeros((R, M))
    sm = np.zeros((R, M))
    first = np.full((R, M), -1)
    peak = np.zeros((R, M))
    for j in range(B):
        on = (j >= warm_blocks)[None, :]  # (1, M)
        if RB is not None:
            on = on & (RB[:, j][:, None] <= r_max[None, :])
        sp = np.where(on, np.maximum(0.0, sp + z[:, j] - k), 0.0)
        sm = np.where(on, np.maximum(0.0, sm - z[:, j] - k), 0.0)
        s = np.maximum(sp, sm)
        peak = np.maximum(peak, s)
        hit = (s > h) & (first < 0)
        first[hit] = j
    return first, peak


def tail_threshold(peaks, p_target, tail_fraction=TAIL_FRACTION):
    """h with P(run peak > h) = p_target from an exponential fit of the upper tail of the peaks."""
    x = np.sort(peaks)[::-1]
    n = len(x)
    m = max(5, int(round(tail_fraction * n)))
    xs = x[:m]
    surv = (np.arange(m) + 0.5) / n  # empirical P(peak > x_i), plotting position
    A = np.vstack([np.ones(m), -xs]).T
    (a, theta), *_ = np.linalg.lstsq(A, np.log(surv), rcond=None)
    if not theta > 0:
        return float(x[0] * 2.0), float("nan"), float(a)
    return float((a - math.log(p_target)) / theta), float(theta), float(a)


def fit(cal: dict, k: float = K_DEFAULT, r_max: float = R_MAX_DEFAULT) -> dict:
    """Normalisation and thresholds from the calibration set (see module docstring)."""
    BM = cal["block_means"].astype(np.float64)
    UB = cal["u"].astype(np.float64)
    n_runs, nb, _ = BM.shape
    warm = warm_blocks([WARMUP_S[m] for m in MODULE_IDS])
    nodes = np.array(U_NODES)
    mean = np.zeros((N_MODULES, len(nodes)))
    scale = np.zeros((N_MODULES, len(nodes)))
    counts = np.zeros(len(nodes), dtype=int)
    for m in range(N_MODULES):
        ok = np.arange(nb)[None, :] >= warm[m]
        for j, u in enumerate(nodes):
            sel = ok & (np.abs(UB - u) <= NODE_HALF_WIDTH)
            x = BM[:, :, m][sel]
            counts[j] = sel.sum()
            mean[m, j] = x.mean()
            scale[m, j] = x.std()
    z = normalise_blocks(BM, UB, nodes, mean, scale)
    kk = np.full(N_MODULES, k)
    rmax = np.array([r_max if m in PAUSED_MODULES else np.inf for m in MODULE_IDS])
    RB = cal["ratio"].astype(np.float64)
    _, peaks = cusum_offline(z, kk, np.full(N_MODULES, np.inf), warm, RB, rmax)
    hours = n_runs * nb * BLOCK_S / 3600.0
    p_run = FA_TARGET_PER_H * (nb * BLOCK_S / 3600.0) / N_MODULES / FA_MARGIN
    h = np.zeros(N_MODULES)
    tails = {}
    for m, mid in enumerate(MODULE_IDS):
        h[m], theta, a = tail_threshold(peaks[:, m], p_run)
        h[m] = max(h[m], 1.2 * peaks[:, m].max())  # never below the largest calibration peak
        tails[mid] = {
            "theta": theta,
            "a": a,
            "max_peak": float(peaks[:, m].max()),
            "p99_peak": float(np.percentile(peaks[:, m], 99)),
        }
    gpeaks = receiver_peaks(z, UB, RB, warm, rmax)
    gate = transient_gate(UB, BLOCK_S)
    family = np.array([str(p).split(":")[0] for p in cal["profiles"]])
    g_h, g_tail, gtheta = glr_threshold(gpeaks, p_run)
    receiver = {
        "modules": list(RECEIVER_MODULES),
        "h": g_h,
        "order": ORDER,
        "window_blocks": WINDOW_BLOCKS,
        "gate_tau_s": GATE_TAU_S,
        "gate_delta": GATE_DELTA,
        "fit": {
            "tail_h": g_tail,
            "tail_theta_half_square": gtheta,
            "max_peak": float(gpeaks.max()),
            "p99_peak": float(np.percentile(gpeaks, 99)),
            "share_gated": float(gate.mean()),
            "share_gated_by_family": {
                fam: float(gate[family == fam].mean()) for fam in FAMILIES if (family == fam).any()
            },
        },
    }
    return {
        "module_ids": list(MODULE_IDS),
        "block_s": BLOCK_S,
        "u_nodes": nodes.tolist(),
        "mean": mean.tolist(),
        "scale": scale.tolist(),
        "k": kk.tolist(),
        "h": h.tolist(),
        "warmup_s": [WARMUP_S[m] for m in MODULE_IDS],
        "r_max": [float(x) if np.isfinite(x) else 1e9 for x in rmax],
        "fit": {
            "runs": int(n_runs),
            "hours": hours,
            "entropy0": int(cal["entropy0"]),
            "node_blocks": counts.tolist(),
            "per_run_target_probability": p_run,
            "fa_target_per_h": FA_TARGET_PER_H,
            "margin": FA_MARGIN,
            "tail_fraction": TAIL_FRACTION,
            "tails": tails,
            "load_range": list(LOAD_RANGE),
            "families": list(FAMILIES),
            "duration_s": float(cal["duration_s"]),
        },
        "receiver": receiver,
        "command": "python -m studies.diagnosis.sequential_calibration fit",
    }


def check(val: dict, calibration: dict) -> dict:
    """False alarms of the sequential tests (and of the worst-case violations) on a record."""
    BM = val["block_means"].astype(np.float64)
    UB = val["u"].astype(np.float64)
    n_runs, nb, _ = BM.shape
    nodes = np.asarray(calibration["u_nodes"])
    z = normalise_blocks(BM, UB, nodes, np.asarray(calibration["mean"]), np.asarray(calibration["scale"]))
    warm = warm_blocks(calibration["warmup_s"])
    first, peaks = cusum_offline(
        z,
        np.asarray(calibration["k"]),
        np.asarray(calibration["h"]),
        warm,
        val["ratio"].astype(np.float64),
        np.asarray(calibration["r_max"]),
    )
    cus = first >= 0
    worst = ~np.isnan(val["first_violation"])
    rec = calibration.get("receiver")
    if rec is not None:
        gpeaks = receiver_peaks(
            z,
            UB,
            val["ratio"].astype(np.float64),
            warm,
            np.asarray(calibration["r_max"]),
            rec["order"],
            rec["window_blocks"],
            rec["gate_tau_s"],
            rec["gate_delta"],
        )
        glr = gpeaks > rec["h"]
    else:
        gpeaks, glr = np.zeros(n_runs), np.zeros(n_runs, dtype=bool)
    any_alarm = (cus | worst).any(axis=1) | glr
    hours = n_runs * nb * BLOCK_S / 3600.0
    runs = [
        {
            "run": int(i),
            "profile": str(val["profiles"][i]),
            "seed": int(val["seeds"][i]),
            "cusum_modules": [MODULE_IDS[m] for m in np.flatnonzero(cus[i])],
            "worst_case_modules": [MODULE_IDS[m] for m in np.flatnonzero(worst[i])],
            "receiver_test": bool(glr[i]),
        }
        for i in np.flatnonzero(any_alarm)
    ]
    return {
        "runs": int(n_runs),
        "hours": hours,
        "entropy0": int(val["entropy0"]),
        "runs_with_alarm": int(any_alarm.sum()),
        "runs_with_cusum_alarm": int(cus.any(axis=1).sum()),
        "runs_with_worst_case_alarm": int(worst.any(axis=1).sum()),
        "runs_with_receiver_alarm": int(glr.sum()),
        "receiver_peak_over_h_max": float(gpeaks.max() / rec["h"]) if rec is not None else None,
        "alarms_per_module": {mid: int(cus[:, m].sum()) for m, mid in enumerate(MODULE_IDS)},
        "peak_over_h_max": {mid: float(peaks[:, m].max() / calibration["h"][m]) for m, mid in enumerate(MODULE_IDS)},
        "alarm_runs": runs,
    }


def _save(path: Path, rec: dict) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **{k: v for k, v in rec.items()})


def _load(path: Path) -> dict:
    if not path.exists():
        raise SystemExit(f"{path} not found: run the 'record' step first")
    d = np.load(path, allow_pickle=False)
    return {k: (d[k].item() if d[k].ndim == 0 else d[k]) for k in d.files}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", choices=("record", "fit", "check"))
    ap.add_argument("--set", choices=tuple(SETS), default=None, help="record: which set")
    ap.add_argument("--hours", type=float, default=100.0, help="record: engine-hours (300 s runs)")
    ap.add_argument("--out-dir", type=Path, default=Path("results/sequential_calibration"))
    ap.add_argument("--k", type=float, default=K_DEFAULT, help="fit: CUSUM reference value [spreads]")
    ap.add_argument(
        "--r-max",
        type=float,
        default=R_MAX_DEFAULT,
        help="fit: pressure ratio above which the tests of M3.1-M3.4 pause",
    )
    ap.add_argument(
        "--out", type=Path, default=PACKAGE_DATA / "diagnosis" / CALIBRATION_FILE, help="fit: calibration file"
    )
    ap.add_argument(
        "--report",
        type=Path,
        default=Path("docs/data/sequential_calibration_check.json"),
        help="check: where to write the false-alarm report",
    )
    args = ap.parse_args(argv)
    if args.what == "record":
        if args.set is None:
            ap.error("record needs --set calibration|validation")
        if not args.hours > 0:
            ap.error("--hours must be > 0")
        n = int(math.ceil(args.hours * 3600.0 / DURATION_S))
        t0 = time.time()
        rec = record(n, SETS[args.set])
        path = args.out_dir / f"{args.set}.npz"
        _save(path, rec)
        print(f"wrote {path}: {n} runs ({n * DURATION_S / 3600:.1f} h) in {time.time() - t0:.0f} s")
        return 0
    if args.what == "fit":
        cal = fit(_load(args.out_dir / "calibration.npz"), k=args.k, r_max=args.r_max)
        args.out.write_text(json.dumps(cal, indent=1) + "\n")
        print(f"wrote {args.out}")
        print("| module | k | h | largest calibration peak | tail slope |\n|---|---|---|---|---|")
        for m, mid in enumerate(MODULE_IDS):
            t = cal["fit"]["tails"][mid]
            print(f"| {mid} | {cal['k'][m]:g} | {cal['h'][m]:.2f} | {t['max_peak']:.2f} | {t['theta']:.3f} |")
        r = cal["receiver"]
        print(
            f"receiver test ({' + '.join(r['modules'])}): h = {r['h']:.2f} (tail {r['fit']['tail_h']:.2f}, "
            f"largest calibration peak {r['fit']['max_peak']:.2f}, "
            f"{100 * r['fit']['share_gated']:.0f} % of blocks gated)"
        )
        return 0
    calibration = json.loads(args.out.read_text())
    rep = check(_load(args.out_dir / "validation.npz"), calibration)
    rep["command"] = "python -m studies.diagnosis.sequential_calibration check"
    args.report.parent.mkdir(parents=True, exist_ok=True)
    args.report.write_text(json.dumps(rep, indent=1) + "\n")
    print(
        f"{rep['runs']} runs, {rep['hours']:.1f} engine-hours: {rep['runs_with_alarm']} with an alarm "
        f"({rep['runs_with_cusum_alarm']} CUSUM, {rep['runs_with_worst_case_alarm']} worst-case, "
        f"{rep['runs_with_receiver_alarm']} receiver test); wrote {args.report}"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
