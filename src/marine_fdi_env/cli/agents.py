"""``marine-fdi agents``: the agents known by name (baselines and shipped models)."""

from __future__ import annotations

import json

from .common import CommandParser, add_json_option
from .failures import fail

__all__ = ["agents_main"]


def agents_main(argv=None) -> int:
    from ..benchmark.agent_registry import TRAIN_EXTRA_HINT, list_agents
    from .common import parse_cli

    ap = CommandParser(
        prog="marine-fdi agents",
        description="List the agents that 'marine-fdi evaluate --agent NAME' and 'marine-fdi sweep --agents' know by "
        "name: the baselines and every shipped model (a folder of training/models/). Any other agent: "
        "a model folder by path, or path/to/file.py:ClassName (docs/agent_api.md).",
    )
    add_json_option(ap)
    args, code = parse_cli(ap, argv)
    if args is None:
        return code
    try:
        entries = list_agents()
    except ValueError as e:
        return fail("marine-fdi agents", e)
    if args.json:
        print(json.dumps([e.to_dict() for e in entries], indent=2))
        return 0
    w = max(len(e.name) for e in entries)
    for e in entries:
        note = "" if e.available else f"  [needs {', '.join(e.needs)}: {TRAIN_EXTRA_HINT}]"
        alias = f" (also: {', '.join(e.aliases)})" if e.aliases else ""
        print(f"{e.name:<{w}}  {e.kind:<8}  {e.description}{alias}{note}")
    print(f"{len(entries)} agents ({sum(e.kind == 'model' for e in entries)} shipped models)")
    return 0
