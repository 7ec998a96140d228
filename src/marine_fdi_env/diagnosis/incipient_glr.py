"""A GLR test for an incipient shift of known polynomial shape on two pooled residuals, paused while
the load changes: the ``sequential`` diagnoser's receiver test (turbine_seal_leak).

The turbine seal leak grows as s² after its onset and moves only the receiver residuals M3.1 and
M3.2, by less than half a block spread within 300 s; the two chains' fault-free block z are white
and independent at constant load (disjoint sensors), so their normalised sum
``p = (z_M3.1 + z_M3.2) / sqrt(2)`` carries the evidence of both with unit variance.  The
generalised likelihood ratio for a shift a (t - τ)^q with unknown amplitude a and onset τ
(Basseville & Nikiforov 1993, sec. 2.4; Willsky & Jones 1976) after block T is

    g_T = max over τ in [T - W, T) of |Σ_{t=τ+1..T} p_t (t - τ)^q| / sqrt(Σ_{j=1..T-τ} j^(2q))

(W = ``WINDOW_BLOCKS`` onsets are kept: the statistic is a maximum of W matched filters).

* **transient gate.**  Fault-free, the largest recorded g come from load *reductions* to low load,
  100-200 s after the change: the residuals' slow transient model error, common to both chains,
  not noise (calibration runs: peaks to 6.9 without the gate, 4.6 with it; the white-noise
  threshold is 5.7).  The test pauses (and restarts) on every block whose mean fuel setting u lies more than
  ``GATE_DELTA`` from its exponential moving average with time constant ``GATE_TAU_S``: the known
  input alone decides, so a fault cannot open or close the gate.  At constant load it never closes.
* **common shift, not one chain.**  A process fault on the receiver moves both chains alike; a
  sensor fault of one chain moves only its own (and a large one raises the pooled g as well).  At
  the maximising onset the chains' own matched statistics c1, c2 are the GLRs of a shift in chain 1
  alone (c1²/2) and in chain 2 alone (c2²/2); the common shift's is (c1 + c2)²/4.  An alarm counts
  only when the common shift explains the two chains at least as well as either chain alone,
  ``(c1 + c2)² / 2 >= max(c1², c2²)`` (same sign, the smaller at least sqrt(2) - 1 of the larger;
  the three hypotheses have one free amplitude each, so no penalty term): a large one-chain shift
  raises g too, and this keeps it from claiming the other chain's module.
* **only while both chains are unfired.**  The sequential diagnoser runs the test only while
  neither M3.1 nor M3.2 has fired on its own evidence (worst-case threshold or CUSUM): once one
  chain is known to be inconsistent, the pooled sum would lend its fault to the other chain
  (single-v1, before this rule: an S3.3 offset fired M3.1 at once; 76 s later that offset plus a
  mild transient common to both chains passed the condition above, fired M3.2 and ruled S3.3 out).

The streaming update (:func:`glr_pair_update`, compiled, called once per block from the
sequential diagnoser's kernel) keeps, per engine, the W running numerators of each chain in a ring;
:func:`glr_polynomial` is the offline statistic over recorded blocks (same numbers, tested).
"""

from __future__ import annotations

import math
from math import comb

import numpy as np

from .._jit import jit

__all__ = [
    "glr_polynomial",
    "glr_norms",
    "glr_pair_update",
    "common_shift",
    "transient_gate",
    "ORDER",
    "WINDOW_BLOCKS",
    "GATE_TAU_S",
    "GATE_DELTA",
]

ORDER = 2  # shape (t - τ)^2: the seal leak's β R s with β ≈ κ s
WINDOW_BLOCKS = 300  # onsets kept [blocks]
GATE_TAU_S = 30.0  # moving average of the fuel setting [s]
GATE_DELTA = 0.02  # fuel-setting distance from it that pauses the test [-]


def glr_norms(order: int = ORDER, window: int = WINDOW_BLOCKS) -> np.ndarray:
    """(window,) ``sqrt(Σ_{j=1..d} j^(2 order))`` for d = 1..window."""
    return np.sqrt(np.cumsum(np.arange(1, window + 1, dtype=np.float64) ** (2 * order)))


def glr_polynomial(p: np.ndarray, order: int, window: int, paused: np.ndarray | None = None) -> np.ndarray:
    """GLR statistic of a shift a (t - τ)^order (unknown a, onset τ within ``window`` blocks) in unit
    white blocks p (runs, N): ``max_τ |Σ_{t>τ} p_t (t-τ)^q| / sqrt(Σ (t-τ)^{2q})`` after every block
    (runs, N).  Onsets before a ``paused`` block (runs, N bool) are not considered (the test restarts)."""
    p = np.asarray(p, dtype=np.float64)
    R, N = p.shape
    t = np.arange(1, N + 1, dtype=np.float64)
    prefix = [np.concatenate([np.zeros((R, 1)), np.cumsum(p * t**j, axis=1)], axis=1) for j in range(order + 1)]
    if paused is None:
        restart = np.zeros((R, N), dtype=np.int64)
    else:  # prefix index after the last paused block up to t
        idx = np.where(np.asarray(paused, dtype=bool), np.arange(1, N + 1)[None, :], 0)
        restart = np.maximum.accumulate(idx, axis=1)
    norm_g = glr_norms(order, window)
    out = np.zeros((R, N))
    for T in range(1, N + 1):
        taus = np.arange(max(0, T - window), T)  # signal in blocks tau+1 .. T
        num = np.zeros((R, len(taus)))
        for j in range(order + 1):  # (t - tau)^q = sum_j C(q, j) t^j (-tau)^(q - j)
            num += (
                comb(order, j)
                * ((-taus.astype(np.float64)) ** (order - j))[None, :]
                * (prefix[j][:, T][:, None] - prefix[j][:, taus])
            )
        stat = np.abs(num) / norm_g[T - taus - 1][None, :]
        stat = np.where(taus[None, :] >= restart[:, T - 1][:, None], stat, 0.0)
        out[:, T - 1] = stat.max(axis=1)
    return out


def transient_gate(u: np.ndarray, block_s: float, tau_s: float = GATE_TAU_S, delta: float = GATE_DELTA) -> np.ndarray:
    """(runs, N) bool: blocks whose mean fuel setting ``u`` (runs, N) lies more than ``delta`` from its
    exponential moving average with time constant ``tau_s`` (started at the first block): the load is
    changing or changed within the last few τ.  Uses the known input only, so a fault cannot open
    or close it."""
    u = np.asarray(u, dtype=np.float64)
    a = block_s / tau_s
    avg = np.empty_like(u)
    avg[:, 0] = u[:, 0]
    for t in range(1, u.shape[1]):
        avg[:, t] = avg[:, t - 1] + a * (u[:, t] - avg[:, t - 1])
    return np.abs(u - avg) > delta


@jit
def common_shift(c1, c2):
    """True when a shift common to both chains explains their matched statistics c1, c2 at least as
    well as a shift of either chain alone: ``(c1 + c2)² / 2 >= max(c1², c2²)``."""
    return 0.5 * (c1 + c2) * (c1 + c2) >= max(c1 * c1, c2 * c2)


@jit
def glr_pair_update(i, z1, z2, u, active, num, count, pos, avg, norms, order, gate_a, gate_delta):
    """One block of engine i: chains' block z ``z1``, ``z2``, mean fuel setting ``u``; ``active``: the
    chains' tests run in this block (warm-up over, not in their pause region).  State: num (N, W, 2)
    the chains' running numerators per onset (ring), count (N,) onsets kept, pos (N,) ring position,
    avg (N,) moving average of u (NaN: none yet).  Returns (g, c1, c2): the pooled statistic and the
    chains' own matched statistics at its maximising onset (0 while paused or gated)."""
    if avg[i] != avg[i]:
        avg[i] = u
    else:
        avg[i] += gate_a * (u - avg[i])
    if not active or abs(u - avg[i]) > gate_delta:
        count[i] = 0
        return 0.0, 0.0, 0.0
    W = num.shape[1]
    pos[i] = (pos[i] + 1) % W
    num[i, pos[i], 0] = 0.0  # the newest onset: signal from this block on
    num[i, pos[i], 1] = 0.0
    if count[i] < W:
        count[i] += 1
    best = -1.0
    c1 = 0.0
    c2 = 0.0
    for k in range(count[i]):  # onset k blocks before the newest: this block is its (k + 1)-th
        s = pos[i] - k
        if s < 0:
            s += W
        w = float(k + 1) ** order
        num[i, s, 0] += z1 * w
        num[i, s, 1] += z2 * w
        g = abs(num[i, s, 0] + num[i, s, 1]) / (math.sqrt(2.0) * norms[k])
        if g > best:
            best = g
            c1 = num[i, s, 0] / norms[k]
            c2 = num[i, s, 1] / norms[k]
    return best, c1, c2
