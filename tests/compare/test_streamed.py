"""A Parquet set read without its time column (compare(path_a, path_b), issue 25 memory) is the
TraceSet read whole, less the time stamps: the same content hash, median step, values and runs;
any file a TraceSet refuses is read whole, with the TraceSet's own error."""

from __future__ import annotations

import numpy as np
import pyarrow.parquet as pq
import pytest

from helpers import random_walk_set
from simcred.compare import compare
from simcred.compare.method import Method
from simcred.compare.process import load_for
from simcred.compare.resample import sample_period
from simcred.compare.streamed import TimelessSet, read_timeless
from simcred.errors import TraceSetError
from simcred.io.parquet import to_table
from simcred.traces import TraceSet


def jittered_set(rng, runs: int, source: str = "<test>") -> TraceSet:
    """Runs of 2 to 12 steps at irregular times (an odd or even number of steps in all)."""
    out = []
    for length in rng.integers(2, 13, size=runs):
        t = np.cumsum(rng.uniform(0.05, 0.15, size=length)) + rng.uniform(-5, 5)
        out.append({"t": t, "x": rng.normal(size=length).cumsum(), "y": rng.normal(size=length)})
    return TraceSet.from_runs(out, run_ids=[f"r{i}" for i in range(runs)], source=source,
                              metadata={"units": {"x": "m"}})


def written(traces: TraceSet, path, row_group_size: int):
    """``traces`` as simcred writes Parquet, in row groups of ``row_group_size`` rows (runs
    span row groups)."""
    pq.write_table(to_table(traces, where=str(path)), path, row_group_size=row_group_size)
    return path


@pytest.mark.parametrize("seed,group", [(0, 5), (1, 7), (2, 1000), (3, 1), (4, 2)])
def test_timeless_set_is_the_trace_set_less_its_time(tmp_path, seed, group):
    rng = np.random.default_rng(seed)
    path = written(jittered_set(rng, int(rng.integers(1, 30))), tmp_path / "a.parquet", group)
    whole, timeless = TraceSet.read(path), read_timeless(path)
    assert isinstance(timeless, TimelessSet)
    assert timeless.info.digest == whole.digest()
    assert timeless.period == sample_period(whole)  # the median of the steps within runs
    assert timeless.facts() == type(timeless.facts()).of(whole)
    assert np.array_equal(timeless.values, whole.values)
    assert np.array_equal(timeless.offsets, whole.offsets)
    assert (timeless.info.runs, timeless.info.rows) == (whole.n_runs, whole.n_rows)
    assert timeless.source == whole.source and timeless.units == whole.units == {"x": "m"}


def test_comparison_of_paths_is_that_of_the_sets_read_whole(tmp_path):
    rng = np.random.default_rng(5)
    paths = [written(random_walk_set(rng, 40, drift, min_len=3), tmp_path / f"{n}.parquet", 64)
             for n, drift in (("a", 0.0), ("b", 0.4))]
    assert all(isinstance(load_for(p, Method()), TimelessSet) for p in paths)
    for options in (dict(bins=4), dict(bins=3, test="permutation", permutations=19),
                    dict(bins=3, test="bound"), dict(bins=3, history=2), dict(relevance=True)):
        from_paths = compare(*paths, seed=1, **options).to_json()
        assert from_paths == compare(*(TraceSet.read(p) for p in paths), seed=1,
                                     **options).to_json()


@pytest.mark.parametrize("options", [dict(time_bins=2), dict(resample=0.2),
                                     dict(test="response", features=["x", "y"],
                                          inputs=["y"])])
def test_options_that_need_time_read_the_set_whole(tmp_path, options):
    path = written(random_walk_set(np.random.default_rng(6), 5, 0.0), tmp_path / "a.parquet", 9)
    assert isinstance(load_for(path, Method(**options)), TraceSet)


def rows_replaced(path, column: str, row: int, value: float):
    table = pq.read_table(path)
    values = table.column(column).to_numpy().copy()
    values[row] = value
    pq.write_table(table.set_column(table.column_names.index(column), column, [values]), path,
                   row_group_size=4)
    return path


@pytest.mark.parametrize("column,row,value", [("t", 3, 0.0), ("t", 2, np.nan),
                                              ("x", 5, np.inf)])
def test_a_file_a_trace_set_refuses_gives_the_trace_sets_error(tmp_path, column, row, value):
    traces = TraceSet.from_runs([{"t": [0.0, 0.1, 0.2, 0.3, 0.4, 0.5], "x": np.arange(6.0)}] * 2,
                                run_ids=["r0", "r1"])
    path = rows_replaced(written(traces, tmp_path / "a.parquet", 4), column, row, value)
    assert read_timeless(path) is None
    with pytest.raises(TraceSetError) as whole:
        TraceSet.read(path)
    with pytest.raises(TraceSetError) as compared:
        compare(path, path)
    assert str(compared.value) == str(whole.value)


def test_rows_not_grouped_by_run_are_read_whole(tmp_path):
    traces = TraceSet.from_runs([{"t": [0.0, 0.1, 0.2], "x": [1.0, 2, 3]}] * 2, run_ids=["p", "q"])
    table = to_table(traces, where="x").take([0, 3, 1, 4, 2, 5])  # runs interleaved
    pq.write_table(table, tmp_path / "a.parquet")
    assert read_timeless(tmp_path / "a.parquet") is None
    assert read_timeless(tmp_path / "a.csv") is None  # another format (or no file)


def test_a_run_goes_on_across_an_empty_row_group(tmp_path):
    """The last time stamp before an empty row group is carried to the next one: the step
    1.0 → 1.1 counts (without it the median would be 0.15), and a decrease across it is seen."""
    for times, expected in (([0.0, 1.0, 1.1, 1.2], 0.1), ([0.0, 1.0, 0.5, 1.2], None)):
        traces = TraceSet.from_runs([{"t": [0.0, 1.0, 1.1, 1.2], "x": [1.0, 2, 3, 4]},
                                     {"t": [5.0, 5.2, 5.3], "x": [1.0, 2, 3]}],
                                    run_ids=["p", "q"])
        table = to_table(traces, where="x")
        table = table.set_column(1, "t", [times + [5.0, 5.2, 5.3]])
        path = tmp_path / "a.parquet"
        with pq.ParquetWriter(path, table.schema) as writer:
            for lo, n in ((0, 2), (2, 0), (2, 5)):  # rows, none, the rest
                writer.write_table(table.slice(lo, n))
        assert [pq.ParquetFile(path).metadata.row_group(i).num_rows for i in range(3)] == [2, 0, 5]
        timeless = read_timeless(path)
        if expected is None:
            assert timeless is None
            continue
        whole = TraceSet.read(path)
        assert timeless.period == sample_period(whole) == pytest.approx(expected)
        assert timeless.info.digest == whole.digest()
