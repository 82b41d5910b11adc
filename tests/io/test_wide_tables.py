"""Wide tables: 10,000 columns read in linear time, and the column limit in every format."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from simcred.errors import TraceSetError
from simcred.io import csvdir, longformat, parquet
from simcred.io._columns import MAX_COLUMNS
from simcred.traces import TraceSet


def _csv(path: Path, names: list[str], rows: np.ndarray) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    lines = [",".join(names), *(",".join(repr(float(v)) for v in row) for row in rows)]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def _one_run(rows: int, signals: int) -> TraceSet:
    values = np.arange(rows * signals, dtype=np.float64).reshape(rows, signals) / 7
    return TraceSet.from_runs([{"t": np.arange(rows, dtype=np.float64),
                                **{f"s{j}": values[:, j] for j in range(signals)}}],
                              run_ids=["a"])


#: format -> (suffix, writer, reader)
FORMATS = {"csv-dir": ("", TraceSet.write, csvdir.read),
           "parquet": (".parquet", TraceSet.write, parquet.read),
           "long csv": (".csv", longformat.write, longformat.read)}


@pytest.mark.parametrize("name", FORMATS)
def test_ten_thousand_columns_read_back_exactly(name, tmp_path):
    """2 rows x 10,000 columns (t, run, 9,998 signals) read back value for value. Their speed
    (linear in the columns, < 5 s, as a ratio to 5,000 rows x 2 columns) is measured by
    benchmarks/wide_columns.py (docs/benchmarks.md), not asserted here: no wall-clock time in
    a test."""
    suffix, write, read = FORMATS[name]
    wide = _one_run(2, MAX_COLUMNS - 2)
    path = tmp_path / f"wide{suffix}"
    write(wide, path)
    found = read(path)
    assert found.values.shape == (2, MAX_COLUMNS - 2)
    assert found.signals == wide.signals
    np.testing.assert_array_equal(found.values, wide.values)


def test_csv_header_over_the_limit_is_refused(tmp_path):
    path = _csv(tmp_path / "d" / "r.csv", ["t", *(f"s{j}" for j in range(MAX_COLUMNS))],
                np.zeros((2, MAX_COLUMNS + 1)))
    with pytest.raises(TraceSetError, match="more than 10000"):
        csvdir.read(path.parent)


def test_quoted_newline_in_a_csv_header_does_not_hide_columns(tmp_path):
    names = ["t", '"a\nb"', *(f"s{j}" for j in range(MAX_COLUMNS))]
    path = _csv(tmp_path / "d" / "r.csv", names, np.zeros((2, len(names))))
    with pytest.raises(TraceSetError, match="more than 10000"):
        csvdir.read(path.parent)


def _wide_table(columns: int) -> pa.Table:
    return pa.table({"run": ["a", "a"], "t": [0.0, 1.0],
                     **{f"s{j}": [0.0, 1.0] for j in range(columns - 2)}})


@pytest.mark.parametrize("reader", [parquet.read, longformat.read], ids=["parquet", "long"])
def test_parquet_over_the_limit_is_refused_before_reading(reader, tmp_path):
    path = tmp_path / "w.parquet"
    pq.write_table(_wide_table(MAX_COLUMNS + 1), path)
    with pytest.raises(TraceSetError, match="more than 10000"):
        reader(path)


def test_long_csv_over_the_limit_is_refused(tmp_path):
    names = ["run", "t", *(f"s{j}" for j in range(MAX_COLUMNS))]
    path = tmp_path / "long.csv"
    path.write_text(",".join(names) + "\n" + ",".join(["a", *["0"] * (len(names) - 1)]) + "\n",
                    encoding="utf-8")
    with pytest.raises(TraceSetError, match="more than 10000"):
        longformat.read(path)


@pytest.mark.parametrize("reader", [parquet.read, longformat.read], ids=["parquet", "long"])
def test_duplicate_column_names_are_one_line(reader, tmp_path):
    path = tmp_path / "d.csv" if reader is longformat.read else tmp_path / "d.parquet"
    if reader is longformat.read:
        path.write_text("run,t,x,x\na,0,1,2\na,1,1,2\n", encoding="utf-8")
    else:
        pq.write_table(pa.Table.from_arrays([pa.array(["a", "a"]), pa.array([0.0, 1.0]),
                                             pa.array([1.0, 2.0]), pa.array([1.0, 2.0])],
                                            names=["run", "t", "x", "x"]), path)
    with pytest.raises(TraceSetError, match=r"'x' appears more than once|matches for .*\(x\)"):
        reader(path)


def test_an_a9_recording_over_the_limit_is_refused(tmp_path):
    from simcred.io.a9 import read_a9

    path = tmp_path / "a9.csv"
    names = ["timestamp", *(f"c{j}" for j in range(MAX_COLUMNS))]
    path.write_text(",".join(names) + "\n" + ",".join(["0"] * len(names)) + "\n")
    with pytest.raises(TraceSetError, match="more than 10000"):
        read_a9(path)


# -- the limit in the formats whose signals are not one file's columns ---------------------------


def test_long_csv_objects_turned_into_too_many_signals_are_refused(tmp_path):
    """Four columns, but 10,000 objects x 1 value: t + 10,000 signals."""
    objects = np.repeat(np.arange(MAX_COLUMNS), 2)
    lines = ["run,t,id,x", *(f"a,{k % 2},{o},1.0" for k, o in enumerate(objects))]
    path = tmp_path / "objects.csv"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    with pytest.raises(TraceSetError, match=r"run 'a': 10001 columns, more than 10000"):
        longformat.read(path, run_column="run", object_column="id")


def test_sumo_fcd_with_too_many_vehicles_as_signals_is_refused(tmp_path):
    """2,500 vehicles x 5 attributes (x, y, angle, speed, pos) as signals of one run."""
    from simcred.io import sumo_fcd

    vehicles = "".join(f'<vehicle id="v{j}" x="1" y="2" angle="0" speed="3" pos="4"/>'
                       for j in range(2500))
    steps = "".join(f'<timestep time="{t}">{vehicles}</timestep>' for t in (0.0, 1.0))
    path = tmp_path / "fcd.xml"
    path.write_text(f"<fcd-export>{steps}</fcd-export>", encoding="utf-8")
    with pytest.raises(TraceSetError, match="12501 columns, more than 10000"):
        sumo_fcd.read(path, objects_as="signals")


def _wide_csv_text(columns: int) -> str:
    return ",".join(["Time", *(f"c{j}" for j in range(columns - 1))]) + "\n" + \
        ",".join(["0"] * columns) + "\n"


def test_a_levelx_tracks_file_over_the_limit_is_refused(tmp_path):
    from simcred.io import levelx

    for name in ("01_tracks.csv", "01_tracksMeta.csv", "01_recordingMeta.csv"):
        (tmp_path / name).write_text(_wide_csv_text(MAX_COLUMNS + 1), encoding="utf-8")
    with pytest.raises(TraceSetError, match="more than 10000"):
        levelx.read(tmp_path)


def test_an_openacc_file_over_the_limit_is_refused(tmp_path):
    from simcred.io.openacc import META_ROWS, read_recording

    path = tmp_path / "acc.csv"
    path.write_text("".join(f"{key},x\n" for key in META_ROWS) + _wide_csv_text(MAX_COLUMNS + 1),
                    encoding="utf-8")
    with pytest.raises(TraceSetError, match="more than 10000"):
        read_recording(path)


def test_a_parquet_data_set_partition_over_the_limit_is_refused(tmp_path):
    from simcred.io.dataset import ParquetDataset

    pq.write_table(_wide_table(MAX_COLUMNS + 1), tmp_path / "part-0.parquet")
    with pytest.raises(TraceSetError, match="more than 10000"):
        ParquetDataset.open(tmp_path)


def test_too_many_ros_fields_in_a_run_are_refused():
    from simcred.io import rosbag

    fields = {f"f{j}": np.zeros(2) for j in range(MAX_COLUMNS)}
    with pytest.raises(TraceSetError, match="10001 columns, more than 10000"):
        rosbag._run("r", {"odom": (np.arange(2.0), fields, None)}, "bag")


def test_an_mdf_file_with_too_many_channels_is_refused(tmp_path):
    asammdf = pytest.importorskip("asammdf")
    from simcred.io import mdf

    t = np.arange(2.0)
    signals = [asammdf.Signal(np.zeros(2), t, name=f"c{j}") for j in range(MAX_COLUMNS)]
    path = tmp_path / "wide.mf4"
    with asammdf.MDF() as file:
        file.append(signals)
        file.save(path)
    with pytest.raises(TraceSetError, match="10001 columns, more than 10000"):
        mdf.read(path)
