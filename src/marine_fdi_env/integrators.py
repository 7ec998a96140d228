"""Time integration of the DAE: a fixed-step exponential integrator and a scipy reference.

Fixed step (:class:`ExponentialRK2`)
    Every state obeys ``x' = a x + F(x, t)`` with a diagonal linear part a = -(1+φ)/τ whose time
    constants (τ_X = 0.015 s, τ_pd = 0.01 s) are as short as the sample time.  Explicit Euler at
    h = 0.01 s would be unstable for x3 (h/τ_pd = 1) and inaccurate for x1.  The exponential
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

from dataclasses import dataclass

import numpy as np

__all__ = ["etd_coefficients", "ExponentialRK2"]


def etd_coefficients(a, h: float):
    """exp(a h), φ1(a h) and φ2(a h) for the ETD2RK update (a may be an array)."""
    z = np.asarray(a, dtype=float) * h
    em1 = np.expm1(z)
    with np.errstate(divide="ignore", invalid="ignore"):
        phi1 = np.where(z == 0.0, 1.0, em1 / np.where(z == 0.0, 1.0, z))
        phi2 = np.where(np.abs(z) < 1e-5, 0.5 + z / 6.0, (em1 - z) / np.where(z == 0.0, 1.0, z * z))
    return em1 + 1.0, phi1, phi2


@dataclass(frozen=True)
class ExponentialRK2:
    """Coefficients of ETD2RK for a fixed step ``h`` and constant linear part ``a``."""

    h: float
    E: np.ndarray
    hphi1: np.ndarray
    hphi2: np.ndarray

    @classmethod
    def for_rate(cls, a, h: float) -> "ExponentialRK2":
        E, p1, p2 = etd_coefficients(a, h)
        return cls(h=h, E=E, hphi1=h * p1, hphi2=h * p2)

    def predict(self, x, F):
        return self.E * x + self.hphi1 * F

    def correct(self, x_pred, F_pred, F):
        return x_pred + self.hphi2 * (F_pred - F)


def reference_solve(
    params,
    profile,
    faults=(),
    duration_s: float = 300.0,
    dt: float = 0.01,
    rtol: float = 1e-10,
    method: str = "Radau",
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
            d, alg = model.derivatives(y[0:1], y[1:2], y[2:3], np.atleast_1d(u), pf_at(t), n_state["n"])
            n_state["n"] = alg.n
            return np.array([d[0][0], d[1][0], d[2][0]])

        return f

    steps = int(round(duration_s / dt))
    t_grid = dt * np.arange(steps + 1)
    ss = steady_state(model, prof(0.0), pf_at(0.0))
    y0 = np.array([ss.x1[0], ss.x3[0], ss.x4[0]])
    n_state["n"] = ss.alg.n
    end = float(t_grid[-1])
    cuts = sorted({0.0, end} | {float(b) for b in prof.breakpoints if 0 < b < end}
                  | {float(b) for b in sched.breakpoints if 0 < b < end})
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
        true[i] = [X[i, 0], alg.p6[0], alg.T6[0], alg.torque[0], X[i, 1], alg.T_in[0], alg.T_out[0], X[i, 2],
                   alg.T1[0], alg.T_co[0]]
    return t_grid, X, true
