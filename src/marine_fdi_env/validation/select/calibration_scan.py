"""What a sensor calibration leaves on its channel: a scan for steps, kinks and local windows beyond a gain and offset.

When the selection names a sensor's gain and offset, the channel's residual is what they leave, and a gain and an
offset remove exactly the part of any effect that is affine in the reading.  What is left of a step in load is a
sawtooth with a jump, of a kink a hinge: their means are zero and they barely tilt, so the bias, trend and
change-point tests of :mod:`.measured.discrepancy` see nothing, and the local-window scan of :mod:`.window_scan` (a
window against the rest) sees little.  Measured on the open-world study (docs/validation.md): of 20 out-of-library
effects, 10 were named as that channel's calibration with nothing reported, where a scan over the study's shape
family at the pipeline's tolerance would have reported about 3 in 4 at 5 % (docs/validation.md, the effect bound).

The scan (generalised likelihood ratio over a dictionary, with a simulated null):

* the dictionary, at the channel's measured points in load order x_1 < ... < x_n: a **step** between every two
  neighbouring points (1 above the split), a **kink** at every point and every midpoint, bending up to either side
  (``max(x - c, 0)``, ``max(c - x, 0)``), and every **window** of 2 .. n/2 neighbouring points; generic shapes, not
  the synthetic effects' (:mod:`.fit.synthesize`: their Gaussian bumps, smooth steps and ranges of centres and
  widths are not used);
* each shape is made orthogonal to [1, reading] (what the gain and the offset absorb) and normalised; shapes left
  with nothing are dropped;
* the statistic is the largest ``|u · r| / σ`` over the shapes, ``r`` the residual in tolerances and ``σ`` the
  data's noise in tolerances (:func:`~.window_scan.noise_ratio`, at least 1, as for the window scan);
* its p-value is the probability that Gaussian noise of ``σ`` projected on the same shapes gives a statistic as
  large, from :data:`NULL_DRAWS` draws of a generator seeded by the number of points (the same numbers on every
  run); a finding must also be worth naming: the fitted shape departs by at least one tolerance at some point.

The residual comes from the final model refitted without the channel, the calibration held
(:func:`~.fit.fitting.loco_predictions`); its gain and offset were fitted with the channel, so the two degrees of
freedom they took are those the projection removes.
"""

from __future__ import annotations

from typing import Any, Sequence

import numpy as np

__all__ = ["shape_dictionary", "orthonormal_directions", "structure_scan", "NULL_DRAWS"]

#: Gaussian draws for the scan's null distribution (p-values resolve down to 1 / (NULL_DRAWS + 1))
NULL_DRAWS = 20_000


def shape_dictionary(x: Sequence[float]) -> tuple[np.ndarray, list[tuple[str, float, float]]]:
    """The scan's shapes at the sorted loads ``x`` (rows) and, per shape, (kind, low, high): the load range where it
    acts (a step: the points above the split; a kink: the side it bends; a window: its points)."""
    x = np.asarray(x, dtype=float)
    n = x.size
    rows, where = [], []
    for k in range(n - 1):
        rows.append((x > x[k]).astype(float))
        where.append(("step", float(x[k + 1]), float(x[-1])))
    centres = sorted(set(x[1:-1].tolist()) | set(((x[:-1] + x[1:]) / 2.0).tolist()))
    for c in centres:
        rows.append(np.maximum(x - c, 0.0))
        where.append(("kink", float(c), float(x[-1])))
        rows.append(np.maximum(c - x, 0.0))
        where.append(("kink", float(x[0]), float(c)))
    for w in range(2, n // 2 + 1):
        for a in range(0, n - w + 1):
            v = np.zeros(n)
            v[a : a + w] = 1.0
            rows.append(v)
            where.append(("window", float(x[a]), float(x[a + w - 1])))
    return np.asarray(rows), where


def orthonormal_directions(
    shapes: np.ndarray, reading: np.ndarray, noise_sd: np.ndarray | float = 1.0
) -> tuple[np.ndarray, np.ndarray]:
    """Unit vectors (columns) of the shapes' (rows) parts orthogonal to [1, reading], all whitened by ``noise_sd``
    per point (what a gain and an offset absorb projected out), and the indices of the shapes kept (those left with
    more than 1e-6 of the largest shape's norm)."""
    sd = np.broadcast_to(np.asarray(noise_sd, dtype=float), reading.shape)
    A = np.column_stack([np.ones_like(reading), reading]) / sd[:, None]
    Q, _ = np.linalg.qr(A)
    D = (shapes / sd[None, :]).T
    U = D - Q @ (Q.T @ D)
    norm = np.linalg.norm(U, axis=0)
    keep = np.flatnonzero(norm > 1e-6 * np.linalg.norm(D, axis=0).max())
    return U[:, keep] / norm[keep], keep


def structure_scan(
    residual: Sequence[float], load: Sequence[float], reading: Sequence[float], tol: float, noise: float = 1.0
) -> dict[str, Any] | None:
    """The scan of the module docstring on one calibrated channel: ``residual`` (model minus measurement, column
    units), ``load`` and ``reading`` (the calibrated model reading) per point, ``tol`` the channel's tolerance and
    ``noise`` the data's noise in tolerances.

    Returns None with fewer than 5 usable points, else ``{p, p_at_floor, z, kind, load_range, d, positions}``: ``d``
    the fitted shape's largest departure (column units, signed), ``positions`` the indices (into the inputs) of the
    points where the shape acts."""
    r = np.asarray(residual, dtype=float)
    x = np.asarray(load, dtype=float)
    y = np.asarray(reading, dtype=float)
    ok = np.flatnonzero(np.isfinite(r) & np.isfinite(x) & np.isfinite(y))
    if ok.size < 5:
        return None
    order = ok[np.argsort(x[ok], kind="stable")]
    xs, rs, ys = x[order], r[order] / tol, y[order]
    shapes, where = shape_dictionary(xs)
    U, keep = orthonormal_directions(shapes, ys)
    if U.shape[1] == 0:
        return None
    sigma = max(float(noise), 1.0)
    proj = U.T @ rs
    j = int(np.argmax(np.abs(proj)))
    z = float(abs(proj[j]) / sigma)
    rng = np.random.default_rng([int(order.size), 20261126])
    null = np.max(np.abs(rng.standard_normal((NULL_DRAWS, order.size)) @ U), axis=1)
    n_ge = int(np.sum(null >= z))
    fitted = proj[j] * U[:, j] * tol
    kind, lo, hi = where[int(keep[j])]
    acts = np.flatnonzero(shapes[int(keep[j])] != 0)
    return {
        "p": (1 + n_ge) / (NULL_DRAWS + 1),
        "p_at_floor": n_ge == 0,
        "z": z,
        "kind": kind,
        "load_range": [lo, hi],
        "d": float(fitted[np.argmax(np.abs(fitted))]),
        "positions": sorted(int(order[i]) for i in acts),
    }
