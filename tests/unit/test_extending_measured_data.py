"""docs/extending.md, "Add a measured-data format": the recipe's Python blocks run as written, in a fresh folder, and
the reader they define gives what the CSV reader gives for the same readings, findings included."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

from marine_fdi_env.validation import DatasetError, DataWarning, load_measured
from tests.paths import ROOT

DOC = ROOT / "docs" / "extending.md"
SECTION = "## Add a measured-data format"


def recipe_blocks() -> list[str]:
    """The Python blocks of the recipe's section, in order."""
    text = DOC.read_text(encoding="utf-8")
    start = text.index(SECTION)
    nxt = text.find("\n## ", start + len(SECTION))
    section = text[start : nxt if nxt >= 0 else len(text)]
    return re.findall(r"^```python\n(.*?)^```", section, flags=re.S | re.M)


@pytest.fixture
def recipe(tmp_path, monkeypatch, capsys):
    """The namespace after running the recipe's blocks in ``tmp_path``, and what they printed."""
    monkeypatch.chdir(tmp_path)
    ns: dict = {"__name__": "recipe"}
    with warnings.catch_warnings():
        warnings.simplefilter("error", DataWarning)  # the recipe's file loads without a warning
        for block in recipe_blocks():
            exec(compile(block, str(DOC), "exec"), ns)
    return ns, capsys.readouterr().out


def test_the_recipe_runs_and_its_reader_is_about_thirty_lines(recipe):
    ns, out = recipe
    assert len(recipe_blocks()) == 2
    assert len(recipe_blocks()[0].strip().splitlines()) <= 30
    assert out.startswith("shop_test: 4 points")
    ds = ns["ds"]
    assert ds.name == "shop_test" and ds.params_name == "wartsila-6l46" and ds.load_law == "propeller"
    np.testing.assert_array_equal(ds.raw["fuel_flow_kg_per_h"], [304.8, 587.2, 838.5, 1141.0])


def test_the_recipes_reader_gives_what_the_csv_reader_gives(recipe, tmp_path):
    ns, _ = recipe
    reader = ns["SemicolonReader"]()
    (tmp_path / "same.csv").write_text((tmp_path / "shop_test.ssv").read_text().replace(",", ".").replace(";", ","))
    (tmp_path / "same.meta.json").write_text((tmp_path / "shop_test.meta.json").read_text())
    a, b = ns["ds"], load_measured(tmp_path / "same.csv")
    assert a.columns == b.columns and a.warnings == b.warnings and a.quality == b.quality
    for q in a.values:
        np.testing.assert_array_equal(a.values[q], b.values[q])
    # a bad cell: the same finding, named by row and column, whatever the format
    (tmp_path / "bad.ssv").write_text("load_fraction;speed_rpm\n0,25;315\n0,5;fast\n")
    (tmp_path / "bad.csv").write_text("load_fraction,speed_rpm\n0.25,315\n0.5,fast\n")
    (tmp_path / "bad.meta.json").write_text((tmp_path / "shop_test.meta.json").read_text())
    found = []
    for path, r in ((tmp_path / "bad.ssv", reader), (tmp_path / "bad.csv", None)):
        with pytest.raises(DatasetError) as ei:
            load_measured(path, reader=r)
        found.append([str(p) for p in ei.value.problems])
    assert found[0] == found[1]
    assert "row 2 (line 3), column 'speed_rpm': non-numeric value 'fast'" in found[0]
