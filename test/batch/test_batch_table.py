"""The sweep table as Parquet: the same values as the CSV one, the same bytes however many
workers ran it."""
from __future__ import annotations

import csv
import math
from pathlib import Path

import pytest

from hecker_dynamics.batch.engines import ProcessPool
from hecker_dynamics.batch.metrics import parse_metric
from hecker_dynamics.batch.run import sweep
from hecker_dynamics.batch.variants import make_variants, parse_setting

pq = pytest.importorskip("pyarrow.parquet", reason="pyarrow is not installed (the test extra)")

SEC = 1_000_000_000
#: A wall makes the contact columns count; the metric is a float column of its own.
SETTINGS = ("bodies.left.mass=0.5,2", "bodies.right.velocity[0]=-1:1:3")
METRIC = "gap=right.x - left.x"


def _sweep(path: Path, workers: int, **variants) -> Path:
    engine = ProcessPool(workers)
    try:
        return sweep(make_variants("sample", [parse_setting(s) for s in SETTINGS],
                                   duration_ns=SEC // 2, **variants),
                     engine, path, metrics=[parse_metric(METRIC)], progress=False)
    finally:
        engine.close()


def _same(text: str, value) -> bool:
    """A CSV cell (``repr`` of a float, ``str`` otherwise, empty for none) against the
    Parquet value of the same row and column."""
    if value is None:
        return text == ""
    if isinstance(value, float):
        return (math.isnan(value) and text == "nan") or float(text) == value
    if isinstance(value, bool):
        return text == str(value)
    return type(value)(text) == value


def test_parquet_equals_csv_value_for_value_and_workers_do_not_change_its_bytes(tmp_path):
    one = _sweep(tmp_path / "one.parquet", 1, samples=5, seed=3)
    two = _sweep(tmp_path / "two.parquet", 2, samples=5, seed=3)
    assert one.suffix == ".parquet" and one.read_bytes() == two.read_bytes()
    text = _sweep(tmp_path / "one.csv", 2, samples=5, seed=3)
    with open(text, newline="") as handle:
        rows = list(csv.reader(handle))
    table = pq.read_table(one)
    assert table.column_names == rows[0]
    assert table.num_rows == len(rows) - 1 == 5
    columns = table.to_pydict()
    for index, row in enumerate(rows[1:]):
        for name, cell in zip(rows[0], row):
            assert _same(cell, columns[name][index]), (name, index, cell,
                                                        columns[name][index])
    # Floats stay doubles: the metric is the difference of the two final x columns exactly.
    assert columns["gap"] == [r - left for r, left in zip(columns["right.x"],
                                                          columns["left.x"])]


def test_without_a_suffix_the_table_is_parquet_where_pyarrow_is(tmp_path):
    path = _sweep(tmp_path / "results", 1)
    assert path.name == "results.parquet"
    assert pq.read_table(path).num_rows == 6
