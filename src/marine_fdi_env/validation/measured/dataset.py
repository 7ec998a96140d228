"""The measured-data format: a CSV with the unit in each column name and a ``FILE.meta.json`` sidecar.

CSV
    One row per operating point.  Column names are registered in
    :mod:`marine_fdi_env.validation.measured.columns` (``speed_rpm``, ``power_kW``,
    ``charge_air_pressure_bar_abs``, ``charge_air_pressure_bar_gauge``, ``turbine_outlet_temperature_C``,
    ``fuel_flow_kg_per_h``, ``sfc_g_per_kWh``, ``air_flow_kg_per_kWh``, ``load_fraction``, ``fuel_rack``,
    ...), plus an optional ``engine`` id column when several engines are recorded.  Empty cells (and
    ``NA``/``NaN``/``n/a``) are missing values: they become NaN and are counted in the data-quality
    summary, never an error.

Sidecar ``FILE.meta.json`` (a JSON object)
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

:func:`load_measured` checks units, columns and values and collects *every* problem with its row and
column; errors raise one :class:`DatasetError` (a ``ValueError``) listing all of them, suspicious but
kept values give :class:`DataWarning` warnings (also kept in ``MeasuredDataset.warnings``).
Row numbers are 1-based data rows; the CSV line is row + 1 (the header is line 1).
"""

from __future__ import annotations

import csv
import dataclasses
import io
import json
import math
import warnings
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any, Iterable, Mapping

import numpy as np

from ...engine.params import EngineParams, list_parameter_sets, load_params
from ...errors import DataFileError, DatasetError
from .boundary_readings import BOUNDARY_OUTLIER_Z, boundary_conditions, cylinder_groups
from .columns import ID_COLUMNS, QUANTITIES, ColumnSpec, column_problem, lookup_column, resolve_quantity
from .plausibility import SETPOINT_QUANTITIES, check_across_engines, check_duplicates, check_values

__all__ = [
    "MeasuredDataset",
    "DatasetError",
    "DataWarning",
    "DataFinding",
    "load_measured",
    "load_shipped",
    "list_shipped",
    "shipped_path",
    "write_measured",
    "parse_ambient",
    "normalise_load_law",
    "MISSING_TOKENS",
    "BOUNDARY_OUTLIER_Z",
]

MISSING_TOKENS = frozenset({"", "na", "nan", "n/a", "none", "null"})

ENGINE_COLUMN = "engine"


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
        return MeasuredDataset(
            name=self.name,
            params_name=self.params_name,
            meta=self.meta,
            columns=self.columns,
            column_quantity=self.column_quantity,
            values={k: v[m] for k, v in self.values.items()},
            raw={k: v[m] for k, v in self.raw.items()},
            engines=eng,
            provenance=self.provenance,
            ambient=amb,
            load_law=self.load_law,
            load_law_text=self.load_law_text,
            rated_power_W=self.rated_power_W,
            quality=_quality(self.columns, {k: v[m] for k, v in self.raw.items()}, eng, self.warnings),
            warnings=self.warnings,
            notes=self.notes,
            path=self.path,
            column_role=self.column_role,
            column_spec=self.column_spec,
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


def parse_ambient(meta: Mapping[str, Any], params: EngineParams) -> tuple[dict[str, Any], list[str]]:
    """Ambient conditions of the sidecar (SI) and notes on what was assumed."""
    notes: list[str] = []
    src = dict(meta)
    if isinstance(meta.get("ambient"), Mapping):
        src.update(meta["ambient"])
    p = T = Tc = None
    if "ambient_pressure_bar" in src:
        p = float(src["ambient_pressure_bar"]) * 1e5
    elif "ambient_pressure_Pa" in src:
        p = float(src["ambient_pressure_Pa"])
    if "ambient_temperature_C" in src:
        T = float(src["ambient_temperature_C"]) + 273.15
    elif "ambient_temperature_K" in src:
        T = float(src["ambient_temperature_K"])
    if "charge_air_coolant_temperature_C" in src:
        Tc = float(src["charge_air_coolant_temperature_C"]) + 273.15
    recorded = p is not None or T is not None
    if p is None:
        notes.append(
            f"ambient pressure not recorded: gauge pressures made absolute with the parameter set's "
            f"p_amb = {params.p_amb_Pa / 1e5:g} bar"
        )
    if p is not None and abs(p - params.p_amb_Pa) > 0.005 * params.p_amb_Pa:
        notes.append(
            f"recorded ambient pressure {p / 1e5:g} bar differs from the parameter set's "
            f"{params.p_amb_Pa / 1e5:g} bar (the base model runs at the parameter set's)"
        )
    if T is not None and abs(T - params.T_amb_K) > 0.5:
        notes.append(
            f"recorded ambient temperature {T - 273.15:g} C differs from the parameter set's "
            f"{params.T_amb_K - 273.15:g} C (the base model runs at the parameter set's)"
        )
    return {
        "p_amb_Pa": p if p is not None else params.p_amb_Pa,
        "T_amb_K": T,
        "coolant_T_K": Tc,
        "recorded": recorded,
    }, notes


def _parse_cell(text: str) -> float | None:
    """Float value of a cell, NaN if missing, ``None`` if not numeric."""
    t = text.strip()
    if t.lower() in MISSING_TOKENS:
        return math.nan
    try:
        v = float(t)
    except ValueError:
        return None
    if math.isinf(v):
        return None
    return v


def _quality(columns, raw, engines, warns) -> dict[str, Any]:
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


# --------------------------------------------------------------------------------------- loader
def load_measured(
    path: str | Path,
    meta: str | Path | Mapping[str, Any] | None = None,
    *,
    params: str | None = None,
    name: str | None = None,
    text: str | None = None,
) -> MeasuredDataset:
    """Load and check a measured dataset (CSV + sidecar); raise :class:`DatasetError` listing every error.

    path : the CSV file.  meta : the sidecar (path or dict); default ``PATH`` with ``.csv`` replaced by
    ``.meta.json``.  params : parameter-set name overriding the sidecar's ``engine_params``.
    text : CSV content to use instead of reading ``path`` (shipped datasets).
    """
    path = Path(path)
    source = name or path.name
    problems: list[DataFinding] = []

    def err(msg, rows=(), column=None):
        problems.append(DataFinding("error", msg, tuple(rows), column))

    def warn(msg, rows=(), column=None):
        problems.append(DataFinding("warning", msg, tuple(rows), column))

    meta_d = _read_sidecar(path, meta, params, err, warn)
    params_name = params or meta_d.get("engine_params")
    p: EngineParams | None = None
    if params_name is None:
        if not any("sidecar" in pr.message for pr in problems):
            err("the sidecar does not name the engine parameter set (key 'engine_params')")
    elif params_name not in list_parameter_sets():
        err(f"unknown engine parameter set {params_name!r} (known: {', '.join(list_parameter_sets())})")
    else:
        p = load_params(params_name)

    # ---- CSV
    try:
        content = text if text is not None else path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise DatasetError(source, [DataFinding("error", f"no such file {path}")]) from None
    except UnicodeDecodeError as e:  # one line: nothing else can be checked in a file that cannot be read
        line = e.object[: e.start].count(b"\n") + 1
        raise DataFileError(
            f"{path}: not UTF-8 text (byte 0x{e.object[e.start]:02x} on line {line}); save the CSV as UTF-8"
        ) from None
    rows = list(csv.reader(io.StringIO(content)))
    while rows and not any(c.strip() for c in rows[-1]):
        rows.pop()
    if not rows:
        raise DatasetError(source, problems + [DataFinding("error", "empty file: no header")])
    header = [h.strip() for h in rows[0]]
    data = rows[1:]
    if not data:
        err("no data rows")

    seen, column_quantity, column_role, column_spec, notes = _resolve_columns(header, meta_d, err, warn)

    n = len(data)
    raw, engines = _read_cells(data, header, seen, column_quantity, err)

    ambient, rated, boundary, b_outliers = _ambient_and_boundary(
        meta_d, p, raw, column_quantity, column_role, column_spec, n, notes, warn
    )
    p_amb_rows = ambient["p_amb_Pa"]

    values = {
        column_quantity[h]: column_spec[h].to_si(raw[h], p_amb_rows)
        for h in column_quantity
        if column_role[h] != "member"
    }
    groups = cylinder_groups(raw, column_quantity, column_role, column_spec, n, p_amb_rows, warn)
    suspect: list[dict[str, Any]] = []
    if p is not None:
        check_values(
            raw,
            values,
            {c: q for c, q in column_quantity.items() if column_role[c] != "member"},
            p,
            rated,
            ambient,
            engines,
            err,
            warn,
        )
        check_duplicates(raw, column_quantity, engines, err)
        check_across_engines(raw, column_quantity, engines, warn, suspect)
    for h in column_quantity:
        if n and not np.any(np.isfinite(raw[h])):
            warn("every value is missing", column=h)
    described = meta_d.get("columns") or {}
    if isinstance(described, Mapping):
        for c in described:
            if c not in seen:
                warn(f"the sidecar describes column {c!r}, which the CSV does not have")

    if any(pr.severity == "error" for pr in problems):
        raise DatasetError(source, problems)
    warns = tuple(pr for pr in problems if pr.severity == "warning")
    for w in warns:
        warnings.warn(f"{source}: {w}", DataWarning, stacklevel=2)
    columns = tuple(column_quantity)
    eng = None if engines is None else tuple(engines)
    law_text = meta_d.get("load_law")
    return MeasuredDataset(
        name=name or (path.name[:-4] if path.name.endswith(".csv") else path.name),
        params_name=params_name,
        meta=meta_d,
        columns=columns,
        column_quantity=column_quantity,
        values=values,
        raw=raw,
        engines=eng,
        provenance=str(meta_d.get("source", "not stated")),
        ambient=ambient,
        load_law=normalise_load_law(law_text),
        load_law_text=law_text,
        rated_power_W=rated,
        quality=_quality(columns, raw, eng, warns),
        warnings=warns,
        notes=tuple(notes),
        path=str(path),
        column_role=column_role,
        column_spec=column_spec,
        boundary=boundary,
        boundary_outliers=tuple(b_outliers),
        groups=groups,
        suspect=tuple(suspect),
    )


def _read_sidecar(
    path: Path, meta: str | Path | Mapping[str, Any] | None, params: str | None, err, warn
) -> dict[str, Any]:
    """The sidecar as a dict (``meta`` itself when it is one; ``{}`` when it is missing or unreadable, with the
    problem reported)."""
    if isinstance(meta, Mapping):
        meta_d = dict(meta)
    else:
        meta_path = (
            Path(meta)
            if meta is not None
            else path.with_name(
                path.name[:-4] + ".meta.json" if path.name.endswith(".csv") else path.name + ".meta.json"
            )
        )
        meta_d = {}
        try:
            meta_d = json.loads(meta_path.read_text())
            if not isinstance(meta_d, dict):
                err(f"sidecar {meta_path.name} must hold a JSON object")
                meta_d = {}
        except FileNotFoundError:
            if params is None:
                err(f"no sidecar {meta_path.name}: it must name the engine parameter set (engine_params)")
            else:
                warn(
                    f"no sidecar {meta_path.name}: parameter set {params!r} from the caller, ambient and load "
                    "law unknown"
                )
        except json.JSONDecodeError as e:
            err(f"sidecar {meta_path.name} is not valid JSON: {e}")
        except UnicodeDecodeError:
            err(f"sidecar {meta_path.name} is not UTF-8 text; save it as UTF-8")
        except IsADirectoryError:
            err(f"sidecar {meta_path.name} is a folder, not a JSON file")
    return meta_d


def _resolve_columns(
    header: list[str], meta_d: Mapping[str, Any], err, warn
) -> tuple[dict[str, int], dict[str, str], dict[str, str], dict[str, ColumnSpec], list[str]]:
    """Header checks (unknown, missing unit, duplicated names and duplicated quantities) and what each column is:
    (column index by name, quantity, role and spec of every usable column, notes)."""
    seen: dict[str, int] = {}
    known: list[tuple[int, str]] = []
    for j, h in enumerate(header):
        if h in seen:
            err(f"duplicated column (also column {seen[h] + 1})", column=h)
            continue
        seen[h] = j
        msg = column_problem(h)
        if msg is not None:
            err(f"column {j + 1}: {msg}", column=h)
            continue
        known.append((j, h))
    column_quantity: dict[str, str] = {}
    column_role: dict[str, str] = {}
    column_spec: dict[str, ColumnSpec] = {}
    notes: list[str] = []
    by_quantity: dict[str, str] = {}
    pref = meta_d.get("pressure_reference") or {}
    if not isinstance(pref, Mapping):
        err('sidecar key \'pressure_reference\' must be an object {column: "gauge" | "absolute"}')
        pref = {}
    assumed_gauge: list[str] = []
    for j, h in known:
        if h in ID_COLUMNS:
            continue
        spec = lookup_column(h)
        try:
            q, note, assumed = resolve_quantity(h, spec, meta_d)
        except ValueError as e:
            err(str(e), column=h)
            continue
        if note:
            (warn(note, column=h) if assumed else notes.append(note))
        if h in pref:
            ref = pref[h]
            if ref not in ("gauge", "absolute"):
                err(f'sidecar pressure_reference[{h!r}] must be "gauge" or "absolute", got {ref!r}', column=h)
                continue
            if not q.endswith("_Pa"):
                err("sidecar pressure_reference names a column that is not a pressure", column=h)
                continue
            spec = dataclasses.replace(spec, gauge=ref == "gauge", gauge_assumed=False)
            notes.append(f"{h}: {ref} pressure (sidecar pressure_reference)")
        elif spec.gauge_assumed:
            assumed_gauge.append(h)
        role = spec.effective_role
        if role != "member":
            if q in by_quantity:
                err(f"duplicated column: holds the same quantity ({q}) as column {by_quantity[q]!r}", column=h)
                continue
            by_quantity[q] = h
        column_quantity[h] = q
        column_role[h] = role
        column_spec[h] = spec

    if assumed_gauge:
        warn(
            f"{', '.join(assumed_gauge)}: the unit does not say gauge or absolute and the source does not state it: "
            "taken as gauge (the convention of the other pressures of a shop-test protocol); the difference is the "
            'ambient pressure (about 1 bar, 0.5 % of a maximum cylinder pressure). Set "pressure_reference" in '
            "the sidecar to decide",
            column=assumed_gauge[0],
        )

    return seen, column_quantity, column_role, column_spec, notes


def _read_cells(
    data: list[list[str]], header: list[str], seen: Mapping[str, int], column_quantity: Mapping[str, str], err
) -> tuple[dict[str, np.ndarray], list[str] | None]:
    """The cells of every usable column as floats in the file's units (NaN where missing), and the engine id per
    row (``None`` without an engine column)."""
    n = len(data)
    raw: dict[str, np.ndarray] = {h: np.full(n, np.nan) for h in column_quantity}
    engines: list[str] | None = [] if ENGINE_COLUMN in seen else None
    for i, row in enumerate(data, start=1):
        if len(row) != len(header):
            err(f"{len(row)} fields, the header has {len(header)}", rows=(i,))
        if engines is not None:
            j = seen[ENGINE_COLUMN]
            e = row[j].strip() if j < len(row) else ""
            if not e:
                err("empty engine id", rows=(i,), column=ENGINE_COLUMN)
            engines.append(e)
        for h in column_quantity:
            j = seen[h]
            if j >= len(row):
                continue
            v = _parse_cell(row[j])
            if v is None:
                err(f"non-numeric value {row[j].strip()!r}", rows=(i,), column=h)
            else:
                raw[h][i - 1] = v
    return raw, engines


def _ambient_and_boundary(
    meta_d: Mapping[str, Any],
    p: EngineParams | None,
    raw: Mapping[str, np.ndarray],
    column_quantity: Mapping[str, str],
    column_role: Mapping[str, str],
    column_spec: Mapping[str, ColumnSpec],
    n: int,
    notes: list[str],
    warn,
) -> tuple[dict[str, Any], float, dict[str, np.ndarray], list[dict[str, Any]]]:
    """Ambient conditions (per row where the file records them), rated power, and the per-row boundary conditions
    with their recording errors left out: (ambient, rated power in W, boundary, outliers); ``notes`` gains what was
    assumed."""
    if p is not None:
        ambient, amb_notes = parse_ambient(meta_d, p)
        rated = float(meta_d["rated_power_kW"]) * 1e3 if "rated_power_kW" in meta_d else p.P_nom_W
    else:
        ambient, amb_notes = {"p_amb_Pa": 1.013e5, "T_amb_K": None, "coolant_T_K": None, "recorded": False}, []
        rated = math.nan
    boundary, b_outliers = boundary_conditions(raw, column_quantity, column_role, column_spec, n, warn)
    if np.any(np.isfinite(boundary["p_amb_Pa"])):
        fill = ambient["p_amb_Pa"]
        ambient["p_amb_Pa"] = np.where(np.isfinite(boundary["p_amb_Pa"]), boundary["p_amb_Pa"], fill)
        ambient["recorded"] = True
        amb_notes = [x for x in amb_notes if not x.startswith("ambient pressure")]
        notes.append(
            "ambient pressure recorded per row: a boundary condition of each row (gauge readings and the "
            "model's compressor inlet)"
        )
    if np.any(np.isfinite(boundary["T_amb_K"])):
        ambient["recorded"] = True
        amb_notes = [x for x in amb_notes if not x.startswith("recorded ambient temperature")]
        notes.append("compressor inlet temperature recorded per row: a boundary condition of each row")
    notes.extend(amb_notes)
    boundary["p_ex_Pa"] = np.broadcast_to(ambient["p_amb_Pa"], (n,)) + boundary.pop(
        "dp_ex_Pa"
    )  # NaN where not recorded
    return ambient, rated, boundary, b_outliers


# --------------------------------------------------------------------------------------- writer
def write_measured(
    path: str | Path,
    columns: Mapping[str, Iterable],
    meta: Mapping[str, Any],
    engines: Iterable[str] | None = None,
    digits: int = 6,
) -> Path:
    """Write a CSV (+ ``.meta.json`` sidecar) in the measured-data format; NaN becomes an empty cell.

    ``columns`` maps registered column names to values in the column's units.
    """
    path = Path(path)
    names = list(columns)
    for c in names:
        msg = column_problem(c)
        if msg is not None:
            raise ValueError(msg)
    cols = [np.asarray(list(columns[c]), dtype=float) for c in names]
    n = len(cols[0]) if cols else 0
    eng = None if engines is None else list(engines)
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(([ENGINE_COLUMN] if eng is not None else []) + names)
        for i in range(n):
            cells = [("" if not math.isfinite(float(c[i])) else f"{float(c[i]):.{digits}g}") for c in cols]
            w.writerow(([eng[i]] if eng is not None else []) + cells)
    meta_path = path.with_name(
        path.name[:-4] + ".meta.json" if path.name.endswith(".csv") else path.name + ".meta.json"
    )
    meta_path.write_text(json.dumps(dict(meta), indent=2) + "\n")
    return path


# --------------------------------------------------------------------------------------- shipped data
def _measured_dir():
    return resources.files("marine_fdi_env") / "data" / "measured"


def list_shipped() -> list[str]:
    """Names of the measured datasets shipped with the package."""
    return sorted(p.name[:-4] for p in _measured_dir().iterdir() if p.name.endswith(".csv"))


def shipped_path(name: str):
    """Traversable of a shipped dataset's CSV."""
    names = list_shipped()
    if name not in names:
        raise ValueError(f"unknown shipped dataset {name!r}; shipped: {', '.join(names)}")
    return _measured_dir() / f"{name}.csv"


def load_shipped(name: str, *, params: str | None = None) -> MeasuredDataset:
    """Load a dataset shipped in ``marine_fdi_env/data/measured`` (``birka_6l46_shop_test``,
    ``man_12v32_40_fpp_iso``); its provenance is the sidecar's ``source``."""
    csv_res = shipped_path(name)
    meta = json.loads((_measured_dir() / f"{name}.meta.json").read_text())
    return load_measured(Path(str(csv_res)), meta, params=params, name=name, text=csv_res.read_text())


def load_data_arg(text: str, params: str | None = None) -> MeasuredDataset:
    """A dataset from a CSV path or the name of a shipped dataset (warnings kept in the dataset)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        p = Path(text)
        if p.is_dir():
            raise ValueError(
                f"{text!r} is a folder; give a CSV file (with its sidecar FILE.meta.json beside it) or a shipped "
                f"dataset name ({', '.join(list_shipped())})"
            )
        if p.exists():
            return load_measured(p, params=params)
        if text in list_shipped():
            return load_shipped(text, params=params)
        raise ValueError(f"no such file {text!r} (shipped datasets: {', '.join(list_shipped())})")
