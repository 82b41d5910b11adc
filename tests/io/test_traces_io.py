"""TraceSet file formats: exact round trips, run order, and one-line errors naming the culprit."""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from simcred.errors import TraceSetError
from simcred.traces import TraceSet

# -- helpers --------------------------------------------------------------------------------------

SPECIAL = [
    0.0, -0.0, 5e-324, -5e-324, 2.2250738585072014e-308, -2.2250738585071e-308,
    1.7976931348623157e308, -1.7976931348623157e308, 1e-300, 1e300, 0.1, 1 / 3, 2.0**60,
    123456789012345678.0, -1.0,
]
FLOATS = st.one_of(
    st.floats(allow_nan=False, allow_infinity=False, width=64),
    st.sampled_from(SPECIAL),
)
OBJECTS = ["ego", "cyclist", "ped", "lead", "ego.sensor"]
FIELDS = ["x", "y", "v", "yaw", "a_long"]
JSON = st.recursive(
    st.none() | st.booleans() | st.integers() | st.text(max_size=6)
    | st.floats(allow_nan=False, allow_infinity=False),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=5), inner,
                                                                max_size=3),
    max_leaves=6,
)


def bits(array) -> bytes:
    """The exact bytes of a float64 array (tells -0.0 from 0.0, unlike ``==``)."""
    return np.ascontiguousarray(array, dtype=np.float64).tobytes()


def assert_bitwise_equal(a, b) -> None:
    assert np.asarray(a).shape == np.asarray(b).shape
    assert bits(a) == bits(b)


def error_of(call, *args) -> str:
    """Run ``call(*args)``; it must raise a one-line TraceSetError (a ValueError). Return it."""
    with pytest.raises(TraceSetError) as info:
        call(*args)
    assert isinstance(info.value, ValueError)
    message = str(info.value)
    assert message
    assert "\n" not in message and "\r" not in message
    return message


def read_error(path: Path) -> str:
    return error_of(TraceSet.read, path)


def write_csv(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


@st.composite
def tracesets(draw):
    """(runs, run_ids, metadata): 1-5 runs of 2-20 steps, 1-4 dotted signals, finite floats."""
    pairs = draw(st.lists(st.tuples(st.sampled_from(OBJECTS), st.sampled_from(FIELDS)),
                          min_size=1, max_size=4, unique=True))
    signals = [f"{obj}.{name}" for obj, name in pairs]
    # run ids in natural order, which often differs from lexicographic order (run_2 < run_10)
    numbers = draw(st.lists(st.integers(0, 30), min_size=1, max_size=5, unique=True))
    run_ids = [f"run_{n}" for n in sorted(numbers)]
    runs = []
    for _ in run_ids:
        steps = draw(st.integers(2, 20))
        t = sorted(draw(st.lists(FLOATS, min_size=steps, max_size=steps, unique=True)))
        values = draw(hnp.arrays(np.float64, (steps, len(signals)), elements=FLOATS))
        run = {"t": np.array(t, dtype=np.float64)}
        run.update({name: values[:, j].copy() for j, name in enumerate(signals)})
        runs.append(run)
    metadata = draw(st.dictionaries(st.text(max_size=8), JSON, max_size=4))
    return runs, run_ids, metadata


# -- 1. exact round trips -------------------------------------------------------------------------


@settings(max_examples=50, deadline=None)
@given(tracesets())
def test_round_trip_is_exact_in_both_formats(case):
    runs, run_ids, metadata = case
    original = TraceSet.from_runs(runs, run_ids=run_ids, metadata=metadata, source="gen")
    with tempfile.TemporaryDirectory() as tmp:
        for target in (Path(tmp) / "csv_dir", Path(tmp) / "traces.parquet"):
            written = original.write(target)
            assert Path(written) == target
            back = TraceSet.read(target)
            assert back.equals(original), target
            assert back.digest() == original.digest(), target
            assert back.run_ids == tuple(run_ids)
            assert back.signals == original.signals
            assert dict(back.metadata) == metadata
            # independent of TraceSet.equals: every run's columns, bit for bit, as generated
            assert back.n_runs == len(runs)
            for i, run in enumerate(runs):
                got = back.run(i)
                assert list(got) == list(run)
                for name, column in run.items():
                    assert_bitwise_equal(got[name], column)


def test_csv_run_order_is_natural_not_lexicographic(tmp_path):
    ids = ["run_10", "run_2", "run_1", "run_100", "run_9"]
    for k, rid in enumerate(ids):
        write_csv(tmp_path / f"{rid}.csv", f"t,ego.x\n0,{k}\n1,{k}.5\n")
    traces = TraceSet.read(tmp_path)
    assert traces.run_ids == ("run_1", "run_2", "run_9", "run_10", "run_100")
    # each run kept its own rows: ego.x of run i starts with the index k it was written with
    assert traces.column("ego.x")[traces.offsets[:-1]].tolist() == [2.0, 1.0, 4.0, 0.0, 3.0]
    assert traces.run_sources == tuple(str(tmp_path / f"{r}.csv") for r in traces.run_ids)


def test_csv_columns_may_come_in_any_order(tmp_path):
    write_csv(tmp_path / "a.csv", "t,x,y\n0,1,2\n1,3,4\n")
    write_csv(tmp_path / "b.csv", "y,t,x\n20,0,10\n40,1,30\n")
    traces = TraceSet.read(tmp_path)
    assert traces.signals == ("x", "y")
    assert traces.values.tolist() == [[1, 2], [3, 4], [10, 20], [30, 40]]


def test_csv_negative_zero_survives(tmp_path):
    # an all-integer column is inferred as int64 by the CSV reader, where "-0" would become +0
    original = TraceSet.from_runs([{"t": [-0.0, 1.0], "x": [-0.0, 2.0]}], run_ids=["r"])
    back = TraceSet.read(original.write(tmp_path / "d"))
    assert np.signbit(back.time).tolist() == [True, False]
    assert np.signbit(back.values[:, 0]).tolist() == [True, False]
    assert back.digest() == original.digest()


def test_csv_write_replaces_old_runs(tmp_path):
    first = TraceSet.from_runs([{"t": [0, 1], "x": [0, 1]}] * 3, run_ids=["a", "b", "c"])
    second = TraceSet.from_runs([{"t": [0, 1], "x": [5, 6]}], run_ids=["z"])
    first.write(tmp_path / "d")
    assert TraceSet.read(second.write(tmp_path / "d")).equals(second)


# -- 2. Parquet with non-contiguous runs ----------------------------------------------------------


def test_parquet_interleaved_runs_grouped_by_first_appearance(tmp_path):
    table = pa.table({
        "run": ["b", "a", "b", "c", "a", "b", "c"],
        "t": [0.0, 10.0, 1.0, 5.0, 11.0, 2.0, 6.0],
        "ego.x": [1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0],
        "ego.y": [-1.0, -2.0, -3.0, -4.0, -5.0, -6.0, -7.0],
    })
    path = tmp_path / "mixed.parquet"
    pq.write_table(table, path, row_group_size=3)  # several row groups: chunked columns
    traces = TraceSet.read(path)
    assert traces.run_ids == ("b", "a", "c")
    assert traces.offsets.tolist() == [0, 3, 5, 7]
    assert traces.time.tolist() == [0.0, 1.0, 2.0, 10.0, 11.0, 5.0, 6.0]
    assert traces.column("ego.x").tolist() == [1.0, 3.0, 6.0, 2.0, 5.0, 4.0, 7.0]
    assert traces.column("ego.y").tolist() == [-1.0, -3.0, -6.0, -2.0, -5.0, -4.0, -7.0]
    assert traces.signals == ("ego.x", "ego.y")
    assert dict(traces.metadata) == {}


def test_parquet_integer_run_column(tmp_path):
    table = pa.table({
        "run": pa.array([7, 3, 7, 3, 12, 12], type=pa.int64()),
        "t": pa.array([0, 0, 1, 1, 0, 1], type=pa.int32()),
        "x": [0.5, 1.5, 2.5, 3.5, 4.5, 5.5],
    })
    path = tmp_path / "ints.pq"
    pq.write_table(table, path)
    traces = TraceSet.read(path)
    assert traces.run_ids == ("7", "3", "12")
    assert traces.time.dtype == np.float64
    assert traces.time.tolist() == [0, 1, 0, 1, 0, 1]
    assert traces.column("x").tolist() == [0.5, 2.5, 1.5, 3.5, 4.5, 5.5]
    # written back it has string run ids and reads to the same content
    assert TraceSet.read(traces.write(tmp_path / "again.parquet")).equals(traces)


def test_parquet_refuses_a_signal_named_run(tmp_path):
    # a signal called "run" would silently replace the run column of the file
    traces = TraceSet.from_runs([{"t": [0, 1], "run": [5, 5]}, {"t": [0, 1], "run": [6, 6]}])
    message = error_of(traces.write, tmp_path / "clash.parquet")
    assert "'run'" in message
    assert not (tmp_path / "clash.parquet").exists()
    # a CSV directory has no run column, so there it is fine
    assert TraceSet.read(traces.write(tmp_path / "d")).signals == ("run",)


# -- 3. bad input: CSV directory ------------------------------------------------------------------


def test_csv_missing_time_column(tmp_path):
    write_csv(tmp_path / "run_1.csv", "x,y\n0,1\n1,2\n")
    message = read_error(tmp_path)
    assert "run_1.csv" in message and "'t'" in message


def test_csv_missing_time_column_in_a_later_file(tmp_path):
    write_csv(tmp_path / "run_1.csv", "t,x\n0,1\n1,2\n")
    write_csv(tmp_path / "run_2.csv", "x,t_s\n0,1\n1,2\n")
    message = read_error(tmp_path)
    assert "run_2.csv" in message and "run_1.csv" not in message


@pytest.mark.parametrize(
    ("cell", "shown"), [("nan", "nan"), ("NaN", "nan"), ("inf", "inf"), ("-inf", "-inf")]
)
def test_csv_non_finite_value(tmp_path, cell, shown):
    write_csv(tmp_path / "run_1.csv", "t,x,y\n0,1,2\n1,2,3\n")
    write_csv(tmp_path / "run_2.csv", f"t,x,y\n0,1,2\n1,2,3\n2,3,{cell}\n")
    message = read_error(tmp_path)
    assert "run_2.csv" in message and "run_1.csv" not in message
    assert "'y'" in message and "row 3" in message
    assert shown in message


def test_csv_non_finite_time(tmp_path):
    write_csv(tmp_path / "a.csv", "t,x\n0,1\ninf,2\n")
    message = read_error(tmp_path)
    assert "a.csv" in message and "'t'" in message and "row 2" in message


def test_csv_empty_value(tmp_path):
    write_csv(tmp_path / "run_1.csv", "t,ego.x,ego.y\n0,1,2\n1,,3\n2,3,4\n")
    message = read_error(tmp_path)
    assert "run_1.csv" in message and "'ego.x'" in message and "row 2" in message
    assert "missing" in message


def test_csv_column_with_every_value_empty(tmp_path):
    write_csv(tmp_path / "run_1.csv", "t,x,y\n0,1,\n1,2,\n")
    message = read_error(tmp_path)
    assert "run_1.csv" in message and "'y'" in message and "row 1" in message
    assert "missing" in message


def test_csv_non_numeric_column(tmp_path):
    write_csv(tmp_path / "run_1.csv", "t,x,label\n0,1,car\n1,2,bike\n")
    message = read_error(tmp_path)
    assert "run_1.csv" in message and "'label'" in message and "numeric" in message


def test_csv_one_bad_cell_makes_column_non_numeric(tmp_path):
    write_csv(tmp_path / "r.csv", "t,x\n0,1\n1,2x\n")
    message = read_error(tmp_path)
    assert "r.csv" in message and "'x'" in message


@pytest.mark.parametrize(("times", "row"), [("0,1,1", 3), ("0,2,1,3", 3), ("5,4", 2)])
def test_csv_time_not_increasing(tmp_path, times, row):
    write_csv(tmp_path / "run_1.csv", "t,x\n0,0\n1,1\n")
    lines = "".join(f"{t},{k}\n" for k, t in enumerate(times.split(",")))
    write_csv(tmp_path / "run_2.csv", "t,x\n" + lines)
    message = read_error(tmp_path)
    assert "run_2.csv" in message and "run_1.csv" not in message
    assert f"row {row}" in message and "increasing" in message


def test_csv_run_with_one_row(tmp_path):
    write_csv(tmp_path / "run_1.csv", "t,x\n0,0\n1,1\n")
    write_csv(tmp_path / "run_2.csv", "t,x\n0,0\n")
    message = read_error(tmp_path)
    assert "run_2.csv" in message and "1 step" in message


def test_csv_run_with_header_only(tmp_path):
    write_csv(tmp_path / "run_1.csv", "t,x\n0,0\n1,1\n")
    write_csv(tmp_path / "run_2.csv", "t,x\n")
    message = read_error(tmp_path)
    assert "run_2.csv" in message and "0 step" in message


def test_csv_empty_directory(tmp_path):
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "notes.txt").write_text("not a run\n")
    message = read_error(tmp_path / "empty")
    assert str(tmp_path / "empty") in message and "empty" in message


def test_csv_files_with_different_headers(tmp_path):
    write_csv(tmp_path / "run_1.csv", "t,x,y\n0,0,0\n1,1,1\n")
    write_csv(tmp_path / "run_2.csv", "t,x,y\n0,0,0\n1,1,1\n")
    write_csv(tmp_path / "run_3.csv", "t,x,z\n0,0,0\n1,1,1\n")
    message = read_error(tmp_path)
    assert "run_3.csv" in message
    assert "run_1.csv" not in message and "run_2.csv" not in message
    assert "'y'" in message and "'z'" in message


def test_csv_file_with_an_extra_column(tmp_path):
    write_csv(tmp_path / "run_1.csv", "t,x\n0,0\n1,1\n")
    write_csv(tmp_path / "run_2.csv", "t,x,w\n0,0,0\n1,1,1\n")
    message = read_error(tmp_path)
    assert "run_2.csv" in message and "'w'" in message


def test_csv_duplicate_column_names(tmp_path):
    write_csv(tmp_path / "run_1.csv", "t,x,x\n0,0,0\n1,1,1\n")
    message = read_error(tmp_path)
    assert "run_1.csv" in message and "duplicate" in message


def test_csv_ragged_row(tmp_path):
    write_csv(tmp_path / "run_1.csv", "t,x,y\n0,0,0\n1,1,1\n")
    write_csv(tmp_path / "run_2.csv", "t,x,y\n0,0,0\n1,1\n2,2,2\n")
    message = read_error(tmp_path)
    assert "run_2.csv" in message and "run_1.csv" not in message
    assert "unreadable" in message


def test_csv_empty_file(tmp_path):
    write_csv(tmp_path / "run_1.csv", "t,x\n0,0\n1,1\n")
    write_csv(tmp_path / "run_2.csv", "")
    message = read_error(tmp_path)
    assert "run_2.csv" in message and "run_1.csv" not in message


def test_csv_bad_metadata(tmp_path):
    write_csv(tmp_path / "run_1.csv", "t,x\n0,0\n1,1\n")
    write_csv(tmp_path / "traceset.json", "{not json\n")
    assert "traceset.json" in read_error(tmp_path)
    write_csv(tmp_path / "traceset.json", "[1, 2]\n")
    assert "traceset.json" in read_error(tmp_path)


def test_non_existent_path(tmp_path):
    for name in ("nowhere", "nowhere.parquet"):
        message = read_error(tmp_path / name)
        assert str(tmp_path / name) in message and "no such" in message


def test_txt_file_is_not_a_trace_set(tmp_path):
    path = write_csv(tmp_path / "runs.txt", "t,x\n0,0\n1,1\n")
    message = read_error(path)
    assert "runs.txt" in message and "not a trace set" in message


def test_csv_file_path_is_one_long_format_run(tmp_path):
    # a single CSV file is the long format (simcred.io.longformat): one run named by its stem
    path = write_csv(tmp_path / "run_1.csv", "t,x\n0,0\n1,1\n")
    traces = TraceSet.read(path)
    assert traces.run_ids == ("run_1",) and traces.signals == ("x",)
    assert traces.column("x").tolist() == [0.0, 1.0]


# -- 3. bad input: Parquet ------------------------------------------------------------------------


def test_parquet_missing_run_column(tmp_path):
    path = tmp_path / "norun.parquet"
    pq.write_table(pa.table({"t": [0.0, 1.0], "x": [0.0, 1.0]}), path)
    message = read_error(path)
    assert "norun.parquet" in message and "'run'" in message


def test_parquet_missing_time_column(tmp_path):
    path = tmp_path / "notime.parquet"
    pq.write_table(pa.table({"run": ["a", "a"], "x": [0.0, 1.0]}), path)
    message = read_error(path)
    assert "notime.parquet" in message and "'t'" in message


def test_parquet_zero_rows(tmp_path):
    path = tmp_path / "zero.parquet"
    table = pa.table({"run": pa.array([], pa.string()), "t": pa.array([], pa.float64()),
                      "x": pa.array([], pa.float64())})
    pq.write_table(table, path)
    message = read_error(path)
    assert "zero.parquet" in message and "empty" in message


@pytest.mark.parametrize("content", [b"", b"this is not parquet\n" * 10, b"PAR1garbagePAR1"])
def test_parquet_garbage_bytes(tmp_path, content):
    path = tmp_path / "garbage.parquet"
    path.write_bytes(content)
    message = read_error(path)
    assert "garbage.parquet" in message and "Parquet" in message


@pytest.mark.parametrize(("bad", "shown"), [(float("nan"), "nan"), (float("-inf"), "-inf")])
def test_parquet_non_finite_signal(tmp_path, bad, shown):
    path = tmp_path / "nan.parquet"
    table = pa.table({
        "run": ["a", "b", "a", "b", "b"],
        "t": [0.0, 0.0, 1.0, 1.0, 2.0],
        "ego.x": [0.0, 0.0, 1.0, 1.0, 2.0],
        "ego.v": [0.0, 0.0, 1.0, 1.0, bad],
    })
    pq.write_table(table, path)
    message = read_error(path)
    assert "nan.parquet" in message and "'b'" in message and "'ego.v'" in message
    assert "row 3" in message and shown in message


def test_parquet_missing_value(tmp_path):
    path = tmp_path / "null.parquet"
    pq.write_table(pa.table({"run": ["a", "a"], "t": [0.0, 1.0], "x": [1.0, None]}), path)
    message = read_error(path)
    assert "null.parquet" in message and "'x'" in message and "missing" in message


def test_parquet_non_numeric_signal(tmp_path):
    path = tmp_path / "str.parquet"
    pq.write_table(pa.table({"run": ["a", "a"], "t": [0.0, 1.0], "kind": ["car", "car"]}), path)
    message = read_error(path)
    assert "str.parquet" in message and "'kind'" in message and "numeric" in message


def test_parquet_time_not_increasing_names_run(tmp_path):
    path = tmp_path / "time.parquet"
    pq.write_table(pa.table({"run": ["a", "b", "a", "b"], "t": [0.0, 0.0, 1.0, 0.0],
                             "x": [0.0, 0.0, 0.0, 0.0]}), path)
    message = read_error(path)
    assert "time.parquet" in message and "'b'" in message and "row 2" in message


def test_parquet_run_with_one_row(tmp_path):
    path = tmp_path / "short.parquet"
    pq.write_table(pa.table({"run": ["a", "b", "a"], "t": [0.0, 0.0, 1.0], "x": [0.0] * 3}), path)
    message = read_error(path)
    assert "short.parquet" in message and "'b'" in message and "1 step" in message


# -- 4. from_runs ---------------------------------------------------------------------------------


def test_from_runs_mismatched_signals_names_the_run():
    runs = [
        {"t": [0, 1], "ego.x": [0, 1], "ego.y": [0, 1]},
        {"t": [0, 1], "ego.x": [0, 1], "ego.y": [0, 1]},
        {"t": [0, 1], "ego.x": [0, 1], "ego.z": [0, 1]},
    ]
    message = error_of(lambda: TraceSet.from_runs(runs, run_ids=["r1", "r2", "r3"], source="src"))
    assert "src" in message and "'r3'" in message
    assert "'r1'" not in message and "'r2'" not in message
    assert "ego.y" in message and "ego.z" in message


def test_from_runs_extra_signal_and_default_ids():
    runs = [{"t": [0, 1], "x": [0, 1]}, {"t": [0, 1], "x": [0, 1], "y": [2, 3]}]
    message = error_of(TraceSet.from_runs, runs)
    assert "run '1'" in message and "'y'" in message


def test_from_runs_missing_time_names_the_run():
    runs = [{"t": [0, 1], "x": [0, 1]}, {"x": [0, 1]}]
    message = error_of(lambda: TraceSet.from_runs(runs, run_ids=["ok", "bad"]))
    assert "'bad'" in message and "'t'" in message


def test_from_runs_same_signals_in_other_order_is_fine():
    runs = [{"t": [0, 1], "x": [0, 1], "y": [2, 3]}, {"y": [6, 7], "t": [0, 1], "x": [4, 5]}]
    traces = TraceSet.from_runs(runs)
    assert traces.signals == ("x", "y")
    assert traces.values.tolist() == [[0, 2], [1, 3], [4, 6], [5, 7]]


def test_from_runs_empty():
    assert "empty" in error_of(TraceSet.from_runs, [])


# -- 5. features ----------------------------------------------------------------------------------


def test_features_unknown_signal_names_signal_and_source():
    traces = TraceSet.from_runs([{"t": [0, 1], "x": [0, 1], "ego.v": [2, 3]}],
                                source="data/sim_runs")
    message = error_of(traces.features, ["x", "nope"])
    assert "'nope'" in message and "data/sim_runs" in message
    assert "ego.v" in message  # lists the known signals
    assert traces.features(["ego.v", "x"]).tolist() == [[2, 0], [3, 1]]


def test_column_unknown_signal_names_source(tmp_path):
    write_csv(tmp_path / "r.csv", "t,x\n0,0\n1,1\n")
    traces = TraceSet.read(tmp_path)
    message = error_of(traces.column, "y")
    assert "'y'" in message and str(tmp_path) in message


def test_csv_directory_reads_any_case_suffix_and_refuses_non_files(tmp_path):
    directory = tmp_path / "runs"
    directory.mkdir()
    for name in ("run_0.csv", "run_1.CSV"):
        (directory / name).write_text("t,x\n0,1\n0.1,2\n")
    assert TraceSet.read(directory).run_ids == ("run_0", "run_1")
    (directory / "run_1.csv").write_text("t,x\n0,1\n0.1,2\n")
    with pytest.raises(TraceSetError, match="run 'run_1' also in"):
        TraceSet.read(directory)
    (directory / "run_1.csv").unlink()
    os.mkfifo(directory / "run_2.csv")
    with pytest.raises(TraceSetError, match="run_2.csv: not a regular file"):
        TraceSet.read(directory)


@pytest.mark.parametrize(("header", "message"), [
    (b"t,\xff\n", "header is not UTF-8"),
    (("t," + ",".join(f"c{i}" for i in range(10_000)) + "\n").encode(), "more than 10000"),
])
def test_csv_headers_are_checked_before_parsing(tmp_path, header, message):
    directory = tmp_path / "runs"
    directory.mkdir()
    (directory / "run_0.csv").write_bytes(header + b"0,1\n")
    with pytest.raises(TraceSetError, match=message):
        TraceSet.read(directory)


def test_deeply_nested_metadata_is_one_line_error(tmp_path):
    directory = tmp_path / "runs"
    directory.mkdir()
    (directory / "run_0.csv").write_text("t,x\n0,1\n")
    (directory / "traceset.json").write_text("[" * 100_000 + "]" * 100_000)
    with pytest.raises(TraceSetError, match="nested too deeply"):
        TraceSet.read(directory)


def test_parquet_run_ids_that_differ_only_by_a_nul_stay_two_runs(tmp_path):
    path = tmp_path / "nul.parquet"
    pq.write_table(pa.table({"run": ["r0", "r0", "r0\x00", "r0\x00"], "t": [0.0, 0.1, 0.0, 0.1],
                             "x": [1.0, 2.0, 3.0, 4.0]}), path)
    traces = TraceSet.read(path)
    assert traces.run_ids == ("r0", "r0\x00") and traces.lengths.tolist() == [2, 2]
    with pytest.raises(TraceSetError, match="cannot be a file name"):
        traces.write(tmp_path / "as_csv")
