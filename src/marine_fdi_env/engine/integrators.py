"""Time integration of the DAE: a fixed-step exponential integrator and a scipy reference.

Fixed step (:func:`advance_batch`)
    Every state obeys ``x' = a x + F(x, t)`` with a diagonal linear part a = -(1+φ)/τ whose time
    constants (τ_X = 0.015 s, τ_pd = 0.01 s) are as short as the sample time.  Explicit Euler at
    h = 0.01 s would sit at its stability limit for x3 (h/τ_pd = 1, unstable beyond 2, e.g. under
    a turbine seal leak) and be grossly inaccurate for x1 and x3.  The exponential
    Runge-Kutta method of Cox and Matthews (ETD2RK) integrates the linear part exactly and the
    forcing to second order::

        x_p     = e^{ah} x_n + h φ1(ah) F(x_n, t_n)
        x_{n+1} = x_p + h φ2(ah) (F(x_p, t_{n+1}) - F(x_n, t_n))

    with φ1(z) = (e^z - 1)/z and φ2(z) = (e^z - 1 - z)/z².  It is exact for x1 under a fuel
    setting that is piecewise linear between samples, and A-stable for any τ.  The algebraic
    loop is re-solved at x_p and at x_{n+1}, its speed iteration warm-started from the previous
    solution, so a step costs two algebraic solves (the second one also gives the outputs).

Reference (:func:`reference_solve`)
    ``scipy.integrate.solve_ivp`` with Radau at tight tolerances, the algebraic part solved to
    convergence inside the right-hand side, and the integration restarted at every breakpoint
    of the fuel-setting profile and every fault onset (where the right-hand side is not smooth).
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import jit, jit_inline
from .constants import kernel_constants
from .fault_registry import I_F_U, I_PHI_INT, I_PHI_TUR
from .model import forcings, solve_algebraic_kernel

__all__ = [
    "advance_batch",
    "reference_solve",
    "FAILURE_REASONS",
    "PREDICTOR_SWEEPS",
    "OUTPUT_SWEEPS",
    "TRANSIENT_TOL",
    "thread_pool",
    "etd_scalar",
    "failure_code",
]

# The predictor stage needs the speed only to second order in h: one sweep from the previous
# sample's speed (contraction 0.06-0.13) leaves an error of about a tenth of the speed change per
# sample (1e-5 relative in steady running, up to 1e-2 at a large fuel step, where the substeps
# shrink the change per step).
PREDICTOR_SWEEPS = 1
# The output stage starts from the predictor's speed, which differs from the final one by far
# less than a sample's change; two sweeps (contraction <= 0.12) leave a relative speed and torque
# error below 2e-6 even at a fuel-setting step (measured against the fully converged solve),
# negligible against the 1e-3 accuracy budget of the fixed-step solver.
OUTPUT_SWEEPS = 2
# Substeps are taken while |x1 - x1_target| exceeds this fraction of x1_nom.
TRANSIENT_TOL = 1e-3
FAILURE_REASONS = (
    "",
    "non-finite state",
    "stall: shaft torque not positive",
    "stall: engine speed below 5 % of nominal",
    "air excess ratio below 1",
    "turbine pressure ratio at or below 1",
    "charge-air pressure not positive",
)


@jit
def etd_scalar(a, h):
    """exp(a h), h φ1(a h), h φ2(a h) for one rate."""
    z = a * h
    em1 = math.expm1(z)
    phi1 = 1.0 if z == 0.0 else em1 / z
    phi2 = 0.5 + z / 6.0 if abs(z) < 1e-5 else (em1 - z) / (z * z)
    return em1 + 1.0, h * phi1, h * phi2


@jit
def limited_fuel_setting(u_cmd, x4, T1, lam_lim, c):
    """Governor output with a charge-air (smoke) limiter: min(u_cmd, setting giving λ = lam_lim).

    The limiter knows the charge-air pressure and temperature but not the faults: it caps the
    fuel at ``m1 / (lam_lim σ_f)`` with the healthy trapped mass ``m1 = x4 V1 / (R_a T1)``.
    ``lam_lim <= 0`` disables it (the thesis model has no limiter).
    """
    if lam_lim <= 0.0:
        return u_cmd
    u_max = x4 * c.V1_m3 / (c.R_a_J_per_kgK * T1 * lam_lim * c.sigma_f * c.x1_nom_kg)
    return min(u_cmd, u_max)


@jit
def healthy_coefficients(c, h):
    """ETD2RK coefficients (E, hφ1, hφ2) of x1, x3, x4 without seal-leak faults, for step h."""
    return etd_scalar(-1.0 / c.tau_X_s, h) + etd_scalar(-1.0 / c.tau_pd_s, h) + etd_scalar(-1.0 / c.tau_TC_s, h)


@jit_inline
def _etd_once(c, csm, h, coef, x1, x3, x4, u0, u1, pf0, pf1, alg0, algp, alg_out, lam_lim):
    """One ETD2RK step of one engine; alg0 is the algebraic state at the start, alg_out the end.
    c, csm: the constants of :func:`~marine_fdi_env.engine.constants.kernel_constants`.

    u0, u1 are the commanded fuel settings; the applied ones pass the charge-air limiter.
    ``coef`` holds the healthy coefficients for step h; a seal-leak fault (evaluated at mid-step)
    changes the linear rate of x3 or x4 and its coefficients are recomputed.
    """
    E1, q1, r1, E3, q3, r3, E4, q4, r4 = coef
    phi_tur = 0.5 * (pf0[I_PHI_TUR] + pf1[I_PHI_TUR])
    phi_int = 0.5 * (pf0[I_PHI_INT] + pf1[I_PHI_INT])
    if phi_tur != 0.0:
        E3, q3, r3 = etd_scalar(-(1.0 + phi_tur) / c.tau_pd_s, h)
    if phi_int != 0.0:
        E4, q4, r4 = etd_scalar(-(1.0 + phi_int) / c.tau_TC_s, h)
    F1, F3, F4 = forcings(limited_fuel_setting(u0, x4, alg0[9], lam_lim, c), pf0, alg0, c)
    y1 = E1 * x1 + q1 * F1
    y3 = E3 * x3 + q3 * F3
    y4 = E4 * x4 + q4 * F4
    solve_algebraic_kernel(c, csm, y1, y3, y4, pf1, alg0[0], PREDICTOR_SWEEPS, algp)
    G1, G3, G4 = forcings(limited_fuel_setting(u1, y4, algp[9], lam_lim, c), pf1, algp, c)
    z1 = y1 + r1 * (G1 - F1)
    z3 = y3 + r3 * (G3 - F3)
    z4 = y4 + r4 * (G4 - F4)
    solve_algebraic_kernel(c, csm, z1, z3, z4, pf1, algp[0], OUTPUT_SWEEPS, alg_out)
    return z1, z3, z4


@jit_inline
def failure_code(c, x1, x3, x4, alg):
    """0 when the engine is within its physical range, else the index in FAILURE_REASONS."""
    total = x1 + x3 + x4 + alg[0] + alg[7] + alg[10]
    if not math.isfinite(total):
        return 1
    if not alg[1] > 0.0:
        return 2
    if not alg[0] > 0.05 * c.n_nom_rev_s:
        return 3
    if not alg[11] >= 1.0:
        return 4
    if not x3 > c.p_ex_Pa:
        return 5
    if not x4 > 0.0:
        return 6
    return 0


@jit_inline
def _engine_step(
    c,
    csm,
    h,
    substeps,
    x1,
    x3,
    x4,
    u0,
    u1,
    pf0,
    pf1,
    alg,
    alg_new,
    algp,
    pfa,
    pfb,
    alg_a,
    alg_b,
    lam_lim,
    coef,
    coef_sub,
):
    """One sample of one engine from the state (x1, x3, x4) and algebraic state ``alg`` under the commanded
    fuel settings u0, u1 and the process-fault vectors pf0, pf1 at the start and end: returns the state and
    the failure code at the end, the algebraic state in ``alg_new`` (algp, pfa, pfb, alg_a, alg_b: the
    engine's scratch rows; pf0, pf1 too, filled per sample).  Inlined into the loop by numba with scalars and
    the engine's row views as arguments: every array argument of an out-of-line call, and every view made
    per sample, costs an atomic reference-count increment and decrement."""
    target = c.x1_nom_kg * pf1[I_F_U] * limited_fuel_setting(u1, x4, alg[9], lam_lim, c)
    if substeps > 1 and abs(x1 - target) > TRANSIENT_TOL * c.x1_nom_kg:
        # fuel pump far from its target: substeps, u and process faults linear within the step
        hs = h / substeps
        for m in range(alg_a.shape[0]):
            alg_a[m] = alg[m]
        for j in range(substeps):
            w0, w1 = j / substeps, (j + 1) / substeps
            for k in range(pfa.shape[0]):
                pfa[k] = pf0[k] + w0 * (pf1[k] - pf0[k])
                pfb[k] = pf0[k] + w1 * (pf1[k] - pf0[k])
            ua = u0 + w0 * (u1 - u0)
            ub = u0 + w1 * (u1 - u0)
            x1, x3, x4 = _etd_once(c, csm, hs, coef_sub, x1, x3, x4, ua, ub, pfa, pfb, alg_a, algp, alg_b, lam_lim)
            for m in range(alg_a.shape[0]):
                alg_a[m] = alg_b[m]
        for m in range(alg_a.shape[0]):
            alg_new[m] = alg_a[m]
    else:
        x1, x3, x4 = _etd_once(c, csm, h, coef, x1, x3, x4, u0, u1, pf0, pf1, alg, algp, alg_new, lam_lim)
    return x1, x3, x4, failure_code(c, x1, x3, x4, alg_new)


@jit
def _advance_range(
    c,
    csm,
    h,
    substeps,
    i0,
    i1,
    X,
    UR,
    UL,
    PF,
    ALG,
    alive,
    lam_lim,
    NOISE,
    noise_pos,
    NB,
    SENSOR_COLS,
    Y,
    UAPP,
    STATE,
    record,
    CODES,
    FAIL_K,
    SCR_PF,
    SCR_ALG,
    X_NEW,
    ALG_NEW,
):
    """K samples of engines i0..i1-1: step, charge-air limiter, noisy sensor readings (one call)."""
    K = Y.shape[1]
    n_s = SENSOR_COLS.shape[0]
    n_alg = ALG.shape[1]
    n_pf = PF.shape[2]
    coef = healthy_coefficients(c, h)
    coef_sub = healthy_coefficients(c, h / max(substeps, 1))
    multi_pf = PF.shape[0] > 1
    for i in range(i0, i1):
        alg, alg_new = ALG[i], ALG_NEW[i]  # the engine's rows, one view each per call (not per sample)
        algp, alg_a, alg_b = SCR_ALG[i, 0], SCR_ALG[i, 1], SCR_ALG[i, 2]
        # the fault terms at the sample's start and end and two substep rows: views made once per engine,
        # filled per sample (a view per sample would cost a reference-count increment and decrement)
        pf0, pf1, pfa, pfb = SCR_PF[i, 0], SCR_PF[i, 1], SCR_PF[i, 2], SCR_PF[i, 3]
        for k in range(K):
            r0 = k if multi_pf else 0
            r1 = k + 1 if multi_pf else 0
            if alive[i]:
                for m in range(n_pf):
                    pf0[m] = PF[r0, i, m]
                    pf1[m] = PF[r1, i, m]
                x1, x3, x4, code = _engine_step(
                    c,
                    csm,
                    h,
                    substeps,
                    X[i, 0],
                    X[i, 1],
                    X[i, 2],
                    UR[k, i],
                    UL[k + 1, i],
                    pf0,
                    pf1,
                    alg,
                    alg_new,
                    algp,
                    pfa,
                    pfb,
                    alg_a,
                    alg_b,
                    lam_lim,
                    coef,
                    coef_sub,
                )
                if code == 0:
                    X[i, 0] = x1
                    X[i, 1] = x3
                    X[i, 2] = x4
                    for j in range(n_alg):
                        alg[j] = alg_new[j]
                else:  # freeze at the last valid state
                    alive[i] = False
                    CODES[i] = code
                    FAIL_K[i] = k
            UAPP[i, k] = limited_fuel_setting(UR[k + 1, i], X[i, 2], alg[9], lam_lim, c)
            base = (noise_pos + k) * n_s
            for s in range(n_s):
                col = SENSOR_COLS[s]
                v = X[i, col] if col < 3 else alg[col - 3]
                Y[i, k, s] = v + NOISE[i, base + s] * NB[s]
            if record:
                for j in range(3):
                    STATE[i, k, j] = X[i, j]
                for j in range(n_alg):
                    STATE[i, k, 3 + j] = alg[j]


def advance_batch(
    c,
    h,
    substeps,
    X,
    UR,
    UL,
    PF,
    ALG,
    alive,
    lam_lim,
    NOISE,
    noise_pos,
    NB,
    SENSOR_COLS,
    Y,
    UAPP,
    STATE,
    record,
    CODES,
    FAIL_K,
    SCR_PF,
    SCR_ALG,
    X_NEW,
    ALG_NEW,
):
    """Advance every engine by K = Y.shape[1] samples in one compiled call (state updated in place).

    UR, UL: (K+1, N) right and left limits of the commanded fuel setting at the K+1 sample times;
    PF: (K+1, N, T) the fault terms' values (T = len(``fault_registry.TERMS``), the order of
    ``model.PF_FIELDS``), or (1, N, T) when constant; SCR_PF: (N, 4, T) scratch; alive: (N,) bool, cleared
    at a failure (CODES gets the reason, FAIL_K the sample index within the block; the state
    freezes).  NOISE: (N, M) pre-drawn U[0,1) - 1/2 values, sample k of the block at columns
    (noise_pos + k) * 19 ...; NB: (19,) twice the noise bounds.  Outputs: Y (N, K, 19) noisy
    readings, UAPP (N, K) applied fuel setting, STATE (N, K, 19) [x1, x3, x4, ALG] if record.
    Batches of at least ``THREADED_MIN_ENGINES`` engines run as two contiguous halves on two
    threads (the compiled loop releases the GIL; engines are independent, so the results equal
    the single-thread loop bit for bit).  numba's own parallel loop measures 30 % slower than
    serial on the 2-core target machine.  One call per block of samples instead of one per sample
    removes the Python overhead per sample (70 µs -> 2 µs for one engine).
    """
    n = X.shape[0]
    kc, csm = kernel_constants(c)  # floats only: no reference counting of the constants per compiled call
    args = (
        X,
        UR,
        UL,
        PF,
        ALG,
        alive,
        float(lam_lim),
        NOISE,
        int(noise_pos),
        NB,
        SENSOR_COLS,
        Y,
        UAPP,
        STATE,
        bool(record),
        CODES,
        FAIL_K,
        SCR_PF,
        SCR_ALG,
        X_NEW,
        ALG_NEW,
    )
    if n < THREADED_MIN_ENGINES:
        _advance_range(kc, csm, h, substeps, 0, n, *args)
        return
    half = n // 2
    list(thread_pool().map(lambda r: _advance_range(kc, csm, h, substeps, r[0], r[1], *args), [(0, half), (half, n)]))


THREADED_MIN_ENGINES = 256
_EXECUTOR = None


def thread_pool():
    """A process-wide pool of two worker threads, created on first use."""
    global _EXECUTOR
    if _EXECUTOR is None:
        from concurrent.futures import ThreadPoolExecutor

        _EXECUTOR = ThreadPoolExecutor(max_workers=2, thread_name_prefix="marine-fdi-kernel")
    return _EXECUTOR


def reference_solve(
    params,
    profile,
    faults=(),
    duration_s: float = 300.0,
    dt: float = 0.01,
    rtol: float = 1e-10,
    method: str = "Radau",
    fuel_limiter_lambda: float = 1.3,
):
    """Reference solution of one engine with ``scipy.integrate.solve_ivp`` (noise-free).

    Returns ``(t, x, true)``: sample times (T,), states (T, 3) = (x1, x3, x4) and the noise-free
    measured variables (T, 10) in the order of ``sensors.MEASURED_VARIABLES``.  The integration
    restarts at every breakpoint of the profile and every fault onset/end, the algebraic loop is
    solved with extra speed sweeps, and the initial state is the same steady state the fixed-step
    simulator starts from.
    """
    from scipy.integrate import solve_ivp

    from .faults import CompiledSchedule
    from .model import HEALTHY, EngineModel
    from .params import load_params
    from .profiles import make_profile
    from .steady_state import steady_state
    from .subsystems.air_intake import inlet_air_temperature

    p = load_params(params) if isinstance(params, str) else params
    prof = make_profile(profile).snapped(dt)
    sched = CompiledSchedule.compile([list(faults)])
    model = EngineModel(p, speed_sweeps=6)

    def pf_at(t):
        return sched.process_values(t) if sched.process else HEALTHY

    n_state = {"n": None}

    def rhs_until(t_end):
        """Right-hand side on a segment ending at t_end, using the left limit of u there."""

        def f(t, y):
            u = prof(t) if t < t_end else prof.left_limit(t_end)
            pf = pf_at(t)
            T1 = float(inlet_air_temperature(float(np.asarray(pf.dT_inl_K).reshape(-1)[0]), model.constants))
            u = limited_fuel_setting(float(u), float(y[2]), T1, fuel_limiter_lambda, model.constants)
            d, alg = model.derivatives(y[0:1], y[1:2], y[2:3], np.atleast_1d(u), pf, n_state["n"])
            n_state["n"] = alg.n
            return np.array([d[0][0], d[1][0], d[2][0]])

        return f

    steps = int(round(duration_s / dt))
    t_grid = dt * np.arange(steps + 1)
    ss = steady_state(model, prof(0.0), pf_at(0.0))
    y0 = np.array([ss.x1[0], ss.x3[0], ss.x4[0]])
    n_state["n"] = ss.alg.n
    end = float(t_grid[-1])
    cuts = sorted(
        {0.0, end}
        | {float(b) for b in prof.breakpoints if 0 < b < end}
        | {float(b) for b in sched.breakpoints if 0 < b < end}
    )
    X = np.empty((len(t_grid), 3))
    X[0] = y0
    atol = np.array([1e-12 * p.x1_nom_kg, 1e-12 * p.p1_nom_Pa, 1e-12 * p.p1_nom_Pa])
    for a, b in zip(cuts[:-1], cuts[1:]):
        idx = np.flatnonzero((t_grid > a + 1e-9) & (t_grid < b - 1e-9))
        t_eval = np.concatenate([t_grid[idx], [b]])
        sol = solve_ivp(rhs_until(b), (a, b), y0, method=method, rtol=rtol, atol=atol, t_eval=t_eval)
        if not sol.success:
            raise RuntimeError(f"reference solver failed on [{a}, {b}]: {sol.message}")
        X[idx] = sol.y[:, :-1].T
        y0 = sol.y[:, -1]
        j = int(round(b / dt))
        if abs(j * dt - b) < 1e-9:
            X[j] = y0
    true = np.empty((len(t_grid), 10))
    n_guess = None
    for i, t in enumerate(t_grid):
        alg = model.algebraic(X[i, 0:1], X[i, 1:2], X[i, 2:3], pf_at(t), n_guess)
        n_guess = alg.n
        true[i] = [
            X[i, 0],
            alg.p6[0],
            alg.T6[0],
            alg.torque[0],
            X[i, 1],
            alg.T_in[0],
            alg.T_out[0],
            X[i, 2],
            alg.T1[0],
            alg.T_co[0],
        ]
    return t_grid, X, true
