"""Rewrite the shipped parameter sets from their input tables (:mod:`marine_fdi_env.engine.calibration`).

    python -m studies.engine.parameter_sets

``tests/unit/test_params.py`` checks that the shipped files match what this writes.
"""

from __future__ import annotations

from marine_fdi_env.engine.calibration import write_parameter_sets
from studies.paths import PACKAGE_DATA

if __name__ == "__main__":
    for path in write_parameter_sets(PACKAGE_DATA / "params"):
        print(f"wrote {path}")
