"""The column registry of the measured-data format: column name -> (model quantity, unit conversion).

A measured-data CSV names each column ``<quantity stem>_<unit>``, e.g. ``speed_rpm``,
``charge_air_pressure_bar_abs``, ``turbine_outlet_temperature_C``; dimensionless columns carry no
unit (``load_fraction``, ``fuel_rack``).  Every known column maps to a :class:`Quantity` (an SI
quantity named after the keys of :meth:`marine_fdi_env.steady_state.SteadyState.summary`) and an
affine conversion ``SI = value * scale + offset`` (plus the ambient pressure for gauge pressures).

Each quantity knows how to read itself from a model steady state (``Quantity.model``), which is what
makes a column a *channel* the model can be compared on; quantities without a model counterpart
(``fuel_rack``) are operating inputs only.

``charge_air_temperature_C`` is ambiguous in location (after the compressor, or after the cooler in
the charge-air receiver).  :func:`resolve_quantity` decides it from the sidecar: an explicit
``"column_quantities": {"charge_air_temperature_C": "compressor_outlet_temperature_K"}`` wins; else
a column description that mentions the compressor or "before the cooler" means the compressor
outlet; else it is the air at the cylinder inlet (after cooler and inlet duct).
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass
from typing import Callable, Mapping

import numpy as np

__all__ = [
    "Quantity", "ColumnSpec", "QUANTITIES", "COLUMNS", "ID_COLUMNS", "ModelContext", "lookup_column",
    "column_problem", "resolve_quantity", "quantity_stems",
]

ID_COLUMNS = ("engine",)


@dataclass(frozen=True)
class ModelContext:
    """What a quantity needs besides the steady-state summary to read itself off the model."""

    rated_power_W: float
    T_c_K: float  # charge-air cooler outlet temperature of the model (constant parameter)


Summary = Mapping[str, float]


@dataclass(frozen=True)
class Quantity:
    """An SI quantity a measured column can hold.

    kind: ``ratio`` (absolute scale: relative errors meaningful), ``temperature`` (kelvin),
    ``dimensionless`` or ``index`` (no physical unit, e.g. a fuel rack position).
    model: reads the quantity from a steady-state summary (SI keys), ``None`` if the model has none.
    """

    name: str
    si_unit: str
    kind: str
    description: str
    model: Callable[[Summary, ModelContext], float] | None = None


def _s(key: str) -> Callable[[Summary, ModelContext], float]:
    return lambda s, ctx: float(s[key])


def _per_power(key: str) -> Callable[[Summary, ModelContext], float]:
    return lambda s, ctx: float(s[key]) / float(s["power_W"]) if s["power_W"] > 0 else float("nan")


_Q = [
    Quantity("engine_speed_rev_s", "rev/s", "ratio", "engine speed", _s("engine_speed_rev_s")),
    Quantity("power_W", "W", "ratio", "brake power", _s("power_W")),
    Quantity("load_fraction", "-", "dimensionless", "brake power / rated power",
             lambda s, ctx: float(s["power_W"]) / ctx.rated_power_W),
    Quantity("torque_Nm", "N m", "ratio", "brake torque", _s("torque_Nm")),
    Quantity("fuel_setting", "-", "dimensionless", "model fuel setting u (1 = nominal fuel per cycle)",
             _s("fuel_setting")),
    Quantity("fuel_rack", "index", "index", "fuel rack position as recorded (no model counterpart)", None),
    Quantity("fuel_mass_flow_kg_s", "kg/s", "ratio", "fuel mass flow", _s("fuel_mass_flow_kg_s")),
    Quantity("sfc_kg_per_J", "kg/J", "ratio", "specific fuel consumption", _s("sfc_kg_per_J")),
    Quantity("charge_air_pressure_Pa", "Pa", "ratio", "charge-air (scavenge) pressure, absolute",
             _s("charge_air_pressure_Pa")),
    Quantity("exhaust_receiver_pressure_Pa", "Pa", "ratio", "exhaust receiver pressure, absolute",
             _s("exhaust_receiver_pressure_Pa")),
    Quantity("p_max_Pa", "Pa", "ratio", "maximum cylinder pressure, absolute", _s("p_max_Pa")),
    Quantity("compressor_outlet_temperature_K", "K", "temperature", "charge air after the compressor",
             _s("compressor_outlet_temperature_K")),
    Quantity("charge_air_cooler_outlet_temperature_K", "K", "temperature",
             "charge air after the cooler (model: the constant T_c of eq. 3.37)", lambda s, ctx: ctx.T_c_K),
    Quantity("inlet_air_temperature_K", "K", "temperature",
             "air at the cylinder inlet, after cooler and inlet duct (z1 of eq. 3.37)",
             _s("inlet_air_temperature_K")),
    Quantity("turbine_inlet_temperature_K", "K", "temperature", "exhaust before the turbine",
             _s("turbine_inlet_temperature_K")),
    Quantity("turbine_outlet_temperature_K", "K", "temperature", "exhaust after the turbine",
             _s("turbine_outlet_temperature_K")),
    Quantity("air_mass_flow_kg_s", "kg/s", "ratio", "air mass flow incl. scavenge air", _s("air_mass_flow_kg_s")),
    Quantity("exhaust_mass_flow_kg_s", "kg/s", "ratio", "exhaust mass flow", _s("exhaust_mass_flow_kg_s")),
    Quantity("specific_air_flow_kg_per_J", "kg/J", "ratio", "air mass flow / brake power",
             _per_power("air_mass_flow_kg_s")),
    Quantity("specific_exhaust_flow_kg_per_J", "kg/J", "ratio", "exhaust mass flow / brake power",
             _per_power("exhaust_mass_flow_kg_s")),
    Quantity("air_excess_ratio", "-", "dimensionless", "air excess ratio lambda", _s("air_excess_ratio")),
]
QUANTITIES: dict[str, Quantity] = {q.name: q for q in _Q}

# Placeholder quantity of the ambiguous charge-air temperature column, resolved per dataset.
AMBIGUOUS_CHARGE_AIR_T = "charge_air_temperature_K"


@dataclass(frozen=True)
class ColumnSpec:
    """A known column: its stem, unit, quantity and conversion ``SI = value*scale + offset (+ p_amb)``."""

    column: str
    stem: str
    unit: str
    quantity: str
    scale: float = 1.0
    offset: float = 0.0
    gauge: bool = False

    def to_si(self, values, p_amb_Pa: float | None = None) -> np.ndarray:
        v = np.asarray(values, dtype=float) * self.scale + self.offset
        if self.gauge:
            if p_amb_Pa is None:
                raise ValueError(f"column {self.column!r} is a gauge pressure: an ambient pressure is needed")
            v = v + p_amb_Pa
        return v

    def from_si(self, values, p_amb_Pa: float | None = None) -> np.ndarray:
        v = np.asarray(values, dtype=float)
        if self.gauge:
            if p_amb_Pa is None:
                raise ValueError(f"column {self.column!r} is a gauge pressure: an ambient pressure is needed")
            v = v - p_amb_Pa
        return (v - self.offset) / self.scale


# unit tables: unit suffix -> (scale, offset, gauge)
_SPEED = {"rpm": (1.0 / 60.0, 0.0, False), "rev_s": (1.0, 0.0, False), "rev_per_s": (1.0, 0.0, False)}
_POWER = {"W": (1.0, 0.0, False), "kW": (1e3, 0.0, False), "MW": (1e6, 0.0, False)}
_TORQUE = {"Nm": (1.0, 0.0, False), "kNm": (1e3, 0.0, False)}
_PRESSURE = {
    "bar_abs": (1e5, 0.0, False), "bar_gauge": (1e5, 0.0, True),
    "kPa_abs": (1e3, 0.0, False), "kPa_gauge": (1e3, 0.0, True),
    "MPa_abs": (1e6, 0.0, False), "Pa_abs": (1.0, 0.0, False),
}
_TEMPERATURE = {"C": (1.0, 273.15, False), "K": (1.0, 0.0, False)}
_MASS_FLOW = {"kg_per_h": (1.0 / 3600.0, 0.0, False), "kg_per_s": (1.0, 0.0, False),
              "t_per_h": (1000.0 / 3600.0, 0.0, False)}
_SPECIFIC = {"g_per_kWh": (1e-3 / 3.6e6, 0.0, False), "kg_per_kWh": (1.0 / 3.6e6, 0.0, False),
             "kg_per_J": (1.0, 0.0, False)}
_SPECIFIC_FLOW = {"kg_per_kWh": (1.0 / 3.6e6, 0.0, False), "kg_per_J": (1.0, 0.0, False)}

# stem -> {unit: quantity} for stems whose quantity depends on the unit (mass flow vs specific flow)
_STEMS: dict[str, list[tuple[dict, str]]] = {
    "speed": [(_SPEED, "engine_speed_rev_s")],
    "power": [(_POWER, "power_W")],
    "torque": [(_TORQUE, "torque_Nm")],
    "fuel_flow": [(_MASS_FLOW, "fuel_mass_flow_kg_s")],
    "sfc": [(_SPECIFIC, "sfc_kg_per_J")],
    "charge_air_pressure": [(_PRESSURE, "charge_air_pressure_Pa")],
    "exhaust_receiver_pressure": [(_PRESSURE, "exhaust_receiver_pressure_Pa")],
    "max_cylinder_pressure": [(_PRESSURE, "p_max_Pa")],
    "compressor_outlet_temperature": [(_TEMPERATURE, "compressor_outlet_temperature_K")],
    "charge_air_cooler_outlet_temperature": [(_TEMPERATURE, "charge_air_cooler_outlet_temperature_K")],
    "inlet_air_temperature": [(_TEMPERATURE, "inlet_air_temperature_K")],
    "charge_air_temperature": [(_TEMPERATURE, AMBIGUOUS_CHARGE_AIR_T)],
    "turbine_inlet_temperature": [(_TEMPERATURE, "turbine_inlet_temperature_K")],
    "turbine_outlet_temperature": [(_TEMPERATURE, "turbine_outlet_temperature_K")],
    "air_flow": [(_SPECIFIC_FLOW, "specific_air_flow_kg_per_J"),
                 ({k: v for k, v in _MASS_FLOW.items()}, "air_mass_flow_kg_s")],
    "exhaust_flow": [(_SPECIFIC_FLOW, "specific_exhaust_flow_kg_per_J"),
                     ({k: v for k, v in _MASS_FLOW.items()}, "exhaust_mass_flow_kg_s")],
}

# dimensionless columns: the full name, no unit suffix
_DIMENSIONLESS = {
    "load_fraction": ("load_fraction", 1.0),
    "load_percent": ("load_fraction", 0.01),
    "fuel_rack": ("fuel_rack", 1.0),
    "fuel_setting": ("fuel_setting", 1.0),
    "air_excess_ratio": ("air_excess_ratio", 1.0),
}


def _build() -> dict[str, ColumnSpec]:
    out: dict[str, ColumnSpec] = {}
    for stem, tables in _STEMS.items():
        for units, quantity in tables:
            for unit, (scale, offset, gauge) in units.items():
                col = f"{stem}_{unit}"
                out[col] = ColumnSpec(col, stem, unit, quantity, scale, offset, gauge)
    for col, (quantity, scale) in _DIMENSIONLESS.items():
        out[col] = ColumnSpec(col, col, "-", quantity, scale, 0.0, False)
    return out


COLUMNS: dict[str, ColumnSpec] = _build()


def quantity_stems() -> list[str]:
    """The stems that need a unit suffix (longest first)."""
    return sorted(_STEMS, key=len, reverse=True)


def lookup_column(name: str) -> ColumnSpec | None:
    return COLUMNS.get(name)


def _units_of(stem: str) -> list[str]:
    return [c.unit for c in COLUMNS.values() if c.stem == stem]


def column_problem(name: str) -> str | None:
    """Why ``name`` is not a known column (``None`` if it is known or an id column)."""
    if name in COLUMNS or name in ID_COLUMNS:
        return None
    if name == "":
        return "empty column name"
    for stem in quantity_stems():
        if name == stem:
            units = ", ".join(f"{stem}_{u}" for u in _units_of(stem))
            return f"missing unit suffix: {name!r} has no unit (use one of {units})"
        if name.startswith(stem + "_"):
            unit = name[len(stem) + 1:]
            units = ", ".join(f"{stem}_{u}" for u in _units_of(stem))
            hint = " ('bar' is ambiguous: say bar_abs or bar_gauge)" if unit in ("bar", "kPa", "MPa", "Pa") else ""
            return f"unknown unit {unit!r} in column {name!r}{hint}; known: {units}"
    close = difflib.get_close_matches(name, list(COLUMNS) + list(ID_COLUMNS), n=3, cutoff=0.75)
    hint = f" (did you mean {', '.join(close)}?)" if close else ""
    return f"unknown column {name!r}{hint}"


_COMPRESSOR_HINTS = ("after the compressor", "after compressor", "compressor outlet", "before the cooler",
                     "before cooler", "before the intercooler")


def resolve_quantity(column: str, spec: ColumnSpec, meta: Mapping) -> tuple[str, str | None]:
    """The quantity of ``column`` in this dataset and a note when it had to be resolved."""
    explicit = (meta.get("column_quantities") or {}).get(column)
    if explicit is not None:
        if explicit not in QUANTITIES:
            raise ValueError(f"sidecar column_quantities[{column!r}] = {explicit!r} is not a known quantity; "
                             f"known: {', '.join(QUANTITIES)}")
        return explicit, f"{column}: quantity {explicit} (sidecar column_quantities)"
    if spec.quantity != AMBIGUOUS_CHARGE_AIR_T:
        return spec.quantity, None
    desc = str((meta.get("columns") or {}).get(column, "")).lower()
    if any(h in desc for h in _COMPRESSOR_HINTS):
        return "compressor_outlet_temperature_K", (
            f"{column}: location ambiguous; the sidecar description ({desc!r}) places it after the compressor, "
            "so it is compared with the model's compressor outlet temperature")
    return "inlet_air_temperature_K", (
        f"{column}: location ambiguous; taken as the air at the cylinder inlet (after the cooler). Set "
        "\"column_quantities\" in the sidecar to say otherwise")
