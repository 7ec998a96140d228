"""Batched engine simulator: N engines with their own faults, noise and profiles, one call per sample.

>>> sim = Simulator("thesis-12v28", n_engines=4, seeds=[0, 1, 2, 3],
...                 faults=[[FaultSpec("S4.2", 235.0)], [], [], []], profiles="constant")
>>> result = sim.run(300.0)            # doctest: +SKIP
>>> result.measurements.shape          # (samples, engines, 19 sensors)  # doctest: +SKIP

Reproducibility: engine i draws its noise from ``SeedSequence(seeds[i])`` alone, in blocks of
fixed size, and every operation on the state is elementwise, so an engine gives the same numbers
bit for bit whether it runs alone or in any batch.

Accuracy: ETD2RK at the sample time (:mod:`marine_fdi_env.integrators`).  While the fuel pump is
far from its target (|x1 - x1_target| > 1e-3 x1_nom, i.e. for about 8 samples after a step of
the fuel setting) the affected engines take ``substeps`` smaller steps, because the receiver
pressure then follows a forcing that changes on the 15 ms time scale of the pump.

Engine failure: when an engine leaves its physical range (stall, air excess ratio below 1,
turbine pressure ratio at or below 1, non-finite values) its state freezes at the last valid
sample and an :class:`EngineFailure` event (time, reason) is recorded; nothing turns NaN.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .faults import PROCESS_FAULT_IDS, FAULT_IDS, CompiledSchedule, FaultSpec, parse_fault_spec
from .integrators import FAILURE_REASONS, _failure_code, etd2rk_batch
from .model import ALG_FIELDS, HEALTHY, HEALTHY_PF, N_ALG, PF_FIELDS, Algebraic, EngineModel, ProcessFaultValues
from .params import EngineParams, load_params
from .profiles import Profile, make_profile
from .sensors import MEASURED_VARIABLES, NOISE_BOUNDS, N_SENSORS, SENSOR_IDS, VARIABLE_OF_SENSOR
from .steady_state import steady_state

__all__ = ["Simulator", "SimulationResult", "EngineFailure", "TRUTH_VARIABLES"]

# True variables recorded with every sample (units: see docs/model.md).
TRUTH_VARIABLES: tuple[str, ...] = (
    "u", "x1", "x3", "x4", "n", "torque", "power", "p6", "T6", "p_max", "T_in", "T_out", "T1", "T_co", "lam",
)
_NOISE_BLOCK = 128
_CHUNK = 512  # samples of fuel setting and fault values precomputed at a time
DEFAULT_LIMITER_LAMBDA = 1.3


@dataclass(frozen=True)
class EngineFailure:
    engine: int
    time_s: float
    reason: str

    def to_dict(self) -> dict:
        return {"engine": self.engine, "time_s": self.time_s, "reason": self.reason}


@dataclass
class SimulationResult:
    """Everything a run produced; arrays are indexed (sample, engine, ...)."""

    params_name: str
    dt: float
    t: np.ndarray  # (T,)
    measurements: np.ndarray  # (T, N, 19)
    truth: np.ndarray  # (T, N, len(TRUTH_VARIABLES))
    fault_active: np.ndarray  # (T, N, 26) bool
    fault_value: np.ndarray  # (T, N, 26) fault function values (see faults.py)
    seeds: list[int]
    schedules: list[list[FaultSpec]]
    profiles: list[Profile]
    failures: list[EngineFailure]
    noise_scale: float

    def truth_of(self, name: str) -> np.ndarray:
        return self.truth[..., TRUTH_VARIABLES.index(name)]


def _as_schedules(faults, n: int) -> list[list[FaultSpec]]:
    if faults is None:
        return [[] for _ in range(n)]
    faults = list(faults)
    if all(isinstance(f, (FaultSpec, str)) for f in faults):  # one schedule for every engine
        sched = [parse_fault_spec(f) if isinstance(f, str) else f for f in faults]
        return [list(sched) for _ in range(n)]
    if len(faults) != n:
        raise ValueError(f"faults must be one schedule or one schedule per engine ({n}), got {len(faults)}")
    return [[parse_fault_spec(f) if isinstance(f, str) else f for f in s] for s in faults]


class Simulator:
    """N engines of one parameter set advanced together at the sensor sample time.

    Parameters
    ----------
    params : parameter-set name or :class:`EngineParams`.
    n_engines : number of engines N.
    seeds : one int (engine i uses seed + i) or N ints.  Noise of engine i depends only on its seed.
    faults : a fault schedule for all engines (list of :class:`FaultSpec` or spec strings) or one
        list per engine.
    profiles : a profile (name, spec string, constant or :class:`Profile`) or one per engine.
    dt : sample time [s] (default 0.01 s).
    noise_scale : multiplier of the table 6.3 noise bounds (0 = noise-free).
    substeps : substeps while the fuel pump is in a fast transient.
    fuel_limiter_lambda : the governor's charge-air (smoke) limiter keeps the air excess ratio
        at or above this value by capping the applied fuel setting (0 disables it; see below).

    The thesis's turbocharger is slow (τ_TC = 51 s), so a fast load increase would drive the air
    excess ratio below 1, where the Seiliger heat release (all fuel burns) is no longer valid.
    Marine governors prevent that with a charge-air-pressure-dependent fuel limiter; ours caps
    the fuel setting at the value giving λ = ``fuel_limiter_lambda`` (default 1.3, below every
    steady state of the three parameter sets, so it never acts in steady running; it does act
    during load increases, which with this slow turbocharger means much of a manoeuvring profile:
    38 % of its samples).  The applied setting is recorded as the truth variable ``u`` and is the
    control input a diagnoser sees.
    """

    def __init__(
        self,
        params: "str | EngineParams" = "thesis-12v28",
        n_engines: int = 1,
        seeds: "int | list[int]" = 0,
        faults=None,
        profiles: "str | Profile | float | list" = "constant",
        dt: float = 0.01,
        noise_scale: float = 1.0,
        substeps: int = 4,
        fuel_limiter_lambda: float = DEFAULT_LIMITER_LAMBDA,
    ) -> None:
        self.params = load_params(params) if isinstance(params, str) else params
        if not isinstance(n_engines, (int, np.integer)) or n_engines < 1:
            raise ValueError(f"n_engines must be a positive integer, got {n_engines!r}")
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and dt > 0):
            raise ValueError(f"dt must be a positive finite number of seconds, got {dt!r}")
        if not (isinstance(noise_scale, (int, float)) and math.isfinite(noise_scale) and noise_scale >= 0):
            raise ValueError(f"noise_scale must be a finite number >= 0, got {noise_scale!r}")
        self.n = int(n_engines)
        self.dt = float(dt)
        self.noise_scale = float(noise_scale)
        self.substeps = int(substeps)
        if not (isinstance(fuel_limiter_lambda, (int, float)) and math.isfinite(fuel_limiter_lambda)
                and fuel_limiter_lambda >= 0):
            raise ValueError(f"fuel_limiter_lambda must be a finite number >= 0, got {fuel_limiter_lambda!r}")
        self.fuel_limiter_lambda = float(fuel_limiter_lambda)
        if isinstance(seeds, (int, np.integer)):
            self.seeds = [int(seeds) + i for i in range(self.n)]
        else:
            self.seeds = [int(s) for s in seeds]
            if len(self.seeds) != self.n:
                raise ValueError(f"seeds must be one int or {self.n} ints, got {len(self.seeds)}")
        self.schedules = _as_schedules(faults, self.n)
        if isinstance(profiles, (list, tuple)):
            if len(profiles) != self.n:
                raise ValueError(f"profiles must be one profile or {self.n}, got {len(profiles)}")
            self.profiles = [make_profile(p).snapped(self.dt) for p in profiles]
        else:
            prof = make_profile(profiles).snapped(self.dt)
            self.profiles = [prof] * self.n
        self.model = EngineModel(self.params)
        self.schedule = CompiledSchedule.compile(self.schedules)
        self.reset()

    # ----------------------------------------------------------------------------- set-up
    def reset(self) -> None:
        """Put every engine at the steady state of its fuel setting at t = 0 and rewind the noise."""
        n = self.n
        self.k = 0
        self.t = 0.0
        self._rngs = [np.random.Generator(np.random.PCG64(np.random.SeedSequence(s).spawn(2)[0])) for s in self.seeds]
        self._prec_rngs = None
        self._noise_raw = np.empty((n, _NOISE_BLOCK * N_SENSORS))
        self._noise_bounds = 2.0 * NOISE_BOUNDS * self.noise_scale
        self._noise_pos = _NOISE_BLOCK
        self._stuck = np.full(len(self.schedule.s_engine), np.nan)
        self._last_y = None
        self._fill_chunk(0)
        u0 = self._u_right[0].copy()
        ss = steady_state(self.model, u0, self._pf_values(0))
        self.X = np.ascontiguousarray(np.stack([ss.x1, ss.x3, ss.x4], axis=1))
        self.ALG = np.ascontiguousarray(np.stack([getattr(ss.alg, f) for f in ALG_FIELDS], axis=1))
        self._X_new = np.empty_like(self.X)
        self._ALG_new = np.empty_like(self.ALG)
        self._codes = np.zeros(n, dtype=np.int64)
        self._scr_pf = np.empty((n, 3, len(PF_FIELDS)))
        self._scr_alg = np.empty((n, 3, N_ALG))
        self.u = self._applied_u(u0)
        self.failed = np.zeros(n, dtype=bool)
        self.failures: list[EngineFailure] = []
        codes = np.zeros(n, dtype=np.int64)
        for i in range(n):
            codes[i] = _failure_code(self.model.constants, self.X[i, 0], self.X[i, 1], self.X[i, 2], self.ALG[i])
        self._record_failures(codes, 0.0)
        self.y = self._measure(0.0)

    # state views
    @property
    def x1(self) -> np.ndarray:
        return self.X[:, 0]

    @property
    def x3(self) -> np.ndarray:
        return self.X[:, 1]

    @property
    def x4(self) -> np.ndarray:
        return self.X[:, 2]

    @property
    def alg(self) -> Algebraic:
        return Algebraic.from_array(self.ALG)

    def _pf_values(self, j: int) -> ProcessFaultValues:
        if self._pf is None:
            return HEALTHY
        return ProcessFaultValues(*(self._pf[j, :, m] for m in range(len(PF_FIELDS))))

    def _fill_chunk(self, k0: int) -> None:
        """Precompute u (right and left limits) and process-fault values on samples k0..k0+_CHUNK."""
        t = self.dt * np.arange(k0, k0 + _CHUNK + 1)
        self._chunk_k0 = k0
        self._u_right = np.empty((len(t), self.n))
        self._u_left = np.empty((len(t), self.n))
        groups: dict[int, list[int]] = {}
        for i, pr in enumerate(self.profiles):
            groups.setdefault(id(pr), []).append(i)
        for idx in groups.values():
            pr = self.profiles[idx[0]]
            self._u_right[:, idx] = pr(t)[:, None]
            self._u_left[:, idx] = pr.left_limit(t)[:, None]
        if self.schedule.process:
            pf = self.schedule.process_values(t)
            self._pf = np.empty((len(t), self.n, len(PF_FIELDS)))
            for m, name in enumerate(PF_FIELDS):
                self._pf[:, :, m] = getattr(pf, name)
        else:
            self._pf = None
            # a writable copy: compiled code is specialised on array flags, and one specialisation
            # for every batch size keeps batched runs bit-identical to single runs
            self._pf_healthy = np.tile(HEALTHY_PF, (self.n, 1))
        if len(self.schedule.s_engine):
            self._sf_s, self._sf_beta = self.schedule.sensor_fault_state(t[:, None])

    def _grid_row(self, k: int) -> int:
        j = k - self._chunk_k0
        if j < 0 or j > _CHUNK:
            self._fill_chunk(k)
            j = 0
        return j

    # ----------------------------------------------------------------------------- stepping
    def step(self) -> np.ndarray:
        """Advance all engines by one sample; returns the measurements (N, 19) at the new time."""
        j0 = self._grid_row(self.k)
        if j0 == _CHUNK:  # the step needs rows j0 and j0 + 1 of one chunk
            self._fill_chunk(self.k)
            j0 = 0
        j1 = j0 + 1
        if self._pf is None:
            pf0 = pf1 = self._pf_healthy
        else:
            pf0, pf1 = self._pf[j0], self._pf[j1]
        etd2rk_batch(self.model.constants, self.dt, self.substeps, self.X, self._u_right[j0], self._u_left[j1],
                     pf0, pf1, self.ALG, ~self.failed, self._X_new, self._ALG_new, self._codes,
                     self._scr_pf, self._scr_alg, self.fuel_limiter_lambda)
        self.X, self._X_new = self._X_new, self.X
        self.ALG, self._ALG_new = self._ALG_new, self.ALG
        self.u = self._applied_u(self._u_right[j1])
        self.k += 1
        self.t = self.k * self.dt
        if self._codes.any():
            self._record_failures(self._codes, self.t)
        self.y = self._measure(self.t)
        return self.y

    def _applied_u(self, u_cmd: np.ndarray) -> np.ndarray:
        """Fuel setting after the charge-air limiter (see class docstring)."""
        if self.fuel_limiter_lambda <= 0:
            return u_cmd.copy()
        p = self.params
        u_max = self.X[:, 2] * p.V1_m3 / (p.R_a_J_per_kgK * self.ALG[:, 9] * self.fuel_limiter_lambda * p.sigma_f
                                          * p.x1_nom_kg)
        return np.minimum(u_cmd, u_max)

    # ------------------------------------------------------------------------- failures
    def _record_failures(self, codes: np.ndarray, t: float) -> None:
        for i in np.flatnonzero(codes):
            if not self.failed[i]:
                self.failed[i] = True
                self.failures.append(EngineFailure(int(i), float(t), FAILURE_REASONS[int(codes[i])]))

    # ------------------------------------------------------------------------- sensors
    def _next_noise(self) -> np.ndarray:
        if self._noise_pos >= _NOISE_BLOCK:
            raw = self._noise_raw
            for i, rng in enumerate(self._rngs):
                rng.random(out=raw[i])  # U[0, 1), one contiguous block per engine
            raw -= 0.5
            self._noise_pos = 0
        j = self._noise_pos * N_SENSORS
        self._noise_pos += 1
        # uniform noise d = (2 U - 1) * bound
        return self._noise_raw[:, j:j + N_SENSORS] * self._noise_bounds

    def true_variables(self) -> np.ndarray:
        """Noise-free measured variables, shape (N, 10) in the order of MEASURED_VARIABLES."""
        return np.concatenate([self.X, self.ALG], axis=1)[:, _MEASURED_COLUMNS]

    def _measure(self, t: float) -> np.ndarray:
        true = np.concatenate([self.X, self.ALG], axis=1)[:, _SENSOR_COLUMNS]
        y = true + self._next_noise()
        self._fault_dev = None
        if len(self.schedule.s_engine):
            y = self._apply_sensor_faults(t, y, true)
        self._last_y = y
        return y

    def _precision_noise(self, engines: np.ndarray) -> np.ndarray:
        if self._prec_rngs is None:
            self._prec_rngs = {}
        out = np.empty(len(engines))
        for j, e in enumerate(engines):
            e = int(e)
            if e not in self._prec_rngs:
                self._prec_rngs[e] = np.random.Generator(
                    np.random.PCG64(np.random.SeedSequence(self.seeds[e]).spawn(2)[1]))
            out[j] = self._prec_rngs[e].uniform(-1.0, 1.0)
        return out

    def _apply_sensor_faults(self, t: float, y: np.ndarray, true: np.ndarray) -> np.ndarray:
        sch = self.schedule
        j = self._grid_row(self.k)
        s, beta = self._sf_s[j], self._sf_beta[j]
        active = ~np.isnan(s)
        e, j, kind, mag = sch.s_engine, sch.s_sensor, sch.s_kind, sch.s_params["mag"]
        yv = y[e, j]
        dev = np.zeros(len(e))
        # offset
        k0 = active & (kind == 0)
        dev[k0] = beta[k0] * mag[k0]
        k1 = active & (kind == 1)
        dev[k1] = beta[k1] * mag[k1] * s[k1]
        k3 = active & (kind == 3)
        dev[k3] = beta[k3] * mag[k3] * true[e[k3], j[k3]]
        k4 = active & (kind == 4)
        if k4.any():
            dev[k4] = beta[k4] * mag[k4] * self._precision_noise(e[k4])
        new = yv + dev
        k2 = kind == 2
        if k2.any():
            prev = self._last_y[e, j] if self._last_y is not None else yv
            opening = k2 & active & np.isnan(self._stuck)
            self._stuck[opening] = np.where(np.isnan(mag[opening]), prev[opening], mag[opening])
            self._stuck[k2 & ~active] = np.nan
            hold = k2 & active
            new[hold] = self._stuck[hold]
        y = y.copy()
        y[e, j] = new
        self._fault_dev = (active, new - yv)
        return y

    # ------------------------------------------------------------------------- ground truth
    def fault_truth(self, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(active (N, 26) bool, value (N, 26)) of every fault id at the current sample."""
        act = np.zeros((self.n, len(FAULT_IDS)), dtype=bool)
        val = np.zeros((self.n, len(FAULT_IDS)))
        sch = self.schedule
        if len(sch.s_engine):
            a, dev = self._fault_dev if self._fault_dev is not None else (np.zeros(len(sch.s_engine), bool), 0.0)
            act[sch.s_engine, sch.s_sensor] = a
            val[sch.s_engine, sch.s_sensor] = np.where(a, dev, 0.0)
        if sch.process:
            pf = self._pf_values(self._grid_row(self.k))
            for k, d in sch.process.items():
                col = FAULT_IDS.index(k)
                s = _active_time(t, d)
                act[d["engine"], col] = ~np.isnan(s)
                v = getattr(pf, _PF_FIELD[k])
                v = v[d["engine"]]
                val[d["engine"], col] = (1.0 - v) if k == "valve_seizing" else v
        return act, val

    def truth_vector(self) -> np.ndarray:
        a = self.alg
        return np.stack([self.u, self.x1, self.x3, self.x4, a.n, a.torque, a.power(), a.p6, a.T6, a.p_max,
                         a.T_in, a.T_out, a.T1, a.T_co, a.lam], axis=1)

    # ------------------------------------------------------------------------- whole runs
    def run(self, duration_s: float, progress: bool = False, record: bool = True) -> SimulationResult:
        """Simulate ``duration_s`` seconds from the current state and return the recorded samples."""
        if not (isinstance(duration_s, (int, float)) and math.isfinite(duration_s) and duration_s > 0):
            raise ValueError(f"duration must be a positive finite number of seconds, got {duration_s!r}")
        steps = int(round(duration_s / self.dt))
        T = steps + 1
        nF = len(FAULT_IDS)
        meas = np.empty((T, self.n, N_SENSORS)) if record else np.empty((1, self.n, N_SENSORS))
        truth = np.empty((T, self.n, len(TRUTH_VARIABLES))) if record else np.empty((1, self.n, len(TRUTH_VARIABLES)))
        f_act = np.zeros((T, self.n, nF), dtype=bool) if record else np.zeros((1, self.n, nF), bool)
        f_val = np.zeros((T, self.n, nF)) if record else np.zeros((1, self.n, nF))
        times = self.t + self.dt * np.arange(T)

        def rec(i):
            j = i if record else 0
            meas[j] = self.y
            truth[j] = self.truth_vector()
            f_act[j], f_val[j] = self.fault_truth(self.t)

        rec(0)
        iterator = range(1, T)
        if progress:
            from tqdm import tqdm

            iterator = tqdm(iterator, desc="simulate", unit="sample", mininterval=0.5)
        for i in iterator:
            self.step()
            if record:
                rec(i)
        if not record:
            rec(0)
        return SimulationResult(
            params_name=self.params.name,
            dt=self.dt,
            t=times if record else times[-1:],
            measurements=meas,
            truth=truth,
            fault_active=f_act,
            fault_value=f_val,
            seeds=list(self.seeds),
            schedules=[list(s) for s in self.schedules],
            profiles=list(self.profiles),
            failures=list(self.failures),
            noise_scale=self.noise_scale,
        )


_PF_FIELD = {
    "valve_seizing": "f_u",
    "bore_damage": "dV1_m3",
    "turbine_seal_leak": "phi_tur",
    "turbine_lubrication_loss": "dT_sl_K",
    "compressor_seal_leak": "phi_int",
    "compressor_lubrication_loss": "dT_inl_K",
    "intercooler_blockage": "dT_c_K",
}


# columns of [X | ALG] holding the measured variables, in MEASURED_VARIABLES / sensor order
_STATE_COLS = {"x1": 0, "x3": 1, "x4": 2}
_MEASURED_COLUMNS = np.array([_STATE_COLS[v] if v in _STATE_COLS else 3 + ALG_FIELDS.index(v)
                              for v in MEASURED_VARIABLES])
_SENSOR_COLUMNS = _MEASURED_COLUMNS[VARIABLE_OF_SENSOR]


def _active_time(t, d):
    from .faults import _window_time

    return _window_time(t, d["onset"], d["end"], d["period"], d["duty"])
