"""The numeric fields of a measured-data sidecar (``FILE.meta.json``), checked by name before the
validation reads them, so that a bad value is one line naming the file and the field."""

from __future__ import annotations

import json
import math
from pathlib import Path

from ..errors import DataFileError

__all__ = ["NUMERIC_FIELDS", "check_sidecar_numbers"]

# field -> unit, as the sidecar format defines them (marine_fdi_env.validation.measured.dataset; docs/measured_data.md)
NUMERIC_FIELDS = {
    "ambient_pressure_bar": "bar",
    "ambient_pressure_Pa": "Pa",
    "ambient_temperature_C": "°C",
    "ambient_temperature_K": "K",
    "charge_air_coolant_temperature_C": "°C",
    "rated_power_kW": "kW",
}


def check_sidecar_numbers(data: str) -> None:
    """Raise :class:`DataFileError` when the sidecar of the CSV ``data`` holds a numeric field (at the
    top level or under ``"ambient"``) that is not a finite number.  A missing or unreadable sidecar is
    left to the validation's own checks."""
    csv = Path(data)
    if not csv.is_file():
        return
    side = csv.with_name((csv.name[:-4] if csv.name.endswith(".csv") else csv.name) + ".meta.json")
    try:
        meta = json.loads(side.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return
    if not isinstance(meta, dict):
        return
    places = [("", meta)] + ([("ambient.", meta["ambient"])] if isinstance(meta.get("ambient"), dict) else [])
    for prefix, fields in places:
        for name, unit in NUMERIC_FIELDS.items():
            if name not in fields:
                continue
            v = fields[name]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise DataFileError(f"{side}: field {prefix + name!r} must be a finite number in {unit}, got {v!r}")
