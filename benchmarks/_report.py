"""Shared output of the benchmark scripts: one JSON object, or one aligned line per metric."""

from __future__ import annotations

import json

from marine_fdi_env import coldstart

coldstart.enable("benchmark")  # one line when numba compiles a cold cache (the timings exclude it)


def emit(out: dict, as_json: bool) -> None:
    if as_json:
        print(json.dumps(out))
        return
    width = max(len(k) for k in out) + 2
    for k, v in out.items():
        print(f"{k:{width}s} {v}")
