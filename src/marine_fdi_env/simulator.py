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
from .integrators import ExponentialRK2
from .model import HEALTHY, Algebraic, EngineModel, ProcessFaultValues
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
_CHUNK = 256
# The predictor stage needs the speed only to second order in h: one sweep from the previous
# sample's speed (contraction ~0.1, speed change per sample ~1e-4) is accurate to ~1e-5 there.
_PREDICTOR_SWEEPS = 1
# The output stage starts from the predictor's speed, which differs from the final one by far
# less than a sample's change; two sweeps (contraction <= 0.12) leave a relative speed and torque
# error below 2e-6 even at a fuel-setting step (measured against the fully converged solve),
# negligible against the 1e-3 accuracy budget of the fixed-step solver.
_OUTPUT_SWEEPS = 2
_TRANSIENT_TOL = 1e-3


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
        p = self.params
        self.k = 0
        self.t = 0.0
        self._rngs = [np.random.Generator(np.random.PCG64(np.random.SeedSequence(s).spawn(2)[0])) for s in self.seeds]
        self._prec_rngs = None
        self._noise_raw = np.empty((self.n, _NOISE_BLOCK * N_SENSORS))
        self._noise = np.empty((_NOISE_BLOCK, self.n, N_SENSORS))
        self._noise_pos = _NOISE_BLOCK
        u0 = np.array([pr(0.0) for pr in self.profiles], dtype=float)
        pf0 = self._process(0.0)
        ss = steady_state(self.model, u0, pf0)
        self.x1, self.x3, self.x4 = ss.x1.copy(), ss.x3.copy(), ss.x4.copy()
        self.alg = ss.alg
        self.u = u0
        self.failed = np.zeros(self.n, dtype=bool)
        self.failures: list[EngineFailure] = []
        self._stuck = np.full(len(self.schedule.s_engine), np.nan)
        self._fill_chunk(0)
        self._last_y = None
        a1, a3, a4 = self.model.linear_coefficients()
        self._etd = {h: tuple(ExponentialRK2.for_rate(a, h) for a in (a1, a3, a4))
                     for h in (self.dt, self.dt / self.substeps)}
        self._x1_target_coeff = p.x1_nom_kg
        self._check_failure(0.0, np.ones(self.n, dtype=bool))
        self.y = self._measure(0.0)

    def _process(self, t: float) -> ProcessFaultValues:
        return self.schedule.process_values(t) if self.schedule.process else HEALTHY

    def _u(self, t: float, left: bool = False) -> np.ndarray:
        if left:
            return np.array([pr.left_limit(t) for pr in self.profiles], dtype=float)
        return np.array([pr(t) for pr in self.profiles], dtype=float)

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
            fields_ = vars(pf)
            self._pf_rows = [ProcessFaultValues(**{f: (v[j] if np.ndim(v) == 2 else v) for f, v in fields_.items()})
                             for j in range(len(t))]
        else:
            self._pf_rows = None
        if len(self.schedule.s_engine):
            self._sf_s, self._sf_beta = self.schedule.sensor_fault_state(t[:, None])

    def _grid(self, k: int):
        """(u right limit, u left limit, process faults) at sample k."""
        j = k - self._chunk_k0
        if j < 0 or j > _CHUNK:
            self._fill_chunk(k)
            j = 0
        pf = HEALTHY if self._pf_rows is None else self._pf_rows[j]
        return self._u_right[j], self._u_left[j], pf

    # ----------------------------------------------------------------------------- stepping
    def _etd_step(self, h, t0, x1, x3, x4, n, u0, u1, pf0: ProcessFaultValues, pf1: ProcessFaultValues, sel=None):
        """One ETD2RK step of length h for the engines ``sel`` (all if None)."""
        m = self.model

        def pick(v):
            return v if sel is None or np.ndim(v) == 0 else v[sel]

        pf0s = ProcessFaultValues(**{k: pick(v) for k, v in vars(pf0).items()})
        pf1s = ProcessFaultValues(**{k: pick(v) for k, v in vars(pf1).items()})
        c = self._rates(t0 + 0.5 * h, h, sel) if self.schedule.has_seal_faults else self._etd[h]
        alg0 = m.algebraic(x1, x3, x4, pf0s, n)
        F0 = m.forcing(u0, alg0, pf0s)
        xp = [c[i].predict(x, F0[i]) for i, x in enumerate((x1, x3, x4))]
        algp = m.algebraic(*xp, pf1s, alg0.n)
        Fp = m.forcing(u1, algp, pf1s)
        xn = [c[i].correct(xp[i], Fp[i], F0[i]) for i in range(3)]
        return xn, algp.n

    def _rates(self, t_mid: float, h: float, sel=None):
        """ETD2RK coefficients with the seal-leak faults evaluated at mid-step."""
        pfm = self._process(t_mid)
        a1, a3, a4 = self.model.linear_coefficients(pfm)
        if sel is not None:
            a3, a4 = np.asarray(a3)[sel] if np.ndim(a3) else a3, np.asarray(a4)[sel] if np.ndim(a4) else a4
        return (self._etd[h][0], ExponentialRK2.for_rate(a3, h), ExponentialRK2.for_rate(a4, h))

    def step(self) -> np.ndarray:
        """Advance all engines by one sample; returns the measurements (N, 19) at the new time."""
        h = self.dt
        t0, t1 = self.t, (self.k + 1) * self.dt
        u0, _, pf0 = self._grid(self.k)  # right limit of u at t0
        u1_right, u1, pf1 = self._grid(self.k + 1)  # left limit at t1
        # ETD2RK from the start-of-step algebraic state self.alg (x1's forcing uses the right limit of u)
        m = self.model
        c = self._etd[h] if not self.schedule.has_seal_faults else self._rates(t0 + 0.5 * h, h)
        F0 = m.forcing(u0, self.alg, pf0)
        xp = [c[i].predict(x, F0[i]) for i, x in enumerate((self.x1, self.x3, self.x4))]
        algp = m.algebraic(*xp, pf1, self.alg.n, sweeps=_PREDICTOR_SWEEPS)
        Fp = m.forcing(u1, algp, pf1)
        x1, x3, x4 = [c[i].correct(xp[i], Fp[i], F0[i]) for i in range(3)]
        n_guess = algp.n
        # substeps for engines whose fuel pump is far from its target
        target = self._x1_target_coeff * np.asarray(pf1.f_u) * u1
        trans = np.abs(self.x1 - target) > _TRANSIENT_TOL * self.params.x1_nom_kg
        if self.substeps > 1 and trans.any():
            sel = np.flatnonzero(trans)
            hs = h / self.substeps
            sx1, sx3, sx4, sn = self.x1[sel], self.x3[sel], self.x4[sel], self.alg.n[sel]
            for j in range(self.substeps):
                ta, tb = t0 + j * hs, t0 + (j + 1) * hs
                w0, w1 = j / self.substeps, (j + 1) / self.substeps
                ua = u0[sel] + w0 * (u1[sel] - u0[sel])
                ub = u0[sel] + w1 * (u1[sel] - u0[sel])
                pfa = pf0 if j == 0 else self._process(ta)
                pfb = pf1 if j == self.substeps - 1 else self._process(tb)
                (sx1, sx3, sx4), sn = self._etd_step(hs, ta, sx1, sx3, sx4, sn, ua, ub, pfa, pfb, sel)
            x1, x3, x4 = x1.copy(), x3.copy(), x4.copy()
            x1[sel], x3[sel], x4[sel] = sx1, sx3, sx4
            n_guess = n_guess.copy()
            n_guess[sel] = sn
        alg = self.model.algebraic(x1, x3, x4, pf1, n_guess, sweeps=_OUTPUT_SWEEPS)
        ok = ~self.failed
        prev = (self.x1, self.x3, self.x4, self.alg)
        self.x1, self.x3, self.x4, self.alg = x1, x3, x4, alg
        self.u = u1_right
        self.k += 1
        self.t = t1
        newly = self._check_failure(t1, ok)
        frozen = self.failed
        if frozen.any():
            self._restore(frozen, prev)
        self.y = self._measure(t1)
        return self.y

    # ------------------------------------------------------------------------- failures
    def _check_failure(self, t: float, candidates: np.ndarray) -> np.ndarray:
        p = self.params
        a = self.alg
        with np.errstate(invalid="ignore"):
            checks = (
                ("non-finite state", ~np.isfinite(self.x1 + self.x3 + self.x4 + a.n + a.T_in + a.T_co)),
                ("stall: shaft torque not positive", ~(a.torque > 0.0)),
                ("stall: engine speed below 5 % of nominal", ~(a.n > 0.05 * p.n_nom_rev_s)),
                ("air excess ratio below 1", ~(a.lam >= 1.0)),
                ("turbine pressure ratio at or below 1", ~(self.x3 > p.p_ex_Pa)),
                ("charge-air pressure not positive", ~(self.x4 > 0.0)),
            )
        any_bad = checks[0][1]
        for _, bad in checks[1:]:
            any_bad = any_bad | bad
        newly = any_bad & candidates & ~self.failed
        if newly.any():
            for i in np.flatnonzero(newly):
                reason = next(r for r, bad in checks if bad[i])
                self.failures.append(EngineFailure(int(i), float(t), reason))
            self.failed |= newly
        return newly

    def _restore(self, mask: np.ndarray, prev) -> None:
        x1, x3, x4, alg = prev
        self.x1 = np.where(mask, x1, self.x1)
        self.x3 = np.where(mask, x3, self.x3)
        self.x4 = np.where(mask, x4, self.x4)
        self.alg = Algebraic(**{k: np.where(mask, getattr(alg, k), v) for k, v in vars(self.alg).items()})

    # ------------------------------------------------------------------------- sensors
    def _next_noise(self) -> np.ndarray:
        if self._noise_pos >= _NOISE_BLOCK:
            raw = self._noise_raw
            for i, rng in enumerate(self._rngs):
                rng.random(out=raw[i])  # U[0, 1), one contiguous block per engine
            # scaled noise d = (2 U - 1) * bound, laid out (sample, engine, sensor)
            bounds = NOISE_BOUNDS * self.noise_scale
            np.multiply(raw.reshape(self.n, _NOISE_BLOCK, N_SENSORS).transpose(1, 0, 2), 2.0, out=self._noise)
            self._noise -= 1.0
            self._noise *= bounds
            self._noise_pos = 0
        z = self._noise[self._noise_pos]
        self._noise_pos += 1
        return z

    def true_variables(self) -> np.ndarray:
        """Noise-free measured variables, shape (N, 10) in the order of MEASURED_VARIABLES."""
        a = self.alg
        return np.stack([self.x1, a.p6, a.T6, a.torque, self.x3, a.T_in, a.T_out, self.x4, a.T1, a.T_co], axis=1)

    def _measure(self, t: float) -> np.ndarray:
        true = self.true_variables()[:, VARIABLE_OF_SENSOR]
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
        j = self.k - self._chunk_k0
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
            pf = self._process(t)
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


def _active_time(t, d):
    from .faults import _window_time

    return _window_time(t, d["onset"], d["end"], d["period"], d["duty"])
