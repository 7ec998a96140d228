"""Shared output of the benchmark scripts: one JSON object, or one aligned line per metric."""

from __future__ import annotations

import json


def emit(out: dict, as_json: bool) -> None:
    if as_json:
        print(json.dumps(out))
        return
    width = max(len(k) for k in out) + 2
    for k, v in out.items():
        print(f"{k:{width}s} {v}")
