"""The operating envelope of a real engine: the bounds a steady state of the model can fall outside of at
very low or very high fuel settings, and beyond which a measured reading is not a steady operating point
(the measured-data checks of :mod:`marine_fdi_env.validation` read the same :data:`ENVELOPE`).

* Speed: a medium-speed four-stroke diesel runs stably from about a quarter of its rated speed
  (idle) up to 115 % of it: its speed governor must keep it within 15 % above the rated speed (IACS
  UR M3.1.1; the separate overspeed trip acts at up to 120 %); outside that band the mean-value model
  is extrapolating.
* Brake power: a shop test runs up to the 110 % overload; no engine delivers more than about 115 % of
  its rated power at a steady point.
* Specific fuel consumption: no diesel engine converts fuel to brake work at more than about 55 %
  (150 g/kWh with 42.7 MJ/kg fuel), and above about 350 g/kWh (24 %) it is idling or barely
  loaded, where the model's combustion and friction laws are not calibrated.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["Envelope", "ENVELOPE", "envelope_warnings"]


@dataclass(frozen=True)
class Envelope:
    """Plausibility bounds of a steady state: speed as a fraction of the rated speed [-], brake power as a
    fraction of the rated power [-], brake specific fuel consumption [g/kWh]."""

    min_speed_fraction: float = 0.25
    max_speed_fraction: float = 1.15
    max_power_fraction: float = 1.15
    min_sfc_g_per_kWh: float = 150.0
    max_sfc_g_per_kWh: float = 350.0


ENVELOPE = Envelope()


def envelope_warnings(
    speed_rev_s: float, sfc_kg_per_J: float, rated_speed_rev_s: float, envelope: Envelope = ENVELOPE
) -> list[str]:
    """One sentence per bound a steady state violates (empty when it is inside the envelope)."""
    out = []
    frac = speed_rev_s / rated_speed_rev_s
    rpm, rated_rpm = 60.0 * speed_rev_s, 60.0 * rated_speed_rev_s
    if frac < envelope.min_speed_fraction:
        out.append(
            f"engine speed {rpm:.0f} rpm is below {envelope.min_speed_fraction:.0%} of the rated "
            f"{rated_rpm:.0f} rpm: below the engine's stable speed range"
        )
    elif frac > envelope.max_speed_fraction:
        out.append(
            f"engine speed {rpm:.0f} rpm is above {envelope.max_speed_fraction:.0%} of the rated "
            f"{rated_rpm:.0f} rpm: beyond the overspeed limit"
        )
    sfc = sfc_kg_per_J * 3.6e9
    if math.isfinite(sfc) and not envelope.min_sfc_g_per_kWh <= sfc <= envelope.max_sfc_g_per_kWh:
        out.append(
            f"specific fuel consumption {sfc:,.0f} g/kWh is outside the plausible "
            f"{envelope.min_sfc_g_per_kWh:.0f}-{envelope.max_sfc_g_per_kWh:.0f} g/kWh of a diesel engine"
        )
    return out
