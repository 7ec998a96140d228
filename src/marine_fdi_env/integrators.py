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
