"""The column registry of the measured-data format: column name -> role, model quantity, unit conversion.

A measured-data CSV names each column ``<quantity stem>_<unit>``, e.g. ``speed_rpm``,
``charge_air_pressure_bar_abs``, ``turbine_outlet_temperature_C``; dimensionless columns carry no
unit (``load_fraction``, ``fuel_rack``).  Every known column has a *role*:

``channel``       a model output compared with the measurement (a :class:`Quantity` with ``model``);
``setpoint``      fixes the operating point (power, load fraction, speed, fuel flow, fuel rack) and is a
                  channel when something else fixes the point;
``boundary``      a boundary condition of the row (ambient pressure, compressor inlet temperature, exhaust
                  back pressure): the model runs at the row's value, it is not compared;
``member``        one cylinder of a per-cylinder group (``cylinder_3_exhaust_temperature_C``): the group's
                  spread per row is the measurement spread of the engine-mean channel;
``not_modelled``  recorded, but the model has no counterpart (with the reason; listed in every report).

Conversions: ``SI = value * scale + offset`` (plus the row's ambient pressure for gauge pressures).

Pressures must say gauge or absolute in the unit (``bar_gauge``, ``bar_abs``); a plain ``bar`` is an
error except where a convention fixes it (``exhaust_back_pressure_mbar`` and pressure drops are
differences by definition) or the reference is a stated assumption: maximum cylinder pressures in plain
``bar`` are taken as gauge (the convention of the other pressures of a shop-test protocol) with a
warning, unless the sidecar says otherwise (``"pressure_reference": {column: "gauge" | "absolute"}``).

Where a column's quantity depends on where it was measured (``charge_air_temperature_C``: after the
compressor, or after the cooler), only an explicit sidecar key decides it:
``"column_quantities": {"charge_air_temperature_C": "compressor_outlet_temperature_K"}``.  Without the
key it is taken as the air after the cooler (the usual meaning of "charge-air temperature") with a
warning naming the column; free-text descriptions are never read.
"""

from __future__ import annotations

import difflib
import re
from dataclasses import dataclass
from typing import Callable, Mapping

import numpy as np

__all__ = [
    "Quantity",
    "ColumnSpec",
    "QUANTITIES",
    "COLUMNS",
    "ID_COLUMNS",
    "ModelContext",
    "lookup_column",
    "column_problem",
    "resolve_quantity",
    "quantity_stems",
    "ROLES",
    "AMBIGUOUS_CHARGE_AIR_T",
    "GROUP_PATTERNS",
]

ID_COLUMNS = ("engine",)
ROLES = ("channel", "setpoint", "boundary", "member", "not_modelled", "id")


@dataclass(frozen=True)
class ModelContext:
    """What a quantity needs besides the steady-state summary to read itself off the model."""

    rated_power_W: float


Summary = Mapping[str, float]


@dataclass(frozen=True)
class Quantity:
    """An SI quantity a measured column can hold.

    kind: ``ratio`` (absolute scale: relative errors meaningful), ``temperature`` (kelvin),
    ``dimensionless`` or ``index`` (no physical unit, e.g. a fuel rack position).
    model: reads the quantity from a steady-state summary (SI keys), ``None`` if the model has none.
    role: the role of a column holding it (see the module docstring).  reason: why a
    ``not_modelled``/``boundary`` quantity is not compared.
    """

    name: str
    si_unit: str
    kind: str
    description: str
    model: Callable[[Summary, ModelContext], float] | None = None
    role: str = "channel"
    reason: str = ""


def _s(key: str, factor: float = 1.0) -> Callable[[Summary, ModelContext], float]:
    return lambda s, ctx: float(s[key]) * factor


def _per_power(key: str) -> Callable[[Summary, ModelContext], float]:
    return lambda s, ctx: float(s[key]) / float(s["power_W"]) if s["power_W"] > 0 else float("nan")


_Q = [
    Quantity("engine_speed_rev_s", "rev/s", "ratio", "engine speed", _s("engine_speed_rev_s"), "setpoint"),
    Quantity("power_W", "W", "ratio", "brake power", _s("power_W"), "setpoint"),
    Quantity(
        "load_fraction",
        "-",
        "dimensionless",
        "brake power / rated power",
        lambda s, ctx: float(s["power_W"]) / ctx.rated_power_W,
        "setpoint",
    ),
    Quantity("torque_Nm", "N m", "ratio", "brake torque", _s("torque_Nm")),
    Quantity(
        "fuel_setting",
        "-",
        "dimensionless",
        "model fuel setting u (1 = nominal fuel per cycle)",
        _s("fuel_setting"),
        "setpoint",
    ),
    Quantity("fuel_rack", "index", "index", "fuel rack position as recorded (no model counterpart)", None, "setpoint"),
    Quantity("fuel_mass_flow_kg_s", "kg/s", "ratio", "fuel mass flow", _s("fuel_mass_flow_kg_s"), "setpoint"),
    Quantity("sfc_kg_per_J", "kg/J", "ratio", "specific fuel consumption", _s("sfc_kg_per_J")),
    Quantity(
        "sfc_iso_kg_per_J",
        "kg/J",
        "ratio",
        "specific fuel consumption corrected to ISO 3046-1 conditions",
        None,
        "not_modelled",
        "the ISO correction needs the fuel's heating value, which the data do not record; the measured fuel "
        "flow carries the same information and is compared (the report gives the implied correction factor)",
    ),
    Quantity(
        "charge_air_pressure_Pa",
        "Pa",
        "ratio",
        "charge-air (scavenge) pressure, absolute",
        _s("charge_air_pressure_Pa"),
    ),
    Quantity(
        "exhaust_receiver_pressure_Pa",
        "Pa",
        "ratio",
        "exhaust receiver (turbine inlet) pressure, absolute",
        _s("exhaust_receiver_pressure_Pa"),
    ),
    Quantity("p_max_Pa", "Pa", "ratio", "maximum cylinder pressure, absolute (engine mean)", _s("p_max_Pa")),
    Quantity(
        "compressor_outlet_temperature_K",
        "K",
        "temperature",
        "charge air after the compressor",
        _s("compressor_outlet_temperature_K"),
    ),
    Quantity(
        "charge_air_cooler_outlet_temperature_K",
        "K",
        "temperature",
        "charge air after the cooler (the model's T_c: constant in the base model, eq. 3.37)",
        _s("charge_air_cooler_outlet_temperature_K"),
    ),
    Quantity(
        "inlet_air_temperature_K",
        "K",
        "temperature",
        "air at the cylinder inlet, after cooler and inlet duct (z1 of eq. 3.37)",
        _s("inlet_air_temperature_K"),
    ),
    Quantity(
        "turbine_inlet_temperature_K",
        "K",
        "temperature",
        "exhaust before the turbine (its thermocouple)",
        _s("turbine_inlet_temperature_K"),
    ),
    Quantity(
        "turbine_outlet_temperature_K",
        "K",
        "temperature",
        "exhaust at the turbine outlet",
        _s("turbine_outlet_temperature_K"),
    ),
    Quantity(
        "cylinder_outlet_temperature_K",
        "K",
        "temperature",
        "gas leaving the cylinders (engine mean of the cylinder outlet thermocouples; model: exhaust and slip "
        "air mixed, before manifold heat loss and bypass air)",
        _s("cylinder_outlet_temperature_K"),
    ),
    Quantity(
        "turbocharger_speed_rev_s",
        "rev/s",
        "ratio",
        "turbocharger rotor speed",
        _s("turbocharger_speed_rpm", 1.0 / 60.0),
    ),
    Quantity(
        "air_mass_flow_kg_s",
        "kg/s",
        "ratio",
        "compressor air mass flow (cylinders and bypass)",
        _s("air_mass_flow_kg_s"),
    ),
    Quantity("exhaust_mass_flow_kg_s", "kg/s", "ratio", "exhaust mass flow", _s("exhaust_mass_flow_kg_s")),
    Quantity(
        "specific_air_flow_kg_per_J", "kg/J", "ratio", "air mass flow / brake power", _per_power("air_mass_flow_kg_s")
    ),
    Quantity(
        "specific_exhaust_flow_kg_per_J",
        "kg/J",
        "ratio",
        "exhaust mass flow / brake power",
        _per_power("exhaust_mass_flow_kg_s"),
    ),
    Quantity("air_excess_ratio", "-", "dimensionless", "air excess ratio lambda", _s("air_excess_ratio")),
    # boundary conditions of a row
    Quantity(
        "ambient_pressure_Pa",
        "Pa",
        "ratio",
        "ambient (test-bed) pressure",
        None,
        "boundary",
        "boundary condition: the row's ambient pressure (compressor inlet, gauge readings, turbine back pressure)",
    ),
    Quantity(
        "ambient_temperature_K",
        "K",
        "temperature",
        "air temperature at the compressor inlet",
        None,
        "boundary",
        "boundary condition: the row's compressor inlet temperature (T_amb of the model)",
    ),
    Quantity(
        "exhaust_back_pressure_Pa",
        "Pa",
        "ratio",
        "exhaust pressure after the turbine above ambient",
        None,
        "boundary",
        "boundary condition: the turbine back pressure p_ex = ambient + back pressure",
    ),
    # recorded, no model counterpart
    Quantity(
        "relative_humidity",
        "-",
        "dimensionless",
        "relative humidity of the intake air",
        None,
        "not_modelled",
        "the model's air is dry (table 4.1 gas properties); humidity changes c_p and R by well under 1 %",
    ),
    Quantity(
        "cooler_pressure_drop_Pa",
        "Pa",
        "ratio",
        "pressure drop over the charge-air cooler",
        None,
        "not_modelled",
        "the model has no cooler pressure drop (compressor outlet = charge-air pressure); "
        "recorded drops are below 1 % of the charge-air pressure",
    ),
]
QUANTITIES: dict[str, Quantity] = {q.name: q for q in _Q}

# Placeholder quantity of the ambiguous charge-air temperature column, resolved per dataset.
AMBIGUOUS_CHARGE_AIR_T = "charge_air_temperature_K"


@dataclass(frozen=True)
class ColumnSpec:
    """A known column: stem, unit, quantity, conversion ``SI = value*scale + offset (+ p_amb)``, role.

    gauge_assumed : the column's unit does not say gauge or absolute and the registry assumes gauge
    (a warning in every load; the sidecar's ``pressure_reference`` can say otherwise).
    group : the per-cylinder group of a ``member`` column; index : its cylinder number.
    """

    column: str
    stem: str
    unit: str
    quantity: str
    scale: float = 1.0
    offset: float = 0.0
    gauge: bool = False
    role: str = ""
    gauge_assumed: bool = False
    group: str = ""
    index: int = 0

    @property
    def effective_role(self) -> str:
        """The column's role: its own (``member``) or its quantity's."""
        if self.role:
            return self.role
        q = QUANTITIES.get(self.quantity)
        return q.role if q is not None else "channel"

    def to_si(self, values, p_amb_Pa=None) -> np.ndarray:
        v = np.asarray(values, dtype=float) * self.scale + self.offset
        if self.gauge:
            if p_amb_Pa is None:
                raise ValueError(f"column {self.column!r} is a gauge pressure: an ambient pressure is needed")
            v = v + np.asarray(p_amb_Pa, float)
        return v

    def from_si(self, values, p_amb_Pa=None) -> np.ndarray:
        v = np.asarray(values, dtype=float)
        if self.gauge:
            if p_amb_Pa is None:
                raise ValueError(f"column {self.column!r} is a gauge pressure: an ambient pressure is needed")
            v = v - np.asarray(p_amb_Pa, float)
        return (v - self.offset) / self.scale


# unit tables: unit suffix -> (scale, offset, gauge)
_SPEED = {"rpm": (1.0 / 60.0, 0.0, False), "rev_s": (1.0, 0.0, False), "rev_per_s": (1.0, 0.0, False)}
_POWER = {"W": (1.0, 0.0, False), "kW": (1e3, 0.0, False), "MW": (1e6, 0.0, False)}
_TORQUE = {"Nm": (1.0, 0.0, False), "kNm": (1e3, 0.0, False)}
_PRESSURE = {
    "bar_abs": (1e5, 0.0, False),
    "bar_gauge": (1e5, 0.0, True),
    "kPa_abs": (1e3, 0.0, False),
    "kPa_gauge": (1e3, 0.0, True),
    "MPa_abs": (1e6, 0.0, False),
    "Pa_abs": (1.0, 0.0, False),
    "mbar_abs": (1e2, 0.0, False),
    "mbar_gauge": (1e2, 0.0, True),
}
_ABS_PRESSURE = {
    "hPa": (1e2, 0.0, False),
    "mbar": (1e2, 0.0, False),
    "bar": (1e5, 0.0, False),
    "kPa": (1e3, 0.0, False),
    "Pa": (1.0, 0.0, False),
}  # ambient pressure: absolute by nature
_DIFF_PRESSURE = {
    "mbar": (1e2, 0.0, False),
    "kPa": (1e3, 0.0, False),
    "Pa": (1.0, 0.0, False),
    "bar": (1e5, 0.0, False),
}  # differences (back pressure above ambient, pressure drops)
_TEMPERATURE = {"C": (1.0, 273.15, False), "K": (1.0, 0.0, False)}
_MASS_FLOW = {
    "kg_per_h": (1.0 / 3600.0, 0.0, False),
    "kg_per_s": (1.0, 0.0, False),
    "t_per_h": (1000.0 / 3600.0, 0.0, False),
}
_SPECIFIC = {
    "g_per_kWh": (1e-3 / 3.6e6, 0.0, False),
    "kg_per_kWh": (1.0 / 3.6e6, 0.0, False),
    "kg_per_J": (1.0, 0.0, False),
}
_SPECIFIC_FLOW = {"kg_per_kWh": (1.0 / 3.6e6, 0.0, False), "kg_per_J": (1.0, 0.0, False)}
_PERCENT = {"percent": (0.01, 0.0, False), "fraction": (1.0, 0.0, False)}
_RACK = {"mm": (1.0, 0.0, False), "index": (1.0, 0.0, False)}

# stem -> [(unit table, quantity)]; several tables where the quantity depends on the unit
_STEMS: dict[str, list[tuple[dict, str]]] = {
    "speed": [(_SPEED, "engine_speed_rev_s")],
    "power": [(_POWER, "power_W")],
    "torque": [(_TORQUE, "torque_Nm")],
    "fuel_flow": [(_MASS_FLOW, "fuel_mass_flow_kg_s")],
    "fuel_rack": [(_RACK, "fuel_rack")],
    "sfc": [(_SPECIFIC, "sfc_kg_per_J")],
    "sfoc": [(_SPECIFIC, "sfc_kg_per_J")],
    "sfoc_iso": [(_SPECIFIC, "sfc_iso_kg_per_J")],
    "sfc_iso": [(_SPECIFIC, "sfc_iso_kg_per_J")],
    "charge_air_pressure": [(_PRESSURE, "charge_air_pressure_Pa")],
    "exhaust_receiver_pressure": [(_PRESSURE, "exhaust_receiver_pressure_Pa")],
    "turbine_inlet_pressure": [(_PRESSURE, "exhaust_receiver_pressure_Pa")],
    "max_cylinder_pressure": [(_PRESSURE, "p_max_Pa")],
    "mean_max_cylinder_pressure": [(_PRESSURE, "p_max_Pa")],
    "compressor_outlet_temperature": [(_TEMPERATURE, "compressor_outlet_temperature_K")],
    "charge_air_cooler_outlet_temperature": [(_TEMPERATURE, "charge_air_cooler_outlet_temperature_K")],
    "inlet_air_temperature": [(_TEMPERATURE, "inlet_air_temperature_K")],
    "charge_air_temperature": [(_TEMPERATURE, AMBIGUOUS_CHARGE_AIR_T)],
    "turbine_inlet_temperature": [(_TEMPERATURE, "turbine_inlet_temperature_K")],
    "turbine_outlet_temperature": [(_TEMPERATURE, "turbine_outlet_temperature_K")],
    "cylinder_exhaust_temperature_mean": [(_TEMPERATURE, "cylinder_outlet_temperature_K")],
    "cylinder_outlet_temperature": [(_TEMPERATURE, "cylinder_outlet_temperature_K")],
    "turbocharger_speed": [(_SPEED, "turbocharger_speed_rev_s")],
    "air_flow": [(_SPECIFIC_FLOW, "specific_air_flow_kg_per_J"), (_MASS_FLOW, "air_mass_flow_kg_s")],
    "exhaust_flow": [(_SPECIFIC_FLOW, "specific_exhaust_flow_kg_per_J"), (_MASS_FLOW, "exhaust_mass_flow_kg_s")],
    "ambient_pressure": [(_ABS_PRESSURE, "ambient_pressure_Pa")],
    "compressor_inlet_temperature": [(_TEMPERATURE, "ambient_temperature_K")],
    "ambient_temperature": [(_TEMPERATURE, "ambient_temperature_K")],
    "exhaust_back_pressure": [(_DIFF_PRESSURE, "exhaust_back_pressure_Pa")],
    "relative_humidity": [(_PERCENT, "relative_humidity")],
    "charge_air_cooler_pressure_drop": [(_DIFF_PRESSURE, "cooler_pressure_drop_Pa")],
}

# dimensionless columns: the full name, no unit suffix
_DIMENSIONLESS = {
    "load_fraction": ("load_fraction", 1.0),
    "load_percent": ("load_fraction", 0.01),
    "fuel_rack": ("fuel_rack", 1.0),
    "fuel_setting": ("fuel_setting", 1.0),
    "air_excess_ratio": ("air_excess_ratio", 1.0),
}

# plain-"bar" maximum cylinder pressures: gauge by assumption (see the module docstring)
_ASSUMED_GAUGE = {"mean_max_cylinder_pressure_bar": "p_max_Pa", "max_cylinder_pressure_bar": "p_max_Pa"}

# per-cylinder groups: pattern -> (group (the engine-mean quantity), unit table, gauge assumed)
GROUP_PATTERNS: dict[str, tuple[re.Pattern, str, dict, bool]] = {
    "cylinder_exhaust_temperature": (
        re.compile(r"^cylinder_(\d+)_exhaust_temperature_(C|K)$"),
        "cylinder_outlet_temperature_K",
        _TEMPERATURE,
        False,
    ),
    "cylinder_max_pressure": (
        re.compile(r"^cylinder_(\d+)_max_pressure_(bar|bar_abs|bar_gauge)$"),
        "p_max_Pa",
        {"bar": (1e5, 0.0, True), "bar_abs": (1e5, 0.0, False), "bar_gauge": (1e5, 0.0, True)},
        True,
    ),
}


def _build() -> dict[str, ColumnSpec]:
    out: dict[str, ColumnSpec] = {}
    for stem, tables in _STEMS.items():
        for units, quantity in tables:
            for unit, (scale, offset, gauge) in units.items():
                col = f"{stem}_{unit}"
                out.setdefault(col, ColumnSpec(col, stem, unit, quantity, scale, offset, gauge))
    for col, (quantity, scale) in _DIMENSIONLESS.items():
        out[col] = ColumnSpec(col, col, "-", quantity, scale, 0.0, False)
    for col, quantity in _ASSUMED_GAUGE.items():
        out[col] = ColumnSpec(col, col[:-4], "bar", quantity, 1e5, 0.0, True, gauge_assumed=True)
    return out


COLUMNS: dict[str, ColumnSpec] = _build()


def quantity_stems() -> list[str]:
    """The stems that need a unit suffix (longest first)."""
    return sorted(_STEMS, key=len, reverse=True)


def lookup_column(name: str) -> ColumnSpec | None:
    """The spec of a registered column or a per-cylinder group member (``None`` if unknown)."""
    spec = COLUMNS.get(name)
    if spec is not None:
        return spec
    for group, (pat, quantity, units, assumed) in GROUP_PATTERNS.items():
        m = pat.match(name)
        if m:
            scale, offset, gauge = units[m.group(2)]
            return ColumnSpec(
                name,
                group,
                m.group(2),
                quantity,
                scale,
                offset,
                gauge,
                role="member",
                gauge_assumed=assumed and m.group(2) == "bar",
                group=group,
                index=int(m.group(1)),
            )
    return None


def _units_of(stem: str) -> list[str]:
    return [c.unit for c in COLUMNS.values() if c.stem == stem]


def column_problem(name: str) -> str | None:
    """Why ``name`` is not a known column (``None`` if it is known or an id column)."""
    if lookup_column(name) is not None or name in ID_COLUMNS:
        return None
    if name == "":
        return "empty column name"
    for stem in quantity_stems():
        if name == stem:
            units = ", ".join(f"{stem}_{u}" for u in _units_of(stem))
            return f"missing unit suffix: {name!r} has no unit (use one of {units})"
        if name.startswith(stem + "_"):
            unit = name[len(stem) + 1 :]
            units = ", ".join(f"{stem}_{u}" for u in _units_of(stem))
            hint = " ('bar' is ambiguous: say bar_abs or bar_gauge)" if unit in ("bar", "kPa", "MPa", "Pa") else ""
            return f"unknown unit {unit!r} in column {name!r}{hint}; known: {units}"
    close = difflib.get_close_matches(name, list(COLUMNS) + list(ID_COLUMNS), n=3, cutoff=0.75)
    hint = f" (did you mean {', '.join(close)}?)" if close else ""
    return f"unknown column {name!r}{hint}"


def resolve_quantity(column: str, spec: ColumnSpec, meta: Mapping) -> tuple[str, str | None, bool]:
    """The quantity of ``column`` in this dataset, a note on how it was decided, and whether that note is a
    warning (an assumption the sidecar should settle)."""
    explicit = (meta.get("column_quantities") or {}).get(column)
    if explicit is not None:
        if explicit not in QUANTITIES:
            raise ValueError(
                f"sidecar column_quantities[{column!r}] = {explicit!r} is not a known quantity; "
                f"known: {', '.join(QUANTITIES)}"
            )
        return explicit, f"{column}: quantity {explicit} (sidecar column_quantities)", False
    if spec.quantity != AMBIGUOUS_CHARGE_AIR_T:
        return spec.quantity, None, False
    return (
        "charge_air_cooler_outlet_temperature_K",
        (
            f"{column}: where it is measured (after the compressor or after the cooler) is not stated by the sidecar "
            'key "column_quantities"; taken as the air after the cooler. Set "column_quantities": '
            f'{{"{column}": "compressor_outlet_temperature_K"}} (or ...cooler_outlet...) to decide'
        ),
        True,
    )
