"""Sensor and process faults, their time profiles and fault schedules.

Time profile (eq. 2.3-2.6, 5.1, 5.2): a fault is active on one or more windows
``[t_a, t_b)``; inside a window its value is ``β(t - t_a) φ(t - t_a)`` with the evolution
``β(s) = 1 - exp(-κ s)`` (κ = inf: abrupt, β = 1).  Permanent: one window [onset, ∞).
Transient: [onset, end).  Intermittent: windows of length ``duty·period`` repeating every
``period`` from onset until ``end``.

Fault functions φ
-----------------
Sensor faults (any of the 19 sensor ids), ``kind``:

``offset``     y += φ, φ = magnitude (default: table 6.3 magnitude), eq. 5.1.
``drift``      y += R s, R = magnitude [unit/s] (default: table 6.3 magnitude per 60 s).
``stuck``      y = reading just before the window opened (magnitude ignored) or, if a magnitude
               is given, that constant value.
``gain``       y = (1 + β g) (true value) + noise, g = magnitude (default 0.05).
``precision``  extra uniform noise with bound β·magnitude (default: 3x the sensor's noise bound).

Process faults (tables 3.1, 3.2, 6.4): declared in :mod:`.fault_registry`, one record each (symbol, the
equation term it drives, its law, the table 6.4 onset, κ and magnitude, allowed ranges).  A fault's law
gives its contribution to its term at time s after its window opened: ``fraction`` 1 - β φ (valve_seizing:
the fuel-setting factor f_u; table 6.4 gives φ_u = 25 "%", read as the fraction 0.25), ``ramp`` β R s (the
other six: ΔV1, φ_tur, ΔT_sl, φ_int, ΔT_inl, ΔT_co), ``level`` β φ; the faults on one term add (a factor:
multiply).  The seal leaks act as ``f_x = φ x`` on the state (table 3.2) and are subtracted, see
:mod:`marine_fdi_env.engine.subsystems.exhaust_receiver`.

Fault SPEC strings (CLI ``--fault``): ``ID@ONSET[:MAGNITUDE][,key=value...]`` e.g.
``S4.2@235:5e4``, ``S3.4@175``, ``bore_damage@5``, ``S2.1@20:3e4,kind=drift``,
``S1.1@50,kind=offset,end=80``, ``valve_seizing@20:0.1,kappa=0.05``,
``S3.3@10,period=20,duty=0.25``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from .fault_registry import FAULT_TYPES, TERM_INDEX, TERMS, fault_type
from .sensors import DEFAULT_FAULT_MAGNITUDES, NOISE_BOUNDS, SENSOR_IDS, sensor_index

__all__ = [
    "PROCESS_FAULT_IDS",
    "FAULT_IDS",
    "SENSOR_FAULT_KINDS",
    "PROCESS_FAULT_DEFAULTS",
    "FaultSpec",
    "parse_fault_spec",
    "random_fault_schedule",
    "fault_class",
    "window_time",
]

PROCESS_FAULT_IDS: tuple[str, ...] = tuple(f.id for f in FAULT_TYPES if f.kind == "process")
FAULT_IDS: tuple[str, ...] = tuple(f.id for f in FAULT_TYPES)
SENSOR_FAULT_KINDS: tuple[str, ...] = ("offset", "drift", "stuck", "gain", "precision")
if FAULT_IDS[: len(SENSOR_IDS)] != SENSOR_IDS:  # the sensor faults come first, in sensor order
    raise ImportError("the fault registry must list the 19 sensor faults first, in sensor order")


@dataclass(frozen=True)
class ProcessFaultDefault:
    """Table 6.4's defaults of a process fault (a view of its :class:`FaultType`)."""

    symbol: str
    onset_s: float
    kappa: float
    magnitude: float
    unit: str
    subsystem: int


PROCESS_FAULT_DEFAULTS: dict[str, ProcessFaultDefault] = {
    f.id: ProcessFaultDefault(f.symbol, f.onset_s, f.kappa, f.magnitude, f.unit, f.subsystem)
    for f in FAULT_TYPES
    if f.kind == "process"
}


def fault_class(fault_id: str) -> str:
    """'sensor' or 'process'; ``ValueError`` for an unknown id."""
    return fault_type(fault_id).kind


def _check_number(name: str, value, *, positive: bool = False, nonneg: bool = False, allow_inf: bool = False):
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"fault field {name!r} must be a number, got {value!r}") from None
    if math.isnan(v) or (math.isinf(v) and not allow_inf):
        raise ValueError(f"fault field {name!r} must be finite, got {value!r}")
    if positive and not v > 0:
        raise ValueError(f"fault field {name!r} must be > 0, got {value!r}")
    if nonneg and v < 0:
        raise ValueError(f"fault field {name!r} must be >= 0, got {value!r}")
    return v


@dataclass(frozen=True)
class FaultSpec:
    """One scheduled fault.

    fault_id : a sensor id (``S4.2``) or a process fault id (``bore_damage``).
    onset_s : start of the first active window [s].
    magnitude : fault function parameter (see module docstring); None -> thesis default.
    kind : sensor fault kind (``offset`` default); process faults accept only their own kind.
    kappa : evolution rate κ [1/s]; None -> default (inf for sensor faults, table 6.4 for process).
    end_s : end of activity (None: permanent).
    period_s, duty : intermittent activity (both or neither).
    """

    fault_id: str
    onset_s: float
    magnitude: float | None = None
    kind: str | None = None
    kappa: float | None = None
    end_s: float | None = None
    period_s: float | None = None
    duty: float | None = None

    def __post_init__(self) -> None:
        cls = fault_class(self.fault_id)
        _check_number("onset_s", self.onset_s, nonneg=True)
        if self.magnitude is not None:
            m = _check_number("magnitude", self.magnitude)
            if cls == "process":
                lo, hi = fault_type(self.fault_id).magnitude_range
                if not lo <= m <= hi:
                    raise ValueError(
                        f"fault field 'magnitude' of {self.fault_id} must lie in [{lo:g}, {hi:g}], got {m!r}"
                    )
            if cls == "sensor" and self.resolved_kind in ("precision",) and m < 0:
                raise ValueError(f"fault field 'magnitude' of a precision fault must be >= 0, got {m!r}")
        if self.kind is not None:
            allowed = SENSOR_FAULT_KINDS if cls == "sensor" else ("process",)
            if self.kind not in allowed:
                raise ValueError(f"fault field 'kind' of {self.fault_id} must be one of {allowed}, got {self.kind!r}")
        if self.kappa is not None:
            k = _check_number("kappa", self.kappa, positive=True, allow_inf=True)
            if cls == "process":
                lo, hi = fault_type(self.fault_id).kappa_range
                if not lo <= k <= hi:
                    raise ValueError(f"fault field 'kappa' of {self.fault_id} must lie in [{lo:g}, {hi:g}], got {k!r}")
        if self.end_s is not None:
            e = _check_number("end_s", self.end_s, nonneg=True)
            if e <= float(self.onset_s):
                raise ValueError(f"fault field 'end_s' ({e}) must be later than 'onset_s' ({self.onset_s})")
        if (self.period_s is None) != (self.duty is None):
            raise ValueError("fault fields 'period_s' and 'duty' must be given together")
        if self.period_s is not None:
            _check_number("period_s", self.period_s, positive=True)
            d = _check_number("duty", self.duty, positive=True)
            if d > 1:
                raise ValueError(f"fault field 'duty' must lie in (0, 1], got {self.duty!r}")

    @property
    def fault_class(self) -> str:
        return fault_class(self.fault_id)

    @property
    def resolved_kind(self) -> str:
        if fault_class(self.fault_id) == "process":
            return "process"
        return self.kind or "offset"

    @property
    def resolved_kappa(self) -> float:
        if self.kappa is not None:
            return float(self.kappa)
        return fault_type(self.fault_id).kappa  # table 6.4's for a process fault, inf (abrupt) for a sensor

    @property
    def resolved_magnitude(self) -> float:
        if self.magnitude is not None:
            return float(self.magnitude)
        if fault_class(self.fault_id) == "process":
            return fault_type(self.fault_id).magnitude
        j = sensor_index(self.fault_id)
        kind = self.resolved_kind
        if kind == "offset":
            return float(DEFAULT_FAULT_MAGNITUDES[j])
        if kind == "drift":
            return float(DEFAULT_FAULT_MAGNITUDES[j]) / 60.0
        if kind == "gain":
            return 0.05
        if kind == "precision":
            return 3.0 * float(NOISE_BOUNDS[j])
        return math.nan  # stuck at the last reading

    def to_dict(self) -> dict:
        return {
            "fault_id": self.fault_id,
            "class": self.fault_class,
            "kind": self.resolved_kind,
            "onset_s": float(self.onset_s),
            "magnitude": self.resolved_magnitude,
            "kappa": self.resolved_kappa,
            "end_s": None if self.end_s is None else float(self.end_s),
            "period_s": None if self.period_s is None else float(self.period_s),
            "duty": None if self.duty is None else float(self.duty),
        }

    def with_onset(self, onset_s: float) -> "FaultSpec":
        return replace(self, onset_s=onset_s)


_SPEC_KEYS = {"kind": str, "kappa": float, "end": float, "period": float, "duty": float, "magnitude": float}


def parse_fault_spec(text: str) -> FaultSpec:
    """Parse ``ID@ONSET[:MAGNITUDE][,key=value...]`` (see module docstring) into a :class:`FaultSpec`."""
    if not isinstance(text, str) or "@" not in text:
        raise ValueError(f"fault spec {text!r} must look like ID@ONSET[:MAGNITUDE][,key=value...], e.g. S4.2@235:5e4")
    head, *opts = text.split(",")
    fid, _, rest = head.partition("@")
    onset_txt, _, mag_txt = rest.partition(":")
    fault_class(fid.strip())
    kwargs: dict = {}
    try:
        onset = float(onset_txt)
    except ValueError:
        raise ValueError(f"fault spec {text!r}: onset {onset_txt!r} is not a number") from None
    if mag_txt:
        try:
            kwargs["magnitude"] = float(mag_txt)
        except ValueError:
            raise ValueError(f"fault spec {text!r}: magnitude {mag_txt!r} is not a number") from None
    for opt in opts:
        key, eq, val = opt.partition("=")
        key = key.strip()
        if not eq or key not in _SPEC_KEYS:
            raise ValueError(f"fault spec {text!r}: option {opt!r} must be key=value with key in {sorted(_SPEC_KEYS)}")
        try:
            v = _SPEC_KEYS[key](val)
        except ValueError:
            raise ValueError(f"fault spec {text!r}: option {key} value {val!r} is not valid") from None
        kwargs[{"end": "end_s", "period": "period_s"}.get(key, key)] = v
    return FaultSpec(fault_id=fid.strip(), onset_s=onset, **kwargs)


def random_fault_schedule(
    rng: np.random.Generator,
    duration_s: float,
    max_faults: int = 2,
    fault_ids: tuple[str, ...] = FAULT_IDS,
    onset_range: tuple[float, float] | None = None,
) -> list[FaultSpec]:
    """Draw 0..max_faults distinct faults with uniform onsets and default magnitudes (seeded)."""
    k = int(rng.integers(0, max_faults + 1))
    ids = rng.choice(len(fault_ids), size=k, replace=False)
    lo, hi = onset_range or (0.1 * duration_s, 0.7 * duration_s)
    return [FaultSpec(fault_ids[i], float(rng.uniform(lo, hi))) for i in sorted(ids)]


# ----------------------------------------------------------------------------- compiled schedules
def window_time(t: float, onset, end, period, duty):
    """Time since the current window opened (NaN when inactive); arrays of equal shape."""
    s = t - onset
    active = (s >= 0.0) & (t < end)
    with np.errstate(invalid="ignore"):
        s_mod = np.where(np.isfinite(period), np.mod(s, np.where(np.isfinite(period), period, 1.0)), s)
        on = active & (~np.isfinite(period) | (s_mod < duty * period))
    return np.where(on, s_mod, np.nan)


def _beta(s, kappa):
    """Evolution β(s) = 1 - exp(-κ s) (eq. 2.4), 1 for abrupt faults; 0 where s is NaN."""
    with np.errstate(invalid="ignore", over="ignore"):
        b = np.where(np.isinf(kappa), 1.0, -np.expm1(-np.where(np.isinf(kappa), 0.0, kappa) * s))
    return np.where(np.isnan(s), 0.0, b)


@dataclass
class CompiledSchedule:
    """Fault schedules of N engines as flat arrays, evaluated in one vectorised call per sample.

    ``process[k]`` holds, for process fault k, index arrays over engines with that fault; sensor
    faults are flat lists of (engine, sensor) pairs.
    """

    n_engines: int
    process: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)
    s_engine: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    s_sensor: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    s_kind: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    s_params: dict[str, np.ndarray] = field(default_factory=dict)
    breakpoints: np.ndarray = field(default_factory=lambda: np.zeros(0))

    @classmethod
    def compile(cls, schedules: list[list[FaultSpec]]) -> "CompiledSchedule":
        n = len(schedules)
        out = cls(n_engines=n)
        proc: dict[str, list] = {k: [] for k in PROCESS_FAULT_IDS}
        sens: list = []
        breaks = []
        for i, sched in enumerate(schedules):
            seen = set()
            for f in sched:
                if not isinstance(f, FaultSpec):
                    raise ValueError(f"fault schedule of engine {i} must hold FaultSpec items, got {f!r}")
                if f.fault_id in seen:
                    raise ValueError(
                        f"fault {f.fault_id!r} is scheduled twice for engine {i}; one window set per fault"
                    )
                seen.add(f.fault_id)
                row = (
                    i,
                    f.onset_s,
                    f.resolved_kappa,
                    f.resolved_magnitude,
                    math.inf if f.end_s is None else f.end_s,
                    math.inf if f.period_s is None else f.period_s,
                    1.0 if f.duty is None else f.duty,
                )
                breaks.append(f.onset_s)
                if f.end_s is not None:
                    breaks.append(f.end_s)
                if f.fault_id in PROCESS_FAULT_IDS:
                    proc[f.fault_id].append(row)
                else:
                    sens.append(row + (sensor_index(f.fault_id), SENSOR_FAULT_KINDS.index(f.resolved_kind)))
        names = ("engine", "onset", "kappa", "mag", "end", "period", "duty")
        for k, rows in proc.items():
            if rows:
                arr = list(zip(*rows))
                out.process[k] = {
                    nm: np.asarray(col, dtype=np.int64 if nm == "engine" else float) for nm, col in zip(names, arr)
                }
        if sens:
            cols = list(zip(*sens))
            out.s_engine = np.asarray(cols[0], dtype=np.int64)
            out.s_params = {nm: np.asarray(c, dtype=float) for nm, c in zip(names[1:], cols[1:7])}
            out.s_sensor = np.asarray(cols[7], dtype=np.int64)
            out.s_kind = np.asarray(cols[8], dtype=np.int64)
        out.breakpoints = np.unique(np.asarray(breaks, dtype=float))
        return out

    def fault_state(self, fault_id: str, t, per_engine: bool = False):
        """(s, contribution) of a scheduled process fault at time(s) t on the engines that have it (last
        axis): the time since its window opened (NaN: inactive) and its own contribution to its term
        (the law of its :class:`~marine_fdi_env.engine.fault_registry.FaultType`; 1 or 0 when inactive).
        t as in :meth:`process_values`."""
        d = self.process[fault_id]
        t_arr = np.asarray(t, dtype=float)
        tt = t_arr[..., d["engine"]] if per_engine else t_arr[..., None]
        s = window_time(tt, d["onset"], d["end"], d["period"], d["duty"])
        b = _beta(s, d["kappa"])
        law = fault_type(fault_id).law
        if law == "fraction":
            return s, 1.0 - b * d["mag"]
        if law == "ramp":
            return s, b * d["mag"] * np.where(np.isnan(s), 0.0, s)
        return s, b * d["mag"]

    def fault_values(self, fault_id: str, t, per_engine: bool = False):
        """(s, value) of a scheduled process fault: the time since its window opened (NaN: inactive) and
        its fault function's value (β φ, β R s; what the ground truth records) on its engines."""
        s, own = self.fault_state(fault_id, t, per_engine)
        return s, (1.0 - own) if fault_type(fault_id).law == "fraction" else own

    def process_values(self, t, per_engine: bool = False):
        """Values of the model's fault terms (``fault_registry.TERMS``) at time t (scalar -> arrays (N,);
        array (T,) -> (T, N)): each scheduled fault's contribution (:meth:`fault_state`) combined into its
        term (added, or multiplied for a factor).

        With ``per_engine``, t is (T, N): each engine's own clock (engines restarted at different
        times).  A term no scheduled fault drives keeps its healthy value (a scalar: 1 for f_u, 0 otherwise).
        """
        from .model import ProcessFaultValues

        t_arr = np.asarray(t, dtype=float)
        shape = t_arr.shape if per_engine else t_arr.shape + (self.n_engines,)
        vals: dict[str, np.ndarray] = {}
        for k, d in self.process.items():
            term = TERMS[TERM_INDEX[fault_type(k).term]]
            _, own = self.fault_state(k, t_arr, per_engine)
            if term.name not in vals:
                vals[term.name] = np.full(shape, term.healthy)
            v = vals[term.name]
            if term.combine == "multiply":
                v[..., d["engine"]] *= own
            else:
                v[..., d["engine"]] += own
        return ProcessFaultValues(**vals)

    def sensor_fault_state(self, t, entries=None):
        """(active window time s or NaN, β) for every scheduled sensor fault (or the ``entries``
        given, indices into ``s_engine``) at time(s) t (one column per entry)."""
        p = self.s_params if entries is None else {k: v[entries] for k, v in self.s_params.items()}
        s = window_time(t, p["onset"], p["end"], p["period"], p["duty"])
        return s, _beta(s, p["kappa"])
