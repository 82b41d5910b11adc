"""TraceSets as Arrow, pandas and polars tables: exact round trips, long-format reading, errors."""

from __future__ import annotations

import numpy as np
import pandas as pd
import polars as pl
import pyarrow as pa
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from simcred.errors import OptionError, TraceSetError
from simcred.traces import TraceSet

SPECIAL = [0.0, -0.0, 5e-324, -5e-324, 2.2250738585072014e-308, 1.7976931348623157e308,
           -1.7976931348623157e308, 0.1, 1 / 3, 2.0**60, -1.0]
FLOATS = st.one_of(st.floats(allow_nan=False, allow_infinity=False, width=64),
                   st.sampled_from(SPECIAL))
NAMES = st.text(st.characters(codec="utf-8", exclude_categories=("Cs",)), min_size=1, max_size=8)
JSON = st.recursive(
    st.none() | st.booleans() | st.integers(-2**53, 2**53) | st.text(max_size=6)
    | st.floats(allow_nan=False, allow_infinity=False),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=5), inner,
                                                                max_size=3),
    max_leaves=6)


@st.composite
def tracesets(draw) -> TraceSet:
    """1-4 runs (any text ids, any order) of 2-12 steps, 1-4 signals with units, any metadata."""
    signals = draw(st.lists(NAMES.filter(lambda s: s not in ("run", "t")), min_size=1,
                            max_size=4, unique=True))
    run_ids = draw(st.lists(NAMES, min_size=1, max_size=4, unique=True))
    runs = []
    for _ in run_ids:
        steps = draw(st.integers(2, 12))
        t = sorted(draw(st.lists(FLOATS, min_size=steps, max_size=steps, unique=True)))
        values = draw(hnp.arrays(np.float64, (steps, len(signals)), elements=FLOATS))
        runs.append({"t": np.array(t), **{s: values[:, j] for j, s in enumerate(signals)}})
    units = {s: draw(st.sampled_from(["m", "m/s", "rad", "m/s^2"])) for s in signals}
    metadata = {"units": units, **draw(st.dictionaries(st.text(max_size=8).filter(
        lambda k: k != "units"), JSON, max_size=3))}
    return TraceSet.from_runs(runs, run_ids=run_ids, metadata=metadata, source="gen")


def bits(array) -> bytes:
    return np.ascontiguousarray(array, dtype=np.float64).tobytes()


def assert_identical(back: TraceSet, original: TraceSet) -> None:
    """Same signals, run ids, offsets, time and values bit for bit (-0.0 is not 0.0), metadata."""
    assert back.signals == original.signals
    assert back.run_ids == original.run_ids
    assert back.offsets.tolist() == original.offsets.tolist()
    assert bits(back.time) == bits(original.time)
    assert bits(back.values) == bits(original.values)
    assert dict(back.metadata) == dict(original.metadata)
    assert back.units == original.units


# -- 1. exact round trips --------------------------------------------------------------------------


@settings(max_examples=60, deadline=None)
@given(tracesets())
def test_pandas_and_arrow_round_trips_are_exact(original):
    frame = original.to_pandas()
    assert_identical(TraceSet.from_pandas(frame), original)
    table = original.to_arrow()
    assert_identical(TraceSet.from_arrow(table), original)
    # pandas -> TraceSet -> Arrow -> TraceSet, the chain of the issue
    assert_identical(TraceSet.from_arrow(TraceSet.from_pandas(frame).to_arrow()), original)


@settings(max_examples=30, deadline=None)
@given(tracesets())
def test_polars_round_trip_is_exact_with_the_metadata_given(original):
    if any("\0" in name for name in original.signals):  # refused, tested below
        return
    frame = original.to_polars()
    assert_identical(TraceSet.from_polars(frame, metadata=original.metadata), original)
    assert dict(TraceSet.from_polars(frame).metadata) == {}  # polars carries none


def test_the_tables_hold_the_trace_set_row_for_row():
    ts = TraceSet.from_runs([{"t": [0, 1], "x": [-0.0, 1.5]}, {"t": [0, 2], "x": [2, 3]}],
                            run_ids=["b", "a"], metadata={"units": {"x": "m"}})
    frame = ts.to_pandas()
    assert list(frame.columns) == ["run", "t", "x"]
    assert frame["run"].tolist() == ["b", "b", "a", "a"]
    assert isinstance(frame["run"].dtype, pd.CategoricalDtype)
    assert frame["t"].tolist() == [0.0, 1.0, 0.0, 2.0]
    assert np.signbit(frame["x"].to_numpy()[0])
    assert frame.attrs["simcred"] == {"units": {"x": "m"}}
    assert ts.to_polars()["x"].to_list() == [-0.0, 1.5, 2.0, 3.0]


def test_arrow_time_column_is_not_copied():
    ts = TraceSet.from_runs([{"t": np.arange(5.0), "x": np.ones(5)}])
    column = ts.to_arrow().column("t").chunk(0).to_numpy()
    assert np.shares_memory(column, ts.time)


def test_pandas_metadata_is_a_copy_not_shared():
    ts = TraceSet.from_runs([{"t": [0, 1], "x": [0, 1]}], metadata={"units": {"x": "m"}})
    frame = ts.to_pandas()
    frame.attrs["simcred"]["units"]["x"] = "km"
    assert ts.units == {"x": "m"}


# -- 2. user tables in long format -----------------------------------------------------------------


def test_pandas_long_table_with_objects_becomes_dotted_signals():
    frame = pd.DataFrame({"trip": [1, 1, 1, 1, 2, 2], "time": [0.0, 0.0, 0.1, 0.1, 0.0, 0.1],
                          "id": ["ego", "lead"] * 2 + ["ego", "ego"],
                          "x": [0.0, 10.0, 1.0, 11.0, 5.0, 6.0]})
    with pytest.raises(TraceSetError, match="lead"):  # trip 2 has no lead vehicle
        TraceSet.from_pandas(frame, run="trip", time="time", object="id")
    ts = TraceSet.from_pandas(frame.iloc[:4], run="trip", time="time", object="id")
    assert ts.run_ids == ("1",)
    assert ts.signals == ("ego.x", "lead.x")
    assert ts.column("lead.x").tolist() == [10.0, 11.0]


def test_a_table_without_run_column_is_one_run():
    ts = TraceSet.from_polars(pl.DataFrame({"t": [0.0, 0.5], "v": [3.0, 4.0]}), run=None)
    assert ts.run_ids == ("0",) and ts.column("v").tolist() == [3.0, 4.0]


# -- 3. bad input: one line naming the culprit -----------------------------------------------------


@pytest.mark.parametrize("make, match", [
    (lambda: TraceSet.from_pandas({"t": [0, 1]}), "expected a pandas DataFrame, got dict"),
    (lambda: TraceSet.from_arrow(pd.DataFrame({"t": [0, 1]})), "expected a pyarrow Table"),
    (lambda: TraceSet.from_pandas(pd.DataFrame({"run": ["a", "a"], "t": [1.0, 1.0],
                                                "x": [0.0, 1.0]})),
     r"<pandas>: run 'a' has two rows at t=1.0 \(rows 1 and 2\)"),
    (lambda: TraceSet.from_pandas(pd.DataFrame({"t": [0.0, 1.0], "x": [0.0, 1.0]})),
     "no column 'run'"),
    (lambda: TraceSet.from_pandas(pd.DataFrame({"run": ["a", "a"], "t": [0.0, 1.0],
                                                "x": [0.0, np.nan]})),
     "<pandas>: run 'a': column 'x', row 2: value is missing"),
    (lambda: TraceSet.from_arrow(pa.table({"run": ["a", "a"], "t": [0.0, 1.0],
                                           "x": ["1", "2"]}), signals=["x"]), "not numeric"),
])
def test_bad_tables_are_one_line_errors(make, match):
    with pytest.raises(TraceSetError, match=match) as info:
        make()
    assert "\n" not in str(info.value)


def test_polars_refuses_a_nul_in_a_signal_name_instead_of_panicking():
    ts = TraceSet.from_runs([{"t": [0, 1], "a\0b": [0, 1]}], source="nul")
    with pytest.raises(TraceSetError, match="nul: a signal name holds a NUL"):
        ts.to_polars()
    assert TraceSet.from_pandas(ts.to_pandas()).signals == ("a\0b",)  # pandas takes it


def test_bad_options_are_option_errors():
    frame = pd.DataFrame({"run": ["a", "a"], "t": [0.0, 1.0], "x": [0.0, 1.0]})
    with pytest.raises(OptionError, match="metadata must be a mapping"):
        TraceSet.from_pandas(frame, metadata=[1])
    with pytest.raises(OptionError, match="different columns"):
        TraceSet.from_pandas(frame, run="t")
    with pytest.raises(TypeError):
        TraceSet.from_pandas(frame, run_column="run")  # the table API names it run=


def test_a_signal_named_run_cannot_become_a_table():
    ts = TraceSet.from_runs([{"t": [0, 1], "run": [5, 5]}], source="clash")
    with pytest.raises(TraceSetError, match="clash: a signal is named 'run'"):
        ts.to_pandas()
