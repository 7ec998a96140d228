"""JSON in and out: reading a user-given JSON file with an error that names the file, and the one
conversion of results into what :func:`json.dumps` writes.

Non-finite numbers have three conventions, chosen by each writer with ``nonfinite`` of
:func:`json_safe` (one function, so that a writer says which one it uses):

==========  =====================================================  ==========================================
nonfinite   NaN, +inf, -inf become                                 used by
==========  =====================================================  ==========================================
``"null"``  ``null`` (strict JSON; a reader sees "no value")       reports: validation, diagnose, CLI listings
``"string"``  ``"nan"``, ``"inf"``, ``"-inf"`` (strict JSON, kept)   run-file metadata (:mod:`marine_fdi_env.runio`)
``"keep"``  ``NaN``, ``Infinity``, ``-Infinity`` (Python's JSON)     cache keys and headers (hashed, never parsed
                                                                   by another tool)
==========  =====================================================  ==========================================
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, Literal

import numpy as np

__all__ = ["read_json", "json_safe", "NONFINITE"]

NONFINITE = ("null", "string", "keep")


def read_json(path: "str | Path", what: str):
    """The parsed JSON of ``path``; ``ValueError("PATH: not a readable WHAT (reason)")`` otherwise."""
    try:
        return json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise ValueError(f"{path}: not a readable {what} ({e})") from None


def json_safe(obj: Any, *, nonfinite: Literal["null", "string", "keep"] = "null") -> Any:
    """A copy of ``obj`` that :func:`json.dumps` writes: objects with ``to_dict()`` by that dict,
    mapping keys as strings, tuples and arrays as lists, numpy scalars as Python ones, and non-finite
    floats by the ``nonfinite`` convention (module docstring)."""
    if nonfinite not in NONFINITE:
        raise ValueError(f"nonfinite: {nonfinite!r} is not one of {', '.join(NONFINITE)}")
    return _safe(obj, nonfinite)


def _safe(obj: Any, nonfinite: str) -> Any:
    if isinstance(obj, dict):
        return {str(k): _safe(v, nonfinite) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_safe(v, nonfinite) for v in obj]
    if isinstance(obj, np.ndarray):
        return _safe(obj.tolist(), nonfinite)
    if isinstance(obj, (bool, np.bool_)):
        return bool(obj)
    if isinstance(obj, (int, np.integer)):
        return int(obj)
    if isinstance(obj, (float, np.floating)):
        v = float(obj)
        if math.isfinite(v) or nonfinite == "keep":
            return v
        if nonfinite == "null":
            return None
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf")
    if hasattr(obj, "to_dict"):
        return _safe(obj.to_dict(), nonfinite)
    return obj
