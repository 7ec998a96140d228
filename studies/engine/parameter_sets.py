"""Rewrite the shipped parameter sets from their input tables (:mod:`marine_fdi_env.engine.calibration`).

    python -m studies.engine.parameter_sets

``tests/unit/test_params.py`` checks that the shipped files match what this writes.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from marine_fdi_env.engine.calibration import write_parameter_sets
from studies.paths import PACKAGE_DATA


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m studies.engine.parameter_sets", description=__doc__.splitlines()[0])
    ap.add_argument("--out-dir", type=Path, default=PACKAGE_DATA / "params", help="where to write NAME.json")
    args = ap.parse_args(argv)
    for path in write_parameter_sets(args.out_dir):
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
