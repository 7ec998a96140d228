"""Cylinder and crank geometry: effective compression and expansion ratios (eq. B.1-B.8).

Correction of the thesis: eq. B.4 defines ``r_tg`` with ``sin(alpha_IC)`` and uses it in both
B.1 (exhaust open) and B.2 (inlet close).  The piston position at a crank angle alpha depends on
``sqrt(1 - lambda_CR^2 sin^2 alpha)`` of *that* angle, so B.1 uses ``alpha_EO``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["CylinderGeometry", "cylinder_geometry", "cylinder_space_length"]


@dataclass(frozen=True)
class CylinderGeometry:
    """Derived geometry of one cylinder.

    r_c : effective compression ratio V_IC / V_TDC (eq. B.6).
    r_eo : ratio of the volume at exhaust opening to the volume at inlet closure (eq. B.5).
    swept_volume_m3 : displacement per cylinder.
    V_IC_m3 : cylinder volume at inlet closure (Seiliger point 1) from the geometry.
    """

    r_c: float
    r_eo: float
    swept_volume_m3: float
    V_IC_m3: float


def cylinder_space_length(stroke_m: float, crank_rod_m: float, eps_c: float, alpha_deg: float) -> float:
    """Length of the gas space above the piston at crank angle alpha after TDC (eq. B.1/B.2)."""
    lam = stroke_m / (2.0 * crank_rod_m)  # eq. B.3
    a = math.radians(alpha_deg)
    r_tg = math.sqrt(1.0 - lam**2 * math.sin(a) ** 2)  # eq. B.4, at the angle in question
    return stroke_m * (1.0 / (eps_c - 1.0) + 0.5 * (1.0 - math.cos(a) + (1.0 - r_tg) / lam))


def cylinder_geometry(
    bore_m: float, stroke_m: float, crank_rod_m: float, eps_c: float, alpha_IC_deg: float, alpha_EO_deg: float
) -> CylinderGeometry:
    """Effective compression ratio and exhaust-open ratio of the six-point Seiliger cycle (eq. B.1-B.8)."""
    L_IC = cylinder_space_length(stroke_m, crank_rod_m, eps_c, alpha_IC_deg)
    L_EO = cylinder_space_length(stroke_m, crank_rod_m, eps_c, alpha_EO_deg)
    L_BDC = eps_c * stroke_m / (eps_c - 1.0)  # eq. B.8
    x_c = L_IC / L_BDC  # eq. B.7
    r_c = (eps_c - 1.0) * x_c + 1.0  # eq. B.6
    r_eo = L_EO / L_IC  # eq. B.5
    area = math.pi / 4.0 * bore_m**2
    return CylinderGeometry(r_c=r_c, r_eo=r_eo, swept_volume_m3=area * stroke_m, V_IC_m3=area * L_IC)
