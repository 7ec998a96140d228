"""Σ2 for the inclusion bounds of the monitoring modules: the speed loop and the Seiliger cycle at
the centre (the measured x1, x4, T1 of a sensor chain) and at ±d̄ of each (eq. 3.7-3.13).

Every module that needs the engine speed (M2.x, M3.x, M4.1/2, M4.5/6) takes it from here; the
perturbed rows are the inclusion terms of M2.1-M2.4 and the perturbed speeds of the M3/M4
inclusions.  :func:`cycle_table` does one chain; :func:`centre_speed2` and
:func:`perturbed_rows2` do both chains of a sample at once with each chain's operations in the
same order (the same numbers bit for bit), interleaved so that the processor overlaps them.
:mod:`marine_fdi_env.diagnosis.inclusion_table` tabulates the perturbed rows.
"""

from __future__ import annotations

import math

from .._jit import jit
from ..engine.subsystems.engine_block import engine_block, speed_sweep

__all__ = [
    "SPEED_SWEEPS",
    "ONE_SIDED",
    "LINEAR_SPEED",
    "SLOPE_STEP",
    "SLOPE_LIMIT",
    "cycle_table",
    "centre_speed",
    "centre_speed2",
    "perturbed_rows",
    "perturbed_rows2",
]

SPEED_SWEEPS = 4
ONE_SIDED = False  # measured and rejected (see residuals' module docstring)
LINEAR_SPEED = True  # perturbed points: one sweep + linearisation in the speed (see cycle_table)
SLOPE_STEP = 1e-5  # relative step of the centre's speed slope
SLOPE_LIMIT = 0.5  # the linearised perturbed speeds need a contraction |f'(n)| below this


@jit
def centre_speed(c, x1, x4, T1, n_guess):
    """Σ2's speed loop at the centre from the previous sample's speed: two sweeps and an Aitken
    extrapolation (as ``engine_block``), one sweep and a second extrapolation with the slope of
    the first two sweeps, and the output sweep; returns (n, p6, T6).  Four sweeps where
    ``engine_block(..., SPEED_SWEEPS=4)`` takes five; same result to ~1e-12 (measured)."""
    V1 = c.V1_m3
    m1 = x4 * V1 / (c.R_a_J_per_kgK * T1)
    q = (c.eta_comb * c.h_L_J_per_kg) * x1 / m1
    X_ct = c.X_ct_nom * x1 / c.x1_nom_kg
    n0 = n_guess
    n1, torque, cyc = speed_sweep(n0, x4, T1, q, m1, X_ct, c)
    n2, torque, cyc = speed_sweep(n1, x4, T1, q, m1, X_ct, c)
    den = (n2 - n1) - (n1 - n0)
    k = (n2 - n1) / (n1 - n0) if n1 != n0 else 0.0
    a = n2 - (n2 - n1) ** 2 / den if den != 0.0 else n2
    b, torque, cyc = speed_sweep(a, x4, T1, q, m1, X_ct, c)
    if math.isfinite(k) and abs(k) < SLOPE_LIMIT:
        a = a + (b - a) / (1.0 - k)
    else:
        a = b
    n, torque, cyc = speed_sweep(a, x4, T1, q, m1, X_ct, c)
    return n, cyc[5], cyc[3]


@jit
def cycle_table(c, x1, x4, T1, dx1, dx4, dT1, n_guess, tab):
    """Σ2 at the centre and at +d̄ (and -d̄ unless ``ONE_SIDED``) of x1, x4, T1: rows (n, p6, T6) in
    the order centre, x1+, x1-, x4+, x4-, T1+, T1- (fills tab 7x3; skipped rows repeat the centre).

    The centre is solved to ~1e-12 relative by :func:`centre_speed` (from the previous sample's speed).
    A perturbed point is one sweep from the centre's speed n_c, linearised in the speed with the
    centre's slopes (one more sweep at n_c + h)::

        n_p  = n_c + (f_p(n_c) - n_c) / (1 - f_c'(n_c))
        p6_p = p6_p(n_c) + p6_c'(n_c) (n_p - n_c)           (T6 alike)

    exact to first order in the perturbation; the neglected terms are second order (the slope's
    change over the noise box times the speed change, and the curvature in n), the same order as
    the mixed terms the coordinate-wise inclusion neglects (see the module docstring).  Where the
    slope is not a contraction (never seen in the envelope) every point is solved in full.
    """
    n_c, p6, T6 = centre_speed(c, x1, x4, T1, n_guess)
    tab[0, 0] = n_c
    tab[0, 1] = p6
    tab[0, 2] = T6
    perturbed_rows(c, x1, x4, T1, dx1, dx4, dT1, tab)


@jit
def perturbed_rows(c, x1, x4, T1, dx1, dx4, dT1, tab):
    """Rows 1-6 of :func:`cycle_table` given its centre row tab[0]."""
    V1 = c.V1_m3
    n_c, p6, T6 = tab[0, 0], tab[0, 1], tab[0, 2]
    for p in range(1, 7):
        tab[p, 0] = n_c
        tab[p, 1] = p6
        tab[p, 2] = T6
    step = 2 if ONE_SIDED else 1
    h = SLOPE_STEP * n_c
    n_h, tq, p6_h, T6_h, p_max, m1 = engine_block(x1, x4, T1, V1, n_c + h, c, 1)
    k = (n_h - n_c) / h
    linear = LINEAR_SPEED and math.isfinite(k) and abs(k) < SLOPE_LIMIT
    s_p6 = (p6_h - p6) / h
    s_T6 = (T6_h - T6) / h
    for p in range(1, 7, step):
        a = dx1 if p == 1 else (-dx1 if p == 2 else 0.0)
        b = dx4 if p == 3 else (-dx4 if p == 4 else 0.0)
        d = dT1 if p == 5 else (-dT1 if p == 6 else 0.0)
        _perturbed_row(c, x1 + a, x4 + b, T1 + d, n_c, linear, k, s_p6, s_T6, tab, p)


@jit
def centre_speed2(c, x1a, x4a, T1a, nga, x1b, x4b, T1b, ngb):
    """:func:`centre_speed` at two operating points at once (the two sensor chains): each point's
    operations in the same order as there, so each result equals :func:`centre_speed`'s bit for
    bit; interleaved sweep by sweep so that the processor overlaps the two dependent chains
    (measured 1.8x faster than two calls one after the other)."""
    V1 = c.V1_m3
    m1a = x4a * V1 / (c.R_a_J_per_kgK * T1a)
    m1b = x4b * V1 / (c.R_a_J_per_kgK * T1b)
    qa = (c.eta_comb * c.h_L_J_per_kg) * x1a / m1a
    qb = (c.eta_comb * c.h_L_J_per_kg) * x1b / m1b
    Xa = c.X_ct_nom * x1a / c.x1_nom_kg
    Xb = c.X_ct_nom * x1b / c.x1_nom_kg
    n0a = nga
    n0b = ngb
    n1a, _, _ = speed_sweep(n0a, x4a, T1a, qa, m1a, Xa, c)
    n1b, _, _ = speed_sweep(n0b, x4b, T1b, qb, m1b, Xb, c)
    n2a, _, _ = speed_sweep(n1a, x4a, T1a, qa, m1a, Xa, c)
    n2b, _, _ = speed_sweep(n1b, x4b, T1b, qb, m1b, Xb, c)
    dena = (n2a - n1a) - (n1a - n0a)
    denb = (n2b - n1b) - (n1b - n0b)
    ka = (n2a - n1a) / (n1a - n0a) if n1a != n0a else 0.0
    kb = (n2b - n1b) / (n1b - n0b) if n1b != n0b else 0.0
    aa = n2a - (n2a - n1a) ** 2 / dena if dena != 0.0 else n2a
    ab = n2b - (n2b - n1b) ** 2 / denb if denb != 0.0 else n2b
    ba, _, _ = speed_sweep(aa, x4a, T1a, qa, m1a, Xa, c)
    bb, _, _ = speed_sweep(ab, x4b, T1b, qb, m1b, Xb, c)
    if math.isfinite(ka) and abs(ka) < SLOPE_LIMIT:
        aa = aa + (ba - aa) / (1.0 - ka)
    else:
        aa = ba
    if math.isfinite(kb) and abs(kb) < SLOPE_LIMIT:
        ab = ab + (bb - ab) / (1.0 - kb)
    else:
        ab = bb
    na, _, cyca = speed_sweep(aa, x4a, T1a, qa, m1a, Xa, c)
    nb, _, cycb = speed_sweep(ab, x4b, T1b, qb, m1b, Xb, c)
    return na, cyca[5], cyca[3], nb, cycb[5], cycb[3]


@jit
def perturbed_rows2(c, x1a, x4a, T1a, dx1a, dx4a, dT1a, taba, x1b, x4b, T1b, dx1b, dx4b, dT1b, tabb):
    """Rows 1-6 of :func:`cycle_table` for both chains, given their centre rows (tab[0]); each
    chain's operations in the same order as there (equal results bit for bit), the two chains'
    sweeps adjacent so that they overlap."""
    V1 = c.V1_m3
    n_ca = taba[0, 0]
    n_cb = tabb[0, 0]
    p6a, T6a, p6b, T6b = taba[0, 1], taba[0, 2], tabb[0, 1], tabb[0, 2]
    for p in range(1, 7):
        taba[p, 0] = n_ca
        taba[p, 1] = p6a
        taba[p, 2] = T6a
        tabb[p, 0] = n_cb
        tabb[p, 1] = p6b
        tabb[p, 2] = T6b
    step = 2 if ONE_SIDED else 1
    ha = SLOPE_STEP * n_ca
    hb = SLOPE_STEP * n_cb
    n_ha, tq, p6_ha, T6_ha, p_max, m1 = engine_block(x1a, x4a, T1a, V1, n_ca + ha, c, 1)
    n_hb, tq, p6_hb, T6_hb, p_max, m1 = engine_block(x1b, x4b, T1b, V1, n_cb + hb, c, 1)
    ka = (n_ha - n_ca) / ha
    kb = (n_hb - n_cb) / hb
    lina = LINEAR_SPEED and math.isfinite(ka) and abs(ka) < SLOPE_LIMIT
    linb = LINEAR_SPEED and math.isfinite(kb) and abs(kb) < SLOPE_LIMIT
    s_p6a = (p6_ha - p6a) / ha
    s_T6a = (T6_ha - T6a) / ha
    s_p6b = (p6_hb - p6b) / hb
    s_T6b = (T6_hb - T6b) / hb
    for p in range(1, 7, step):
        sg = 1.0 if p % 2 == 1 else -1.0
        aa = sg * dx1a if p < 3 else 0.0
        ba = sg * dx4a if 2 < p < 5 else 0.0
        da = sg * dT1a if p > 4 else 0.0
        ab = sg * dx1b if p < 3 else 0.0
        bb = sg * dx4b if 2 < p < 5 else 0.0
        db = sg * dT1b if p > 4 else 0.0
        if lina and linb:
            f_pa, tq, p6_pa, T6_pa, p_max, m1 = engine_block(x1a + aa, x4a + ba, T1a + da, V1, n_ca, c, 1)
            f_pb, tq, p6_pb, T6_pb, p_max, m1 = engine_block(x1b + ab, x4b + bb, T1b + db, V1, n_cb, c, 1)
            dna = (f_pa - n_ca) / (1.0 - ka)
            dnb = (f_pb - n_cb) / (1.0 - kb)
            taba[p, 0] = n_ca + dna
            taba[p, 1] = p6_pa + s_p6a * dna
            taba[p, 2] = T6_pa + s_T6a * dna
            tabb[p, 0] = n_cb + dnb
            tabb[p, 1] = p6_pb + s_p6b * dnb
            tabb[p, 2] = T6_pb + s_T6b * dnb
        else:
            _perturbed_row(c, x1a + aa, x4a + ba, T1a + da, n_ca, lina, ka, s_p6a, s_T6a, taba, p)
            _perturbed_row(c, x1b + ab, x4b + bb, T1b + db, n_cb, linb, kb, s_p6b, s_T6b, tabb, p)


@jit
def _perturbed_row(c, x1, x4, T1, n_c, linear, k, s_p6, s_T6, tab, p):
    """One perturbed row of :func:`cycle_table` (the same operations)."""
    V1 = c.V1_m3
    if linear:
        f_p, tq, p6_p, T6_p, p_max, m1 = engine_block(x1, x4, T1, V1, n_c, c, 1)
        dn = (f_p - n_c) / (1.0 - k)
        tab[p, 0] = n_c + dn
        tab[p, 1] = p6_p + s_p6 * dn
        tab[p, 2] = T6_p + s_T6 * dn
    else:
        n, tq, p6_p, T6_p, p_max, m1 = engine_block(x1, x4, T1, V1, n_c, c, SPEED_SWEEPS)
        tab[p, 0] = n
        tab[p, 1] = p6_p
        tab[p, 2] = T6_p
