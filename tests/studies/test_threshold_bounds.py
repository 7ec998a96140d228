"""The global bounds the thesis's threshold readings use are what their command computes."""

import json

from marine_fdi_env.diagnosis.thresholds import load_global_bounds
from studies.diagnosis.threshold_bounds import main


def test_the_shipped_global_bounds_are_reproduced_by_their_command(tmp_path):
    out = tmp_path / "bounds.json"
    assert main(["--out", str(out)]) == 0
    data = json.loads(out.read_text())
    assert data["params"]["thesis-12v28"] == load_global_bounds("thesis-12v28")
