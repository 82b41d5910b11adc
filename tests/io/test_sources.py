"""One reader dispatch (issue 27): trace-set formats and data sets by name, and what a path is
for a role (a ``.csv`` is long format for ``io.read``, an A9 recording for ``reprocess``)."""

from __future__ import annotations

import numpy as np
import pytest

import simcred.io as io
from simcred import data
from simcred.errors import OptionError, TraceSetError
from simcred.io.a9 import read_a9
from simcred.io.measurement import Measurement
from simcred.io.openacc import read_recording
from simcred.traces import TraceSet

A9 = data.path("a9/testfile_straight.csv")


def _runs() -> TraceSet:
    t = np.arange(5, dtype=float)
    return TraceSet.from_runs([{"t": t, "x": 2 * t}], run_ids=["r"])


def test_a_csv_is_long_format_for_traces_and_a9_for_a_drive(tmp_path):
    assert io.detect_source(A9) == "long"
    assert io.detect_source(A9, role="drive") == "a9"
    assert io.detect_source(A9, role="drive", long=True) == "long"
    assert io.detect_source(tmp_path, role="drive") == "measurement"
    (tmp_path / "s.xml").write_text("<commonRoad/>")
    assert io.detect_source(tmp_path / "s.xml", role="drive") == "commonroad"
    assert io.detect_source(tmp_path / "t.parquet", role="drive") == "long"


def test_unknown_role_or_kind_is_one_line(tmp_path):
    with pytest.raises(OptionError, match="unknown role 'nope'"):
        io.detect_source(A9, role="nope")
    with pytest.raises(TraceSetError, match="not a measurement"):
        io.detect_source(tmp_path / "x.txt", role="drive")
    with pytest.raises(OptionError, match="unknown format or data set 'nope'"):
        io.read_source(A9, "nope")


def test_io_read_names_read_source_for_a_data_set():
    with pytest.raises(OptionError, match=r"'a9' is a data set.*read_source\(path, 'a9'\)"):
        io.read(A9, format="a9")


def test_data_sets_read_into_their_own_types(tmp_path):
    recording = io.read_source(A9, "a9")
    assert type(recording) is type(read_a9(A9))
    assert recording.metadata() == read_a9(A9).metadata()
    acc = sorted(data.path("openacc/short_setting").iterdir())[0]
    if acc.suffix.lower() in (".csv", ".parquet"):
        assert io.read_source(acc, "openacc").date == read_recording(acc).date
    Measurement(sd=_runs()).write(tmp_path / "m")
    read = io.read_source(tmp_path / "m", "measurement")
    assert isinstance(read, Measurement) and read.sd.column("x").tolist() == [0, 2, 4, 6, 8]


def test_trace_set_formats_by_name(tmp_path):
    io.write(_runs(), tmp_path / "runs.parquet")
    read = io.read_source(tmp_path / "runs.parquet", "parquet")
    assert read.run_ids == ("r",) and read.column("x").tolist() == [0, 2, 4, 6, 8]
