"""Turbocharger rotor speed: an output of the model (the thesis model has no rotor-speed state).

Law: a constant isentropic head coefficient of the compressor, ``Δh_c,is = ψ u²`` with the tip speed
``u ∝ N``, so ``N = N_nom sqrt(Δh_c,is / Δh_c,is,nom)`` with
``Δh_c,is = c_p,a T_amb ((x4/p_amb)^((κa-1)/κa) - 1)`` (compressor inlet at the ambient state, outlet at
the charge-air pressure; the cooler's pressure drop is neglected).  ``N_tc_nom_rpm`` and
``dh_c_nom_J_per_kg`` are one calibration point of the parameter set (:mod:`marine_fdi_env.engine.calibration`,
step 8).

Evidence for the law: on the Birka ME1 protocol, Δh_c,is / N² computed from the measured charge-air
pressure, ambient pressure and compressor-inlet temperature varies by ±2.6 % over the six loads
(25-110 %), so the law predicts the measured speed within about 1.5 % from the 100 % calibration point
(``tests/unit/test_submodels.py``, ``test_turbocharger_speed_law_on_the_protocol``).
"""

from __future__ import annotations

import numpy as np

from .params import EngineParams

__all__ = ["isentropic_compressor_head", "turbocharger_speed_rpm"]


def isentropic_compressor_head(p_out_Pa, p_in_Pa, T_in_K, c_p: float = 1005.0, kappa: float = 1.4) -> np.ndarray:
    """Δh_c,is = c_p T_in ((p_out/p_in)^((κ-1)/κ) - 1) [J/kg] (pressure ratio clipped at 1)."""
    pi = np.maximum(np.asarray(p_out_Pa, float) / np.asarray(p_in_Pa, float), 1.0)
    return c_p * np.asarray(T_in_K, float) * (pi ** ((kappa - 1.0) / kappa) - 1.0)


def turbocharger_speed_rpm(params: EngineParams, charge_air_pressure_Pa, p_amb_Pa=None, T_amb_K=None) -> np.ndarray:
    """Rotor speed [rpm] at charge-air pressure x4 (ambient of ``params`` unless given)."""
    p_amb = params.p_amb_Pa if p_amb_Pa is None else p_amb_Pa
    T_amb = params.T_amb_K if T_amb_K is None else T_amb_K
    dh = isentropic_compressor_head(charge_air_pressure_Pa, p_amb, T_amb, params.c_p_a_J_per_kgK, params.kappa_a)
    return params.N_tc_nom_rpm * np.sqrt(dh / params.dh_c_nom_J_per_kg)
