"""Tabulated Σ2 inclusion terms with a certified interpolation-error margin (the fast inclusion).

The adaptive thresholds of M2.1-M2.4 need, every sample and for each sensor chain, the Σ2 model
(Seiliger cycle and speed loop, eq. 3.7-3.13) at the centre and at ±d̄ of x1, x4 and T1
(:func:`marine_fdi_env.diagnosis.residuals.cycle_table`): 7 Seiliger cycles per chain and sample
besides the centre's speed solve, and the perturbed speeds also feed the inclusion of M3.q, M3.3/4,
M4.q and M4.5/6.  These 18 differences (row - centre of speed n, p6 and T6 for each of the 6
perturbed points) are smooth functions of the operating point (x1, x4, T1) alone, for the chain's
noise bounds.  This module tabulates them once on a uniform grid and interpolates multilinearly.

Certified margin.  For a C² function the error of multilinear interpolation in a cell with
steps h_d is at most (1/8) Σ_d h_d² max_cell |∂²q/∂x_d²| (tensor-product linear interpolation is
exact for the mixed terms).  We bound h_d² |∂²q/∂x_d²| by the largest central second difference
of the node values along d at the cell's corners and their neighbours, times ``SAFETY_2ND`` = 2
(the second difference is the second derivative at some point within ±h_d; the factor covers its
variation over the cell), and take the larger of that bound and ``SAFETY_CENTRE`` = 2 times the
error measured at the cell centre.  A test checks the margin against the exact values at random
points of every region of the table.  Cells with a corner where the speed loop is not a
contraction (|slope| >= 0.5, the exact path then solves in full) or where anything is not finite
are invalid; the kernel then computes that sample exactly, as it does outside the table.

Domain: x1 in [0.1, 1.4] x the nominal fuel per cycle, x4 in [0.8, 6.5] bar, T1 in [280, 420] K
(the fault-free envelope is x1 0.2-1.2 nominal, x4 1.03-4.95 bar, T1 = 328 K; the rest is room for
noise, transients and faults).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._jit import jit, jit_inline
from ..engine.constants import kernel_constants
from ..engine.subsystems.engine_block import engine_block
from .sigma2 import SLOPE_LIMIT, SLOPE_STEP, cycle_table

__all__ = ["Sigma2Table", "sigma2_table", "TABLE_STEPS", "N_ROWS", "interpolate_rows"]

N_ROWS = 6  # perturbed points: x1+, x1-, x4+, x4-, T1+, T1-
N_COLS = 3  # speed n, p6, T6 (differences from the centre)
SAFETY_2ND = 2.0
SAFETY_CENTRE = 2.0
# floor of the margin relative to the centre value: the rounding of the node values and of the
# kernel's own centre solve (converged to about 1e-12, docs/diagnosis.md)
ROUND_FLOOR = 1e-10
# grid: steps (x1 as a fraction of the nominal fuel per cycle, x4 [Pa], T1 [K]) and bounds
TABLE_STEPS = (0.02, 7.5e3, 10.0)
X1_RANGE = (0.1, 1.4)  # x nominal
X4_RANGE_PA = (0.8e5, 6.5e5)
T1_RANGE_K = (280.0, 420.0)
CENTRE_SWEEPS = 12


@dataclass(frozen=True)
class Sigma2Table:
    """The tabulated differences of one chain's noise bounds (dx1, dx4, dT1).

    lo : (3,) the grid's first node (x1 [kg], x4 [Pa], T1 [K]); step : (3,); shape : (3,) nodes.
    delta : (n1, n4, nT, 6, 3) node values: row p (x1+, x1-, x4+, x4-, T1+, T1-) minus the centre,
        columns speed [rev/s], p6 [Pa], T6 [K] (as :func:`residuals.cycle_table` computes them).
    margin : (n1-1, n4-1, nT-1, 6, 3) certified bound of |interpolated - exact| in each cell.
    valid : (n1-1, n4-1, nT-1) bool; invalid cells are computed exactly.
    """

    noise_bounds: tuple[float, float, float]
    lo: np.ndarray
    step: np.ndarray
    shape: tuple[int, int, int]
    delta: np.ndarray
    margin: np.ndarray
    valid: np.ndarray


@jit
def _node(c, x1, x4, T1, dx1, dx4, dT1, n_guess, tab):
    """Exact rows at one operating point (the speed solved in full first, then cycle_table's
    centre and perturbed rows); returns the speed, or NaN where the point is not usable."""
    n, tq, p6, T6, p_max, m1 = engine_block(x1, x4, T1, c.V1_m3, n_guess, c, CENTRE_SWEEPS)
    if not (math.isfinite(n) and n > 0.0):
        return math.nan
    cycle_table(c, x1, x4, T1, dx1, dx4, dT1, n, tab)
    n_c = tab[0, 0]
    # the slope of the speed loop (the linear path of cycle_table is taken only below SLOPE_LIMIT)
    h = SLOPE_STEP * n_c
    n_h, tq, p6_h, T6_h, p_max, m1 = engine_block(x1, x4, T1, c.V1_m3, n_c + h, c, 1)
    k = (n_h - n_c) / h
    if not (math.isfinite(k) and abs(k) < SLOPE_LIMIT):
        return math.nan
    for p in range(7):
        for q in range(3):
            if not math.isfinite(tab[p, q]):
                return math.nan
    return n_c


@jit
def _fill_nodes(c, x1s, x4s, T1s, dx1, dx4, dT1, delta, ok):
    tab = np.empty((7, 3))
    for i in range(len(x1s)):
        guess = c.n_nom_rev_s
        for j in range(len(x4s)):
            for k in range(len(T1s)):
                n = _node(c, x1s[i], x4s[j], T1s[k], dx1, dx4, dT1, guess, tab)
                ok[i, j, k] = math.isfinite(n)
                for p in range(N_ROWS):
                    for q in range(N_COLS):
                        delta[i, j, k, p, q] = tab[p + 1, q] - tab[0, q] if ok[i, j, k] else math.nan
                if ok[i, j, k]:
                    guess = n


@jit_inline
def interpolate_rows(delta, dims, grid, valid, ti, x1, x4, T1, out):
    """Multilinear interpolation of table ``ti``'s 6 x 3 differences at (x1, x4, T1) into out
    (6, 3); returns the flat cell index (within the table), or -1 outside the table or in an
    invalid cell.

    delta : flat (ntab * n1 * n4 * nT * 18,) node values; dims : (3,) nodes (n1, n4, nT);
    grid : (ntab, 2, 3) first node and 1/step; valid : flat (ntab * cells,).  Flat arrays and one
    base offset, so that the 8 corners' 18 values are contiguous runs (no per-access index
    arithmetic, no array views in the hot path)."""
    n1, n4, nT = dims[0], dims[1], dims[2]
    f0 = (x1 - grid[ti, 0, 0]) * grid[ti, 1, 0]
    f1 = (x4 - grid[ti, 0, 1]) * grid[ti, 1, 1]
    f2 = (T1 - grid[ti, 0, 2]) * grid[ti, 1, 2]
    if not (f0 >= 0.0 and f1 >= 0.0 and f2 >= 0.0):  # also catches NaN
        return -1
    i = int(f0)
    j = int(f1)
    k = int(f2)
    if i >= n1 - 1 or j >= n4 - 1 or k >= nT - 1:
        return -1
    cell = (i * (n4 - 1) + j) * (nT - 1) + k
    if not valid[ti * ((n1 - 1) * (n4 - 1) * (nT - 1)) + cell]:
        return -1
    a = f0 - i
    b = f1 - j
    g = f2 - k
    w000 = (1.0 - a) * (1.0 - b) * (1.0 - g)
    w001 = (1.0 - a) * (1.0 - b) * g
    w010 = (1.0 - a) * b * (1.0 - g)
    w011 = (1.0 - a) * b * g
    w100 = a * (1.0 - b) * (1.0 - g)
    w101 = a * (1.0 - b) * g
    w110 = a * b * (1.0 - g)
    w111 = a * b * g
    # unsigned offsets: no negative-index wrap-around per load, so the 18-value loop vectorises
    nq = N_ROWS * N_COLS
    sk = np.uint64(nq)
    sj = np.uint64(nT * nq)
    si = np.uint64(n4 * nT * nq)
    o000 = np.uint64((((ti * n1 + i) * n4 + j) * nT + k) * nq)
    o001 = o000 + sk
    o010 = o000 + sj
    o011 = o010 + sk
    o100 = o000 + si
    o101 = o100 + sk
    o110 = o100 + sj
    o111 = o110 + sk
    for rr in range(nq):
        r = np.uint64(rr)
        out[rr // N_COLS, rr % N_COLS] = (
            w000 * delta[o000 + r]
            + w001 * delta[o001 + r]
            + w010 * delta[o010 + r]
            + w011 * delta[o011 + r]
            + w100 * delta[o100 + r]
            + w101 * delta[o101 + r]
            + w110 * delta[o110 + r]
            + w111 * delta[o111 + r]
        )
    return cell


@jit
def _second_differences(delta, ok, d2):
    """d2[d, i, j, k, p, q] = |central second difference along axis d| at each node (at the
    boundary: that of the inner neighbour; NaN where a node used is not ok)."""
    n1, n4, nT = ok.shape
    for d in range(3):
        size = n1 if d == 0 else (n4 if d == 1 else nT)
        e0 = 1 if d == 0 else 0
        e1 = 1 if d == 1 else 0
        e2 = 1 if d == 2 else 0
        for i in range(n1):
            for j in range(n4):
                for k in range(nT):
                    pos = i if d == 0 else (j if d == 1 else k)
                    sh = min(max(pos, 1), size - 2) - pos  # move boundary nodes inwards
                    ic, jc, kc = i + sh * e0, j + sh * e1, k + sh * e2
                    good = ok[ic - e0, jc - e1, kc - e2] and ok[ic, jc, kc] and ok[ic + e0, jc + e1, kc + e2]
                    for p in range(N_ROWS):
                        for q in range(N_COLS):
                            if good:
                                d2[d, i, j, k, p, q] = abs(
                                    delta[ic + e0, jc + e1, kc + e2, p, q]
                                    - 2.0 * delta[ic, jc, kc, p, q]
                                    + delta[ic - e0, jc - e1, kc - e2, p, q]
                                )
                            else:
                                d2[d, i, j, k, p, q] = math.nan


@jit
def _margins(c, delta, ok, d2, lo, step, dx1, dx4, dT1, margin, valid):
    n1, n4, nT = ok.shape
    tab = np.empty((7, 3))
    interp = np.empty((N_ROWS, N_COLS))
    flat = delta.reshape(-1)
    dims = np.array([n1, n4, nT], dtype=np.int64)
    grid1 = np.empty((1, 2, 3))
    for d in range(3):
        grid1[0, 0, d] = lo[d]
        grid1[0, 1, d] = 1.0 / step[d]
    valid_flat = valid.reshape(-1)
    for i in range(n1 - 1):
        for j in range(n4 - 1):
            for k in range(nT - 1):
                good = True
                for a in range(2):
                    for b in range(2):
                        for g in range(2):
                            if not ok[i + a, j + b, k + g]:
                                good = False
                valid[i, j, k] = good
                if not good:
                    continue
                # exact rows at the cell centre
                x1 = lo[0] + (i + 0.5) * step[0]
                x4 = lo[1] + (j + 0.5) * step[1]
                T1 = lo[2] + (k + 0.5) * step[2]
                n = _node(c, x1, x4, T1, dx1, dx4, dT1, c.n_nom_rev_s, tab)
                if not math.isfinite(n):
                    valid[i, j, k] = False
                    continue
                interpolate_rows(flat, dims, grid1, valid_flat, 0, x1, x4, T1, interp)
                for p in range(N_ROWS):
                    for q in range(N_COLS):
                        bound = 0.0
                        for d in range(3):
                            m = 0.0
                            for a in range(2):
                                for b in range(2):
                                    for g in range(2):
                                        v = d2[d, i + a, j + b, k + g, p, q]
                                        if not (v <= m):  # NaN or larger
                                            m = v
                            bound += m / 8.0
                        centre_err = abs((tab[p + 1, q] - tab[0, q]) - interp[p, q])
                        e = max(SAFETY_2ND * bound, SAFETY_CENTRE * centre_err) + ROUND_FLOOR * abs(tab[0, q])
                        if not math.isfinite(e):
                            valid[i, j, k] = False
                        margin[i, j, k, p, q] = e


_CACHE: dict = {}


def sigma2_table(c, dx1: float, dx4: float, dT1: float) -> Sigma2Table:
    """The table for model constants ``c`` and one chain's noise bounds, built on first use
    (about 0.5 s) and kept for the process."""
    # the constants hold arrays (submodel schedules): key them by their bytes
    key = (tuple(v.tobytes() if isinstance(v, np.ndarray) else v for v in c), float(dx1), float(dx4), float(dT1))
    if key in _CACHE:
        return _CACHE[key]
    kc = kernel_constants(c)[0]  # floats only: no reference counting per call (the same numbers)
    x1_nom = c.x1_nom_kg
    lo = np.array([X1_RANGE[0] * x1_nom, X4_RANGE_PA[0], T1_RANGE_K[0]])
    step = np.array([TABLE_STEPS[0] * x1_nom, TABLE_STEPS[1], TABLE_STEPS[2]])
    hi = np.array([X1_RANGE[1] * x1_nom, X4_RANGE_PA[1], T1_RANGE_K[1]])
    shape = tuple(int(math.ceil((hi[d] - lo[d]) / step[d] - 1e-9)) + 1 for d in range(3))
    axes = [lo[d] + step[d] * np.arange(shape[d]) for d in range(3)]
    delta = np.empty(shape + (N_ROWS, N_COLS))
    ok = np.zeros(shape, dtype=np.bool_)
    _fill_nodes(kc, axes[0], axes[1], axes[2], float(dx1), float(dx4), float(dT1), delta, ok)
    d2 = np.empty((3,) + shape + (N_ROWS, N_COLS))
    _second_differences(delta, ok, d2)
    cells = tuple(s - 1 for s in shape)
    margin = np.zeros(cells + (N_ROWS, N_COLS))
    valid = np.zeros(cells, dtype=np.bool_)
    _margins(kc, delta, ok, d2, lo, step, float(dx1), float(dx4), float(dT1), margin, valid)
    table = Sigma2Table((float(dx1), float(dx4), float(dT1)), lo, step, shape, delta, margin, valid)
    _CACHE[key] = table
    return table
