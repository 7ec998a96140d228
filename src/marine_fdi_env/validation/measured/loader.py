"""Loading measured data: a file read by its reader and checked (:func:`load_measured`), the datasets shipped with
the package, the ``--data`` argument of the commands, and the CSV writer of the format."""

from __future__ import annotations

import csv
import json
import math
import warnings
from importlib import resources
from pathlib import Path
from typing import Any, Iterable, Mapping

import numpy as np

from .checks import ENGINE_COLUMN, check_measured
from .columns import column_problem
from .dataset import DataWarning, MeasuredDataset
from .readers import READERS, CsvReader, MeasuredFile, Reader, read_file
from .sidecar import sidecar_path

__all__ = ["load_measured", "load_shipped", "list_shipped", "shipped_path", "load_data_arg", "write_measured"]


def load_measured(
    path: str | Path,
    meta: str | Path | Mapping[str, Any] | None = None,
    *,
    params: str | None = None,
    name: str | None = None,
    reader: str | Reader | None = None,
) -> MeasuredDataset:
    """Read and check a measured dataset; raise :class:`~marine_fdi_env.errors.DatasetError` listing every error.

    path : the data file (CSV, Parquet: :mod:`.readers`).  meta : the sidecar (path or dict); default
    ``STEM.meta.json`` beside the file.  params : parameter-set name overriding the sidecar's ``engine_params``.
    name : the dataset's name (default: the file's name without its ending).  reader : a reader's name
    (:data:`~.readers.READERS`) or a :class:`~.readers.Reader`; default: by the file's ending.
    """
    return check_measured(read_file(path, meta, reader=reader, source=name), params=params, name=name)


# --------------------------------------------------------------------------------------- shipped data
def _measured_dir():
    return resources.files("marine_fdi_env") / "data" / "measured"


def list_shipped() -> list[str]:
    """Names of the measured datasets shipped with the package."""
    return sorted(p.name[:-4] for p in _measured_dir().iterdir() if p.name.endswith(".csv"))


def shipped_path(name: str):
    """Traversable of a shipped dataset's CSV."""
    names = list_shipped()
    if name not in names:
        raise ValueError(f"unknown shipped dataset {name!r}; shipped: {', '.join(names)}")
    return _measured_dir() / f"{name}.csv"


def load_shipped(name: str, *, params: str | None = None) -> MeasuredDataset:
    """Load a dataset shipped in ``marine_fdi_env/data/measured`` (:func:`list_shipped`); its provenance is the
    sidecar's ``source``."""
    csv_res = shipped_path(name)
    meta = json.loads((_measured_dir() / f"{name}.meta.json").read_text())
    table = CsvReader.parse(csv_res.read_text())
    file = MeasuredFile(Path(str(csv_res)), CsvReader.name, name, table, meta, f"{name}.meta.json")
    return check_measured(file, params=params, name=name)


def load_data_arg(text: str, params: str | None = None, reader: str | None = None) -> MeasuredDataset:
    """A dataset from a data file's path or the name of a shipped dataset (warnings kept in the dataset)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DataWarning)
        p = Path(text)
        if p.is_dir():
            raise ValueError(
                f"{text!r} is a folder; give a data file ({', '.join(f'*{r.suffixes[0]}' for r in READERS.values())}"
                f", with its sidecar FILE.meta.json beside it) or a shipped dataset name ({', '.join(list_shipped())})"
            )
        if p.exists():
            return load_measured(p, params=params, reader=reader)
        if text in list_shipped():
            return load_shipped(text, params=params)
        raise ValueError(f"no such file {text!r} (shipped datasets: {', '.join(list_shipped())})")


# --------------------------------------------------------------------------------------- writer
def write_measured(
    path: str | Path,
    columns: Mapping[str, Iterable],
    meta: Mapping[str, Any],
    engines: Iterable[str] | None = None,
    digits: int = 6,
) -> Path:
    """Write a CSV (+ ``.meta.json`` sidecar) in the measured-data format; NaN becomes an empty cell.

    ``columns`` maps registered column names to values in the column's units.
    """
    path = Path(path)
    names = list(columns)
    for c in names:
        msg = column_problem(c)
        if msg is not None:
            raise ValueError(msg)
    cols = [np.asarray(list(columns[c]), dtype=float) for c in names]
    n = len(cols[0]) if cols else 0
    eng = None if engines is None else list(engines)
    with path.open("w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(([ENGINE_COLUMN] if eng is not None else []) + names)
        for i in range(n):
            cells = [("" if not math.isfinite(float(c[i])) else f"{float(c[i]):.{digits}g}") for c in cols]
            w.writerow(([eng[i]] if eng is not None else []) + cells)
    stem = path.name[:-4] if path.name.endswith(".csv") else path.name
    sidecar_path(path, stem).write_text(json.dumps(dict(meta), indent=2) + "\n")
    return path
