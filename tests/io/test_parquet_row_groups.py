"""Parquet files read row group by row group give what the whole-table reading gives: the same
trace set, the same errors (issue 25: memory of reading)."""

from __future__ import annotations

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

import simcred.io.parquet as parquet
from simcred.compare import compare
from simcred.examples import lane_change_sets
from simcred.traces import TraceSet


def whole_table(path, monkeypatch):
    monkeypatch.setattr(parquet, "_read_row_groups", lambda p: None)
    try:
        return parquet.read(path)
    finally:
        monkeypatch.undo()


@pytest.mark.parametrize("row_group_size", [7, 100, 10_000])
def test_row_groups_give_the_whole_table_reading(tmp_path, monkeypatch, row_group_size):
    traces, _ = lane_change_sets(runs=20, steps=25, seed=3)
    traces = TraceSet(traces.signals, traces.time, traces.values, traces.offsets,
                      traces.run_ids, metadata={"units": {"x": "m"}})
    path = tmp_path / "a.parquet"
    pq.write_table(parquet.to_table(traces, where="test"), path,
                   row_group_size=row_group_size)  # runs span row groups
    assert parquet._read_row_groups(path) is not None  # the row-group reading is used
    got, expected = parquet.read(path), whole_table(path, monkeypatch)
    assert got.equals(expected) and got.equals(traces) and got.source == expected.source
    assert got.digest() == expected.digest() == traces.digest()


def test_a_missing_value_is_the_same_error(tmp_path, monkeypatch):
    traces, _ = lane_change_sets(runs=10, steps=20, seed=4)
    table = parquet.to_table(traces, where="test")
    x = table.column("x").to_numpy().copy()
    mask = np.zeros(len(x), dtype=bool)
    mask[57] = True
    table = table.set_column(table.schema.get_field_index("x"), "x", pa.array(x, mask=mask))
    path = tmp_path / "b.parquet"
    pq.write_table(table, path, row_group_size=50)
    assert parquet._read_row_groups(path) is None  # left to the whole-table reading
    with pytest.raises(Exception, match=r"column 'x', row 58: value is missing"):
        parquet.read(path)


def test_compare_of_paths_is_compare_of_sets(tmp_path):
    a, b = lane_change_sets(runs=40, steps=30, seed=5)
    a = TraceSet(a.signals, a.time, a.values, a.offsets, a.run_ids,
                 metadata={"units": {"y": "m"}})
    paths = [s.write(tmp_path / f"{name}.parquet") for s, name in ((a, "a"), (b, "b"))]
    options = dict(features=["x", "y"], bins=4, permutations=49, seed=2, baseline=1)
    from_paths = compare(*paths, **options)
    from_sets = compare(TraceSet.read(paths[0]), TraceSet.read(paths[1]), **options)
    assert from_paths.to_json() == from_sets.to_json()
    assert from_paths.units == ("", "m")
