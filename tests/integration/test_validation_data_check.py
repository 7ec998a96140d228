"""``marine-fdi validate --check`` and ``--columns``: what the pipeline will do with a file, before any fit.

A user's first contact with the pipeline is their own CSV.  These tests hold the dry run to what it promises:
every column's role, the readings left out, the tolerance of each compared channel and where it comes from,
no report written; and the worked example of docs/measured_data.md loads and names its hidden cause."""

from __future__ import annotations

import json
import re
import shutil

import pytest

from marine_fdi_env.cli.synthesize import synthesize_main
from marine_fdi_env.cli.validate import validate_main
from marine_fdi_env.validation.measured.columns import COLUMNS, GROUP_PATTERNS
from tests.paths import ROOT

EXAMPLE = ROOT / "docs" / "examples" / "measured" / "example_engine.csv"


def _row(out: str, column: str) -> str:
    """The tolerance row of ``column`` (the last line that starts with it)."""
    rows = [ln for ln in out.splitlines() if ln.strip().startswith(column + " ")]
    assert rows, f"no line for {column}"
    return rows[-1]


def test_columns_lists_every_registered_stem_and_group(capsys):
    assert validate_main(["--columns"]) == 0
    out = capsys.readouterr().out
    for spec in COLUMNS.values():
        shown = spec.stem if spec.unit == "-" else spec.stem + "_"
        assert shown in out, spec.column
    for group, (pat, _, units, _) in GROUP_PATTERNS.items():
        assert pat.pattern.strip("^$").split("(")[0] + "<n>" in out, group
    # every accepted unit of a pressure that needs gauge/absolute is listed; plain "bar" only where assumed
    line = next(ln for ln in out.splitlines() if ln.startswith("charge_air_pressure_<unit>"))
    units = out.splitlines()[out.splitlines().index(line) + 1]
    assert "bar_gauge" in units and "bar_abs" in units and not re.search(r"\bbar\b(?!_)", units)


def test_check_the_protocol_says_what_becomes_of_every_column(tmp_path, capsys):
    report = tmp_path / "r.json"
    assert (
        validate_main(
            [
                "--data",
                "birka_me1_test_protocol",
                "--check",
                "--out",
                str(report),
                "--tolerance",
                "turbine_outlet_temperature_C=10",
                "--tolerance",
                "charge_air_pressure_bar_gauge=2%",
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    # nothing is silent: each of the file's 33 columns has a line with its role
    header = (
        (ROOT / "src" / "marine_fdi_env" / "data" / "measured" / "birka_me1_test_protocol.csv")
        .read_text()
        .splitlines()[0]
        .split(",")
    )
    for col in header:
        assert re.search(rf"^  {re.escape(col)}\s+(channel|setpoint|boundary|member|not_modelled)\s", out, re.M), col
    for col in ("sfoc_iso_g_per_kWh", "relative_humidity_percent", "charge_air_cooler_pressure_drop_mbar"):
        assert re.search(rf"^  {col}\s+not_modelled\s+\S", out, re.M)
    assert re.search(r"^  ambient_pressure_hPa\s+boundary", out, re.M)
    assert "left out: row 2 compressor_inlet_temperature_C = 0" in out and "runs at 32" in out
    assert "fixed by power" in out and "leave-one-point-out (6 folds)" in out
    # tolerances: the stated ones with their source, the defaults with their basis
    assert re.search(
        r"turbine_outlet_temperature_C\s+10\s+\S+\s+--tolerance$", _row(out, "turbine_outlet_temperature_C")
    )
    # 2 % of the mean absolute charge-air pressure: twice the default 1 % (0.03197 bar)
    tol = float(_row(out, "charge_air_pressure_bar_gauge").split()[1])
    assert tol == pytest.approx(2 * 0.03197, rel=2e-3)
    assert _row(out, "turbine_inlet_temperature_C").endswith("default (5 K)")
    assert _row(out, "turbine_inlet_pressure_bar_gauge").endswith("default (1 % of the mean absolute reading)")
    assert not report.exists()  # --check fits nothing and writes nothing, --out or not
    assert out.rstrip().endswith("--check: nothing fitted, nothing written")


def test_check_names_sidecar_tolerances_and_a_suspect_reading(tmp_path, capsys):
    src = ROOT / "src" / "marine_fdi_env" / "data" / "measured"
    shutil.copy(src / "birka_6l46_shop_test.csv", tmp_path / "shop.csv")
    meta = json.loads((src / "birka_6l46_shop_test.meta.json").read_text())
    meta["tolerances"] = {"fuel_flow_kg_per_h": 12.0}
    (tmp_path / "shop.meta.json").write_text(json.dumps(meta))
    assert validate_main(["--data", str(tmp_path / "shop.csv"), "--check"]) == 0
    out = capsys.readouterr().out
    assert re.search(r"fuel_flow_kg_per_h\s+12\s+\S+\s+sidecar$", _row(out, "fuel_flow_kg_per_h"))
    assert "leave-one-engine-out (3 folds)" in out
    assert validate_main(["--data", str(tmp_path / "shop.csv"), "--check", "--holdout-engine", "ME2"]) == 0
    held = capsys.readouterr().out
    assert "leave-one-engine-out (2 folds)" in held and "hold-out: engine ME2 of shop, 5 points" in held
    assert "suspect reading, kept" in out and "row 6 charge_air_pressure_bar_gauge = 1.3" in out
    assert "fuel_rack" in out and "not compared (the model has no counterpart)" in out


def test_check_reads_a_parquet_file_as_it_reads_the_csv(tmp_path, capsys):
    """``--data`` picks the reader by the file's ending: the shop test as Parquet is checked line for line as the CSV;
    a file its reader cannot read is one line naming the file and the reader."""
    from tests.unit.test_validation_dataset import to_parquet

    src = ROOT / "src" / "marine_fdi_env" / "data" / "measured"
    for f in ("birka_6l46_shop_test.csv", "birka_6l46_shop_test.meta.json"):
        shutil.copy(src / f, tmp_path / f)
    parquet = to_parquet(tmp_path / "birka_6l46_shop_test.csv")
    outs = []
    for data in (tmp_path / "birka_6l46_shop_test.csv", parquet):
        assert validate_main(["--data", str(data), "--check"]) == 0
        outs.append(capsys.readouterr().out)
    assert outs[0] == outs[1] and "15 points" in outs[0]
    parquet.write_bytes(b"PAR1 but not really")
    assert validate_main(["--data", str(parquet), "--check"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"marine-fdi validate: error: --data: {parquet}: the parquet reader")


def test_check_and_columns_bad_input(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text(EXAMPLE.read_text().replace("charge_air_pressure_bar_gauge", "charge_air_pressure_bar"))
    shutil.copy(EXAMPLE.with_suffix("").with_suffix(".meta.json"), tmp_path / "bad.meta.json")
    cases = [
        (["--check"], "--data is required"),
        (["--data", "birka_me1_test_protocol"], "--out is required (or --check"),
        (["--data", str(bad), "--check"], "'bar' is ambiguous: say bar_abs or bar_gauge"),
        (["--data", "birka_me1_test_protocol", "--check", "--tolerance", "boost=1"], "not a compared channel"),
    ]
    capsys.readouterr()
    for argv, msg in cases:
        assert validate_main(argv) == 2, argv
        assert msg in capsys.readouterr().err, argv


def test_docs_example_is_checked_clean(capsys):
    """The file docs/measured_data.md walks through: every column known, no warning, all compared."""
    assert validate_main(["--data", str(EXAMPLE), "--check"]) == 0
    out = capsys.readouterr().out
    assert "warning" not in out
    header = EXAMPLE.read_text().splitlines()[0].split(",")
    compared = [c for c in header if c not in ("load_fraction", "power_kW")]
    for c in compared:
        assert re.search(rf"^  {c}\s+channel\s", out, re.M), c


def test_synthesized_sidecar_calls_gauge_columns_gauge(tmp_path):
    out = tmp_path / "s.csv"
    assert (
        synthesize_main(
            [
                "--params",
                "wartsila-6l46",
                "--points",
                "3",
                "--seed",
                "1",
                "--out",
                str(out),
                "--columns",
                "load_fraction,power_kW,charge_air_pressure_bar_gauge,charge_air_pressure_bar_abs",
            ]
        )
        == 0
    )
    cols = json.loads((tmp_path / "s.meta.json").read_text())["columns"]
    assert "gauge" in cols["charge_air_pressure_bar_gauge"] and "absolute" not in cols["charge_air_pressure_bar_gauge"]
    assert "absolute" in cols["charge_air_pressure_bar_abs"]


@pytest.mark.slow
def test_docs_example_names_its_hidden_cause(tmp_path, capsys):
    """The walk-through's fit: the example was drawn with turbine_flow_law (area 0.85, exponent 2, 1 % noise; its
    truth file beside it); the pipeline names it alone and recovers the area within two standard errors."""
    truth = json.loads(EXAMPLE.with_name("example_engine.truth.json").read_text())["mechanisms"][0]
    assert validate_main(["--data", str(EXAMPLE), "--out", str(tmp_path / "r.json"), "--quiet"]) == 0
    rep = json.loads((tmp_path / "r.json").read_text())
    assert rep["selected_labels"] == [truth["id"]]
    p = rep["parameters"][truth["id"]]["area_scale"]
    assert abs(p["value"] - truth["values"]["area_scale"]) < 2 * p["stderr"]
