"""``marine-fdi replicas``: would the pipeline name the same causes again on data like these?"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Sequence

from ..errors import UsageError
from ..validation.fit.mechanisms import PHYSICAL_MECHANISMS
from ..validation.fit.problem import FitProblem
from ..validation.measured.loader import load_data_arg
from ..validation.select.replicas import NOISE_MODELS, markdown_table, replicate
from ..validation.select.selection import select_causes
from .common import CommandParser, add_progress_option, parse_cli
from .failures import fail
from .selection_options import add_valve_options, rules_from_args


def replicas_main(argv: Sequence[str] | None = None) -> int:
    ap = CommandParser(
        prog="marine-fdi replicas",
        description="Would the pipeline name the same causes again on data like these? "
        "(a parametric bootstrap at the data's design; module docstring)",
    )
    ap.add_argument(
        "--data", required=True, metavar="NAME|FILE", help="shipped dataset name or data file (as marine-fdi validate)"
    )
    ap.add_argument("--params", default=None, help="parameter set or engine file (default: the dataset's)")
    ap.add_argument("--target", default="auto", help="what fixes each point (as marine-fdi validate)")
    ap.add_argument("--replicas", type=int, default=10, help="replicas per hypothesis (default 10)")
    ap.add_argument("--noise", default="residual", choices=NOISE_MODELS, help="replica noise (default residual)")
    ap.add_argument(
        "--alternatives",
        default=None,
        metavar="ID,...",
        help="physical mechanisms to put in place of the first named one (default: the best --top of "
        "the first selection step)",
    )
    ap.add_argument("--top", type=int, default=4, help="number of alternatives by default (default 4)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--max-folds", type=int, default=None, help="as marine-fdi validate")
    ap.add_argument("--workers", type=int, default=1, help="processes (default 1)")
    ap.add_argument("--out", default=None, metavar="FILE.json")
    ap.add_argument("--markdown", default=None, metavar="FILE.md")
    ap.add_argument(
        "--tolerance",
        action="append",
        default=[],
        metavar="COLUMN=VALUE",
        help="a channel's tolerance in its units or as P%% of its mean value (as marine-fdi validate)",
    )
    add_valve_options(ap)
    add_progress_option(ap)
    args, code = parse_cli(ap, list(argv) if argv is not None else None)
    if args is None:
        return code
    alts = None if args.alternatives is None else [a.strip() for a in args.alternatives.split(",") if a.strip()]
    try:
        if args.top < 0:
            raise ValueError(f"--top must be >= 0, got {args.top}")
        if args.replicas < 1 or args.workers < 1:
            raise ValueError("--replicas and --workers must be >= 1")
        known = {m.id for m in PHYSICAL_MECHANISMS}
        if alts is not None and not set(alts) <= known:  # before the selection's minutes, not after
            raise ValueError(
                f"--alternatives: unknown physical mechanism(s) {', '.join(sorted(set(alts) - known))}; "
                f"known: {', '.join(sorted(known))}"
            )
        rules = rules_from_args(args)
        try:
            ds = load_data_arg(args.data, args.params)
        except ValueError as e:
            raise UsageError(f"--data: {e}") from None
        pr = FitProblem(ds, params=args.params, target=args.target, held_out_valves=rules.held_out_valves)
        if args.tolerance:
            pr = FitProblem(
                ds,
                params=args.params,
                target=args.target,
                tolerances=pr.stated_tolerances(args.tolerance),
                held_out_valves=rules.held_out_valves,
            )
        say = None if args.no_progress else (lambda s: print(f"replicas: {s}", file=sys.stderr))
        if say:
            say("selecting causes on the data (as marine-fdi validate)")
        sel = select_causes(pr, rules=rules)
        if say:
            say(f"named on the data: {' + '.join(sel.selected_labels) or '(nothing)'}")
        rep = replicate(
            sel,
            replicas=args.replicas,
            noise=args.noise,
            seed=args.seed,
            alternatives=alts,
            top=args.top,
            workers=args.workers,
            progress=not args.no_progress,
        )
    except ValueError as e:
        return fail("marine-fdi replicas", e)
    table = markdown_table(rep)
    print(table)
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(json.dumps(rep, indent=1, default=float) + "\n")
    if args.markdown:
        Path(args.markdown).parent.mkdir(parents=True, exist_ok=True)
        Path(args.markdown).write_text(table + "\n")
    return 0
