"""Plausibility checks of measured values that need no model: the engine's operating envelope (errors beyond it:
:data:`marine_fdi_env.engine.envelope.ENVELOPE` and the fuel-setting range of the steady states), suspicious values
(warnings, kept), duplicate operating points, and an engine far from the others at the same set point.

Used by :func:`~.dataset.load_measured`; each check reports through the loader's ``err``/``warn`` callables (message,
1-based rows, column).
"""

from __future__ import annotations

import math
from typing import Mapping

import numpy as np

from ...engine.envelope import ENVELOPE
from ...engine.params import EngineParams
from ...engine.steady_state import FUEL_SETTING_RANGE
from .columns import QUANTITIES, lookup_column

__all__ = ["SETPOINT_QUANTITIES", "check_across_engines", "check_duplicates", "check_values", "rows_where"]

# Columns that set an operating point (identify duplicates); responses are everything else.
SETPOINT_QUANTITIES = ("load_fraction", "engine_speed_rev_s", "power_W")


def _fmt(v: float) -> str:
    return f"{v:g}"


def rows_where(mask) -> list[int]:
    """1-based rows where ``mask`` is true."""
    return [int(i) + 1 for i in np.flatnonzero(mask)]


def check_values(raw, values, column_quantity, p: EngineParams, rated, ambient, engines, err, warn) -> None:
    """Envelope (errors) and plausibility (warnings) of every value, one problem per column and kind."""
    n_nom = p.n_nom_rev_s
    speed_max, power_max = ENVELOPE.max_speed_fraction, ENVELOPE.max_power_fraction
    for col, q in column_quantity.items():
        v = values[q]
        fin = np.isfinite(v)
        kind = QUANTITIES[q].kind

        def flag(mask, msg, f=err):
            rows = rows_where(mask & fin)
            if rows:
                f(msg, rows=rows, column=col)

        if q == "load_fraction":
            flag(v < 0, "negative load fraction")
            flag(v > power_max, f"load fraction above {power_max:g} (outside the engine envelope)")
        elif q == "engine_speed_rev_s":
            flag(v <= 0, "speed not positive")
            flag(
                v > speed_max * n_nom,
                f"speed above {speed_max:g} x nominal ({speed_max * n_nom * 60:g} rpm; outside the engine envelope)",
            )
            flag((v > 0) & (v < 0.2 * n_nom), "speed below 0.2 x nominal (suspicious, kept)", warn)
        elif q == "power_W":
            flag(v < 0, "negative power")
            flag(
                v > power_max * rated,
                f"power above {power_max:g} x rated ({power_max * rated / 1e3:g} kW; outside the engine envelope)",
            )
        elif q == "fuel_setting":
            lo, hi = FUEL_SETTING_RANGE
            flag((v < lo) | (v > hi), f"fuel setting outside [{lo:g}, {hi:g}]")
        elif q in ("exhaust_back_pressure_Pa", "cooler_pressure_drop_Pa"):
            flag(v < -5e3, "pressure difference below -50 mbar (suspicious, kept)", warn)
            flag(v > 1e5, "pressure difference above 1 bar (outside any engine's exhaust or cooler)")
        elif q == "ambient_pressure_Pa":
            flag(v <= 0, "ambient pressure not positive")
            flag(
                (v > 0) & ((v < 850e2) | (v > 1100e2)),
                "ambient pressure outside [850, 1100] hPa (suspicious, kept)",
                warn,
            )
        elif q == "ambient_temperature_K":
            flag(v < 0, "temperature below absolute zero")
            flag(
                (v >= 0) & ((v < 243.15) | (v > 333.15)),
                "intake temperature outside [-30, 60] C (suspicious, kept)",
                warn,
            )
        elif q == "relative_humidity":
            flag((v < 0) | (v > 1), "relative humidity outside [0, 100] %")
        elif q.endswith("_Pa"):
            spec = lookup_column(col)
            flag(v <= 0, "negative absolute pressure" + (" (gauge reading below -ambient)" if spec.gauge else ""))
            if spec.gauge:
                flag((v > 0) & (raw[col] < 0), "gauge pressure below ambient (suspicious, kept)", warn)
            elif q == "charge_air_pressure_Pa":
                flag(
                    (v > 0) & (v < 0.9 * ambient["p_amb_Pa"]),
                    "charge-air pressure below ambient (suspicious, kept)",
                    warn,
                )
        elif kind == "temperature":
            flag(v < 0, "temperature below absolute zero")
            flag(
                (v >= 0) & ((v < 223.15) | (v > 1273.15)), "temperature outside [-50, 1000] C (suspicious, kept)", warn
            )
        elif q == "sfc_kg_per_J":
            flag(v <= 0, "specific fuel consumption not positive")
            lo, hi = 150e-3 / 3.6e6, 400e-3 / 3.6e6
            flag((v > 0) & ((v < lo) | (v > hi)), "SFC outside [150, 400] g/kWh (suspicious, kept)", warn)
        elif q in (
            "fuel_mass_flow_kg_s",
            "air_mass_flow_kg_s",
            "exhaust_mass_flow_kg_s",
            "specific_air_flow_kg_per_J",
            "specific_exhaust_flow_kg_per_J",
            "torque_Nm",
        ):
            flag(v < 0, "negative value")
            if q == "fuel_mass_flow_kg_s":
                nominal = p.SFC_nom_kg_per_J * p.P_nom_W
                flag(
                    v > 1.4 * nominal,
                    f"fuel flow above 1.4 x nominal ({1.4 * nominal * 3600:g} kg/h; suspicious, kept)",
                    warn,
                )
        elif q in ("fuel_rack", "air_excess_ratio"):
            flag(v < 0, "negative value")
    # consistency of load fraction and power
    if "load_fraction" in values and "power_W" in values and math.isfinite(rated):
        lf, pw = values["load_fraction"], values["power_W"]
        bad = np.isfinite(lf) & np.isfinite(pw) & (np.abs(pw / rated - lf) > 0.02)
        if np.any(bad):
            warn(
                f"load fraction and power / rated power ({rated / 1e3:g} kW) differ by more than 0.02 "
                "(suspicious, kept)",
                rows=rows_where(bad),
                column=_column_of(column_quantity, "load_fraction"),
            )


def _column_of(column_quantity: Mapping[str, str], quantity: str) -> str | None:
    for c, q in column_quantity.items():
        if q == quantity:
            return c
    return None


def _setpoint_columns(column_quantity) -> list[str]:
    return [c for c, q in column_quantity.items() if q in SETPOINT_QUANTITIES]


def check_duplicates(raw, column_quantity, engines, err) -> None:
    """Duplicate operating points: same engine and same set-point values (load, speed, power); without any
    set-point column, identical rows."""
    keys_cols = _setpoint_columns(column_quantity) or list(column_quantity)
    if not keys_cols:
        return
    n = len(raw[keys_cols[0]])
    groups: dict[tuple, list[int]] = {}
    for i in range(n):
        vals = tuple(raw[c][i] for c in keys_cols)
        if any(not math.isfinite(v) for v in vals):
            continue
        key = ((engines[i] if engines is not None else None),) + tuple(round(v, 9) for v in vals)
        groups.setdefault(key, []).append(i + 1)
    for key, rws in groups.items():
        if len(rws) > 1:
            what = ", ".join(f"{c}={_fmt(v)}" for c, v in zip(keys_cols, key[1:]))
            eng = f"engine {key[0]}, " if key[0] is not None else ""
            err(f"duplicate operating point ({eng}{what})", rows=rws)


def check_across_engines(raw, column_quantity, engines, warn, suspect=None) -> None:
    """With three or more engines at the same set point, a value far from the others' median is suspicious."""
    if engines is None or len(set(engines)) < 3:
        return
    keys_cols = _setpoint_columns(column_quantity)
    if not keys_cols:
        return
    n = len(engines)
    groups: dict[tuple, list[int]] = {}
    for i in range(n):
        vals = tuple(raw[c][i] for c in keys_cols)
        if all(math.isfinite(v) for v in vals):
            groups.setdefault(tuple(round(v, 6) for v in vals), []).append(i)
    for col, q in column_quantity.items():
        if col in keys_cols or QUANTITIES[q].kind == "index":
            continue
        temp = QUANTITIES[q].kind == "temperature"
        for key, idx in groups.items():
            x = raw[col][idx]
            ok = np.isfinite(x)
            if ok.sum() < 3:
                continue
            med = float(np.median(x[ok]))
            for i, xi in zip(idx, x):
                if not math.isfinite(xi):
                    continue
                dev = abs(xi - med)
                if (temp and dev > 25.0) or (not temp and dev > 0.25 * abs(med) and dev > 1e-12):
                    others = ", ".join(f"{engines[k]}: {_fmt(raw[col][k])}" for k in idx if k != i)
                    warn(
                        f"engine {engines[i]} reads {_fmt(xi)} where the other engines at the same set point read "
                        f"{others} (suspicious, kept)",
                        rows=(i + 1,),
                        column=col,
                    )
                    if suspect is not None:
                        suspect.append(
                            {
                                "row": i + 1,
                                "column": col,
                                "value": float(xi),
                                "median_of_others": med,
                                "why": "far from the other engines at the same set point",
                            }
                        )
