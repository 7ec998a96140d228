"""tests/validation_reports.py, the before/after check of the shipped validation reports: what it leaves out (the
run's time, paths, date and command) and that it finds any other difference."""

from __future__ import annotations

import json

from tests.validation_reports import compare


def _write(folder, report, md="# r\n"):
    folder.mkdir()
    (folder / "r.json").write_text(json.dumps(report))
    (folder / "r.md").write_text(md)


def test_the_run_is_left_out_the_result_is_not(tmp_path):
    rep = {
        "seconds": 12.5,
        "dataset": {"name": "d", "path": "/a/d.csv"},
        "cv": {"score": 1.5},
        "explanation_rule": {"seconds": 3.0, "band": 2.0},
        "fitted_engine": {"provenance": {"date": "2026-11-28", "command": "validate --out /a/r.json", "x": 1}},
    }
    _write(tmp_path / "a", rep)
    other = json.loads(json.dumps(rep))
    other["seconds"], other["dataset"]["path"], other["explanation_rule"]["seconds"] = 99.0, "/b/d.csv", 4.0
    other["fitted_engine"]["provenance"].update(date="2026-11-29", command="validate --out /b/r.json")
    _write(tmp_path / "b", other)
    assert compare(tmp_path / "a", tmp_path / "b") == []
    other["cv"]["score"] = 1.5000000000000002
    other["fitted_engine"]["provenance"]["x"] = 2
    _write(tmp_path / "c", other, md="# r \n")
    found = compare(tmp_path / "a", tmp_path / "c")
    assert any("/cv/score" in f for f in found) and any("/fitted_engine/provenance/x" in f for f in found)
    assert "r.md: the Markdown differs" in found
