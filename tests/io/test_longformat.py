"""Long-format CSV/Parquet: hand-computed readings, documented missing-row rules, round trips."""

from __future__ import annotations

import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from simcred.errors import OptionError, SimcredError, TraceSetError
from simcred.io import longformat, read, write
from simcred.traces import TraceSet

LOG = """trip,time,id,x,v,lane
b,0.1,7,10,1.5,left
a,0.0,7,0,2,left
a,0.0,12,5,3,right
a,0.1,12,6,3.5,right
a,0.1,7,1,2.5,left
b,0.0,7,9,1,left
b,0.0,12,20,0,right
b,0.1,12,21,-0,right
"""


def one_line_error(call, *args, **kwargs) -> str:
    with pytest.raises(SimcredError) as info:
        call(*args, **kwargs)
    message = str(info.value)
    assert message and "\n" not in message
    return message


def write_text(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def test_logger_export_by_hand(tmp_path):
    path = write_text(tmp_path / "log.csv", LOG)
    ts = read(path, run_column="trip", time_column="time", object_column="id")
    # runs by first appearance, objects by first appearance, rows sorted by time per run
    assert ts.run_ids == ("b", "a")
    assert ts.signals == ("obj7.x", "obj7.v", "obj12.x", "obj12.v")
    assert ts.time.tolist() == [0.0, 0.1, 0.0, 0.1]
    assert ts.values.tolist() == [[9, 1, 20, 0], [10, 1.5, 21, 0], [0, 2, 5, 3], [1, 2.5, 6, 3.5]]
    assert np.signbit(ts.column("obj12.v")).tolist() == [False, True, False, False]
    assert ts.metadata["skipped_columns"] == ["lane"]


def test_objects_as_runs_and_prefix(tmp_path):
    path = write_text(tmp_path / "log.csv", LOG)
    ts = read(path, run_column="trip", time_column="time", object_column="id",
              objects_as="runs", signals=["x"])
    assert ts.run_ids == ("b.obj7", "a.obj7", "a.obj12", "b.obj12")
    assert ts.signals == ("x",)
    assert ts.column("x").tolist() == [9, 10, 0, 1, 5, 6, 20, 21]
    named = read(path, run_column="trip", time_column="time", object_column="id",
                 object_prefix="veh", signals=["v"])
    assert named.signals == ("veh7.v", "veh12.v")


def test_without_run_or_object_column_the_file_is_one_run(tmp_path):
    path = write_text(tmp_path / "drive_3.csv", "t,gap,speed\n0,10,5\n0.5,9.5,5.5\n1,9,6\n")
    ts = read(path)
    assert ts.run_ids == ("drive_3",) and ts.signals == ("gap", "speed")
    assert ts.values.tolist() == [[10, 5], [9.5, 5.5], [9, 6]]


def test_missing_rows_error_names_run_object_and_time(tmp_path):
    text = "run,t,obj,x\n1,0,ego,0\n1,0,lead,5\n1,1,ego,1\n1,2,ego,2\n1,2,lead,7\n"
    path = write_text(tmp_path / "gaps.csv", text)
    message = one_line_error(read, path, run_column="run", object_column="obj")
    assert "run '1'" in message and "object 'lead'" in message and "t=1.0" in message
    kept = read(path, run_column="run", object_column="obj", missing="intersect")
    assert kept.time.tolist() == [0, 2]
    assert kept.values.tolist() == [[0, 5], [2, 7]]
    assert kept.metadata["rows_dropped_by_intersect"] == 1


def test_a_column_an_object_never_has_is_not_its_signal(tmp_path):
    text = "t,obj,x,brake\n0,ego,0,0.5\n0,lead,5,\n1,ego,1,0.25\n1,lead,6,\n"
    ts = read(write_text(tmp_path / "f.csv", text), object_column="obj")
    assert ts.signals == ("ego.x", "ego.brake", "lead.x")
    text_partial = "t,obj,x,brake\n0,ego,0,0.5\n0,lead,5,\n1,ego,1,\n1,lead,6,\n"
    message = one_line_error(read, write_text(tmp_path / "g.csv", text_partial),
                             object_column="obj")
    assert "'brake'" in message and "row 3" in message


@pytest.mark.parametrize(("text", "options", "expected"), [
    ("t,obj,x\n0,a,1\n0,a,2\n1,a,3\n", {"object_column": "obj"}, "rows 1 and 2"),
    ("t,x\n0,1\n1,nan\n", {}, "row 2"),
    ("t,x\n0,1\n1,inf\n", {}, "value is inf"),
    ("time,x\n0,1\n1,2\n", {}, "no column 't'"),
    ("t,x\n0,1\n1,2\n", {"run_column": "trip"}, "no column 'trip'"),
    ("t,x,name\n0,1,a\n1,2,b\n", {"signals": ["name"]}, "'name' is not numeric"),
    ("t,name\n0,a\n1,b\n", {}, "no numeric value columns"),
    ("t,x\n0,1\n", {}, "1 time step"),
    ("t,x\n", {}, "empty"),
    ("t,x\n0,1\n1,2\n", {"missing": "drop"}, "missing must be one of"),
    ("t,x\n0,1\n1,2\n", {"run_column": "t"}, "must be different"),
    ("r,t,obj,x\n1,0,a,1\n1,1,a,2\n2,0,b,1\n2,1,b,2\n", {"run_column": "r", "object_column": "obj"},
     "signal names differ"),
    ("t,x\n0,1\n1,2\n", {"layout": "scenario"}, "has no option 'layout'"),
])
def test_bad_input_is_one_line(tmp_path, text, options, expected):
    path = write_text(tmp_path / "bad.csv", text)
    assert expected in one_line_error(read, path, **options)


def test_unreadable_files(tmp_path):
    path = tmp_path / "junk.parquet"
    path.write_bytes(b"not parquet")
    assert "unreadable Parquet" in one_line_error(read, path, run_column="run")
    assert "no such file" in one_line_error(read, tmp_path / "none.csv")


def test_writer_refuses_undotted_signals_with_an_object_column(tmp_path):
    ts = TraceSet.from_runs([{"t": [0, 1], "gap": [1, 2]}])
    with pytest.raises(TraceSetError, match="'gap'"):
        write(ts, tmp_path / "x.csv", object_column="obj")
    with pytest.raises(OptionError, match="no option 'missing'"):
        write(ts, tmp_path / "x.csv", missing="error")


# -- round trips -----------------------------------------------------------------------------------

FLOATS = st.one_of(st.floats(allow_nan=False, allow_infinity=False, width=64),
                   st.sampled_from([0.0, -0.0, 5e-324, 1.7976931348623157e308, 0.1, 1 / 3]))


@st.composite
def object_tracesets(draw):
    """1-4 runs, objects with possibly different field sets, dotted signals grouped by object."""
    objects = draw(st.lists(st.sampled_from(["ego", "lead", "obj7", "ped.1"]), min_size=1,
                            max_size=3, unique=True))
    signals = []
    for obj in objects:
        fields = draw(st.lists(st.sampled_from(["x", "y", "v", "a"]), min_size=1, max_size=3,
                               unique=True))
        signals += [f"{obj}.{f}" for f in fields]
    runs = []
    for _ in range(draw(st.integers(1, 4))):
        steps = draw(st.integers(2, 8))
        t = sorted(draw(st.lists(FLOATS, min_size=steps, max_size=steps, unique=True)))
        run = {"t": t}
        for s in signals:
            run[s] = draw(st.lists(FLOATS, min_size=steps, max_size=steps))
        runs.append(run)
    ids = [f"r{k}" for k in draw(st.permutations(range(len(runs))))]
    meta = draw(st.dictionaries(st.sampled_from(["model", "seed"]), st.integers(), max_size=2))
    return TraceSet.from_runs(runs, run_ids=ids, metadata=meta)


def documented_order(signals: tuple[str, ...], by_object: bool) -> tuple[str, ...]:
    """Objects by first appearance, each object's fields in file-column order."""
    if not by_object:
        return signals
    parts = [s.rpartition(".")[::2] for s in signals]
    objects = list(dict.fromkeys(o for o, _ in parts))
    columns = list(dict.fromkeys(f for _, f in parts))
    return tuple(f"{o}.{f}" for o in objects for f in columns if f"{o}.{f}" in signals)


def assert_same(back: TraceSet, original: TraceSet, *, metadata: bool,
                by_object: bool = False) -> None:
    assert back.run_ids == original.run_ids
    assert back.signals == documented_order(original.signals, by_object)
    assert back.offsets.tolist() == original.offsets.tolist()
    assert back.time.tobytes() == original.time.tobytes()
    # bit for bit, -0.0 included
    assert back.features(original.signals).tobytes() == original.values.tobytes()
    if metadata:
        assert dict(back.metadata) == dict(original.metadata)


@settings(max_examples=40, deadline=None)
@given(object_tracesets())
def test_long_format_round_trip_is_exact(original):
    with tempfile.TemporaryDirectory() as tmp:
        for suffix in (".csv", ".parquet"):
            for columns in ({"run_column": "trip", "time_column": "time"},
                            {"run_column": "trip", "time_column": "time", "object_column": "id"}):
                path = write(original, Path(tmp) / f"long{suffix}", **columns)
                back = read(path, **columns)
                assert_same(back, original, metadata=suffix == ".parquet",
                            by_object="object_column" in columns)


def test_written_rows_are_ordered_by_run_time_object(tmp_path):
    ts = TraceSet.from_runs([{"t": [0, 1], "ego.x": [0, 1], "lead.x": [5, 6], "ego.v": [2, 3]}],
                            run_ids=["a"])
    table = longformat.to_table(ts, object_column="obj")
    assert table.column("obj").to_pylist() == ["ego", "lead", "ego", "lead"]
    assert table.column("x").to_pylist() == [0, 5, 1, 6]
    assert table.column("v").to_pylist() == [2, None, 3, None]
    back = read(write(ts, tmp_path / "o.csv", object_column="obj"), object_column="obj",
                run_column="run")
    # signals come back grouped by object (first appearance), fields in column order
    assert back.signals == ("ego.x", "ego.v", "lead.x")
    assert back.features(ts.signals).tolist() == ts.values.tolist()


def test_highd_style_frames_and_semicolons(tmp_path):
    # highD tracks: frame numbers at 25 Hz, one row per (frame, vehicle); here with ';' as in
    # SUMO's xml2csv default and many spreadsheet exports
    path = write_text(tmp_path / "01_tracks.csv", "frame;id;x;xVelocity\n1;3;10.0;30\n"
                      "1;4;50.0;28\n2;3;11.2;30.5\n2;4;51.1;28.25\n")
    ts = read(path, time_column="frame", object_column="id", objects_as="runs", time_scale=0.04)
    assert ts.run_ids == ("obj3", "obj4") and ts.signals == ("x", "xVelocity")
    assert ts.time.tolist() == [0.04, 0.08, 0.04, 0.08]
    assert ts.column("xVelocity").tolist() == [30, 30.5, 28, 28.25]
    with pytest.raises(OptionError, match="time_scale must be"):
        read(path, time_column="frame", time_scale=0)
