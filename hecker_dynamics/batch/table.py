"""The results table of a sweep: Parquet where pyarrow is installed, else CSV.

Rows are written sorted by variant index, so the file is the same bytes however many
workers ran the variants and in whatever order they finished. CSV cells hold numbers by
``repr`` (the shortest text that reads back as the same double), an empty cell for a
missing value; columns come in the order of the first row, which every row of a sweep
shares (the scene fixes the bodies).

While the variants run, finished rows go to a partial CSV file next to the table as they
come (``<table>.partial.csv``, one row per line, each written whole or cut back off), so a
sweep that stops keeps what it finished; the partial file is removed once the table is
written.

:func:`check_table` checks ``-o`` before any variant runs (:mod:`hecker_dynamics.files`:
neither the table nor the partial file of an earlier sweep is replaced without
``--overwrite``; Parquet needs pyarrow), and the table is written whole or not at all.
"""
from __future__ import annotations

import contextlib
import csv
import importlib.util
import io
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Optional, TextIO

from ..files import OutputError, check_file, file_path, replacing

__all__ = ["table_format", "table_path", "partial_path", "check_table", "write_table",
           "PartialRows"]

FORMATS = {".parquet": "parquet", ".csv": "csv"}


def _has_pyarrow() -> bool:
    return importlib.util.find_spec("pyarrow") is not None


def table_format(path: Path) -> str:
    """``parquet`` or ``csv``: by the suffix, else Parquet when pyarrow is installed."""
    if path.suffix.lower() in FORMATS:
        return FORMATS[path.suffix.lower()]
    return "parquet" if _has_pyarrow() else "csv"


def table_path(path: Path) -> Path:
    """``path``, with the suffix of its format added when it has neither."""
    return path if path.suffix.lower() in FORMATS else path.with_name(
        path.name + "." + table_format(path))


def partial_path(table: Path) -> Path:
    """Where the rows of a running sweep go as they finish."""
    return table.with_name(table.name + ".partial.csv")


def check_table(text: str, *, overwrite: bool = False) -> Path:
    """The table ``-o TEXT`` names (its suffix added), checked before any work; raises
    :class:`~hecker_dynamics.files.OutputError`."""
    path = table_path(file_path(text))
    check_file(path, overwrite=overwrite,
               also=[(partial_path(path), "the rows of a sweep that stopped")])
    if table_format(path) == "parquet" and not _has_pyarrow():
        raise OutputError(f"-o {path}: Parquet needs pyarrow (pip install pyarrow); or "
                          "write a .csv")
    return path


def _cell(value: Any) -> str:
    if value is None:
        return ""
    if isinstance(value, float):
        return repr(value)
    return str(value)


def _columns(rows: Sequence[Mapping[str, Any]]) -> list[str]:
    columns: dict[str, None] = {}
    for row in rows:
        columns.update(dict.fromkeys(row))
    return list(columns)


def _write_csv(stream: TextIO, columns: Sequence[str], rows: Sequence[Mapping[str, Any]],
               header: bool = True) -> None:
    writer = csv.writer(stream, lineterminator="\n")
    if header:
        writer.writerow(columns)
    for row in rows:
        writer.writerow([_cell(row.get(c)) for c in columns])


def write_table(path: Path, rows: Sequence[Mapping[str, Any]], *,
                overwrite: bool = False) -> Path:
    """Write ``rows`` (each with a ``variant`` index) sorted by variant; returns the path."""
    path = table_path(path)
    ordered = sorted(rows, key=lambda row: row["variant"])
    columns = _columns(ordered)
    with replacing(path, overwrite=overwrite) as scratch:
        if table_format(path) == "parquet":
            import pyarrow as pa
            import pyarrow.parquet as pq

            table = pa.table({c: [row.get(c) for row in ordered] for c in columns})
            pq.write_table(table, scratch)
        else:
            text = io.StringIO()
            _write_csv(text, columns, ordered)
            scratch.write_text(text.getvalue())
    return path


class PartialRows:
    """Finished rows appended to a CSV file as they come, in finishing order, each whole:
    a write that fails part-way (a full disk) cuts the file back to the rows before it, so
    a reader never takes half a row for a row with empty cells."""

    def __init__(self, path: Path, *, overwrite: bool = False) -> None:
        self.path = path
        self.overwrite = overwrite
        self._fd: Optional[int] = None
        self._size = 0  # bytes of whole rows (the header's included) in the file
        self._columns: list[str] = []

    def add(self, row: Mapping[str, Any]) -> None:
        text = io.StringIO()
        if self._fd is None:
            self._columns = list(row)
            # Open across add() calls, so rows reach the disk as they come; close() shuts it.
            replace = os.O_TRUNC if self.overwrite else os.O_EXCL
            self._fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | replace, 0o666)
            _write_csv(text, self._columns, [])
        _write_csv(text, self._columns, [row], header=False)
        data = text.getvalue().encode()
        _append_whole(self._fd, data, self._size)
        self._size += len(data)

    def close(self, *, keep: bool) -> None:
        """Close the file; remove it unless ``keep`` and it holds a row."""
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None
        if not keep or not self._size:
            self.path.unlink(missing_ok=True)


def _append_whole(fd: int, data: bytes, size: int) -> None:
    """Write ``data`` at the end of the file of ``fd``, which holds ``size`` bytes, unbuffered;
    on an :class:`OSError` cut the file back to ``size`` bytes and raise it."""
    try:
        view = memoryview(data)
        while view:  # a write may take part of it (a disk filling up) before it fails
            view = view[os.write(fd, view):]
    except OSError:
        with contextlib.suppress(OSError):
            os.ftruncate(fd, size)
        raise
