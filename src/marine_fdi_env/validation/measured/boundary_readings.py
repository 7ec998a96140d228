"""Per-row conditions of a measured dataset: the boundary conditions each row runs at (ambient pressure, compressor
inlet temperature, exhaust back pressure) with recording errors left out, and the per-cylinder groups whose spread is
the measurement spread of the engine-mean channel.

Used by :func:`~.dataset.load_measured`.
"""

from __future__ import annotations

import math
import warnings
from typing import Any

import numpy as np

from .columns import QUANTITIES
from .plausibility import rows_where

__all__ = ["BOUNDARY_OUTLIER_Z", "boundary_conditions", "cylinder_groups"]

BOUNDARY_OUTLIER_Z = 5.0  # robust z-score above which a boundary reading is a recording error
# resolution floors of the robust scale of boundary readings (a MAD of 0 must not flag 0.5 K differences)
_BOUNDARY_FLOOR = {"ambient_temperature_K": 1.0, "ambient_pressure_Pa": 200.0, "exhaust_back_pressure_Pa": 300.0}
_BOUNDARY_KEY = {
    "ambient_pressure_Pa": "p_amb_Pa",
    "ambient_temperature_K": "T_amb_K",
    "exhaust_back_pressure_Pa": "dp_ex_Pa",
}


def boundary_conditions(
    raw, column_quantity, column_role, column_spec, n, warn
) -> tuple[dict[str, np.ndarray], list[dict]]:
    """Per-row boundary conditions (SI, NaN where not recorded) with recording errors left out.

    A reading is a recording error when its robust z-score against the other rows (deviation from their
    median over 1.4826 x their median absolute deviation, floored at the reading's resolution) exceeds
    ``BOUNDARY_OUTLIER_Z``; it is replaced by the median of the other rows and reported.
    """
    out = {k: np.full(n, np.nan) for k in ("p_amb_Pa", "T_amb_K", "dp_ex_Pa")}
    outliers: list[dict] = []
    for h, q in column_quantity.items():
        if column_role.get(h) != "boundary" or q not in _BOUNDARY_KEY:
            continue
        spec = column_spec[h]
        si = spec.to_si(raw[h], 0.0) if spec.gauge else spec.to_si(raw[h])
        key = _BOUNDARY_KEY[q]
        fin = np.flatnonzero(np.isfinite(si))
        clean = si.copy()
        if fin.size >= 4:
            for i in fin:
                others = si[np.setdiff1d(fin, [i])]
                med = float(np.median(others))
                scale = max(1.4826 * float(np.median(np.abs(others - med))), _BOUNDARY_FLOOR.get(q, 0.0))
                z = abs(si[i] - med) / scale if scale > 0 else math.inf
                if z > BOUNDARY_OUTLIER_Z:
                    clean[i] = med
                    outliers.append(
                        {
                            "column": h,
                            "row": int(i) + 1,
                            "value": float(raw[h][i]),
                            "replacement": float(spec.from_si(med, 0.0) if spec.gauge else spec.from_si(med)),
                            "robust_z": float(z),
                        }
                    )
                    warn(
                        f"boundary reading {raw[h][i]:g} is {z:.0f} robust standard deviations from the other rows' "
                        f"median {spec.from_si(med, 0.0) if spec.gauge else spec.from_si(med):g}: a recording error; "
                        "left out, the row runs at that median",
                        rows=(int(i) + 1,),
                        column=h,
                    )
        out[key] = clean
    return out, outliers


def cylinder_groups(raw, column_quantity, column_role, column_spec, n, p_amb, warn) -> dict[str, dict[str, Any]]:
    """Per-cylinder groups: members, the engine-mean column, the per-row spread (sample standard deviation
    of the members, in the mean column's units) and the member count; checks the recorded mean."""
    out: dict[str, dict[str, Any]] = {}
    for h, role in column_role.items():
        if role != "member":
            continue
        g = column_spec[h].group
        out.setdefault(g, {"columns": [], "quantity": column_quantity[h]})["columns"].append(h)
    for g, d in out.items():
        mean_col = next(
            (c for c, q in column_quantity.items() if q == d["quantity"] and column_role.get(c) != "member"), None
        )
        members = np.column_stack([column_spec[c].to_si(raw[c], p_amb) for c in d["columns"]])
        cnt = np.sum(np.isfinite(members), axis=1)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            mean_si = np.nanmean(members, axis=1)
            spread_si = np.nanstd(members, axis=1, ddof=1)
        spread_si = np.where(cnt >= 2, spread_si, np.nan)
        d["mean_column"] = mean_col
        d["n"] = cnt
        if mean_col is not None:
            spec = column_spec[mean_col]
            d["spread"] = spread_si / spec.scale
            rec = spec.to_si(raw[mean_col], p_amb)
            dev = np.abs(rec - mean_si)
            bad = np.isfinite(dev) & (
                dev
                > np.maximum(0.01 * np.abs(mean_si) if QUANTITIES[d["quantity"]].kind != "temperature" else 2.0, 1e-9)
            )
            if np.any(bad):
                warn(
                    f"the recorded mean differs from the mean of {', '.join(d['columns'])} (kept as recorded)",
                    rows=rows_where(bad),
                    column=mean_col,
                )
        else:
            d["spread"] = spread_si
            warn(
                f"per-cylinder group {g!r} has no engine-mean column: its members are listed, not compared",
                column=d["columns"][0],
            )
    return out
