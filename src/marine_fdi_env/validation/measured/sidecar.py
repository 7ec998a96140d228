"""The sidecar ``FILE.meta.json`` of a measured-data file, whatever the file's format: where it is, how it is read,
and the type of its numeric fields.

The keys and what they mean: :mod:`.dataset` and docs/measured_data.md.  :func:`read_sidecar` only reads: a
missing sidecar is ``(None, None)``, one that is no JSON object is ``(None, why)``, and :mod:`.checks` decides what
either means (an error, or a warning when the caller names the engine).  :func:`check_numbers` refuses a numeric
field that is not a finite number with one line naming the sidecar and the field.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, Mapping

from ...errors import DataFileError

__all__ = ["NUMERIC_FIELDS", "sidecar_path", "read_sidecar", "check_numbers"]

#: the sidecar's numeric fields (at the top level or under "ambient") and their units
NUMERIC_FIELDS = {
    "ambient_pressure_bar": "bar",
    "ambient_pressure_Pa": "Pa",
    "ambient_temperature_C": "°C",
    "ambient_temperature_K": "K",
    "charge_air_coolant_temperature_C": "°C",
    "rated_power_kW": "kW",
}


def sidecar_path(path: str | Path, stem: str) -> Path:
    """``STEM.meta.json`` beside ``path`` (``stem``: the file's name without its format's ending)."""
    return Path(path).with_name(f"{stem}.meta.json")


def read_sidecar(path: Path) -> tuple[dict[str, Any] | None, str | None]:
    """``(the sidecar's JSON object, None)``; ``(None, None)`` when there is no such file; ``(None, why)`` when it
    cannot be used."""
    try:
        content = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        return None, None
    except json.JSONDecodeError as e:
        return None, f"sidecar {path.name} is not valid JSON: {e}"
    except UnicodeDecodeError:
        return None, f"sidecar {path.name} is not UTF-8 text; save it as UTF-8"
    except IsADirectoryError:
        return None, f"sidecar {path.name} is a folder, not a JSON file"
    if not isinstance(content, dict):
        return None, f"sidecar {path.name} must hold a JSON object"
    return content, None


def check_numbers(meta: Mapping[str, Any], name: str) -> None:
    """Raise :class:`DataFileError` when a numeric field of the sidecar ``name`` (at the top level or under
    ``"ambient"``) is not a finite number."""
    places = [("", meta)] + ([("ambient.", meta["ambient"])] if isinstance(meta.get("ambient"), Mapping) else [])
    for prefix, fields in places:
        for field, unit in NUMERIC_FIELDS.items():
            if field not in fields:
                continue
            v = fields[field]
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
                raise DataFileError(f"{name}: field {prefix + field!r} must be a finite number in {unit}, got {v!r}")
