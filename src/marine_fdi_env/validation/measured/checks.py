"""The checks of a measured-data file, run once after any reader (:mod:`.readers`): from a
:class:`~.readers.MeasuredFile` to a :class:`~.dataset.MeasuredDataset`.

In order: the sidecar (present, a JSON object, its numeric fields numbers, the engine's parameter set named), the
header (known columns with units, no duplicates, each column's quantity and role), every cell (a number or missing;
an engine id where there is an engine column; a row as long as the header), the ambient and per-row boundary
conditions (recording errors left out), the per-cylinder groups, the plausibility of every value (the engine's
envelope; :mod:`.plausibility`), duplicate operating points and engines far from the others.  Every problem is
collected with its rows and column; errors raise one :class:`~marine_fdi_env.errors.DatasetError` listing all of
them, warnings are kept in the dataset and issued as :class:`~.dataset.DataWarning`.
"""

from __future__ import annotations

import dataclasses
import math
import warnings
from typing import Any, Mapping, Sequence

import numpy as np

from ...engine.params import EngineParams, list_parameter_sets, load_params
from ...errors import DatasetError
from .boundary_readings import boundary_conditions, cylinder_groups
from .columns import ID_COLUMNS, ColumnSpec, column_problem, lookup_column, resolve_quantity
from .dataset import DataFinding, DataWarning, MeasuredDataset, normalise_load_law, quality_summary
from .plausibility import check_across_engines, check_duplicates, check_values
from .readers import Cell, MeasuredFile
from .sidecar import check_numbers

__all__ = ["check_measured", "parse_ambient", "cell_value", "cell_text", "MISSING_TOKENS", "ENGINE_COLUMN"]

#: cell texts that mean "not recorded" (any case): NaN in the data, counted as missing, never an error
MISSING_TOKENS = frozenset({"", "na", "nan", "n/a", "none", "null"})

ENGINE_COLUMN = "engine"


def check_measured(file: MeasuredFile, *, params: str | None = None, name: str | None = None) -> MeasuredDataset:
    """The checked dataset of a file as read; raise :class:`DatasetError` listing every error.

    params : parameter-set name overriding the sidecar's ``engine_params``.  name : the dataset's name (default: the
    file's name without its ending), also what the messages call it.
    """
    source = name or file.path.name
    problems: list[DataFinding] = []

    def err(msg, rows=(), column=None):
        problems.append(DataFinding("error", msg, tuple(rows), column))

    def warn(msg, rows=(), column=None):
        problems.append(DataFinding("warning", msg, tuple(rows), column))

    meta_d = _sidecar(file, params, err, warn)
    params_name = params or meta_d.get("engine_params")
    p: EngineParams | None = None
    if params_name is None:
        if not any("sidecar" in pr.message for pr in problems):
            err("the sidecar does not name the engine parameter set (key 'engine_params')")
    elif params_name not in list_parameter_sets():
        err(f"unknown engine parameter set {params_name!r} (known: {', '.join(list_parameter_sets())})")
    else:
        p = load_params(params_name)

    # ---- the table
    if not file.table.columns:
        raise DatasetError(source, problems + [DataFinding("error", "empty file: no header")])
    header = [str(h).strip() for h in file.table.columns]
    data = file.table.rows
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
                warn(f"the sidecar describes column {c!r}, which the data file does not have")

    if any(pr.severity == "error" for pr in problems):
        raise DatasetError(source, problems)
    warns = tuple(pr for pr in problems if pr.severity == "warning")
    for w in warns:
        warnings.warn(f"{source}: {w}", DataWarning, stacklevel=2)
    columns = tuple(column_quantity)
    eng = None if engines is None else tuple(engines)
    law_text = meta_d.get("load_law")
    return MeasuredDataset(
        name=name or file.stem,
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
        quality=quality_summary(columns, raw, eng, warns),
        warnings=warns,
        notes=tuple(notes),
        path=str(file.path),
        column_role=column_role,
        column_spec=column_spec,
        boundary=boundary,
        boundary_outliers=tuple(b_outliers),
        groups=groups,
        suspect=tuple(suspect),
    )


def _sidecar(file: MeasuredFile, params: str | None, err, warn) -> dict[str, Any]:
    """The sidecar's content (``{}`` when missing or unreadable, with the problem reported); a numeric field that is not
    a number raises :class:`~marine_fdi_env.errors.DataFileError` at once."""
    if file.meta_problem is not None:
        err(file.meta_problem)
        return {}
    if file.meta is None:
        if params is None:
            err(f"no sidecar {file.meta_name}: it must name the engine parameter set (engine_params)")
        else:
            warn(f"no sidecar {file.meta_name}: parameter set {params!r} from the caller, ambient and load law unknown")
        return {}
    check_numbers(file.meta, file.meta_name)
    return dict(file.meta)


def cell_value(cell: Cell) -> float | None:
    """The number a cell holds: NaN if missing (empty, ``None``, NaN or a :data:`MISSING_TOKENS` text), ``None`` if
    it holds no finite number."""
    if cell is None:
        return math.nan
    if isinstance(cell, str):
        t = cell.strip()
        if t.lower() in MISSING_TOKENS:
            return math.nan
        try:
            v = float(t)
        except ValueError:
            return None
    elif isinstance(cell, (int, float)) and not isinstance(cell, bool):
        v = float(cell)
        if math.isnan(v):
            return math.nan
    else:
        return None
    if math.isinf(v):
        return None
    return v


def cell_text(cell: Cell) -> str:
    """A cell as text: stripped text, a number as written, ``""`` for an empty cell."""
    if cell is None:
        return ""
    return cell.strip() if isinstance(cell, str) else str(cell)


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
    data: Sequence[Sequence[Cell]], header: list[str], seen: Mapping[str, int], column_quantity: Mapping[str, str], err
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
            e = cell_text(row[j]) if j < len(row) else ""
            if not e:
                err("empty engine id", rows=(i,), column=ENGINE_COLUMN)
            engines.append(e)
        for h in column_quantity:
            j = seen[h]
            if j >= len(row):
                continue
            v = cell_value(row[j])
            if v is None:
                err(f"non-numeric value {cell_text(row[j])!r}", rows=(i,), column=h)
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
