"""The 19 redundant sensors of thesis table 6.3 (eq. 3.3) with uniformly bounded noise.

Sensor ids follow the thesis's S^(l){j}: ``S<subsystem>.<index>``; odd indices are the primary
sensors, even ones their redundant twins (Σ3 has one turbine-outlet sensor, S3.5).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = [
    "SensorSpec",
    "SENSORS",
    "SENSOR_IDS",
    "sensor_index",
    "N_SENSORS",
    "true_sensor_values",
    "NOISE_BOUNDS",
    "DEFAULT_FAULT_MAGNITUDES",
]


@dataclass(frozen=True)
class SensorSpec:
    """One sensor: id, the model variable it reads, unit, noise bound and default offset (table 6.3)."""

    id: str
    variable: str  # attribute of the simulator state: x1, x3, x4 or an Algebraic field
    description: str
    unit: str
    noise_bound: float
    fault_magnitude: float


SENSORS: tuple[SensorSpec, ...] = (
    SensorSpec("S1.1", "x1", "fuel injected per cylinder and cycle", "kg", 4.5e-5, 1.8e-4),
    SensorSpec("S1.2", "x1", "fuel injected per cylinder and cycle (redundant)", "kg", 4.5e-5, 1.8e-4),
    SensorSpec("S2.1", "p6", "cylinder pressure at exhaust opening", "Pa", 2e4, 9e4),
    SensorSpec("S2.2", "p6", "cylinder pressure at exhaust opening (redundant)", "Pa", 2e4, 9e4),
    SensorSpec("S2.3", "T6", "cylinder temperature at exhaust opening", "K", 17.0, 55.0),
    SensorSpec("S2.4", "T6", "cylinder temperature at exhaust opening (redundant)", "K", 17.0, 55.0),
    SensorSpec("S2.5", "torque", "shaft torque", "N m", 0.75e3, 7.125e3),
    SensorSpec("S2.6", "torque", "shaft torque (redundant)", "N m", 0.75e3, 7.125e3),
    SensorSpec("S3.1", "x3", "exhaust receiver pressure", "Pa", 0.99e3, 5e3),
    SensorSpec("S3.2", "x3", "exhaust receiver pressure (redundant)", "Pa", 0.99e3, 5e3),
    SensorSpec("S3.3", "T_in", "turbine inlet temperature", "K", 8.0, 48.0),
    SensorSpec("S3.4", "T_in", "turbine inlet temperature (redundant)", "K", 8.0, 48.0),
    SensorSpec("S3.5", "T_out", "turbine outlet temperature", "K", 6.0, 25.0),
    SensorSpec("S4.1", "x4", "charge-air pressure", "Pa", 5.5e3, 5e4),
    SensorSpec("S4.2", "x4", "charge-air pressure (redundant)", "Pa", 5.5e3, 5e4),
    SensorSpec("S4.3", "T1", "inlet air temperature", "K", 5.0, 22.0),
    SensorSpec("S4.4", "T1", "inlet air temperature (redundant)", "K", 5.0, 22.0),
    SensorSpec("S4.5", "T_co", "compressor outlet temperature", "K", 5.0, 25.0),
    SensorSpec("S4.6", "T_co", "compressor outlet temperature (redundant)", "K", 5.0, 25.0),
)

SENSOR_IDS: tuple[str, ...] = tuple(s.id for s in SENSORS)
N_SENSORS = len(SENSORS)
NOISE_BOUNDS = np.array([s.noise_bound for s in SENSORS])
DEFAULT_FAULT_MAGNITUDES = np.array([s.fault_magnitude for s in SENSORS])
_INDEX = {s: i for i, s in enumerate(SENSOR_IDS)}
# distinct variables and, per sensor, the column of the variable it reads
MEASURED_VARIABLES: tuple[str, ...] = ("x1", "p6", "T6", "torque", "x3", "T_in", "T_out", "x4", "T1", "T_co")
VARIABLE_OF_SENSOR = np.array([MEASURED_VARIABLES.index(s.variable) for s in SENSORS])


def sensor_index(sensor_id: str) -> int:
    """Column of a sensor id; ``ValueError`` naming the allowed ids for an unknown one."""
    try:
        return _INDEX[sensor_id]
    except (KeyError, TypeError):
        raise ValueError(f"unknown sensor {sensor_id!r}; allowed: {', '.join(SENSOR_IDS)}") from None


def true_sensor_values(variables: dict[str, np.ndarray] | None = None, stacked: np.ndarray | None = None) -> np.ndarray:
    """Noise-free readings, shape (n_engines, 19), from the measured variables.

    Pass either a mapping ``{variable: array}`` or ``stacked`` with shape (n_engines, 10) in the
    order of ``MEASURED_VARIABLES``.
    """
    if stacked is None:
        stacked = np.stack([np.asarray(variables[v], dtype=float) for v in MEASURED_VARIABLES], axis=-1)
    return stacked[..., VARIABLE_OF_SENSOR]
