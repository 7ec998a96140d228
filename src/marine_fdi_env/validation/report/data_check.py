"""What ``marine-fdi validate`` would do with a dataset, before any fit: ``validate --check`` and ``--columns``.

A user bringing their own measurements wants to know, in a second and before a fit of minutes, whether the
file says what they meant: which column is compared with which model output, which fixes the operating
point, which is a boundary condition of its row, which is recorded but not modelled (and why), what was
assumed (gauge vs absolute, where a charge-air temperature was measured), which readings the outlier check
leaves out, and the tolerance every compared channel will carry and where it comes from (command line,
sidecar, default).  :func:`describe` writes that; :func:`column_registry` lists every column name the
loader knows, with its units, quantity and role (:mod:`.measured.columns`).
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from ..fit.problem import FitProblem
from ..measured.columns import COLUMNS, GROUP_PATTERNS, QUANTITIES
from ..measured.dataset import MeasuredDataset
from ..measured.discrepancy import LOAD_TOL, REL_TOL, TEMPERATURE_TOL_K

__all__ = ["describe", "column_registry", "tolerance_sources"]


def tolerance_sources(problem: FitProblem, stated: Sequence[str] = ()) -> dict[str, str]:
    """Where each compared channel's tolerance comes from: ``--tolerance``, ``sidecar`` or ``default``."""
    cli = {str(item).partition("=")[0].strip() for item in stated}
    side = problem.ds.meta.get("tolerances")
    side = side if isinstance(side, Mapping) else {}
    return {c: "--tolerance" if c in cli else "sidecar" if c in side else "default" for c in problem.channels}


def _default_basis(ds: MeasuredDataset, column: str) -> str:
    q = QUANTITIES[ds.column_quantity[column]]
    if q.kind == "temperature":
        return f"{TEMPERATURE_TOL_K:g} K"
    if q.name == "load_fraction":
        return f"{LOAD_TOL:g}"
    return f"{100 * REL_TOL:g} % of the mean" + (" absolute reading" if ds.spec(column).gauge else "")


def describe(
    ds: MeasuredDataset,
    problem: FitProblem,
    tolerances: Mapping[str, float],
    stated: Sequence[str] = (),
    max_folds: int | None = None,
) -> str:
    """The dataset as the pipeline will use it: points, roles of every column, warnings and notes, boundary
    outliers, the operating-point target, the cross-validation scheme and each compared channel's tolerance.

    tolerances : the tolerance per compared channel that the fit will use (column units).  stated : the
    ``--tolerance`` items, only to say where each tolerance comes from."""
    L = [ds.quality_report()]
    L.append(
        f"  engine parameter set: {problem.params.name}; operating points fixed by {problem.target} "
        f"({', '.join(c for c in problem.target_columns if c)})"
    )
    scheme, folds = problem.folds(max_folds)
    L.append(f"  cross-validation: {scheme} ({len(folds)} folds)")
    L.append("")
    inv = ds.column_inventory()
    w = max(len(r["column"]) for r in inv)
    L.append(f"  {'column':{w}s}  {'role':12s}  what happens to it")
    for r in inv:
        role = r["role"]
        if r["column"] in problem.target_columns:
            role, what = "setpoint", "fixes the operating point (the target)"
        elif r["column"] in problem.channels:
            role, what = (
                "channel",
                r["what"].replace(
                    "set point (fixes the operating point, or compared when something else fixes it)",
                    "compared with the model",
                ),
            )
        elif role == "setpoint":
            what = (
                "set point, not compared ("
                + (
                    "the model has no counterpart"
                    if QUANTITIES[r["quantity"]].model is None
                    else "redundant with the target"
                )
                + ")"
            )
        else:
            what = r["what"]
        if role in ("channel", "setpoint") and ds.spec(r["column"]).gauge:
            what += " (the gauge reading plus the row's ambient pressure)"
        L.append(f"  {r['column']:{w}s}  {role:12s}  {what}")
    L.append("")
    src = tolerance_sources(problem, stated)
    L.append(f"  {'compared channel':{w}s}  {'tolerance':>12s}  {'mean reading':>12s}  source")
    for c in problem.channels:
        mean = float(np.nanmean(ds.raw[c])) if np.any(np.isfinite(ds.raw[c])) else float("nan")
        how = src[c] if src[c] != "default" else f"default ({_default_basis(ds, c)})"
        L.append(f"  {c:{w}s}  {tolerances[c]:12.4g}  {mean:12.4g}  {how}")
    for o in ds.boundary_outliers:
        L.append(
            f"  left out: row {o['row']} {o['column']} = {o['value']:g} (robust z {o['robust_z']:.1f}); the row "
            f"runs at {o['replacement']:g}"
        )
    for s in ds.suspect:
        L.append(
            f"  suspect reading, kept (errors are given with and without it): row {s['row']} {s['column']} = "
            f"{s['value']:g} ({s['why']})"
        )
    return "\n".join(L)


def column_registry() -> str:
    """Every column name the loader knows: ``stem_unit`` names grouped by stem, the model quantity, its role."""
    by_stem: dict[str, list] = {}
    for spec in COLUMNS.values():
        by_stem.setdefault((spec.stem, spec.quantity), []).append(spec)
    rows = []
    for (stem, quantity), specs in by_stem.items():
        units = [s.unit for s in specs if s.unit != "-"]
        bare = any(s.unit == "-" for s in specs)
        name = stem if not units else f"{stem}_<unit>" if len(units) > 1 else f"{stem}_{units[0]}"
        if bare and units:
            name = f"{stem}, {name}"
        q = QUANTITIES.get(quantity)
        role = specs[0].effective_role if q is not None else "channel"
        what = (
            q.description
            if q is not None
            else "charge-air temperature: where it was measured is set by the "
            "sidecar's column_quantities (default: after the cooler)"
        )
        if any(s.gauge_assumed for s in specs):
            what += "; plain bar is taken as gauge with a warning (sidecar pressure_reference decides)"
        rows.append((name, role, what, units if len(units) > 1 else []))
    for group, (pat, quantity, units, _assumed) in GROUP_PATTERNS.items():
        stem = pat.pattern.strip("^$").replace(r"(\d+)", "<n>").split("_(")[0]
        rows.append(
            (
                f"{stem}_<unit>",
                "member",
                f"one cylinder of {group}: the group's spread is the measurement "
                "spread of the engine mean" + ("; plain bar is taken as gauge" if _assumed else ""),
                list(units),
            )
        )
    rows.append(("engine", "id", "engine id (several engines in one file: leave-one-engine-out cross-validation)", []))
    w = max(len(r[0]) for r in rows if len(r[0]) <= 48)
    out = [f"{'column':{w}s}  {'role':12s}  quantity"]
    for n, r, d, units in rows:
        out.append(f"{n:{w}s}  {r:12s}  {d}")
        if units:
            out.append(f"{'':{w}s}  {'':12s}  <unit>: {', '.join(units)}")
    out.append("")
    out.append(
        "Pressures say gauge or absolute in the unit (bar_gauge, bar_abs). Sidecar keys: engine_params "
        "(required), ambient, rated_power_kW, load_law, column_quantities, pressure_reference, tolerances, "
        "fuel_rack_at_nominal, source (see docs/measured_data.md)."
    )
    return "\n".join(out)
