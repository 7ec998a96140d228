"""Batched engine simulator: N engines with their own faults, noise and profiles, one call per sample.

>>> sim = Simulator("thesis-12v28", n_engines=4, seeds=[0, 1, 2, 3],
...                 faults=[[FaultSpec("S4.2", 235.0)], [], [], []], profiles="constant")
>>> result = sim.run(300.0)            # doctest: +SKIP
>>> result.measurements.shape          # (samples, engines, 19 sensors)  # doctest: +SKIP

Reproducibility: engine i draws its noise from ``SeedSequence(seeds[i])`` alone, in blocks of
fixed size, and every operation on the state is elementwise, so an engine gives the same numbers
bit for bit whether it runs alone or in any batch.

Accuracy: ETD2RK at the sample time (:mod:`marine_fdi_env.engine.integrators`).  While the fuel pump is
far from its target (|x1 - x1_target| > 1e-3 x1_nom, i.e. for about 8 samples after a step of
the fuel setting) the affected engines take ``substeps`` smaller steps, because the receiver
pressure then follows a forcing that changes on the 15 ms time scale of the pump.

Engine failure: when an engine leaves its physical range (stall, air excess ratio below 1,
turbine pressure ratio at or below 1, non-finite values) its state freezes at the last valid
sample and an :class:`EngineFailure` event (time, reason) is recorded; nothing turns NaN.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .faults import FAULT_IDS, CompiledSchedule, FaultSpec, parse_fault_spec
from .integrators import FAILURE_REASONS, advance_batch, failure_code, limited_fuel_setting
from .model import ALG_FIELDS, HEALTHY, HEALTHY_PF, N_ALG, PF_FIELDS, Algebraic, EngineModel, ProcessFaultValues
from .params import EngineParams, engine_batch
from .profiles import Profile, ProfileTable, make_profile
from .sensors import MEASURED_VARIABLES, N_SENSORS, NOISE_BOUNDS, VARIABLE_OF_SENSOR
from .steady_state import steady_state

__all__ = ["Simulator", "SimulationResult", "Block", "EngineFailure", "TRUTH_VARIABLES"]

# True variables recorded with every sample (units: see docs/model.md).
TRUTH_VARIABLES: tuple[str, ...] = (
    "u",
    "x1",
    "x3",
    "x4",
    "n",
    "torque",
    "power",
    "p6",
    "T6",
    "p_max",
    "T_in",
    "T_out",
    "T1",
    "T_co",
    "lam",
)
# bytes a recorded run holds per engine and sample: measurements, truth and fault values (float64) and the
# fault flags (bool) of SimulationResult
RESULT_BYTES_PER_ENGINE_SAMPLE = 8 * (N_SENSORS + len(TRUTH_VARIABLES) + len(FAULT_IDS)) + len(FAULT_IDS)
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
        self.params, self.n, self.dt = engine_batch(params, n_engines, dt)
        if not (isinstance(noise_scale, (int, float)) and math.isfinite(noise_scale) and noise_scale >= 0):
            raise ValueError(f"noise_scale must be a finite number >= 0, got {noise_scale!r}")
        self.noise_scale = float(noise_scale)
        self.substeps = int(substeps)
        if not (
            isinstance(fuel_limiter_lambda, (int, float))
            and math.isfinite(fuel_limiter_lambda)
            and fuel_limiter_lambda >= 0
        ):
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
        self._profile_table = ProfileTable(self.profiles)
        self.model = EngineModel(self.params)
        self.schedule = CompiledSchedule.compile(self.schedules)
        self.reset()

    # ----------------------------------------------------------------------------- set-up
    def reset(self) -> None:
        """Put every engine at the steady state of its fuel setting at t = 0 and rewind the noise."""
        n = self.n
        self.k = 0
        self.t = 0.0
        self._k_start = np.zeros(n, dtype=np.int64)  # sample at which each engine's clock is 0
        self._rngs = [np.random.Generator(np.random.PCG64(np.random.SeedSequence(s).spawn(2)[0])) for s in self.seeds]
        self._prec_rngs = None
        self._noise_raw = np.empty((n, _NOISE_BLOCK * N_SENSORS))
        self._noise_bounds = 2.0 * NOISE_BOUNDS * self.noise_scale
        self._noise_pos = _NOISE_BLOCK
        self._has_gain = bool(np.any(self.schedule.s_kind == 3)) if len(self.schedule.s_engine) else False
        self._no_state = np.empty((n, 1, 3 + N_ALG))
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
        self._scr_pf = np.empty((n, 4, len(PF_FIELDS)))
        self._scr_alg = np.empty((n, 3, N_ALG))
        self.u = self._applied_u(u0)
        self.failed = np.zeros(n, dtype=bool)
        self.failures: list[EngineFailure] = []
        codes = np.zeros(n, dtype=np.int64)
        for i in range(n):
            codes[i] = failure_code(self.model.constants, self.X[i, 0], self.X[i, 1], self.X[i, 2], self.ALG[i])
        self._record_failures(codes, 0.0)
        self.y = self._measure_initial()

    def restart_engines(self, engines, seeds, faults, profiles) -> None:
        """Start new runs on some engines at the current sample, leaving the others untouched.

        ``engines``: indices; ``seeds``, ``faults`` (one schedule each), ``profiles``: one per
        engine.  A restarted engine's clock restarts at 0 and it produces the same numbers, bit
        for bit, as engine 0 of a fresh ``Simulator(seeds=[seed], faults=[schedule],
        profiles=[profile])`` (what a vector environment's per-engine autoreset needs).
        """
        idx = [int(i) for i in np.atleast_1d(engines)]
        if len(set(idx)) != len(idx) or any(not 0 <= i < self.n for i in idx):
            raise ValueError(f"engines must be distinct indices in [0, {self.n}), got {engines!r}")
        if not (len(seeds) == len(faults) == len(profiles) == len(idx)):
            raise ValueError("restart_engines needs one seed, one fault schedule and one profile per engine")
        new_sched = _as_schedules(list(faults), len(idx)) if idx else []
        old = {(int(e), int(j)): v for e, j, v in zip(self.schedule.s_engine, self.schedule.s_sensor, self._stuck)}
        for i, seed, sched, prof in zip(idx, seeds, new_sched, profiles):
            self.seeds[i] = int(seed)
            self.schedules[i] = sched
            self.profiles[i] = make_profile(prof).snapped(self.dt)
            self._profile_table.set(i, self.profiles[i])
            self._rngs[i] = np.random.Generator(np.random.PCG64(np.random.SeedSequence(int(seed)).spawn(2)[0]))
            if self._prec_rngs is not None:
                self._prec_rngs.pop(i, None)
        self.schedule = CompiledSchedule.compile(self.schedules)
        restarted = np.zeros(self.n, dtype=bool)
        restarted[idx] = True
        sch = self.schedule
        self._stuck = np.array(
            [np.nan if restarted[e] else old.get((int(e), int(j)), np.nan) for e, j in zip(sch.s_engine, sch.s_sensor)],
            dtype=float,
        )
        self._has_gain = bool(np.any(sch.s_kind == 3)) if len(sch.s_engine) else False
        self._fault_dev = None
        self._k_start[idx] = self.k
        j = self._refill_engines(np.asarray(idx, dtype=np.int64), old)
        # steady state of the restarted engines at their t = 0 (row j of the chunk)
        u0 = self._u_right[j, idx].copy()
        pf = self._pf_values(j)
        ss = steady_state(
            self.model,
            u0,
            ProcessFaultValues(
                *(np.asarray(getattr(pf, f))[idx] if np.ndim(getattr(pf, f)) else getattr(pf, f) for f in PF_FIELDS)
            ),
        )
        self.X[idx] = np.stack([ss.x1, ss.x3, ss.x4], axis=1)
        self.ALG[idx] = np.stack([getattr(ss.alg, f) for f in ALG_FIELDS], axis=1)
        self.u = self.u.copy()
        self.u[idx] = self._applied_u(self._u_right[j], idx)
        self.failed[idx] = False
        codes = np.zeros(self.n, dtype=np.int64)
        for i in idx:
            codes[i] = failure_code(self.model.constants, self.X[i, 0], self.X[i, 1], self.X[i, 2], self.ALG[i])
        self._record_failures(codes, 0.0)
        # first reading: the first 19 numbers of each new noise stream, the rest refills the buffer
        state = np.concatenate([self.X, self.ALG], axis=1)
        y = self._last_y.copy()[:, None, :]
        pos = self._noise_pos * N_SENSORS
        for i in idx:
            first = self._rngs[i].random(N_SENSORS) - 0.5
            y[i, 0] = state[i, _SENSOR_COLUMNS] + first * self._noise_bounds
            rest = self._noise_raw[i, pos:]
            if rest.size:
                self._rngs[i].random(out=rest)
                rest -= 0.5
        if len(sch.s_engine):
            sel = np.flatnonzero(restarted[sch.s_engine])
            if len(sel):
                self._apply_sensor_faults(slice(0, 1), y, state[:, None, :], sel=sel, initial=True)
        self._last_y = y[:, 0].copy()
        self.y = self._last_y

    @property
    def local_time(self) -> np.ndarray:
        """Each engine's own clock [s] (differs from ``t`` for engines restarted mid-run)."""
        return (self.k - self._k_start) * self.dt

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
        """Precompute u (right and left limits) and process-fault values on samples k0..k0+_CHUNK.

        Times are each engine's own clock, (k - k0_engine) dt, so an engine restarted mid-run
        sees exactly the numbers of a fresh simulator.
        """
        self._chunk_k0 = k0
        shape = (_CHUNK + 1, self.n)
        self._t_local, self._u_right, self._u_left = np.empty(shape), np.empty(shape), np.empty(shape)
        self._pf = None
        self._fill_columns(np.arange(self.n), {})

    def _refill_engines(self, idx: np.ndarray, old_sensor_keys: dict) -> int:
        """After ``idx`` restarted at sample k: recompute their columns of the current chunk (their
        clocks changed) and carry the other engines' columns over, instead of refilling the whole
        chunk (what one autoreset of a large vector env costs); returns the chunk row of sample k."""
        j = self.k - self._chunk_k0
        if not 0 <= j < _CHUNK:
            self._fill_chunk(self.k)
            return 0
        self._fill_columns(idx, old_sensor_keys)
        return j

    def _fill_columns(self, idx: np.ndarray, old_sensor_keys: dict) -> None:
        """The current chunk's columns of engines ``idx``; the other engines' columns are kept (the
        values are elementwise functions of each engine's own clock, so a column computed alone
        equals the same column of a whole chunk).  ``old_sensor_keys``: (engine, sensor) of the
        previous schedule's sensor faults, in their column order, for carrying those over."""
        k0 = self._chunk_k0
        whole = len(idx) == self.n  # idx is every engine in order: plain slices, far cheaper than fancy indexing
        cols = slice(None) if whole else idx
        t = self.dt * (np.arange(k0, k0 + _CHUNK + 1)[:, None] - self._k_start[None, cols])
        self._t_local[:, cols] = t
        self._u_right[:, cols], self._u_left[:, cols] = self._profile_table.values(t, idx)
        sch = self.schedule
        if sch.process:
            if self._pf is None:  # the columns not filled here are healthy
                self._pf = (
                    np.empty((_CHUNK + 1, self.n, len(PF_FIELDS)))
                    if whole
                    else np.tile(HEALTHY_PF, (_CHUNK + 1, self.n, 1))
                )
            sub = sch if whole else CompiledSchedule.compile([self.schedules[i] for i in idx])
            pf = sub.process_values(t, per_engine=True) if sub.process else HEALTHY
            for m, name in enumerate(PF_FIELDS):
                self._pf[:, cols, m] = getattr(pf, name)
        else:
            self._pf = None
            # a writable copy: compiled code is specialised on array flags, and one specialisation
            # for every batch size keeps batched runs bit-identical to single runs
            self._pf_healthy = np.ascontiguousarray(np.tile(HEALTHY_PF, (1, self.n, 1)))
        if len(sch.s_engine):
            filled = np.zeros(self.n, dtype=bool)
            filled[idx] = True
            new = filled[sch.s_engine]
            s_state = np.empty((_CHUNK + 1, len(sch.s_engine)))
            beta = np.empty_like(s_state)
            fresh = np.flatnonzero(new)
            if len(fresh):
                s_state[:, fresh], beta[:, fresh] = sch.sensor_fault_state(self._t_local[:, sch.s_engine[fresh]], fresh)
            kept = np.flatnonzero(~new)
            if len(kept):
                old_col = {key: c for c, key in enumerate(old_sensor_keys)}
                cols = [old_col[(int(e), int(q))] for e, q in zip(sch.s_engine[kept], sch.s_sensor[kept])]
                s_state[:, kept], beta[:, kept] = self._sf_s[:, cols], self._sf_beta[:, cols]
            self._sf_s, self._sf_beta = s_state, beta

    def _grid_row(self, k: int) -> int:
        j = k - self._chunk_k0
        if j < 0 or j > _CHUNK:
            self._fill_chunk(k)
            j = 0
        return j

    # ----------------------------------------------------------------------------- stepping
    def step(self) -> np.ndarray:
        """Advance all engines by one sample; returns the measurements (N, 19) at the new time."""
        self.advance(1)
        return self.y

    def advance(self, n_samples: int, record: bool = False) -> "Block":
        """Advance all engines by ``n_samples`` samples in as few compiled calls as possible.

        Returns the readings of the new samples (engine-major, the diagnoser's layout) and the
        applied fuel setting; with ``record`` also the truth variables and the fault ground truth.
        ``advance(K)`` gives the same numbers bit for bit as K calls of ``advance(1)``.
        """
        if not isinstance(n_samples, (int, np.integer)) or n_samples < 1:
            raise ValueError(f"n_samples must be a positive integer, got {n_samples!r}")
        K = int(n_samples)
        t = self.dt * np.arange(self.k + 1, self.k + K + 1)
        pieces = []
        done = 0
        while done < K:
            j0 = self._grid_row(self.k)
            if j0 == _CHUNK:  # a step needs rows j0 and j0 + 1 of one chunk
                self._fill_chunk(self.k)
                j0 = 0
            m = min(K - done, _CHUNK - j0)
            pieces.append(self._advance_piece(j0, m, record))
            done += m
        if len(pieces) == 1:
            y, u, truth, act, val = pieces[0]
        else:
            y = np.concatenate([p[0] for p in pieces], axis=1)
            u = np.concatenate([p[1] for p in pieces], axis=1)
            truth, act, val = (
                (np.concatenate([p[i] for p in pieces], axis=1) for i in (2, 3, 4)) if record else (None, None, None)
            )
        return Block(t=t, measurements=y, u=u, truth=truth, fault_active=act, fault_value=val)

    def _advance_piece(self, j0: int, m: int, record: bool):
        """m samples within one precomputed chunk (rows j0 .. j0 + m)."""
        n = self.n
        pos = self._reserve_noise(m)
        Y = np.empty((n, m, N_SENSORS))
        U = np.empty((n, m))
        need_state = record or self._has_gain
        STATE = np.empty((n, m, 3 + N_ALG)) if need_state else self._no_state
        PF = self._pf[j0 : j0 + m + 1] if self._pf is not None else self._pf_healthy
        alive = ~self.failed
        codes = np.zeros(n, dtype=np.int64)
        fail_k = np.full(n, -1, dtype=np.int64)
        advance_batch(
            self.model.constants,
            self.dt,
            self.substeps,
            self.X,
            self._u_right[j0 : j0 + m + 1],
            self._u_left[j0 : j0 + m + 1],
            PF,
            self.ALG,
            alive,
            self.fuel_limiter_lambda,
            self._noise_raw,
            pos,
            self._noise_bounds,
            _SENSOR_COLUMNS,
            Y,
            U,
            STATE,
            need_state,
            codes,
            fail_k,
            self._scr_pf,
            self._scr_alg,
            self._X_new,
            self._ALG_new,
        )
        k_start = self.k
        self.k += m
        self.t = self.k * self.dt
        failed = np.flatnonzero(fail_k >= 0)
        if len(failed):
            for i in failed[np.lexsort((failed, fail_k[failed]))]:
                self.failed[i] = True
                self.failures.append(
                    EngineFailure(
                        int(i),
                        float((k_start + fail_k[i] + 1 - self._k_start[i]) * self.dt),
                        FAILURE_REASONS[int(codes[i])],
                    )
                )
        self.u = U[:, -1].copy()
        rows = slice(j0 + 1, j0 + m + 1)
        sens = self._apply_sensor_faults(rows, Y, STATE) if len(self.schedule.s_engine) else None
        self._last_y = Y[:, -1].copy()
        self.y = self._last_y
        if not record:
            return Y, U, None, None, None
        act, val = self._fault_truth_rows(rows, sens)
        return Y, U, _truth_from_state(STATE, U), act, val

    def _applied_u(self, u_cmd: np.ndarray, engines=None) -> np.ndarray:
        """Fuel setting after the charge-air limiter (see class docstring), for ``engines`` (default
        all); the compiled kernel applies the same function at every sample."""
        idx = range(self.n) if engines is None else engines
        c = self.model.constants
        return np.array(
            [
                limited_fuel_setting(float(u_cmd[i]), self.X[i, 2], self.ALG[i, 9], self.fuel_limiter_lambda, c)
                for i in idx
            ]
        )

    # ------------------------------------------------------------------------- failures
    def _record_failures(self, codes: np.ndarray, t: float) -> None:
        for i in np.flatnonzero(codes):
            if not self.failed[i]:
                self.failed[i] = True
                self.failures.append(EngineFailure(int(i), float(t), FAILURE_REASONS[int(codes[i])]))

    # ------------------------------------------------------------------------- sensors
    def _reserve_noise(self, m: int) -> int:
        """Make m samples of noise available; returns their first sample index in the buffer.

        Each engine's noise is one sequential PCG64 stream of U[0, 1) doubles (minus 1/2), drawn
        into the buffer in blocks; how the stream is cut into blocks does not change the numbers.
        """
        cap = self._noise_raw.shape[1] // N_SENSORS
        if self._noise_pos + m > cap:
            rem = cap - self._noise_pos
            size = max(_NOISE_BLOCK, m)
            buf = np.empty((self.n, size * N_SENSORS))
            buf[:, : rem * N_SENSORS] = self._noise_raw[:, self._noise_pos * N_SENSORS :]
            for i, rng in enumerate(self._rngs):
                rng.random(out=buf[i, rem * N_SENSORS :])
            buf[:, rem * N_SENSORS :] -= 0.5
            self._noise_raw = buf
            self._noise_pos = 0
        pos = self._noise_pos
        self._noise_pos += m
        return pos

    def true_variables(self) -> np.ndarray:
        """Noise-free measured variables, shape (N, 10) in the order of MEASURED_VARIABLES."""
        return np.concatenate([self.X, self.ALG], axis=1)[:, _MEASURED_COLUMNS]

    def _measure_initial(self) -> np.ndarray:
        """Readings at t = 0 (the state set by reset)."""
        state = np.concatenate([self.X, self.ALG], axis=1)
        pos = self._reserve_noise(1)
        noise = self._noise_raw[:, pos * N_SENSORS : (pos + 1) * N_SENSORS] * self._noise_bounds
        y = (state[:, _SENSOR_COLUMNS] + noise)[:, None, :]
        self._fault_dev = None
        if len(self.schedule.s_engine):
            self._apply_sensor_faults(slice(0, 1), y, state[:, None, :], initial=True)
        self._last_y = y[:, 0].copy()
        return self._last_y

    def _precision_noise(self, engine: int, count: int) -> np.ndarray:
        if self._prec_rngs is None:
            self._prec_rngs = {}
        if engine not in self._prec_rngs:
            self._prec_rngs[engine] = np.random.Generator(
                np.random.PCG64(np.random.SeedSequence(self.seeds[engine]).spawn(2)[1])
            )
        return self._prec_rngs[engine].uniform(-1.0, 1.0, size=count)

    def _apply_sensor_faults(self, rows: slice, Y: np.ndarray, STATE: np.ndarray, sel=None, initial=False):
        """Apply the sensor faults to readings Y (N, m, 19) in place; rows: the chunk rows of Y's samples.

        ``sel``: indices of the scheduled sensor faults to apply (default all); ``initial``: the
        first reading of the engines concerned (a stuck-at fault then holds that reading).
        Returns (active (m, F), deviation (m, F)) per selected sensor fault F.
        """
        sch = self.schedule
        sel = np.arange(len(sch.s_engine)) if sel is None else np.asarray(sel, dtype=np.int64)
        s, beta = self._sf_s[rows][:, sel], self._sf_beta[rows][:, sel]  # (m, F)
        active = ~np.isnan(s)
        e, j, kind, mag = sch.s_engine[sel], sch.s_sensor[sel], sch.s_kind[sel], sch.s_params["mag"][sel]
        stuck = self._stuck[sel]
        yv = Y[e, :, j].T  # (m, F)
        dev = np.zeros(yv.shape)
        bm = beta * mag
        k0 = active & (kind == 0)
        dev[k0] = bm[k0]
        k1 = active & (kind == 1)
        dev[k1] = (bm * s)[k1]
        k3 = active & (kind == 3)
        if k3.any():
            true = STATE[e, :, _SENSOR_COLUMNS[j]].T
            dev[k3] = (bm * true)[k3]
        k4 = active & (kind == 4)
        if k4.any():
            prec = np.zeros(yv.shape)
            for eng in np.unique(e[(kind == 4)]):
                cols = np.flatnonzero((e == eng) & (kind == 4))
                mask = k4[:, cols]
                block = np.zeros(mask.shape)
                block[mask] = self._precision_noise(int(eng), int(mask.sum()))  # time-major, then fault order
                prec[:, cols] = block
            dev[k4] = (bm * prec)[k4]
        new = yv + dev
        for f in np.flatnonzero(kind == 2):  # stuck-at: hold the last reading (or the given value)
            prev = yv[0, f] if initial or self._last_y is None else self._last_y[e[f], j[f]]
            for r in range(new.shape[0]):
                if active[r, f]:
                    if np.isnan(stuck[f]):
                        stuck[f] = prev if np.isnan(mag[f]) else mag[f]
                    new[r, f] = stuck[f]
                else:
                    stuck[f] = np.nan
                prev = new[r, f]
        self._stuck[sel] = stuck
        Y[e, :, j] = new.T
        if self._fault_dev is None or len(sel) == len(sch.s_engine):
            self._fault_dev = (active[-1], new[-1] - yv[-1])
        else:
            self._fault_dev[0][sel] = active[-1]
            self._fault_dev[1][sel] = new[-1] - yv[-1]
        return active, new - yv

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
            t_now = self._t_local[self._grid_row(self.k)]
            for k, d in sch.process.items():
                col = FAULT_IDS.index(k)
                s, v = sch.fault_values(k, t_now, per_engine=True)
                act[d["engine"], col] = ~np.isnan(s)
                val[d["engine"], col] = v
        return act, val

    def truth_vector(self) -> np.ndarray:
        a = self.alg
        return np.stack(
            [
                self.u,
                self.x1,
                self.x3,
                self.x4,
                a.n,
                a.torque,
                a.power(),
                a.p6,
                a.T6,
                a.p_max,
                a.T_in,
                a.T_out,
                a.T1,
                a.T_co,
                a.lam,
            ],
            axis=1,
        )

    def _fault_truth_rows(self, rows: slice, sens) -> tuple[np.ndarray, np.ndarray]:
        """(active, value), each (N, m, 26), of every fault id on the samples of chunk rows ``rows``."""
        t = self._t_local[rows]
        m = len(t)
        act = np.zeros((self.n, m, len(FAULT_IDS)), dtype=bool)
        val = np.zeros((self.n, m, len(FAULT_IDS)))
        sch = self.schedule
        if sens is not None:
            a, dev = sens
            act[sch.s_engine, :, sch.s_sensor] = a.T
            val[sch.s_engine, :, sch.s_sensor] = np.where(a, dev, 0.0).T
        if sch.process:
            for k, d in sch.process.items():
                col = FAULT_IDS.index(k)
                s, v = sch.fault_values(k, t, per_engine=True)  # (m, engines of the fault)
                act[d["engine"], :, col] = ~np.isnan(s).T
                val[d["engine"], :, col] = v.T
        return act, val

    # ------------------------------------------------------------------------- whole runs
    def run(
        self, duration_s: float, progress: bool = False, record: bool = True, block_samples: int = 256
    ) -> SimulationResult:
        """Simulate ``duration_s`` seconds from the current state and return the recorded samples."""
        if not (isinstance(duration_s, (int, float)) and math.isfinite(duration_s) and duration_s > 0):
            raise ValueError(f"duration must be a positive finite number of seconds, got {duration_s!r}")
        steps = int(round(duration_s / self.dt))
        T = steps + 1 if record else 1
        nF = len(FAULT_IDS)
        meas = np.empty((T, self.n, N_SENSORS))
        truth = np.empty((T, self.n, len(TRUTH_VARIABLES)))
        f_act = np.zeros((T, self.n, nF), dtype=bool)
        f_val = np.zeros((T, self.n, nF))
        times = self.t + self.dt * np.arange(steps + 1)

        def rec_current(j):
            meas[j] = self.y
            truth[j] = self.truth_vector()
            f_act[j], f_val[j] = self.fault_truth(self.t)

        rec_current(0)
        bar = None
        if progress:
            from tqdm import tqdm

            bar = tqdm(total=steps, desc="simulate", unit="sample", mininterval=0.5)
        done = 0
        while done < steps:
            m = min(block_samples, steps - done)
            blk = self.advance(m, record=record)
            if record:
                sl = slice(done + 1, done + 1 + m)
                meas[sl] = blk.measurements.transpose(1, 0, 2)
                truth[sl] = blk.truth.transpose(1, 0, 2)
                f_act[sl] = blk.fault_active.transpose(1, 0, 2)
                f_val[sl] = blk.fault_value.transpose(1, 0, 2)
            done += m
            if bar is not None:
                bar.update(m)
        if bar is not None:
            bar.close()
        if not record:
            rec_current(0)
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


@dataclass
class Block:
    """Samples produced by :meth:`Simulator.advance`, engine-major: arrays (N, K, ...)."""

    t: np.ndarray  # (K,) sample times [s]
    measurements: np.ndarray  # (N, K, 19)
    u: np.ndarray  # (N, K) applied fuel setting
    truth: "np.ndarray | None" = None  # (N, K, len(TRUTH_VARIABLES)) if recorded
    fault_active: "np.ndarray | None" = None  # (N, K, 26)
    fault_value: "np.ndarray | None" = None  # (N, K, 26)


def _truth_from_state(state: np.ndarray, u: np.ndarray) -> np.ndarray:
    """TRUTH_VARIABLES from recorded [x1, x3, x4, ALG] states (N, K, 19) and applied u (N, K)."""
    a = lambda f: state[..., 3 + ALG_FIELDS.index(f)]  # noqa: E731
    n, torque = a("n"), a("torque")
    return np.stack(
        [
            u,
            state[..., 0],
            state[..., 1],
            state[..., 2],
            n,
            torque,
            2.0 * np.pi * n * torque,
            a("p6"),
            a("T6"),
            a("p_max"),
            a("T_in"),
            a("T_out"),
            a("T1"),
            a("T_co"),
            a("lam"),
        ],
        axis=-1,
    )


# columns of [X | ALG] holding the measured variables, in MEASURED_VARIABLES / sensor order
_STATE_COLS = {"x1": 0, "x3": 1, "x4": 2}
_MEASURED_COLUMNS = np.array(
    [_STATE_COLS[v] if v in _STATE_COLS else 3 + ALG_FIELDS.index(v) for v in MEASURED_VARIABLES]
)
_SENSOR_COLUMNS = _MEASURED_COLUMNS[VARIABLE_OF_SENSOR]
