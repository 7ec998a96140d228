"""The measured-data format and the checked dataset: :class:`MeasuredDataset`, what the checks found
(:class:`DataFinding`), and what the data-in stage hands on.

The format (docs/measured_data.md): one row per operating point, the unit in each column's name.  Column names are
registered in :mod:`marine_fdi_env.validation.measured.columns` (``speed_rpm``, ``power_kW``,
``charge_air_pressure_bar_abs``, ``charge_air_pressure_bar_gauge``, ``turbine_outlet_temperature_C``,
``fuel_flow_kg_per_h``, ``sfc_g_per_kWh``, ``air_flow_kg_per_kWh``, ``load_fraction``, ``fuel_rack``, ...), plus an
optional ``engine`` id column when several engines are recorded.  Empty cells (and ``NA``/``NaN``/``n/a``) are
missing values: they become NaN and are counted in the data-quality summary, never an error.  A CSV file or a
Parquet file holds it (:mod:`.readers`).

Sidecar ``FILE.meta.json`` (a JSON object, beside the file whatever its format; :mod:`.sidecar`)
    ``engine_params``   name of the parameter set (required unless given to the loader);
    ``load_law``        free text ("propeller law", "constant speed", "controllable pitch ..."), optional;
    ambient             ``ambient_pressure_bar``/``_Pa``, ``ambient_temperature_C``/``_K`` (or ``"ambient":
                        "not recorded"``); gauge pressures are made absolute with the recorded ambient
                        pressure, else with the parameter set's ``p_amb_Pa``;
    ``columns``         description per column; ``source`` (provenance), ``kind``, ``notes``;
    ``rated_power_kW``  reference of ``load_fraction`` (default: the parameter set's ``P_nom_W``);
    ``column_quantities`` optional {column: quantity} to resolve ambiguous columns (see columns.py);
    ``fuel_rack_at_nominal`` optional rack position at fuel setting 1 (for rack matching);
    ``pressure_reference`` optional {column: "gauge" | "absolute"} for pressures whose unit does not say;
    ``tolerances`` optional {column: value in its units}.

Roles (:mod:`.columns`): every column is a comparison channel, a set point, a per-row boundary
condition (ambient pressure, compressor inlet temperature, exhaust back pressure: the model runs at the
row's value), a member of a per-cylinder group (the group's spread per row is the measurement spread of
the engine-mean channel) or recorded but not modelled (listed with the reason).  Nothing is dropped
silently: :attr:`MeasuredDataset.column_role` and :meth:`MeasuredDataset.column_inventory` say what
happens to each column.

Boundary readings are checked for outliers across rows (robust z-score of the deviation from the
other rows' median): a reading like a compressor inlet temperature of 0 C among rows at 28-36 C is a
recording error.  It is reported (:attr:`MeasuredDataset.boundary_outliers`), left out, and the row runs
at the median of the other rows' readings.

The checks (:mod:`.checks`, after any reader) collect *every* problem with its row and column; errors raise one
:class:`DatasetError` (a ``ValueError``) listing all of them, suspicious but kept values give :class:`DataWarning`
warnings (also kept in ``MeasuredDataset.warnings``).  Row numbers are 1-based data rows; in a text file the line is
row + 1 (the header is line 1).  :func:`~.loader.load_measured` reads and checks a file.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, Iterable, Mapping

import numpy as np

from ...engine.params import EngineParams, load_params
from ...errors import DatasetError
from .columns import QUANTITIES, ColumnSpec, lookup_column
from .plausibility import SETPOINT_QUANTITIES

__all__ = [
    "MeasuredDataset",
    "DatasetError",
    "DataWarning",
    "DataFinding",
    "normalise_load_law",
    "quality_summary",
]


class DataWarning(UserWarning):
    """A suspicious measured value that is kept (and reported)."""


@dataclass(frozen=True)
class DataFinding:
    """One problem found in a dataset: its rows (1-based data rows), column and message."""

    severity: str  # "error" | "warning"
    message: str
    rows: tuple[int, ...] = ()
    column: str | None = None

    def __str__(self) -> str:
        where = []
        if self.rows:
            lines = ", ".join(str(r + 1) for r in self.rows)
            rows = ", ".join(str(r) for r in self.rows)
            where.append(
                f"row{'s' if len(self.rows) > 1 else ''} {rows} (line{'s' if len(self.rows) > 1 else ''} {lines})"
            )
        if self.column is not None:
            where.append(f"column {self.column!r}")
        return (", ".join(where) + ": " if where else "") + self.message


@dataclass(frozen=True)
class MeasuredDataset:
    """A loaded, checked measured dataset.

    values : SI arrays per quantity (:data:`marine_fdi_env.validation.measured.columns.QUANTITIES`), one entry per
        point; NaN where the cell was empty.  raw : the columns in the file's units.
    column_quantity : quantity of each data column (after resolving ambiguous columns).
    engines : engine id per point (``None`` when the file has no ``engine`` column).
    ambient : ``{"p_amb_Pa", "T_amb_K", "recorded"}``; p_amb_Pa is the pressure used for gauge columns
        (an array per point when the file records it per row).
    boundary : per-point boundary conditions the model runs at, ``{"p_amb_Pa", "T_amb_K", "p_ex_Pa"}``
        (arrays; NaN = the parameter set's value); boundary_outliers : the readings left out of them.
    column_role : role of every data column; column_spec : its spec (with the dataset's gauge decision);
    groups : per-cylinder groups ``{group: {"columns", "mean_column", "spread" (per point, in the mean
        column's units), "n"}}``.
    suspect : readings the loader flags without any model (an engine far from the others at the same set
        point): kept in the data; hold-out errors are reported with and without them.
    load_law : normalised stated load law (``propeller`` | ``constant_speed`` | ``independent`` | ``None``).
    quality : data-quality summary (points, engines, missing cells per column with their rows).
    """

    name: str
    params_name: str
    meta: dict[str, Any]
    columns: tuple[str, ...]
    column_quantity: dict[str, str]
    values: dict[str, np.ndarray]
    raw: dict[str, np.ndarray]
    engines: tuple[str, ...] | None
    provenance: str
    ambient: dict[str, Any]
    load_law: str | None
    load_law_text: str | None
    rated_power_W: float
    quality: dict[str, Any]
    warnings: tuple[DataFinding, ...] = ()
    notes: tuple[str, ...] = ()
    path: str | None = None
    column_role: dict[str, str] = field(default_factory=dict)
    column_spec: dict[str, ColumnSpec] = field(default_factory=dict)
    boundary: dict[str, np.ndarray] = field(default_factory=dict)
    boundary_outliers: tuple[dict[str, Any], ...] = ()
    groups: dict[str, dict[str, Any]] = field(default_factory=dict)
    suspect: tuple[dict[str, Any], ...] = ()

    @property
    def n_points(self) -> int:
        return len(next(iter(self.raw.values()))) if self.raw else 0

    @property
    def params(self) -> EngineParams:
        return load_params(self.params_name)

    def spec(self, column: str) -> ColumnSpec:
        return self.column_spec.get(column) or lookup_column(column)

    def columns_with_role(self, *roles: str) -> list[str]:
        return [c for c in self.columns if self.column_role.get(c) in roles]

    def column_inventory(self) -> list[dict[str, Any]]:
        """What happens to every column: ``{column, role, quantity, what}``."""
        out = []
        for c in self.columns:
            role = self.column_role.get(c, "channel")
            q = QUANTITIES.get(self.column_quantity.get(c, ""))
            if role == "channel":
                what = "compared with the model's " + (q.description if q else "value")
            elif role == "setpoint":
                what = "set point (fixes the operating point, or compared when something else fixes it)"
            elif role == "member":
                g = next((k for k, v in self.groups.items() if c in v["columns"]), "")
                what = (
                    f"one cylinder of group {g!r}: its spread is the measurement spread of "
                    f"{self.groups[g]['mean_column'] if g else 'the mean'}"
                )
            else:
                what = q.reason if q else ""
            out.append({"column": c, "role": role, "quantity": self.column_quantity.get(c), "what": what})
        return out

    def has(self, quantity: str) -> bool:
        return quantity in self.values

    def column_of(self, quantity: str) -> str | None:
        """The data column that holds ``quantity`` (``None`` if absent)."""
        for col, q in self.column_quantity.items():
            if q == quantity:
                return col
        return None

    def to_si(self, column: str, values) -> np.ndarray:
        return self.spec(column).to_si(values, self.ambient["p_amb_Pa"])

    def from_si(self, column: str, values) -> np.ndarray:
        return self.spec(column).from_si(values, self.ambient["p_amb_Pa"])

    def engine_ids(self) -> list[str]:
        """Distinct engine ids in order of appearance (``[]`` without an engine column)."""
        if self.engines is None:
            return []
        return list(dict.fromkeys(self.engines))

    def point_label(self, i: int) -> str:
        parts = [] if self.engines is None else [self.engines[i]]
        for q in SETPOINT_QUANTITIES:
            col = self.column_of(q)
            if col is not None and math.isfinite(self.raw[col][i]):
                parts.append(f"{col}={self.raw[col][i]:g}")
        return f"point {i + 1} (" + ", ".join(parts) + ")"

    def subset(self, mask) -> "MeasuredDataset":
        """The dataset restricted to the points where ``mask`` is true (e.g. one engine left out)."""
        m = np.asarray(mask)
        if m.dtype != bool:
            idx = m
            m = np.zeros(self.n_points, dtype=bool)
            m[idx] = True
        eng = None if self.engines is None else tuple(e for e, k in zip(self.engines, m) if k)
        amb = dict(self.ambient)
        if np.ndim(amb["p_amb_Pa"]):
            amb["p_amb_Pa"] = np.asarray(amb["p_amb_Pa"])[m]
        groups = {g: dict(v, spread=v["spread"][m], n=v["n"][m]) for g, v in self.groups.items()}
        return dataclasses.replace(
            self,
            values={k: v[m] for k, v in self.values.items()},
            raw={k: v[m] for k, v in self.raw.items()},
            engines=eng,
            ambient=amb,
            quality=quality_summary(self.columns, {k: v[m] for k, v in self.raw.items()}, eng, self.warnings),
            boundary={k: v[m] for k, v in self.boundary.items()},
            boundary_outliers=tuple(o for o in self.boundary_outliers if m[o["row"] - 1]),
            groups=groups,
            suspect=tuple(dict(x, row=int(np.sum(m[: x["row"]]))) for x in self.suspect if m[x["row"] - 1]),
        )

    def with_readings(self, readings: Mapping[str, Iterable[float]]) -> "MeasuredDataset":
        """The same dataset (boundary conditions, per-cylinder spreads, flags) with other readings of some channels
        or set-point columns, in the columns' units (e.g. a replica drawn from a fitted model)."""
        raw, values = dict(self.raw), dict(self.values)
        for col, v in readings.items():
            if col not in self.column_quantity or self.column_role.get(col, "channel") not in ("channel", "setpoint"):
                raise ValueError(f"{col!r} is not a reading of {self.name} (a channel or a set point)")
            a = np.asarray(v, dtype=float)
            if a.shape != (self.n_points,):
                raise ValueError(f"{col}: {a.shape[0] if a.ndim else 1} values for {self.n_points} points")
            raw[col] = a.copy()
            values[self.column_quantity[col]] = self.to_si(col, a)
        return dataclasses.replace(self, raw=raw, values=values)

    def quality_report(self) -> str:
        """The data-quality summary as text."""
        q = self.quality
        lines = [
            f"{self.name}: {q['n_points']} points" + (f", engines {', '.join(q['engines'])}" if q["engines"] else "")
        ]
        for col, c in q["columns"].items():
            if c["missing"]:
                lines.append(f"  {col}: {c['missing']} missing (rows {', '.join(map(str, c['missing_rows']))})")
        for w in self.warnings:
            lines.append(f"  warning: {w}")
        for n in self.notes:
            lines.append(f"  note: {n}")
        return "\n".join(lines)


# --------------------------------------------------------------------------------------- helpers
def normalise_load_law(text: str | None) -> str | None:
    """``propeller`` (fixed pitch, P ~ n^3), ``constant_speed`` (generator), ``independent`` (CPP /
    combinator: speed and power set separately) or ``None`` (unknown/unstated)."""
    if text is None:
        return None
    t = str(text).lower()
    if not t.strip() or any(k in t for k in ("unknown", "not stated", "not recorded")):
        return None
    if any(k in t for k in ("controllable", "cpp", "combinator", "independent")):
        return "independent"
    if any(k in t for k in ("generator", "constant speed", "constant-speed", "genset", "isochronous")):
        return "constant_speed"
    if "propeller" in t or "fpp" in t or "cubic" in t:
        return "propeller"
    return None


def quality_summary(columns, raw, engines, warns) -> dict[str, Any]:
    """The data-quality summary: points, engines, missing cells per column (1-based rows), warnings."""
    n = len(next(iter(raw.values()))) if raw else 0
    cols = {}
    for c in columns:
        miss = [i + 1 for i, v in enumerate(raw[c]) if not math.isfinite(v)]
        cols[c] = {"n": n - len(miss), "missing": len(miss), "missing_rows": miss}
    return {
        "n_points": n,
        "engines": [] if engines is None else list(dict.fromkeys(engines)),
        "columns": cols,
        "n_missing": sum(c["missing"] for c in cols.values()),
        "n_warnings": len(warns),
    }
