"""``python -m marine_fdi_env.info [--imports]``: facts about the installed package, and the check of its layers."""

from __future__ import annotations

import importlib.util
import sys

from .._version import __version__
from ..layers import PACKAGE, check_imports, package_roots, print_imports
from .common import CommandParser, parse_cli


def _summary() -> None:
    roots = package_roots()
    print(f"{PACKAGE} {__version__} (python {sys.version.split()[0]})")
    for name, root in roots.items():
        print(f"  {name:<26} {root}")
    extras = {"plots": "matplotlib", "train": "torch", "parquet": "pyarrow", "ray": "ray"}
    have = [f"{k} ({m})" for k, m in extras.items() if importlib.util.find_spec(m) is not None]
    miss = [f"{k} ({m})" for k, m in extras.items() if importlib.util.find_spec(m) is None]
    print(f"  extras installed: {', '.join(have) or 'none'}")
    if miss:
        print(f"  extras missing:   {', '.join(miss)}  (pip install 'marine-fdi-env[EXTRA]')")


def info_main(argv=None) -> int:
    ap = CommandParser(
        prog="python -m marine_fdi_env.info",
        description="Facts about the installed package, and the check of its layers.",
    )
    ap.add_argument(
        "--imports",
        action="store_true",
        help="check the import layers and circles of the package (exit 1 on a violation)",
    )
    ap.add_argument("-v", "--verbose", action="store_true", help="with --imports: list every import")
    args, code = parse_cli(ap, argv)
    if args is None:
        return code
    if args.imports:
        return print_imports(check_imports(), verbose=args.verbose)
    _summary()
    return 0
