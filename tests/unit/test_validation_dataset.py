"""Measured-data format: the shipped datasets load, units convert, and bad input is reported in full; every test of
the shipped datasets runs with both readers (CSV, and the same data written to Parquet), and a file read by either
gives the same dataset and the same findings."""

from __future__ import annotations

import dataclasses
import json
import math
import re
import warnings
from pathlib import Path

import numpy as np
import pytest

from marine_fdi_env.validation import (
    DatasetError,
    DataWarning,
    list_shipped,
    load_measured,
    load_shipped,
    write_measured,
)
from marine_fdi_env.validation.measured.columns import COLUMNS, QUANTITIES, column_problem
from marine_fdi_env.validation.measured.loader import shipped_path
from tests.paths import ROOT

SHARED = ROOT.parent / "shared" / "data"
BIRKA, MAN, PROTOCOL = "birka_6l46_shop_test", "man_12v32_40_fpp_iso", "birka_me1_test_protocol"


def _write(tmp_path: Path, csv_text: str, meta: dict | None = None, name: str = "data") -> Path:
    path = tmp_path / f"{name}.csv"
    path.write_text(csv_text)
    if meta is not None:
        (tmp_path / f"{name}.meta.json").write_text(json.dumps(meta))
    return path


META = {"engine_params": "wartsila-6l46", "load_law": "propeller law", "source": "test"}


def _errors(exc: DatasetError) -> list[str]:
    return [str(p) for p in exc.problems if p.severity == "error"]


def to_parquet(csv_path: Path) -> Path:
    """The CSV file as Parquet beside it (pyarrow's CSV reader, each column's type inferred as a user's conversion
    would: numbers, text, nulls for empty cells), with a copy of its sidecar."""
    pv, pq = pytest.importorskip("pyarrow.csv"), pytest.importorskip("pyarrow.parquet")
    out = csv_path.with_suffix(".parquet")
    pq.write_table(pv.read_csv(csv_path), out)
    side = csv_path.with_name(csv_path.stem + ".meta.json")
    if side.exists():
        out.with_name(out.stem + ".meta.json").write_text(side.read_text())
    return out


@pytest.fixture(params=["csv", "parquet"])
def load(request, tmp_path):
    """Load a shipped dataset by name: as shipped (CSV), or written to Parquet in the test's folder and read back."""

    def load(name: str, **kw):
        if request.param == "csv":
            return load_shipped(name, **kw)
        src = Path(str(shipped_path(name)))
        (tmp_path / src.name).write_text(src.read_text())
        (tmp_path / f"{name}.meta.json").write_text(src.with_name(f"{name}.meta.json").read_text())
        return load_measured(to_parquet(tmp_path / src.name), name=name, **kw)

    return load


# --------------------------------------------------------------------------------------- shipped data
def test_shipped_datasets_listed():
    assert list_shipped() == [BIRKA, PROTOCOL, MAN]


def test_birka_loads_with_missing_temperatures_and_a_warning(load):
    with pytest.warns(DataWarning, match=r"row 6 .*charge_air_pressure_bar_gauge.*ME2 reads 1.3"):
        ds = load(BIRKA)
    assert ds.n_points == 15 and ds.params_name == "wartsila-6l46"
    assert ds.engine_ids() == ["ME1", "ME2", "ME3"]
    assert ds.load_law == "propeller"
    assert "Ecos2015PaperExtension" in ds.provenance
    # ME2's temperatures were not recorded: NaN and counted as missing, not an error
    q = ds.quality["columns"]["charge_air_temperature_C"]
    assert q["missing"] == 5 and q["missing_rows"] == [6, 7, 8, 9, 10]
    assert np.all(np.isnan(ds.raw["charge_air_temperature_C"][5:10]))
    # the ambiguous charge-air temperature is placed after the compressor by the sidecar's explicit key
    assert ds.column_quantity["charge_air_temperature_C"] == "compressor_outlet_temperature_K"
    assert any("sidecar column_quantities" in n for n in ds.notes)
    # SI conversion: rpm -> rev/s, gauge bar -> absolute Pa with the parameter set's ambient (not recorded)
    assert ds.values["engine_speed_rev_s"][4] == pytest.approx(500 / 60)
    assert ds.values["charge_air_pressure_Pa"][4] == pytest.approx(3.15e5 + 1.013e5)
    assert ds.values["fuel_mass_flow_kg_s"][4] == pytest.approx(1141.0 / 3600)
    assert ds.values["compressor_outlet_temperature_K"][4] == pytest.approx(212 + 273.15)


def test_man_loads(load):
    ds = load(MAN)
    assert ds.n_points == 5 and ds.engines is None and ds.params_name == "man-12v32-40"
    assert ds.ambient["p_amb_Pa"] == pytest.approx(1e5) and ds.ambient["T_amb_K"] == pytest.approx(298.15)
    assert ds.values["sfc_kg_per_J"][0] == pytest.approx(187e-3 / 3.6e6)
    assert ds.values["specific_air_flow_kg_per_J"][0] == pytest.approx(7.34 / 3.6e6)
    assert ds.values["power_W"][1] == pytest.approx(4590e3)
    assert ds.quality["n_missing"] == 6  # the 25 % row has SFC only
    assert "MAN 32/40" in ds.provenance


@pytest.mark.skipif(not SHARED.is_dir(), reason="shared data directory not present")
@pytest.mark.parametrize("name", [BIRKA, PROTOCOL, MAN])
def test_shared_files_load_as_they_are_and_match_the_shipped_copies(name):
    ds = _quiet(load_measured, SHARED / f"{name}.csv")
    shipped = _quiet(load_shipped, name)
    assert ds.columns == shipped.columns
    for c in ds.columns:
        np.testing.assert_array_equal(ds.raw[c], shipped.raw[c])
    # the shipped sidecar may add explicit keys (stated under "additions"), nothing else differs
    added = {k for k in shipped.meta if k not in ds.meta}
    assert added <= {"column_quantities", "additions"}
    assert {k: v for k, v in shipped.meta.items() if k not in added} == ds.meta


@pytest.mark.skipif(not SHARED.is_dir(), reason="shared data directory not present")
def test_ambiguous_temperature_without_the_key_is_a_warning_naming_the_column():
    """The shared Birka sidecar places the charge-air temperature only in free text: the loader takes the
    documented default (after the cooler) and warns, naming the column; it never reads free text."""
    with pytest.warns(DataWarning) as rec:  # all of them: the file's other warnings are expected too
        ds = load_measured(SHARED / f"{BIRKA}.csv")
    assert any(re.search(r"charge_air_temperature_C.*column_quantities", str(w.message)) for w in rec)
    assert ds.column_quantity["charge_air_temperature_C"] == "charge_air_cooler_outlet_temperature_K"


def test_protocol_every_column_has_a_role_and_nothing_is_dropped(load):
    with pytest.warns(DataWarning) as rec:
        ds = load(PROTOCOL)
    text = " ".join(str(w.message) for w in rec)
    header = (
        (ROOT / "src" / "marine_fdi_env" / "data" / "measured" / f"{PROTOCOL}.csv")
        .read_text()
        .splitlines()[0]
        .split(",")
    )
    inv = {r["column"]: r for r in ds.column_inventory()}
    assert set(inv) == set(header)  # every column is accounted for
    roles = {c: r["role"] for c, r in inv.items()}
    assert roles["ambient_pressure_hPa"] == roles["compressor_inlet_temperature_C"] == "boundary"
    assert roles["exhaust_back_pressure_mbar"] == "boundary"
    assert roles["relative_humidity_percent"] == roles["sfoc_iso_g_per_kWh"] == "not_modelled"
    assert roles["charge_air_cooler_pressure_drop_mbar"] == "not_modelled"
    assert roles["turbocharger_speed_rpm"] == roles["turbine_inlet_pressure_bar_gauge"] == "channel"
    assert all(roles[f"cylinder_{k}_exhaust_temperature_C"] == "member" for k in range(1, 7))
    assert all(inv[c]["what"] for c in inv)  # each with what happens to it
    # the maximum pressures do not say gauge or absolute: an assumption with one warning naming them
    assert "cylinder_1_max_pressure_bar" in text and "taken as gauge" in text
    assert ds.values["p_max_Pa"][0] == pytest.approx(96e5 + 1025e2)
    # per-row boundary conditions; the 0 C inlet temperature of the 50 % row is found and left out
    np.testing.assert_allclose(ds.boundary["p_amb_Pa"], [102500, 102400, 102400, 102500, 102500, 102600])
    assert [(o["column"], o["row"], o["value"]) for o in ds.boundary_outliers] == [
        ("compressor_inlet_temperature_C", 2, 0.0)
    ]
    assert ds.boundary["T_amb_K"][1] == pytest.approx(32 + 273.15)  # the other rows' median
    assert "row 2" in text and "recording error" in text
    np.testing.assert_allclose(ds.boundary["p_ex_Pa"] - ds.boundary["p_amb_Pa"], [0, 400, 800, 1100, 1500, 1800])
    # gauge columns read against the row's own ambient pressure
    assert ds.values["charge_air_pressure_Pa"][5] == pytest.approx(3.13e5 + 1026e2)
    # per-cylinder spread of the engine-mean channels (sample standard deviation over the six cylinders)
    g = ds.groups["cylinder_exhaust_temperature"]
    assert g["mean_column"] == "cylinder_exhaust_temperature_mean_C"
    first = np.array([343, 376, 378, 376, 371, 360], float)
    assert g["spread"][0] == pytest.approx(first.std(ddof=1))


def test_per_row_ambient_values_are_checked(tmp_path):
    head = "load_fraction,power_kW,ambient_pressure_hPa,compressor_inlet_temperature_C,relative_humidity_percent\n"
    path = _write(tmp_path, head + "0.5,2945,1013,25,40\n0.75,4418,-3,25,140\n1.0,5890,700,90,40\n", META)
    with pytest.raises(DatasetError) as ei:
        load_measured(path)
    text = str(ei.value)
    assert "row 2 (line 3), column 'ambient_pressure_hPa': ambient pressure not positive" in text
    assert "column 'relative_humidity_percent': relative humidity outside [0, 100] %" in text
    assert "ambient pressure outside [850, 1100] hPa" in text and "intake temperature outside [-30, 60] C" in text


def test_boundary_outlier_needs_a_real_departure(tmp_path):
    """Readings within a few kelvin of each other are never recording errors (the robust scale has a 1 K floor)."""
    rows = "\n".join(
        f"{lf},{lf * 5890:.0f},{t}" for lf, t in [(0.25, 28), (0.5, 29), (0.75, 31), (0.85, 32), (1.0, 34), (1.1, 36)]
    )
    path = _write(tmp_path, "load_fraction,power_kW,compressor_inlet_temperature_C\n" + rows + "\n", META)
    ds = _quiet(load_measured, path)
    assert ds.boundary_outliers == ()
    np.testing.assert_allclose(ds.boundary["T_amb_K"] - 273.15, [28, 29, 31, 32, 34, 36])


def _quiet(f, *a, **k):
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        return f(*a, **k)


def test_registry_is_consistent():
    for col, spec in COLUMNS.items():
        assert spec.quantity in QUANTITIES or spec.quantity == "charge_air_temperature_K", col
        assert spec.scale > 0
        v = np.array([1.0, 2.5])
        np.testing.assert_allclose(spec.from_si(spec.to_si(v, 1e5), 1e5), v)
    for q in QUANTITIES.values():  # what is not compared says why
        assert q.role in ("channel", "setpoint") or q.reason, q.name


# --------------------------------------------------------------------------------------- bad input
def test_header_problems_all_reported(tmp_path):
    path = _write(
        tmp_path,
        "speed,power_kW,power_kW,colour_index,charge_air_pressure_bar,load_fraction\n400,3000,3000,1,2.0,0.5\n",
        META,
    )
    with pytest.raises(DatasetError) as ei:
        load_measured(path)
    errs = _errors(ei.value)
    text = str(ei.value)
    assert any("'speed'" in e and "missing unit suffix" in e and "speed_rpm" in e for e in errs)
    assert any("'power_kW'" in e and "duplicated column" in e for e in errs)
    assert any("'colour_index'" in e and "unknown column" in e for e in errs)
    assert any("'charge_air_pressure_bar'" in e and "bar_abs or bar_gauge" in e for e in errs)
    assert len(errs) == 4, text
    assert isinstance(ei.value, ValueError)


def test_same_quantity_twice_is_a_duplicated_column(tmp_path):
    path = _write(tmp_path, "speed_rpm,speed_rev_s,load_fraction\n400,6.67,0.5\n", META)
    with pytest.raises(DatasetError, match=r"column 'speed_rev_s': duplicated column: holds the same quantity"):
        load_measured(path)


def test_non_numeric_values_every_cell_listed(tmp_path):
    path = _write(
        tmp_path,
        "engine,load_fraction,speed_rpm,fuel_flow_kg_per_h\n"
        "A,0.25,315,abc\n"
        "A,0.5,fast,587\n"
        "A,0.75,454,8 38\n"
        "A,1.0,500,1141\n",
        META,
    )
    with pytest.raises(DatasetError) as ei:
        load_measured(path)
    errs = _errors(ei.value)
    assert len(errs) == 3
    assert any(re.search(r"row 1 \(line 2\), column 'fuel_flow_kg_per_h': non-numeric value 'abc'", e) for e in errs)
    assert any(re.search(r"row 2 \(line 3\), column 'speed_rpm': non-numeric value 'fast'", e) for e in errs)
    assert any(re.search(r"row 3 \(line 4\), column 'fuel_flow_kg_per_h': non-numeric value '8 38'", e) for e in errs)


def test_duplicate_operating_points_listed_with_their_rows(tmp_path):
    path = _write(
        tmp_path,
        "engine,load_fraction,speed_rpm,fuel_flow_kg_per_h\n"
        "A,0.5,397,587\n"
        "B,0.5,397,590\n"  # other engine: not a duplicate
        "A,0.5,397,588\n"
        "A,1.0,500,1141\n"
        "B,1.0,500,1150\n"
        "B,1.0,500,1150\n",
        META,
    )
    with pytest.raises(DatasetError) as ei:
        load_measured(path)
    errs = _errors(ei.value)
    assert len(errs) == 2
    assert any("rows 1, 3 (lines 2, 4)" in e and "duplicate operating point (engine A" in e for e in errs)
    assert any("rows 5, 6" in e and "engine B" in e for e in errs)


def test_points_outside_the_envelope_listed(tmp_path):
    # wartsila-6l46: 500 rpm, 5890 kW; envelope: load <= 1.15, speed <= 575 rpm, power <= 6773.5 kW
    path = _write(
        tmp_path,
        "load_fraction,speed_rpm,power_kW,charge_air_pressure_bar_abs\n"
        "0.5,397,2945,2.4\n"
        "1.2,520,7000,4.0\n"
        "0.9,600,5300,-0.5\n"
        "-0.1,300,100,1.0\n",
        META,
    )
    with pytest.raises(DatasetError) as ei:
        load_measured(path)
    errs = _errors(ei.value)
    text = "\n".join(errs)
    assert re.search(r"row 2 \(line 3\), column 'load_fraction': load fraction above 1.15", text)
    assert re.search(r"row 4 \(line 5\), column 'load_fraction': negative load fraction", text)
    assert re.search(r"row 3 \(line 4\), column 'speed_rpm': speed above 1.15 x nominal \(575 rpm", text)
    assert re.search(r"row 2 \(line 3\), column 'power_kW': power above 1.15 x rated", text)
    assert re.search(r"row 3 \(line 4\), column 'charge_air_pressure_bar_abs': negative absolute pressure", text)
    assert len(errs) == 5, text


def test_the_speed_bound_is_the_engine_envelope(tmp_path):
    """One operating envelope: the loader refuses a speed beyond the engine envelope's 115 % of the rated speed (the
    governor's limit, IACS UR M3.1.1) and keeps one between 110 % and 115 % (an overspeed test reaches it)."""
    from marine_fdi_env.engine.envelope import ENVELOPE, envelope_warnings

    assert ENVELOPE.max_speed_fraction == 1.15
    rows = "0.5,397\n0.75,454\n1.0,560\n"  # 560 rpm: 1.12 x the rated 500 rpm
    ds = _quiet(load_measured, _write(tmp_path, "load_fraction,speed_rpm\n" + rows, META))
    assert ds.raw["speed_rpm"][2] == 560 and envelope_warnings(560 / 60, 200 / 3.6e9, 500 / 60) == []
    with pytest.raises(DatasetError, match=r"row 3 .*speed above 1.15 x nominal \(575 rpm"):
        load_measured(_write(tmp_path, "load_fraction,speed_rpm\n" + rows.replace("560", "580"), META))
    assert envelope_warnings(580 / 60, 200 / 3.6e9, 500 / 60)  # the same bound as the steady states'


def test_gauge_pressure_below_minus_ambient_is_an_error_slightly_negative_a_warning(tmp_path):
    path = _write(
        tmp_path,
        "load_fraction,speed_rpm,charge_air_pressure_bar_gauge\n"
        "0.25,315,-0.05\n0.5,397,-1.5\n0.75,454,-2.0\n1.0,500,3.1\n",
        META,
    )
    with pytest.raises(DatasetError) as ei:
        load_measured(path)
    errs = _errors(ei.value)
    assert len(errs) == 1 and "rows 2, 3 (lines 3, 4)" in errs[0] and "negative absolute pressure" in errs[0]
    warns = [str(p) for p in ei.value.problems if p.severity == "warning"]
    assert any("row 1 " in w and "below ambient" in w for w in warns)


def test_every_kind_of_problem_in_one_error(tmp_path):
    path = _write(
        tmp_path,
        "engine,load_fraction,speed,speed_rpm,fuel_flow_kg_per_h,weird\n"
        "A,0.5,1,397,x,1\n"
        "A,0.5,1,397,587,1\n"
        "A,1.3,1,500,1141,1\n"
        "A,0.75,1,454\n",
        META,
    )
    with pytest.raises(DatasetError) as ei:
        load_measured(path)
    text = "\n".join(_errors(ei.value))
    assert "column 'speed': column 3: missing unit suffix" in text
    assert "column 'weird': column 6: unknown column" in text
    assert "row 1 (line 2), column 'fuel_flow_kg_per_h': non-numeric value 'x'" in text
    assert "rows 1, 2 (lines 2, 3): duplicate operating point" in text
    assert "row 3 (line 4), column 'load_fraction': load fraction above 1.15" in text
    assert "row 4 (line 5): 4 fields, the header has 6" in text


def test_missing_cells_are_nan_and_reported_not_errors(tmp_path):
    path = _write(
        tmp_path,
        "load_fraction,speed_rpm,fuel_flow_kg_per_h,turbine_outlet_temperature_C\n"
        "0.25,315,,300\n0.5,397,587,NA\n0.75,454,838,\n1.0,500,1141,350\n",
        META,
    )
    ds = load_measured(path)
    assert math.isnan(ds.raw["fuel_flow_kg_per_h"][0])
    assert ds.quality["columns"]["turbine_outlet_temperature_C"]["missing_rows"] == [2, 3]
    assert ds.quality["columns"]["fuel_flow_kg_per_h"]["missing_rows"] == [1]
    assert "missing (rows 2, 3)" in ds.quality_report()


def test_sidecar_problems(tmp_path):
    path = _write(tmp_path, "load_fraction,speed_rpm\n0.5,397\n")
    with pytest.raises(DatasetError, match="no sidecar data.meta.json"):
        load_measured(path)
    ds = _quiet(load_measured, path, params="wartsila-6l46")  # the caller names the engine
    assert ds.params_name == "wartsila-6l46"
    _write(tmp_path, "load_fraction,speed_rpm\n0.5,397\n", {"engine_params": "no-such-engine"})
    with pytest.raises(DatasetError, match="unknown engine parameter set 'no-such-engine'"):
        load_measured(path)


def test_column_problem_messages():
    assert column_problem("speed_rpm") is None
    assert "missing unit suffix" in column_problem("power")
    assert "unknown unit 'furlongs'" in column_problem("speed_furlongs")
    assert "did you mean speed_rpm" in column_problem("sped_rpm")


def test_write_dataset_round_trip(tmp_path):
    cols = {
        "load_fraction": [0.25, 0.5, 1.0],
        "speed_rpm": [315, 397, 500],
        "turbine_outlet_temperature_C": [300.0, float("nan"), 350.0],
    }
    path = write_measured(tmp_path / "rt.csv", cols, META, engines=["X", "X", "X"])
    ds = load_measured(path)
    assert ds.engine_ids() == ["X"]
    np.testing.assert_array_equal(ds.raw["speed_rpm"], [315, 397, 500])
    assert ds.quality["columns"]["turbine_outlet_temperature_C"]["missing"] == 1


def test_subset_keeps_one_engine(load):
    ds = _quiet(load, BIRKA)
    me3 = ds.subset(np.array(ds.engines) == "ME3")
    assert me3.n_points == 5 and me3.engine_ids() == ["ME3"]
    np.testing.assert_array_equal(me3.raw["fuel_flow_kg_per_h"], ds.raw["fuel_flow_kg_per_h"][10:])
    assert me3.quality["columns"]["charge_air_temperature_C"]["missing"] == 0


def test_the_old_names_of_the_measured_data_functions_still_work_and_say_the_new():
    import marine_fdi_env.validation as v

    with pytest.warns(DeprecationWarning, match="load_measured"):
        assert v.load_dataset is load_measured
    with pytest.warns(DeprecationWarning, match="write_measured"):
        assert v.write_dataset is write_measured
    with pytest.raises(AttributeError):
        v.no_such_name


# --------------------------------------------------------------------------------------- readers
def _same(a, b) -> bool:
    """Equal to the last bit (NaN equal to NaN): numbers, arrays, and containers of them."""
    if isinstance(a, dict) or isinstance(b, dict):
        return (
            isinstance(a, dict) and isinstance(b, dict) and a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
        )
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return type(a) is type(b) and len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        return a.shape == b.shape and a.dtype == b.dtype and np.array_equal(a, b, equal_nan=a.dtype.kind == "f")
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return type(a) is type(b) and a == b


def _both_ways(csv_path: Path, **kw):
    """(outcome, DataWarning messages) of loading ``csv_path`` and of its Parquet copy; the outcome is the dataset or
    the DatasetError's findings."""
    out = []
    for path in (csv_path, to_parquet(csv_path)):
        with warnings.catch_warnings(record=True) as rec:
            warnings.simplefilter("always")
            try:
                got = load_measured(path, name=csv_path.stem, **kw)
            except DatasetError as e:
                got = e.problems
        out.append((got, [str(w.message) for w in rec if w.category is DataWarning]))
    return out


@pytest.mark.parametrize("name", [BIRKA, PROTOCOL, MAN])
def test_a_shipped_dataset_read_from_parquet_is_the_same_dataset(tmp_path, name):
    """The checks run once, after reading, whatever the format: the Parquet copy of a shipped dataset gives the same
    dataset (every field, to the last bit; only the path differs) and the same warnings."""
    src = Path(str(shipped_path(name)))
    (tmp_path / src.name).write_text(src.read_text())
    (tmp_path / f"{name}.meta.json").write_text(src.with_name(f"{name}.meta.json").read_text())
    (a, warned_a), (b, warned_b) = _both_ways(tmp_path / src.name)
    assert a.path.endswith(".csv") and b.path.endswith(".parquet")
    for f in dataclasses.fields(a):
        if f.name != "path":
            assert _same(getattr(a, f.name), getattr(b, f.name)), f.name
    assert a.warnings == b.warnings and warned_a == warned_b
    assert _same(a.raw, _quiet(load_shipped, name).raw)


BAD = {
    "header": "speed,power_kW,colour_index,charge_air_pressure_bar,load_fraction\n400,3000,1,2.0,0.5\n",
    "non-numeric": "engine,load_fraction,speed_rpm,fuel_flow_kg_per_h\nA,0.25,315,abc\nA,0.5,fast,587\n"
    "A,0.75,454,8 38\nA,1.0,500,1141\n",
    "duplicates": "engine,load_fraction,speed_rpm,fuel_flow_kg_per_h\nA,0.5,397,587\nB,0.5,397,590\nA,0.5,397,588\n"
    "B,1.0,500,1150\nB,1.0,500,1150\n",
    "envelope": "load_fraction,speed_rpm,power_kW,charge_air_pressure_bar_abs\n0.5,397,2945,2.4\n1.2,520,7000,4.0\n"
    "0.9,600,5300,-0.5\n-0.1,300,100,1.0\n",
    "missing cells": "load_fraction,speed_rpm,fuel_flow_kg_per_h,turbine_outlet_temperature_C\n0.25,315,,300\n"
    "0.5,397,587,NA\n0.75,454,838,\n1.0,500,1141,350\n",
    "gauge": "load_fraction,speed_rpm,charge_air_pressure_bar_gauge\n0.25,315,-0.05\n0.5,397,-1.5\n0.75,454,-2.0\n"
    "1.0,500,3.1\n",
    "empty engine": "engine,load_fraction,speed_rpm\nA,0.5,397\n,0.75,454\n",
    "no rows": "load_fraction,speed_rpm\n",
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_data_gives_the_same_findings_from_csv_and_parquet(tmp_path, case):
    (a, warned_a), (b, warned_b) = _both_ways(_write(tmp_path, BAD[case], META))
    if isinstance(a, list):  # refused: the same errors and warnings, in the same order
        assert isinstance(b, list) and [str(p) for p in a] == [str(p) for p in b] and a == b
    else:
        assert a.warnings == b.warnings and _same(a.raw, b.raw) and _same(a.values, b.values)
    assert warned_a == warned_b


def test_parquet_cells_of_any_type_are_checked_like_text(tmp_path):
    """A Parquet column of text, booleans or integers goes through the same cell checks as a CSV's text."""
    pa, pq = pytest.importorskip("pyarrow"), pytest.importorskip("pyarrow.parquet")
    table = pa.table(
        {
            "engine": pa.array([1, 1, None]),
            "load_fraction": pa.array([0.5, float("nan"), 1.0]),
            "speed_rpm": pa.array(["397", "x", None]),
            "fuel_flow_kg_per_h": pa.array([True, False, True]),
        }
    )
    path = tmp_path / "typed.parquet"
    pq.write_table(table, path)
    (tmp_path / "typed.meta.json").write_text(json.dumps(META))
    with pytest.raises(DatasetError) as ei:
        load_measured(path)
    errs = _errors(ei.value)
    assert "row 3 (line 4), column 'engine': empty engine id" in errs
    assert "row 2 (line 3), column 'speed_rpm': non-numeric value 'x'" in errs
    assert any("column 'fuel_flow_kg_per_h': non-numeric value 'True'" in e for e in errs)
    assert not any("load_fraction" in e for e in errs)  # NaN: a missing value


def test_the_reader_is_picked_by_the_ending_or_named(tmp_path):
    from marine_fdi_env.validation.measured.readers import READERS, reader_for

    assert list(READERS) == ["csv", "parquet"]
    assert reader_for("a.parquet").name == reader_for("b.PQ").name == "parquet"
    assert reader_for("a.csv").name == reader_for("a.txt").name == "csv"  # any other ending: CSV
    assert reader_for("a.txt", "parquet").name == "parquet"
    with pytest.raises(ValueError, match="unknown reader 'xlsx'; readers: csv, parquet"):
        reader_for("a.xlsx", "xlsx")
    # the sidecar and the dataset's name drop the format's ending
    csv_path = _write(tmp_path, "load_fraction,speed_rpm\n0.5,397\n0.75,454\n", META, name="run")
    ds = load_measured(to_parquet(csv_path))
    assert ds.name == "run" and ds.params_name == "wartsila-6l46"


def test_a_file_the_reader_cannot_read_names_the_file_and_the_reader(tmp_path):
    from marine_fdi_env.errors import DataFileError

    bad = tmp_path / "broken.parquet"
    bad.write_bytes(b"not a parquet file at all")
    with pytest.raises(DataFileError, match=r"broken.parquet: the parquet reader cannot read it"):
        load_measured(bad, META)
    latin = tmp_path / "latin.csv"
    latin.write_bytes("load_fraction,speed_rpm\n0.5,397 \xb0\n".encode("latin-1"))
    with pytest.raises(DataFileError, match=r"latin.csv: not UTF-8 text .*\(csv reader\)"):
        load_measured(latin, META)
    with pytest.raises(DatasetError, match="no such file"):
        load_measured(tmp_path / "absent.parquet", META)


def test_without_pyarrow_a_parquet_file_names_the_extra(tmp_path, monkeypatch):
    import sys

    from marine_fdi_env.errors import MissingExtra

    monkeypatch.setitem(sys.modules, "pyarrow.parquet", None)  # "import pyarrow.parquet" raises ImportError
    with pytest.raises(MissingExtra) as ei:
        load_measured(tmp_path / "x.parquet", META)
    assert str(ei.value) == "reading x.parquet (parquet reader) needs pyarrow: pip install 'marine-fdi-env[parquet]'"


def test_a_sidecar_number_that_is_not_one_is_refused_by_name(tmp_path):
    from marine_fdi_env.errors import DataFileError

    path = _write(tmp_path, "load_fraction,speed_rpm\n0.5,397\n", {**META, "ambient": {"ambient_pressure_bar": "1"}})
    with pytest.raises(DataFileError, match=r"^data.meta.json: field 'ambient.ambient_pressure_bar' must be a finite"):
        load_measured(path)
