"""Reading a user-given JSON file with an error that names the file and what it should have been."""

from __future__ import annotations

import json
from pathlib import Path

__all__ = ["read_json"]


def read_json(path: "str | Path", what: str):
    """The parsed JSON of ``path``; ``ValueError("PATH: not a readable WHAT (reason)")`` otherwise."""
    try:
        return json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        raise ValueError(f"{path}: not a readable {what} ({e})") from None
