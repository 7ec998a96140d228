"""Rebuild the frozen evaluation suites from their builders (:func:`marine_fdi_env.benchmark.suites.build_suite`).

    python -m studies.benchmark.build_suites [NAME ...]   # default: every shipped suite

A frozen suite changes only with a new version (a new name); the tests check that the shipped files
equal their builders' output.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from marine_fdi_env.benchmark.suites import SUITE_NAMES, build_suite
from studies.paths import PACKAGE_DATA


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m studies.benchmark.build_suites", description=__doc__.splitlines()[0])
    ap.add_argument("names", nargs="*", help=f"suites to build (default: all of {', '.join(SUITE_NAMES)})")
    ap.add_argument("--out-dir", type=Path, default=PACKAGE_DATA / "suites")
    args = ap.parse_args(argv)
    args.out_dir.mkdir(parents=True, exist_ok=True)
    for n in args.names or SUITE_NAMES:
        data = build_suite(n)
        (args.out_dir / f"{n}.json").write_text(json.dumps(data, indent=1) + "\n")
        print(f"wrote {args.out_dir / (n + '.json')} ({len(data['scenarios'])} scenarios)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
