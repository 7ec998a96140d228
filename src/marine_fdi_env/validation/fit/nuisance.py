"""Model-error nuisance: the base model's uncertain parameters, fitted within their uncertainty.

No parameter set is exact.  The efficiencies, areas and heat fractions of a sibling engine's set are
scaled or derived from the thesis engine (:mod:`marine_fdi_env.engine.calibration`) and are uncertain by a few
per cent.  Every fit, the base model's included, therefore adjusts these parameters within a prior of
``σ`` = 3 % (a Gaussian penalty ``((s - 1)/σ)²`` added to the loss, and a hard box of ±2σ).  They are not
causes and are never *named*; a named mechanism must explain more than model error of this size can.
Without this, the smallest mismatch of the turbine area or the turbocharger efficiency would be
"explained" by a named cause (the open-world study's negative controls with model error measure it).

=============================  =======================================================================
group                          parameters scaled together
=============================  =======================================================================
``turbine_area``               ``A_eff_m2`` (turbine effective area, eq. 3.16)
``turbocharger_efficiency``    ``a/b/c_eta`` and ``a/b/c_turbo`` (η_TC of eq. 3.33 and η_turbo of eq. 3.26)
``compressor_efficiency``      ``eta_com`` (sets the compressor temperature rise per turbine drop, eq. 3.38)
``combustion_efficiency``      ``eta_comb`` (heat released per kg of fuel)
``heat_release_shape``         ``X_cv_nom`` (constant-volume part of the heat release: the peak pressure)
``late_combustion``            ``X_ct_nom`` (constant-temperature part: expansion work and exhaust heat)
=============================  =======================================================================
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["NuisanceGroup", "NUISANCE", "NUISANCE_SIGMA", "scales_of", "prior_residuals", "nuisance_bounds"]

NUISANCE_SIGMA = 0.03


@dataclass(frozen=True)
class NuisanceGroup:
    """Parameters scaled by one nuisance multiplier (prior N(1, sigma²), box 1 ± 2 sigma)."""

    name: str
    fields: tuple[str, ...]
    description: str
    sigma: float = NUISANCE_SIGMA


NUISANCE: tuple[NuisanceGroup, ...] = (
    NuisanceGroup("turbine_area", ("A_eff_m2",), "turbine effective area"),
    NuisanceGroup(
        "turbocharger_efficiency",
        ("a_eta_per_Pa2", "b_eta_per_Pa", "c_eta", "a_turbo", "b_turbo_per_Pa", "c_turbo_per_Pa2"),
        "turbocharger and turbine efficiency",
    ),
    NuisanceGroup("compressor_efficiency", ("eta_com",), "compressor temperature rise per turbine drop"),
    NuisanceGroup("combustion_efficiency", ("eta_comb",), "heat released per kg of fuel"),
    NuisanceGroup("heat_release_shape", ("X_cv_nom",), "constant-volume share of the heat release"),
    NuisanceGroup("late_combustion", ("X_ct_nom",), "constant-temperature share of the heat release"),
)


def scales_of(x) -> dict[str, float]:
    """``{EngineParams field: multiplier}`` of the nuisance vector ``x`` (one multiplier per group)."""
    out: dict[str, float] = {}
    for g, s in zip(NUISANCE, np.asarray(x, float)):
        for f in g.fields:
            out[f] = float(s)
    return out


def prior_residuals(x) -> np.ndarray:
    """``(s - 1) / sigma`` per group: their squares are the prior's penalty."""
    return np.array([(float(s) - 1.0) / g.sigma for g, s in zip(NUISANCE, np.asarray(x, float))])


def nuisance_bounds() -> tuple[np.ndarray, np.ndarray]:
    lo = np.array([1.0 - 2.0 * g.sigma for g in NUISANCE])
    hi = np.array([1.0 + 2.0 * g.sigma for g in NUISANCE])
    return lo, hi
