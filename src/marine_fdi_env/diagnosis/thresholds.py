"""Readings of the state-based adaptive thresholds (eq. 5.10-5.14) of the observer modules M1.q,
M3.q and M4.q: the reference's own and three readings of the thesis, one switch (``thresholds``).

The residuals do not depend on the reading; only the thresholds of the six observer modules do (the
algebraic modules' inclusion of eq. 5.15-5.16 is the same in every reading).  The observer of
M(l,q) bounds its estimation error with a term for the forcing's uncertainty over the noise of the
sensors it reads besides its state sensor, ``H̄`` (the ``λ_h d̄`` of eq. 5.11):

* ``local`` (the default, the reference's): H̄ is the centred coordinate-wise inclusion of the
  forcing over the noise boxes of every sensor it reads, evaluated at every sample, in the exact
  discrete recursion of eq. 5.10-5.14 with ρ = 1 and ξ = 1/τ + L (docs/diagnosis.md).
* ``thesis-lipschitz``: eq. 5.11 with a global Lipschitz constant: the terms of the table 6.2
  interconnection sensors are replaced by their largest value over the operating envelope
  (``λ_h d̄_χ``, a constant per observer, :data:`GLOBAL_BOUNDS_FILE`); the own sensor set's terms
  stay local, and so does the kink's corner term (a Lipschitz constant does not exist where Ψ_sc has
  its kink, so a global one cannot cover it: docs/diagnosis.md, "Where the model has a kink").
  Looser than ``local`` wherever the operating point is not the worst of the envelope.
* ``thesis-no-interconnection``: the interconnection sensors' terms left out (the forcing read as
  exact in them); the own sensor set's terms stay local.  Not a valid bound: the hypothesis that the
  thesis's M3.q/M4.q thresholds did not carry the interconnection noise.
* ``thesis-table-6.1``: eq. 5.10-5.12 in closed form as printed, with table 6.1's constants
  ρ, ξ, ρ_d, ξ_d for all six observers, the global ``λ_h d̄_χ`` above (every sensor the forcing
  reads besides the state's own) and the slope Λ of the forcing in the state (eq. 5.12).  The
  threshold is then a function of the time since the observer started alone.  The thesis gives no
  x̄ (the bound of the initial estimation error); our observers start from the measurement, whose
  error is at most d̄, so x̄ = d̄/ρ (the smallest x̄ whose term ρ x̄ e^{-ξt} covers that start; with
  x̄ = d̄ the start term of M4.q is 1.67e-7 d̄ and every run fires M4.q at its second sample).
  Table 6.1's constants violate eq. 5.13-5.14 (ρ < 1 for M3.q and M4.q, ρ_d < L for M4.q), so this
  is not a valid bound: ρ = 0.02 scales the interconnection term of M3.q by ρ/ξ = 2.0e-4 s instead
  of about 1/ξ = 9.9e-3 s, and ρ_d = 0.02 makes the noise term of M4.q ρ_d d̄/ξ = 0.1 d̄ instead of
  L d̄/ξ = 0.95 d̄.
* ``thesis-table-6.1-m4``: the closed form of ``thesis-table-6.1`` for the charge-air observers
  M4.q only, ``local`` elsewhere (the reading of table 6.1 under which the M4.q claims of the thesis
  can be checked: with table 6.1's constants in M3.q, every run fires M3.q within a second).

The kernel (:mod:`.residuals`) takes a reading as one array (:func:`threshold_array`); the
default's array multiplies every term by 1.0 and adds 0.0, which leaves its numbers unchanged bit
for bit.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from functools import lru_cache
from importlib import resources

import numpy as np

from .._jit import jit

__all__ = [
    "THRESHOLD_READINGS",
    "DEFAULT_THRESHOLDS",
    "check_thresholds",
    "ObserverConstants",
    "TABLE_6_1",
    "GLOBAL_BOUNDS_FILE",
    "load_global_bounds",
    "threshold_array",
    "closed_form",
    "closed_form_threshold",
    "H_TERMS",
    "OWN_TERMS",
    "N_THR_COLS",
]

THRESHOLD_READINGS = (
    "local",
    "thesis-lipschitz",
    "thesis-no-interconnection",
    "thesis-table-6.1",
    "thesis-table-6.1-m4",
)
# the observers whose thresholds each closed-form reading takes from table 6.1
_CLOSED_FORM = {"thesis-table-6.1": ("M1", "M3", "M4"), "thesis-table-6.1-m4": ("M4",)}
DEFAULT_THRESHOLDS = "local"
GLOBAL_BOUNDS_FILE = "thesis_threshold_bounds.json"

# The terms of H̄ in the kernel, per observer (rows of the kernel's G box): the forcing's deviation
# at ±d̄ of x1, x3, x4, T1 and T_in, the margin of the tabulated perturbed speeds (from x1, x4, T1)
# and the kink's corner term (the (x3, x4) box).
H_TERMS = ("x1", "x3", "x4", "T1", "T_in", "speed_margin", "corner")
# the terms that are a sensor's noise box, and the state sensor's own term per observer
SENSOR_TERMS = ("x1", "x3", "x4", "T1", "T_in")
STATE_TERM = {"M3": "x3", "M4": "x4"}
# Which terms come from the module's own sensor set (table 6.2): M3.q reads x3 and T_in of its own
# set and x1, x4, T1 as interconnection sensors; M4.q reads x4 and T1 of its own set and x1, x3,
# T_in as interconnection sensors.  The speed margin comes from x1, x4, T1 (for M4.q partly its own:
# kept); the corner term needs both x3 and x4 (one of them is an interconnection sensor of either).
OWN_TERMS = {
    "M3": ("x3", "T_in"),
    "M4": ("x4", "T1", "speed_margin"),
}
# kernel array columns: 0-6 weights of H_TERMS, 7 global additive H̄ [state unit/s], 8 closed form
# flag, 9 ρ, 10 ξ [1/s], 11 ρ_d, 12 ξ_d [1/s], 13 Λ [1/s], 14 λ_h d̄_χ [state unit/s], 15 x̄/d̄
N_THR_COLS = 16
_ROWS = {"M1": 0, "M3": 1, "M4": 2}


@dataclass(frozen=True)
class ObserverConstants:
    """Table 6.1's design constants of one observer module pair: gain L [1/s], ρ, ξ [1/s], ρ_d, ξ_d [1/s]."""

    gain_per_s: float
    rho: float
    xi_per_s: float
    rho_d: float
    xi_d_per_s: float


TABLE_6_1 = {
    "M1": ObserverConstants(33.3833, 2.0, 100.0, 40.0, 100.0),
    "M3": ObserverConstants(1.25, 0.02, 101.25, 2.67, 101.27),
    "M4": ObserverConstants(0.3764, 1.67e-7, 0.2, 0.02, 0.4),
}


def check_thresholds(thresholds: str) -> str:
    """``thresholds`` if it names a reading; ValueError naming the allowed ones otherwise."""
    if thresholds not in THRESHOLD_READINGS:
        raise ValueError(f"thresholds must be one of {', '.join(THRESHOLD_READINGS)}, got {thresholds!r}")
    return thresholds


@lru_cache(maxsize=None)
def load_global_bounds(params_name: str = "thesis-12v28") -> dict:
    """The global bounds of the forcing's terms over the operating envelope (written by
    the repository's threshold-bounds study, docs/diagnosis.md): per observer ``M3``/``M4`` the largest
    value of each sensor term of :data:`H_TERMS` over the envelope (``terms``, [state unit/s], the
    forcing's deviation at ±d̄ of that sensor without the safety factor) and the largest slope of the
    forcing in the observer's own state (``lambda_state_per_s``, Λ of eq. 5.12).
    """
    path = resources.files("marine_fdi_env") / "data" / "diagnosis" / GLOBAL_BOUNDS_FILE
    with path.open() as f:
        data = json.load(f)
    if params_name not in data["params"]:
        raise ValueError(
            f"no global threshold bounds for the parameter set {params_name!r} (have: {', '.join(data['params'])}); "
            "python -m studies.diagnosis.threshold_bounds computes them"
        )
    return data["params"][params_name]


def threshold_array(thresholds: str, params_name: str = "thesis-12v28") -> np.ndarray:
    """The kernel's (3, N_THR_COLS) array of a reading (rows M1, M3, M4; see the column comment)."""
    check_thresholds(thresholds)
    a = np.zeros((3, N_THR_COLS))
    a[:, : len(H_TERMS)] = 1.0
    if thresholds == "local":
        return a
    bounds = load_global_bounds(params_name)
    if thresholds in ("thesis-lipschitz", "thesis-no-interconnection"):
        for obs in ("M3", "M4"):
            row = _ROWS[obs]
            inter = [t for t in H_TERMS if t not in OWN_TERMS[obs]]
            for t in inter:
                if not (t == "corner" and thresholds == "thesis-lipschitz"):
                    a[row, H_TERMS.index(t)] = 0.0
            if thresholds == "thesis-lipschitz":
                a[row, 7] = sum(bounds[obs]["terms"][t] for t in inter if t in SENSOR_TERMS)
    if thresholds in _CLOSED_FORM:
        for obs in _CLOSED_FORM[thresholds]:
            row = _ROWS[obs]
            k = TABLE_6_1[obs]
            a[row, 8] = 1.0
            a[row, 9:13] = (k.rho, k.xi_per_s, k.rho_d, k.xi_d_per_s)
            if obs != "M1":  # Σ1's forcing reads the known input only (Λ = 0, no λ_h term)
                b = bounds[obs]
                a[row, 13] = b["lambda_state_per_s"]
                a[row, 14] = sum(v for t, v in b["terms"].items() if t != STATE_TERM[obs])
            a[row, 15] = 1.0 / k.rho  # x̄ = d̄/ρ (see the module docstring)
    return a


@jit
def closed_form(t, dbar, w):
    """Eq. 5.10-5.12 in closed form at time t [s] since the observer started, with the constants of
    one row ``w`` of :func:`threshold_array` (ρ, ξ, ρ_d, ξ_d, Λ, λ_h d̄_χ, x̄/d̄ in columns 9-15):
    E(t) + ρ Λ ∫₀ᵗ E(τ) e^{-ξ(t-τ)} dτ + d̄ with E(t) = ρ e^{-ξt} x̄ + K (1 - e^{-ξ_d t}),
    K = (ρ_d d̄ + ρ λ_h d̄_χ)/ξ (the kernel's ``thesis-table-6.1`` thresholds)."""
    rho, xi, rho_d, xi_d, lam, hbar = w[9], w[10], w[11], w[12], w[13], w[14]
    xbar = w[15] * dbar
    K = (rho_d * dbar + rho * hbar) / xi
    e = math.exp(-xi * t)
    ed = math.exp(-xi_d * t)
    E = rho * e * xbar + K * (1.0 - ed)
    integral = rho * xbar * t * e + K * (1.0 - e) / xi  # ∫₀ᵗ E(τ) e^{-ξ(t-τ)} dτ
    if abs(xi - xi_d) > 1e-12 * xi:
        integral -= K * (ed - e) / (xi - xi_d)
    else:
        integral -= K * t * e
    return E + rho * lam * integral + dbar


def closed_form_threshold(t: float, dbar: float, rho, xi, rho_d, xi_d, lam, hbar, xbar_rel) -> float:
    """:func:`closed_form` with its constants given one by one (x̄ = ``xbar_rel`` d̄, ``hbar`` = λ_h d̄_χ)."""
    w = np.zeros(N_THR_COLS)
    w[9:16] = (rho, xi, rho_d, xi_d, lam, hbar, xbar_rel)
    return float(closed_form(float(t), float(dbar), w))
