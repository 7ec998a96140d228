"""A measured dataset prepared for repeated evaluation of the engine model (with submodels).

:class:`FitProblem` holds what fixes each operating point (power, fuel flow, speed or fuel rack, as in
:mod:`.measured.matching`), the comparison channels, the measurements, a tolerance per channel and the per-row
boundary conditions (ambient pressure, compressor inlet temperature, turbine back pressure).  A
:class:`Setting` is one candidate model: parameter scales (the model-error nuisance of
:mod:`.nuisance`), submodels, offsets of the ambient state, sensor gains/offsets and per-point valve
openings.  :meth:`FitProblem.predict` runs the one engine model
(:func:`marine_fdi_env.engine.operating_point.solve_points`)
at every point and returns the readings in the columns' units.

Tolerances (the residual scale; the smallest discrepancy worth naming): the sidecar's
``tolerances``, else 1 % of the channel's mean value (ratio quantities) or 5 K (temperatures).  For an
engine-mean channel of a per-cylinder group (cylinder outlet temperatures, maximum pressures) the
standard error of the mean over the cylinders is added in quadrature, point by point:
``tol_i = sqrt(tol² + (s_i / sqrt(n_i))²)`` with s_i the spread of the cylinders in that row.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import numpy as np

from ...engine.constants import constants_at_ambient, model_constants
from ...engine.model import HEALTHY_PF, N_ALG
from ...engine.operating_point import (
    LAW_PARAMS,
    MODE_F,
    MODE_P,
    MODE_U,
    Summary,
    power_of_speed,
    solve_raw,
    speed_of_power,
)
from ...engine.params import EngineParams, load_params
from ...engine.submodels import NO_SUBMODELS, EngineSubmodels
from ..measured.columns import QUANTITIES, ModelContext
from ..measured.dataset import MeasuredDataset
from ..measured.discrepancy import column_tolerance
from ..measured.matching import load_law_of, rack_settings, resolve_target, target_values

__all__ = ["Setting", "FitProblem", "BASE_SETTING", "FAIL_RESIDUAL", "VALVES", "HELD_OUT_VALVES", "quantity_values"]

#: how cross-validation predicts a valve's opening at a held-out point (:mod:`.fitting`'s docstring): ``schedule``
#: (the default), ``support`` or ``state`` (ablations, not the default: each lets model error pass as a valve or
#: as a cause beside one; ``FitProblem(..., held_out_valves="support")``; ``state``: :mod:`.held_out_state`)
HELD_OUT_VALVES = ("schedule", "support", "state")

FAIL_RESIDUAL = 50.0  # normalised residual of a cell whose point has no steady state
VALVES = ("waste_gate", "bypass_valve")


@dataclass(frozen=True)
class Setting:
    """One candidate model of a :class:`FitProblem`.

    scales : ``{EngineParams field: multiplier}`` (the model-error nuisance).
    submodels : the engine's submodels.
    dT_amb_K, dp_amb_Pa : offsets added to every row's ambient temperature and pressure (and back pressure).
    sensors : ``{column: (gain, offset)}``, readings ``gain * model + offset`` (column units).
    valves : ``{"waste_gate" | "bypass_valve": openings per point}`` overriding the submodel's schedule at the
        measured points (NaN: the schedule).
    area_scale : multiplier of the turbine effective area (a waste-gated turbine is re-matched), on top of the
        nuisance scale.
    """

    scales: Mapping[str, float] = field(default_factory=dict)
    submodels: EngineSubmodels = NO_SUBMODELS
    dT_amb_K: float = 0.0
    dp_amb_Pa: float = 0.0
    sensors: Mapping[str, tuple[float, float]] = field(default_factory=dict)
    valves: Mapping[str, np.ndarray] = field(default_factory=dict)
    area_scale: float = 1.0

    def replace(self, **changes: Any) -> "Setting":
        return dataclasses.replace(self, **changes)

    def with_submodel(self, **sub: Any) -> "Setting":
        return self.replace(submodels=self.submodels.replace(**sub))


BASE_SETTING = Setting()


class FitProblem:
    """A measured dataset prepared for fitting (see the module docstring).

    ds : the dataset.  params : parameter set (name, file or :class:`EngineParams`; default the sidecar's).
    target : what fixes each point (as :func:`~.measured.matching.match_operating_points`).
    tolerances : per column in its units (default: sidecar ``tolerances``, else the defaults).
    held_out_valves : how cross-validation predicts a valve's opening at a held-out point, ``"schedule"`` (default),
        ``"support"`` or ``"state"`` (ablations, not the default;
        :mod:`.held_out_state`): :data:`HELD_OUT_VALVES`.
    """

    def __init__(
        self,
        ds: MeasuredDataset,
        *,
        params: str | EngineParams | None = None,
        target: str = "auto",
        tolerances: Mapping[str, float] | None = None,
        held_out_valves: str = "schedule",
    ):
        if held_out_valves not in HELD_OUT_VALVES:
            raise ValueError(f"held_out_valves must be one of {', '.join(HELD_OUT_VALVES)}, got {held_out_valves!r}")
        self.held_out_valves = held_out_valves
        self.ds = ds
        self.params: EngineParams = load_params(params) if params is not None else ds.params
        self.target = resolve_target(ds, target)
        self.law = load_law_of(ds)
        n = ds.n_points
        self.n_points = n
        nan = np.full(n, np.nan)
        self.speed_measured = ds.values.get("engine_speed_rev_s", nan).astype(float)
        if self.target == "fuel_rack":
            self.target_si, self.rack_reference = rack_settings(ds)
            self.target_columns: tuple[str, ...] = (ds.column_of("fuel_rack"),)
        else:
            _, self.target_si, self.target_columns = target_values(ds, self.target)
        roles = ds.column_role
        self.predicted_columns = tuple(
            c
            for c in ds.columns
            if roles.get(c, "channel") in ("channel", "setpoint")
            and QUANTITIES[ds.column_quantity[c]].model is not None
        )
        redundant = {ds.column_of("load_fraction")} if "power_W" in ds.values else set()
        self.channels = tuple(c for c in self.predicted_columns if c not in self.target_columns and c not in redundant)
        if not self.channels:
            raise ValueError(f"{ds.name}: no channel to compare (every predicted column fixes the operating point)")
        self.Y = np.column_stack([ds.raw[c] for c in self.channels]).astype(float)
        self.measured_mask = np.isfinite(self.Y)
        if tolerances is None:
            tolerances = ds.meta.get("tolerances") if isinstance(ds.meta.get("tolerances"), Mapping) else {}
        self.tolerance = np.array([float(tolerances.get(c, self.default_tolerance(c))) for c in self.channels])
        self.tolerance_cells = self._cell_tolerances()
        # per-row boundary conditions (NaN: the parameter set's)
        b = ds.boundary or {}
        self.boundary = {k: np.asarray(b.get(k, nan), float) for k in ("p_amb_Pa", "T_amb_K", "p_ex_Pa")}
        self.p_amb_rows = np.broadcast_to(np.asarray(ds.ambient["p_amb_Pa"], float), (n,)).copy()
        self.ctx = ModelContext(rated_power_W=ds.rated_power_W)
        # the parameter set as it is, with its own submodels (an engine file written by --save-params keeps its
        # waste gate when it is validated again); candidate mechanisms are added on top of these
        self.base_setting = (
            BASE_SETTING
            if self.params.submodels == BASE_SETTING.submodels
            else BASE_SETTING.replace(submodels=self.params.submodels)
        )
        self._state = np.full((n, 3), np.nan)
        self._group_cache: dict[bytes, list] = {}
        self._plans: dict[str, tuple] = {}
        self.n_evaluations = 0
        self.eval_seconds = 0.0

    # ---- tolerances
    def default_tolerance(self, column: str) -> float:
        """1 % of the mean measured value (ratio quantities), 5 K (temperatures), 0.01 (load fraction)."""
        return column_tolerance(self.ds, column)

    def stated_tolerances(self, items: Sequence[str]) -> dict[str, float]:
        """The tolerances of this problem with ``COLUMN=VALUE`` items (``marine-fdi validate --tolerance``) put in
        place: VALUE in the column's units, or ``P%`` for P % of the channel's mean value on the default's basis
        (absolute pressure for a gauge column; not for temperatures, whose default is 5 K, not a percentage).

        A tolerance is the residual scale of a channel: the fit weights it by its inverse and the tests of
        unexplained structure count in it, so a tolerance that misstates a sensor's noise weights the channels
        wrongly (docs/validation.md, "What a misstated tolerance costs").  Raises ValueError naming the
        item on an unknown or uncompared column, a malformed or non-positive value, or a column given twice."""
        out = {c: float(t) for c, t in zip(self.channels, self.tolerance)}
        seen: set[str] = set()
        for item in items:
            col, eq, val = str(item).partition("=")
            col, val = col.strip(), val.strip()
            if not eq or not col or not val:
                raise ValueError(f"--tolerance {item!r}: expected COLUMN=VALUE or COLUMN=P%")
            if col not in self.channels:
                raise ValueError(
                    f"--tolerance {item!r}: {col!r} is not a compared channel of {self.ds.name}; "
                    f"channels: {', '.join(self.channels)}"
                )
            if col in seen:
                raise ValueError(f"--tolerance: {col!r} given twice")
            seen.add(col)
            pct = val.endswith("%")
            try:
                x = float(val[:-1] if pct else val)
            except ValueError:
                raise ValueError(f"--tolerance {item!r}: {val!r} is not a number (or P%)") from None
            if not np.isfinite(x) or x <= 0:
                raise ValueError(f"--tolerance {item!r}: must be positive")
            if pct:
                if QUANTITIES[self.ds.column_quantity[col]].kind == "temperature":
                    raise ValueError(
                        f"--tolerance {item!r}: give a temperature's tolerance in its unit, not "
                        "in % (the default is 5 K)"
                    )
                x = column_tolerance(self.ds, col, rel_tol=x / 100.0)
            out[col] = x
        return out

    def _cell_tolerances(self) -> np.ndarray:
        tol = np.broadcast_to(self.tolerance, self.Y.shape).copy()
        for g in self.ds.groups.values():
            col = g.get("mean_column")
            if col in self.channels:
                j = self.channels.index(col)
                sem = np.where(g["n"] >= 2, g["spread"] / np.sqrt(np.maximum(g["n"], 1)), 0.0)
                tol[:, j] = np.sqrt(self.tolerance[j] ** 2 + np.nan_to_num(sem) ** 2)
        return tol

    # ---- model evaluation
    def engine(self, setting: Setting | None = None) -> EngineParams:
        """The engine of ``setting`` (default :attr:`base_setting`) at the parameter set's ambient state (scales,
        submodels, ambient offsets)."""
        setting = self.base_setting if setting is None else setting
        p = self.params
        ch: dict[str, Any] = {k: getattr(p, k) * v for k, v in setting.scales.items() if v != 1.0}
        if setting.area_scale != 1.0:
            ch["A_eff_m2"] = ch.get("A_eff_m2", p.A_eff_m2) * setting.area_scale
        if setting.submodels is not p.submodels:
            ch["submodels"] = setting.submodels
        if setting.dT_amb_K != 0.0:
            ch["T_amb_K"] = p.T_amb_K + setting.dT_amb_K
        if setting.dp_amb_Pa != 0.0:
            ch["p_amb_Pa"] = p.p_amb_Pa + setting.dp_amb_Pa
            ch["p_ex_Pa"] = p.p_ex_Pa + setting.dp_amb_Pa
        return p.replace(validate=False, **ch) if ch else p

    def _groups(self, rows: np.ndarray) -> list[tuple[tuple[float, float, float], np.ndarray]]:
        """Rows grouped by their boundary conditions (cached per set of rows)."""
        rows_key = rows.tobytes()
        hit = self._group_cache.get(rows_key)
        if hit is not None:
            return hit
        b = self.boundary
        groups: dict[tuple, list[int]] = {}
        for i in rows:
            key = tuple(float(b[k][i]) if math.isfinite(b[k][i]) else None for k in ("p_amb_Pa", "T_amb_K", "p_ex_Pa"))
            groups.setdefault(key, []).append(int(i))
        out = [(tuple(math.nan if x is None else x for x in k), np.array(v, dtype=int)) for k, v in groups.items()]
        self._group_cache[rows_key] = out  # keyed by the rows asked for, so that the next call with them hits
        return out

    def point_engine(self, setting: Setting, row: int) -> EngineParams:
        """The engine of ``setting`` at the boundary conditions of ``row``."""
        b = self.boundary
        return self._at_boundary(
            self.engine(setting), setting, tuple(float(b[k][row]) for k in ("p_amb_Pa", "T_amb_K", "p_ex_Pa"))
        )

    @staticmethod
    def _at_boundary(eng: EngineParams, setting: Setting, key: tuple[float, float, float]) -> EngineParams:
        pa, Ta, pe = key
        ch = {}
        if math.isfinite(pa):
            ch["p_amb_Pa"] = pa + setting.dp_amb_Pa
        if math.isfinite(Ta):
            ch["T_amb_K"] = Ta + setting.dT_amb_K
        if math.isfinite(pe):
            ch["p_ex_Pa"] = pe + setting.dp_amb_Pa
        return eng.replace(validate=False, **ch) if ch else eng

    def _inputs(self, p: EngineParams, rows: np.ndarray) -> tuple[int, np.ndarray, np.ndarray, int]:
        """(mode, a0, a1, load law) of the rows for engine ``p``."""
        t = self.target_si[rows]
        zero = np.zeros(rows.size)
        with np.errstate(invalid="ignore", divide="ignore"):
            if self.target == "power":
                return MODE_P, np.where(np.isfinite(t) & (t > 0), t, np.nan), speed_of_power(p, t), LAW_PARAMS
            if self.target == "speed":
                try:
                    P = power_of_speed(p, t)
                except ValueError:
                    P = np.full(t.size, np.nan)
                return MODE_P, np.where(np.isfinite(P) & (P > 0), P, np.nan), t, LAW_PARAMS
            if self.target == "fuel_flow":
                return MODE_F, np.where(np.isfinite(t) & (t > 0), t, np.nan), zero, LAW_PARAMS
            return MODE_U, np.where(np.isfinite(t) & (t > 0), t, np.nan), zero, LAW_PARAMS

    def solve(self, setting: Setting | None = None, rows=None) -> tuple[Summary, np.ndarray]:
        """Operating points of ``rows`` (default all) for ``setting`` (default :attr:`base_setting`): (SI summary
        arrays over the rows, computed on demand; converged)."""
        setting = self.base_setting if setting is None else setting
        rows = np.arange(self.n_points) if rows is None else np.asarray(rows, dtype=int)
        t0 = time.perf_counter()
        eng = self.engine(setting)
        m = rows.size
        alg = np.full((m, N_ALG), np.nan)
        x1 = np.full(m, np.nan)
        conv = np.zeros(m, dtype=bool)
        pos = np.empty(self.n_points, dtype=int)
        pos[rows] = np.arange(m)
        ov_all = np.full((self.n_points, 2), np.nan)
        for j, name in enumerate(VALVES):
            if name in setting.valves:
                ov_all[:, j] = np.asarray(setting.valves[name], float)
        c_eng = model_constants(eng)
        for key, idx in self._groups(rows):
            p = self._at_boundary(eng, setting, key)
            mode, a0, a1, law = self._inputs(p, idx)
            y = self._state[idx]
            c = c_eng if p is eng else constants_at_ambient(c_eng, p)  # = model_constants(p), cheaper
            a_, x_, ok = solve_raw(
                c, mode, a0, np.asarray(a1, float), law, y, HEALTHY_PF, np.ascontiguousarray(ov_all[idx])
            )
            st = self._state[idx]
            st[ok] = y[ok]
            self._state[idx] = st
            k = pos[idx]
            alg[k] = a_
            x1[k] = x_
            conv[k] = ok
        st = self._state[rows]
        b = self.boundary
        p_amb = np.where(
            np.isfinite(b["p_amb_Pa"][rows]), b["p_amb_Pa"][rows], eng.p_amb_Pa
        ) + setting.dp_amb_Pa * np.isfinite(b["p_amb_Pa"][rows])
        T_amb = np.where(np.isfinite(b["T_amb_K"][rows]), b["T_amb_K"][rows] + setting.dT_amb_K, eng.T_amb_K)
        vals = Summary(eng, x1, st[:, 0], st[:, 1], alg, conv, p_amb, T_amb)
        self.n_evaluations += 1
        self.eval_seconds += time.perf_counter() - t0
        return vals, conv

    def readings(
        self,
        setting: Setting,
        vals: Mapping[str, np.ndarray],
        conv: np.ndarray,
        rows: np.ndarray,
        columns: Sequence[str],
    ) -> np.ndarray:
        """Model readings of ``columns`` (their units, sensor gains/offsets applied), NaN where not converged."""
        ds = self.ds
        out = np.empty((rows.size, len(columns)))
        p_amb = self.p_amb_rows[rows] + setting.dp_amb_Pa  # a gauge reads against the actual ambient
        for j, col in enumerate(columns):
            plan = self._plans.get(col)
            if plan is None:
                plan = self._plans[col] = (ds.column_quantity[col], ds.spec(col))
            si = quantity_values(plan[0], vals, self.ctx)
            v = plan[1].from_si(si, p_amb)
            if col in setting.sensors:
                g, o = setting.sensors[col]
                v = g * v + o
            out[:, j] = np.where(conv, v, np.nan)
        return out

    def predict(self, setting: Setting | None = None, rows=None, columns: Sequence[str] | None = None):
        """(readings (rows x channels) in the channels' units, converged per row, SI summaries) of ``setting``
        (default :attr:`base_setting`)."""
        setting = self.base_setting if setting is None else setting
        rows = np.arange(self.n_points) if rows is None else np.asarray(rows, dtype=int)
        vals, conv = self.solve(setting, rows)
        return self.readings(setting, vals, conv, rows, columns or self.channels), conv, vals

    def normalised_residuals(self, pred: np.ndarray, rows=None) -> np.ndarray:
        """``(pred - measured)/tolerance`` on the measured cells of ``rows`` (FAIL_RESIDUAL where the model has
        no value), NaN on cells without a measurement."""
        rows = np.arange(self.n_points) if rows is None else np.asarray(rows, dtype=int)
        r = (pred - self.Y[rows]) / self.tolerance_cells[rows]
        m = self.measured_mask[rows]
        r = np.where(m & ~np.isfinite(r), FAIL_RESIDUAL, r)
        return np.where(m, r, np.nan)

    def rows_with_data(self) -> np.ndarray:
        return np.flatnonzero(self.measured_mask.any(axis=1) & np.isfinite(self.target_si))

    def folds(self, max_folds: int | None = None) -> tuple[str, list[tuple[str, np.ndarray]]]:
        """Cross-validation folds: leave-one-engine-out with several engines, else leave-one-point-out (with
        ``max_folds``: contiguous blocks in load order when there are more points)."""
        rows = self.rows_with_data()
        eng = self.ds.engine_ids()
        if len(eng) >= 2:
            e = np.array(self.ds.engines)
            return "leave-one-engine-out", [(str(x), np.array([i for i in rows if e[i] == x], dtype=int)) for x in eng]
        if max_folds is None or rows.size <= max_folds:
            return "leave-one-point-out", [(f"point {i + 1}", np.array([i], dtype=int)) for i in rows]
        order = rows[np.argsort(self.load_axis()[rows], kind="stable")]
        # interleaved folds: each fold takes every k-th point in load order, so that each leaves out points
        # spread over the load range (contiguous blocks would test extrapolation, not the model)
        return f"{max_folds}-fold (interleaved in load)", [
            (f"fold {k + 1}", np.sort(order[k::max_folds])) for k in range(max_folds)
        ]

    def test_bed_conditions(self) -> dict[str, Any] | None:
        """The boundary conditions this data recorded, as a test bed's: mean ambient pressure [Pa] and intake
        temperature [K], and the back pressure above ambient [Pa] over the load fraction (its points sorted by
        load); None where a quantity was not recorded."""
        b, load = self.boundary, self.load_axis()

        def mean(k):
            v = b[k][np.isfinite(b[k])]
            return float(v.mean()) if v.size else None

        dp = b["p_ex_Pa"] - np.where(np.isfinite(b["p_amb_Pa"]), b["p_amb_Pa"], self.params.p_amb_Pa)
        ok = np.isfinite(dp) & np.isfinite(load)
        order = np.argsort(load[ok], kind="stable")
        out = {
            "p_amb_Pa": mean("p_amb_Pa"),
            "T_amb_K": mean("T_amb_K"),
            "back_pressure": (
                {"load_fraction": load[ok][order].tolist(), "dp_Pa": dp[ok][order].tolist()} if ok.any() else None
            ),
        }
        return out if any(v is not None for v in out.values()) else None

    def assume_boundary(self, conditions: Mapping[str, Any]) -> list[str]:
        """Fill the boundary conditions this data did not record from ``conditions`` (a
        :meth:`test_bed_conditions`, e.g. of the data a fit saw on the same test bed); returns what was filled.
        Recorded values are never replaced."""
        b, n, filled = self.boundary, self.n_points, []
        if conditions.get("p_amb_Pa") is not None and not np.isfinite(b["p_amb_Pa"]).any():
            b["p_amb_Pa"] = np.full(n, float(conditions["p_amb_Pa"]))
            if not self.ds.ambient.get("recorded"):
                self.p_amb_rows = b["p_amb_Pa"].copy()  # the gauge readings' reference too
            filled.append("ambient pressure")
        if conditions.get("T_amb_K") is not None and not np.isfinite(b["T_amb_K"]).any():
            b["T_amb_K"] = np.full(n, float(conditions["T_amb_K"]))
            filled.append("intake temperature")
        bp = conditions.get("back_pressure")
        if bp is not None and not np.isfinite(b["p_ex_Pa"]).any():
            pa = np.where(np.isfinite(b["p_amb_Pa"]), b["p_amb_Pa"], self.params.p_amb_Pa)
            b["p_ex_Pa"] = pa + np.interp(self.load_axis(), bp["load_fraction"], bp["dp_Pa"])
            filled.append("back pressure (over load)")
        if filled:
            self._group_cache.clear()
            self._state[:] = np.nan
        return filled

    def load_axis(self) -> np.ndarray:
        """Load fraction per point (measured power or load / rated, else the target normalised)."""
        v = self.ds.values
        if "power_W" in v:
            return v["power_W"] / self.ds.rated_power_W
        if "load_fraction" in v:
            return v["load_fraction"]
        t = self.target_si
        return t / np.nanmax(t)


def quantity_values(q: str, V: Mapping[str, np.ndarray], ctx: ModelContext) -> np.ndarray:
    """SI values of quantity ``q`` from summary arrays."""
    if q in V:
        return np.asarray(V[q], float)
    P = np.asarray(V["power_W"], float)
    with np.errstate(divide="ignore", invalid="ignore"):
        if q == "load_fraction":
            return P / ctx.rated_power_W
        if q == "specific_air_flow_kg_per_J":
            return np.where(P > 0, V["air_mass_flow_kg_s"] / P, np.nan)
        if q == "specific_exhaust_flow_kg_per_J":
            return np.where(P > 0, V["exhaust_mass_flow_kg_s"] / P, np.nan)
        if q == "turbocharger_speed_rev_s":
            return np.asarray(V["turbocharger_speed_rpm"], float) / 60.0
    raise KeyError(f"the model has no quantity {q!r}")
