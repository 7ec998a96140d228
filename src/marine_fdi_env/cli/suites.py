"""``marine-fdi suites``: the frozen evaluation suites, their size and what each holds."""

from __future__ import annotations

import json

from ..benchmark.suites import SUITE_NAMES, load_suite
from .common import CommandParser, add_json_option, parse_cli

__all__ = ["suites_main"]


def suites_main(argv=None) -> int:
    ap = CommandParser(
        prog="marine-fdi suites",
        description="List the frozen evaluation suites "
        "('marine-fdi evaluate --suite NAME'): name, episodes, description.",
    )
    add_json_option(ap)
    args, code = parse_cli(ap, argv)
    if args is None:
        return code
    rows = []
    for n in SUITE_NAMES:
        s = load_suite(n)
        rows.append({"name": n, "episodes": len(s.scenarios), "description": s["description"]})
    if args.json:
        print(json.dumps(rows, indent=2))
        return 0
    for r in rows:
        print(f"{r['name']:14s} {r['episodes']:4d} episodes  {r['description']}")
    return 0
