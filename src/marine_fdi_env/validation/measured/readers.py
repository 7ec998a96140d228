"""The reader seam of the measured data: a reader turns one file format into a :class:`RawTable`; every check runs
afterwards, the same for every format (:mod:`.checks`).

A :class:`Reader` has a ``name`` (what messages call it), the file endings it reads (``suffixes``) and
``read(path) -> RawTable``: the header (the unit in each column's name, ``speed_rpm``, as the format defines it,
docs/measured_data.md) and one row of cells per operating point, each cell as the file holds it (text, a number, or
``None`` for an empty one).  A reader checks nothing: a short row, a word in a numeric column, a duplicated column
are the checks' to report, with every other problem of the file.  A file it cannot read at all (not text, not
Parquet) raises one :class:`~marine_fdi_env.errors.DataFileError` naming the file and the reader.

Shipped readers (:data:`READERS`): ``csv`` (``.csv``, and any ending no other reader claims) and ``parquet``
(``.parquet``, ``.pq``; needs pyarrow, the ``parquet`` extra, imported when a Parquet file is read).  Whatever the
format, the sidecar ``FILE.meta.json`` beside the file holds the metadata (:mod:`.sidecar`); :func:`read_file`
reads both.
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Mapping, Protocol, Union

from ...errors import DataFileError, DatasetError, MissingExtra
from .dataset import DataFinding
from .sidecar import read_sidecar, sidecar_path

__all__ = [
    "Cell",
    "RawTable",
    "Reader",
    "CsvReader",
    "ParquetReader",
    "READERS",
    "MeasuredFile",
    "reader_for",
    "read_file",
    "stem",
]

#: one cell as a reader gives it: text (CSV), a number, or None (empty)
Cell = Union[str, float, int, None]


@dataclass(frozen=True)
class RawTable:
    """A table as read, before any check: ``columns`` (the header, units in the names) and ``rows`` (one tuple of
    cells per operating point; a row of another length than the header is reported by the checks)."""

    columns: tuple[str, ...]
    rows: tuple[tuple[Cell, ...], ...]


class Reader(Protocol):
    """Reads one file format into a :class:`RawTable`."""

    name: str  # what error messages call the reader, e.g. "csv"
    suffixes: tuple[str, ...]  # the file endings it reads, e.g. (".csv",)

    def read(self, path: Path) -> RawTable: ...


class CsvReader:
    """Comma-separated UTF-8 text, the header on the first line (docs/measured_data.md)."""

    name = "csv"
    suffixes = (".csv",)

    def read(self, path: Path) -> RawTable:
        try:
            text = Path(path).read_text(encoding="utf-8")
        except UnicodeDecodeError as e:  # one line: nothing else can be checked in a file that cannot be read
            line = e.object[: e.start].count(b"\n") + 1
            raise DataFileError(
                f"{path}: not UTF-8 text (byte 0x{e.object[e.start]:02x} on line {line}); save the CSV as UTF-8 "
                f"({self.name} reader)"
            ) from None
        return self.parse(text)

    @staticmethod
    def parse(text: str) -> RawTable:
        """The table of CSV ``text`` (trailing blank lines dropped)."""
        rows = list(csv.reader(io.StringIO(text)))
        while rows and not any(c.strip() for c in rows[-1]):
            rows.pop()
        if not rows:
            return RawTable((), ())
        return RawTable(tuple(rows[0]), tuple(tuple(r) for r in rows[1:]))


class ParquetReader:
    """An Apache Parquet file: one column per measured column, named as in a CSV, one row per operating point."""

    name = "parquet"
    suffixes = (".parquet", ".pq")

    def read(self, path: Path) -> RawTable:
        try:
            import pyarrow.parquet as pq
        except ImportError:
            raise MissingExtra("pyarrow", f"reading {Path(path).name} ({self.name} reader)") from None
        try:
            table = pq.read_table(path)
        except FileNotFoundError:
            raise
        except Exception as e:  # pyarrow's ArrowInvalid, OSError, ...: the file is not a Parquet file
            raise DataFileError(f"{path}: the {self.name} reader cannot read it: {str(e).splitlines()[0]}") from None
        columns = [table.column(i).to_pylist() for i in range(table.num_columns)]
        return RawTable(tuple(table.column_names), tuple(zip(*columns)) if columns else ())


#: the shipped readers by name; the first is the default for an ending no reader claims
READERS: dict[str, Reader] = {r.name: r for r in (CsvReader(), ParquetReader())}


def reader_for(path: str | Path, reader: str | Reader | None = None) -> Reader:
    """The reader of ``path``: ``reader`` itself (a name of :data:`READERS` or a :class:`Reader`), else the one whose
    suffix ``path`` ends with, else the CSV reader."""
    if reader is not None and not isinstance(reader, str):
        return reader
    if reader is not None:
        if reader not in READERS:
            raise ValueError(f"unknown reader {reader!r}; readers: {', '.join(READERS)}")
        return READERS[reader]
    name = Path(path).name.lower()
    for r in READERS.values():
        if any(name.endswith(s) for s in r.suffixes):
            return r
    return READERS["csv"]


def stem(path: str | Path, reader: Reader) -> str:
    """The file's name without the reader's ending (the dataset's name; its sidecar is ``STEM.meta.json``)."""
    name = Path(path).name
    for s in reader.suffixes:
        if name.lower().endswith(s):
            return name[: -len(s)]
    return name


@dataclass(frozen=True)
class MeasuredFile:
    """A measured-data file as read, before any check: its table, the reader that read it (``reader``: its name),
    ``stem`` (the file's name without its format's ending) and its sidecar (``meta``: the JSON object, ``None`` when
    there is none; ``meta_name``: the sidecar's file name; ``meta_problem``: why it could not be used)."""

    path: Path
    reader: str
    stem: str
    table: RawTable
    meta: dict[str, Any] | None
    meta_name: str
    meta_problem: str | None = None


def read_file(
    path: str | Path,
    meta: str | Path | Mapping[str, Any] | None = None,
    *,
    reader: str | Reader | None = None,
    source: str | None = None,
) -> MeasuredFile:
    """Read ``path`` with its reader (:func:`reader_for`) and its sidecar: ``meta`` as given (a dict, or the path of a
    JSON file), else ``STEM.meta.json`` beside the file.  A missing file raises :class:`DatasetError` (``source``
    names it, default the file's name)."""
    path = Path(path)
    r = reader_for(path, reader)
    try:
        table = r.read(path)
    except FileNotFoundError:
        raise DatasetError(source or path.name, [DataFinding("error", f"no such file {path}")]) from None
    name = stem(path, r)
    if isinstance(meta, Mapping):
        return MeasuredFile(path, r.name, name, table, dict(meta), f"{name}.meta.json")
    meta_path = Path(meta) if meta is not None else sidecar_path(path, name)
    content, problem = read_sidecar(meta_path)
    return MeasuredFile(path, r.name, name, table, content, meta_path.name, problem)
