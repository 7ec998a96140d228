"""Saving and loading simulation runs as ``.npz`` files.

A run file holds these arrays (T samples, N engines, k truth variables, F = 26 fault ids):

=================  ==============  ===================================================
array              shape           content
=================  ==============  ===================================================
t                  (T,)            sample times [s]
measurements       (T, N, 19)      sensor readings, columns in the order of sensor_ids
sensor_ids         (19,)           ``S1.1`` ... ``S4.6``
truth              (T, N, k)       true variables, columns named by truth_variables
truth_variables    (k,)            names (``u``, ``x1``, ``x3``, ... see simulator)
fault_ids          (F,)            sensor ids then the process fault ids
fault_active       (T, N, F)       bool, fault window open
fault_value        (T, N, F)       fault function value (see faults.py)
metadata           ()              JSON object: params name, dt, seeds, schedules
                                   (FaultSpec.to_dict per engine), profiles
                                   (Profile.to_dict per engine), failures, noise_scale,
                                   package version, command line, ...
=================  ==============  ===================================================

Non-finite floats in the metadata (e.g. an abrupt fault's κ = inf) are written as the strings
``"inf"``, ``"-inf"`` and ``"nan"`` so that the metadata is strict JSON.

:func:`load_run` validates the file and raises ``ValueError`` naming the offending array (and,
for non-finite samples, the sensor, engine, sample index and time).
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import os
import shlex
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from .engine.faults import FAULT_IDS, PROCESS_FAULT_DEFAULTS, PROCESS_FAULT_IDS, FaultSpec
from .engine.profiles import Profile
from .engine.sensors import SENSOR_IDS, SENSORS
from .jsonfile import json_safe

__all__ = ["save_run", "load_run", "RunData", "fault_unit", "FORMAT_NAME", "FORMAT_VERSION", "REQUIRED_ARRAYS"]

FORMAT_NAME = "marine-fdi-run"
FORMAT_VERSION = 1
REQUIRED_ARRAYS: tuple[str, ...] = (
    "t",
    "measurements",
    "sensor_ids",
    "truth",
    "truth_variables",
    "fault_ids",
    "fault_active",
    "fault_value",
    "metadata",
)
_SENSOR_UNIT = {s.id: s.unit for s in SENSORS}


def _num(v: Any) -> float | None:
    """A float from a metadata number (accepting the ``"inf"``/``"nan"`` strings); None stays None."""
    return None if v is None else float(v)


def _spec_from_dict(d: dict) -> FaultSpec:
    """Rebuild a :class:`FaultSpec` from :meth:`FaultSpec.to_dict` output (resolved values)."""
    mag = _num(d.get("magnitude"))
    if mag is not None and math.isnan(mag):
        mag = None  # stuck fault holding the last reading
    return FaultSpec(
        fault_id=d["fault_id"],
        onset_s=float(d["onset_s"]),
        magnitude=mag,
        kind=d.get("kind"),
        kappa=_num(d.get("kappa")),
        end_s=_num(d.get("end_s")),
        period_s=_num(d.get("period_s")),
        duty=_num(d.get("duty")),
    )


def fault_unit(spec: FaultSpec) -> str:
    """Unit of a fault's magnitude (sensor unit, unit/s for drifts, '-' for gains, table 6.4 units)."""
    if spec.fault_id in PROCESS_FAULT_IDS:
        return PROCESS_FAULT_DEFAULTS[spec.fault_id].unit
    unit = _SENSOR_UNIT[spec.fault_id]
    kind = spec.resolved_kind
    if kind == "drift":
        return f"{unit}/s"
    if kind == "gain":
        return "-"
    return unit


# ----------------------------------------------------------------------------- saving
def save_run(
    result,
    path: "str | os.PathLike[str]",
    *,
    command_line: "str | Sequence[str] | None" = None,
    extra: dict | None = None,
) -> Path:
    """Write a :class:`~marine_fdi_env.engine.simulator.SimulationResult` to ``path`` (compressed ``.npz``).

    ``command_line`` (a string or an argv list) and ``extra`` (a JSON-able dict, e.g. the scenario
    name) go into the metadata.  The file is written to a temporary name and renamed, so an
    interrupted save never leaves a truncated run file.  Returns the path written (exactly
    ``path``; no suffix is appended).
    """
    from ._version import __version__
    from .engine.simulator import TRUTH_VARIABLES

    path = Path(path)
    meas = np.asarray(result.measurements, dtype=float)
    truth = np.asarray(result.truth, dtype=float)
    if meas.ndim != 3 or meas.shape[2] != len(SENSOR_IDS):
        raise ValueError(f"result.measurements must have shape (T, N, {len(SENSOR_IDS)}), got {meas.shape}")
    T, N, _ = meas.shape
    if isinstance(command_line, (list, tuple)):
        command_line = shlex.join(str(a) for a in command_line)
    meta = {
        "format": FORMAT_NAME,
        "format_version": FORMAT_VERSION,
        "package_version": __version__,
        "created_utc": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        "command_line": command_line,
        "params_name": result.params_name,
        "dt": float(result.dt),
        "n_samples": int(T),
        "n_engines": int(N),
        "seeds": [int(s) for s in result.seeds],
        "noise_scale": float(result.noise_scale),
        "schedules": [[f.to_dict() for f in sched] for sched in result.schedules],
        "profiles": [p.to_dict() for p in result.profiles],
        "failures": [f.to_dict() for f in result.failures],
        "sensor_units": dict(_SENSOR_UNIT),
    }
    if extra:
        overlap = set(extra) & set(meta)
        if overlap:
            raise ValueError(f"extra metadata may not override {sorted(overlap)}")
        meta.update(extra)
    arrays = {
        "t": np.asarray(result.t, dtype=float),
        "measurements": meas,
        "sensor_ids": np.array(SENSOR_IDS),
        "truth": truth,
        "truth_variables": np.array(TRUTH_VARIABLES),
        "fault_ids": np.array(FAULT_IDS),
        "fault_active": np.asarray(result.fault_active, dtype=bool),
        "fault_value": np.asarray(result.fault_value, dtype=float),
        "metadata": np.array(json.dumps(json_safe(meta, nonfinite="string"), allow_nan=False)),
    }
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "wb") as fh:
            np.savez_compressed(fh, **arrays)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    return path


# ----------------------------------------------------------------------------- loading
@dataclass
class RunData:
    """A loaded run.  Arrays are indexed (sample, engine, ...), like ``SimulationResult``.

    ``by_sensor`` maps each sensor id to its (T, N) readings (views into ``measurements``).
    """

    t: np.ndarray
    measurements: np.ndarray
    sensor_ids: tuple[str, ...]
    truth: np.ndarray
    truth_variables: tuple[str, ...]
    fault_ids: tuple[str, ...]
    fault_active: np.ndarray
    fault_value: np.ndarray
    metadata: dict
    path: Path | None = None
    by_sensor: dict[str, np.ndarray] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        self.by_sensor = {s: self.measurements[:, :, j] for j, s in enumerate(self.sensor_ids)}

    # ---------------------------------------------------------------- sizes and metadata
    @property
    def n_samples(self) -> int:
        return int(self.measurements.shape[0])

    @property
    def n_engines(self) -> int:
        return int(self.measurements.shape[1])

    @property
    def dt(self) -> float:
        return float(self.metadata["dt"]) if "dt" in self.metadata else float(self.t[1] - self.t[0])

    @property
    def params_name(self) -> str | None:
        return self.metadata.get("params_name")

    @property
    def seeds(self) -> list[int]:
        return list(self.metadata.get("seeds", []))

    @property
    def noise_scale(self) -> float | None:
        return self.metadata.get("noise_scale")

    @property
    def failures(self) -> list[dict]:
        """Engine failures recorded by the simulator: dicts with engine, time_s, reason."""
        return list(self.metadata.get("failures", []))

    @property
    def schedules(self) -> list[list[FaultSpec]]:
        """The fault schedule of each engine, rebuilt as :class:`FaultSpec` (resolved values)."""
        return [[_spec_from_dict(d) for d in s] for s in self.metadata.get("schedules", [[]] * self.n_engines)]

    @property
    def profiles(self) -> list[Profile]:
        return [Profile(p["name"], tuple(p["times"]), tuple(p["values"])) for p in self.metadata.get("profiles", [])]

    # ---------------------------------------------------------------- data access
    def sensor(self, sensor_id: str, engine: int | None = None) -> np.ndarray:
        """Readings of one sensor: (T, N), or (T,) for one engine."""
        if sensor_id not in self.by_sensor:
            raise ValueError(f"unknown sensor {sensor_id!r}; allowed: {', '.join(self.sensor_ids)}")
        y = self.by_sensor[sensor_id]
        return y if engine is None else y[:, self._engine(engine)]

    def truth_of(self, name: str, engine: int | None = None) -> np.ndarray:
        """One true variable: (T, N), or (T,) for one engine."""
        if name not in self.truth_variables:
            raise ValueError(f"unknown truth variable {name!r}; allowed: {', '.join(self.truth_variables)}")
        x = self.truth[:, :, self.truth_variables.index(name)]
        return x if engine is None else x[:, self._engine(engine)]

    def active(self, fault_id: str, engine: int | None = None) -> np.ndarray:
        """Ground-truth activity of one fault id: bool (T, N), or (T,) for one engine."""
        if fault_id not in self.fault_ids:
            raise ValueError(f"unknown fault id {fault_id!r}; allowed: {', '.join(self.fault_ids)}")
        a = self.fault_active[:, :, self.fault_ids.index(fault_id)]
        return a if engine is None else a[:, self._engine(engine)]

    def true_faults(self, engine: int | None = None) -> list[dict]:
        """Ground truth of the scheduled faults, one dict per (engine, fault), sorted by engine, onset.

        Keys: ``engine``, ``id``, ``class`` (sensor/process), ``kind``, ``onset_s``, ``magnitude``,
        ``unit`` (of the magnitude), ``kappa``, ``end_s``, ``period_s``, ``duty``, and from the
        recorded data ``first_active_s`` (time of the first sample with the window open, None if
        it never opened in this run) and ``active_in_run``.
        """
        engines = range(self.n_engines) if engine is None else [self._engine(engine)]
        scheds = self.schedules
        out = []
        for e in engines:
            for spec in sorted(scheds[e] if e < len(scheds) else [], key=lambda f: (f.onset_s, f.fault_id)):
                d = spec.to_dict()
                act = self.active(spec.fault_id, e) if spec.fault_id in self.fault_ids else np.zeros(0, bool)
                idx = np.flatnonzero(act)
                first = float(self.t[idx[0]]) if idx.size else None
                out.append(
                    {
                        "engine": e,
                        "id": spec.fault_id,
                        "class": d["class"],
                        "kind": d["kind"],
                        "onset_s": d["onset_s"],
                        "magnitude": None if math.isnan(d["magnitude"]) else d["magnitude"],
                        "unit": fault_unit(spec),
                        "kappa": d["kappa"],
                        "end_s": d["end_s"],
                        "period_s": d["period_s"],
                        "duty": d["duty"],
                        "first_active_s": first,
                        "active_in_run": first is not None,
                    }
                )
        return out

    def _engine(self, engine: int) -> int:
        e = int(engine)
        if not 0 <= e < self.n_engines:
            raise ValueError(f"engine must lie in [0, {self.n_engines - 1}], got {engine!r}")
        return e


def _first_nonfinite(a: np.ndarray) -> tuple[int, ...] | None:
    """Index of the earliest (by sample) non-finite entry of ``a`` (first axis = sample)."""
    bad = ~np.isfinite(a)
    if not bad.any():
        return None
    rows = np.flatnonzero(bad.reshape(a.shape[0], -1).any(axis=1))
    k = int(rows[0])
    rest = np.unravel_index(int(np.flatnonzero(bad[k].ravel())[0]), a.shape[1:])
    return (k,) + tuple(int(i) for i in rest)


def _refuse_nonfinite(where: str, a: np.ndarray, t: np.ndarray, subject, show_value=False, hint="") -> None:
    """``ValueError`` naming the first non-finite value of ``a`` (T, N, K): ``subject(e, j)`` says whose, with
    its sample and time (and the value itself, and ``hint``)."""
    bad = _first_nonfinite(a)
    if bad is None:
        return
    i, e, j = bad
    value = f" ({a[i, e, j]})" if show_value else ""
    raise ValueError(f"{where}: {subject(e, j)} has a non-finite value{value} at sample {i} (t={t[i]:.6g} s){hint}")


def _strings(z, name: str, where: str) -> tuple[str, ...]:
    a = z[name]
    if a.ndim != 1 or a.dtype.kind not in "US":
        raise ValueError(f"{where}: array {name!r} must be a 1-D array of strings, got dtype {a.dtype} shape {a.shape}")
    return tuple(str(s) for s in a.tolist())


def load_run(path: "str | os.PathLike[str]", *, allow_nonfinite: bool = False) -> RunData:
    """Load and validate a run file written by :func:`save_run`.

    Raises ``ValueError`` for a file that is not a run file, lacks arrays, has arrays of the wrong
    shape, or holds non-finite values.  ``allow_nonfinite=True`` accepts NaN/inf in
    ``measurements`` (sensor dropouts a diagnoser may want to handle); times, ground truth and
    fault values must always be finite.
    """
    path = Path(path)
    if path.is_dir():
        raise ValueError(f"{str(path)!r} is a folder; a run file is a .npz file written by 'marine-fdi simulate'")
    if not path.is_file():
        raise ValueError(f"run file {str(path)!r} does not exist")
    where = f"run file {str(path)!r}"
    try:
        z = np.load(path, allow_pickle=False)
    except ValueError:  # numpy's message for a non-archive speaks of pickles, which misleads
        raise ValueError(f"{str(path)!r} is not a readable .npz run file (not a zip archive of arrays)") from None
    except (OSError, zipfile.BadZipFile, EOFError) as exc:
        raise ValueError(f"{str(path)!r} is not a readable .npz run file: {exc}") from None
    if not isinstance(z, np.lib.npyio.NpzFile):
        raise ValueError(f"{str(path)!r} is not a .npz run file (it holds a single array)")
    with z:
        missing = [k for k in REQUIRED_ARRAYS if k not in z.files]
        if missing:
            raise ValueError(f"{where} lacks array(s): {', '.join(missing)}")

        def get(name: str) -> np.ndarray:
            try:
                return np.asarray(z[name])
            except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
                raise ValueError(f"{where}: array {name!r} cannot be read ({exc})") from None

        t, meas, truth = get("t"), get("measurements"), get("truth")
        f_act, f_val, meta_arr = get("fault_active"), get("fault_value"), get("metadata")
        names = {k: get(k) for k in ("sensor_ids", "truth_variables", "fault_ids")}
    sensor_ids = _strings(names, "sensor_ids", where)
    truth_vars = _strings(names, "truth_variables", where)
    fault_ids = _strings(names, "fault_ids", where)

    # metadata
    if meta_arr.ndim != 0 or meta_arr.dtype.kind not in "US":
        raise ValueError(f"{where}: array 'metadata' must be a JSON string")
    try:
        meta = json.loads(meta_arr.item())
    except json.JSONDecodeError as exc:
        raise ValueError(f"{where}: array 'metadata' is not valid JSON ({exc})") from None
    if not isinstance(meta, dict):
        raise ValueError(f"{where}: array 'metadata' must hold a JSON object")

    # shapes and dtypes
    for name, a in (("t", t), ("measurements", meas), ("truth", truth), ("fault_value", f_val)):
        if a.dtype.kind not in "fiu":
            raise ValueError(f"{where}: array {name!r} must be numeric, got dtype {a.dtype}")
    if f_act.dtype != bool:
        raise ValueError(f"{where}: array 'fault_active' must be boolean, got dtype {f_act.dtype}")
    if sensor_ids != SENSOR_IDS:
        raise ValueError(
            f"{where}: array 'sensor_ids' must be the {len(SENSOR_IDS)} sensors "
            f"{', '.join(SENSOR_IDS)} in this order, got {', '.join(sensor_ids)}"
        )
    if t.ndim != 1 or t.shape[0] < 1:
        raise ValueError(f"{where}: array 't' must have shape (T,) with T >= 1, got {t.shape}")
    T = t.shape[0]
    if meas.ndim != 3 or meas.shape[0] != T or meas.shape[2] != len(SENSOR_IDS) or meas.shape[1] < 1:
        raise ValueError(
            f"{where}: array 'measurements' must have shape (T, N, {len(SENSOR_IDS)}) = "
            f"(samples, engines, sensors) with T = {T} from 't', got {meas.shape}"
        )
    N = meas.shape[1]
    k = len(truth_vars)
    if truth.shape != (T, N, k):
        raise ValueError(
            f"{where}: array 'truth' must have shape (T, N, k) = {(T, N, k)} "
            f"(k = len(truth_variables)), got {truth.shape}"
        )
    nF = len(fault_ids)
    for name, a in (("fault_active", f_act), ("fault_value", f_val)):
        if a.shape != (T, N, nF):
            raise ValueError(
                f"{where}: array {name!r} must have shape (T, N, F) = {(T, N, nF)} (F = len(fault_ids)), got {a.shape}"
            )
    scheds = meta.get("schedules")
    if scheds is not None and (not isinstance(scheds, list) or len(scheds) != N):
        raise ValueError(f"{where}: metadata 'schedules' must hold one fault list per engine ({N})")

    # finite values
    bad = _first_nonfinite(t)
    if bad is not None:
        raise ValueError(f"{where}: array 't' has a non-finite value at sample {bad[0]}")
    if T > 1 and not np.all(np.diff(t) > 0):
        k0 = int(np.flatnonzero(~(np.diff(t) > 0))[0])
        raise ValueError(
            f"{where}: array 't' must increase strictly; sample {k0 + 1} (t={t[k0 + 1]:g} s) "
            f"does not follow sample {k0} (t={t[k0]:g} s)"
        )
    if not allow_nonfinite:
        _refuse_nonfinite(
            where,
            meas,
            t,
            lambda e, j: f"sensor {sensor_ids[j]} of engine {e}",
            show_value=True,
            hint="; pass allow_nonfinite=True to accept dropouts",
        )
    _refuse_nonfinite(where, truth, t, lambda e, j: f"truth variable {truth_vars[j]} of engine {e}")
    _refuse_nonfinite(where, f_val, t, lambda e, j: f"fault_value of {fault_ids[j]} (engine {e})")

    run = RunData(
        t=t.astype(float, copy=False),
        measurements=meas.astype(float, copy=False),
        sensor_ids=sensor_ids,
        truth=truth.astype(float, copy=False),
        truth_variables=truth_vars,
        fault_ids=fault_ids,
        fault_active=f_act,
        fault_value=f_val.astype(float, copy=False),
        metadata=meta,
        path=path,
    )
    for key in ("schedules", "profiles"):
        try:
            getattr(run, key)
        except (ValueError, KeyError, TypeError) as exc:
            raise ValueError(f"{where}: metadata {key!r} is malformed ({exc})") from None
    return run
