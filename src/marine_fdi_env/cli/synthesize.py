"""``marine-fdi synthesize-measurements``: 'measured' data from the model with hidden mechanisms."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Sequence

from ..engine.params import list_parameter_sets
from ..validation.fit.mechanisms import MECHANISM_IDS, parse_mechanism_spec
from ..validation.fit.synthesize import DEFAULT_COLUMNS, LOAD_RANGE, synthesize
from .common import CommandParser, run_parsed
from .failures import fail


def build_parser(prog: str = "marine-fdi synthesize-measurements") -> argparse.ArgumentParser:
    ap = CommandParser(
        prog=prog,
        description="Write synthetic measured data from the model with hidden mechanisms.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="mechanisms: none, " + ", ".join(MECHANISM_IDS) + "\n"
        "  e.g. --mechanism turbocharger_map:eta_scale=1.1,curvature=0.1 --mechanism waste_gate:above=0.8\n"
        "  sensor_calibration:channel=turbine_outlet_temperature_C,gain=1.05,offset=-3\n"
        "parameters not given are drawn from the mechanism's range with the seed.",
    )
    ap.add_argument("--params", required=True, help="parameter set (" + ", ".join(list_parameter_sets()) + ")")
    ap.add_argument(
        "--mechanism",
        action="append",
        default=None,
        metavar="ID[:param=value,...]",
        help="hidden mechanism (repeatable; default none)",
    )
    ap.add_argument("--points", type=int, default=8, help="operating points (per engine), default 8")
    ap.add_argument("--noise", type=float, default=0.01, help="relative measurement noise, default 0.01")
    ap.add_argument(
        "--noise-model",
        default="typical",
        choices=("typical", "reading"),
        help="noise relative to the channel's typical value (default) or to each reading",
    )
    ap.add_argument("--perturb", type=float, default=0.0, help="relative model error of the true engine, default 0")
    ap.add_argument("--seed", type=int, default=0, help="random seed, default 0")
    ap.add_argument(
        "--load-range",
        default=f"{LOAD_RANGE[0]},{LOAD_RANGE[1]}",
        metavar="LO,HI",
        help="load fractions are drawn uniformly in [LO, HI], default %(default)s",
    )
    ap.add_argument(
        "--columns",
        default=None,
        metavar="COL,COL,...",
        help="columns to write (default: " + ",".join(DEFAULT_COLUMNS) + ")",
    )
    ap.add_argument("--engines", type=int, default=0, help="K > 0: K engines E1..EK at the same load points")
    ap.add_argument("--truth", default=None, metavar="FILE.json", help="also write the hidden truth here")
    ap.add_argument("--out", required=True, metavar="FILE.csv", help="output CSV (sidecar FILE.meta.json beside it)")
    return ap


def synthesize_main(argv: Sequence[str] | None = None, prog: str = "marine-fdi synthesize-measurements") -> int:
    """Command line: returns 0 on success, 2 on bad input (message on stderr)."""
    return run_parsed(build_parser, run, argv, prog)


def run(args: argparse.Namespace, argv: Sequence[str], prog: str = "marine-fdi synthesize-measurements") -> int:
    """``marine-fdi synthesize-measurements`` with its parsed options."""
    try:
        try:
            lo, hi = (float(x) for x in args.load_range.split(","))
        except ValueError:
            raise ValueError(f"--load-range must be LO,HI, got {args.load_range!r}") from None
        columns = (
            DEFAULT_COLUMNS if args.columns is None else tuple(c.strip() for c in args.columns.split(",") if c.strip())
        )
        parsed = []
        for s in args.mechanism or ["none"]:
            try:
                parsed.append(parse_mechanism_spec(s))
            except ValueError as e:
                raise ValueError(f"--mechanism {s!r}: {e}") from None
        out = Path(args.out)
        if not out.name.endswith(".csv"):
            raise ValueError(f"--out must name a .csv file, got {args.out!r}")
        if not out.parent.parent.exists():
            raise ValueError(f"--out: directory {str(out.parent.parent)!r} does not exist")
        syn = synthesize(
            args.params,
            parsed,
            points=args.points,
            noise=args.noise,
            seed=args.seed,
            columns=columns,
            load_range=(lo, hi),
            engines=args.engines,
            noise_model=args.noise_model,
            perturb=args.perturb,
        )
        out.parent.mkdir(exist_ok=True)
        syn.write(out, args.truth)
    except ValueError as e:
        return fail(prog, e)
    n = len(next(iter(syn.columns.values())))
    print(
        f"wrote {out} ({n} points, {len(syn.columns)} columns) and {out.name[:-4]}.meta.json"
        + (f"; truth in {args.truth}" if args.truth else "")
    )
    return 0
