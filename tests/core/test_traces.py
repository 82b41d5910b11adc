"""TraceSet construction: the set keeps read-only arrays of its own, never freezing the caller's."""

import numpy as np
import pytest

from simcred.traces import TraceSet, concat, handed_over, take


def _arrays():
    time = np.array([0.0, 1.0, 2.0, 0.0, 1.0])
    values = np.arange(10.0).reshape(5, 2)
    offsets = np.array([0, 3, 5], dtype=np.int64)
    return time, values, offsets


def test_the_callers_arrays_stay_writable_and_later_writes_do_not_reach_the_set():
    time, values, offsets = _arrays()
    traces = TraceSet(("x", "y"), time, values, offsets, ("a", "b"))
    assert time.flags.writeable and values.flags.writeable and offsets.flags.writeable
    for array in (traces.time, traces.values, traces.offsets):
        assert not array.flags.writeable
        with pytest.raises(ValueError, match="read-only"):
            array[0] = 7
    values[0, 0] = 99.0
    time[1] = 0.5
    offsets[1] = 2
    assert traces.values[0, 0] == 0.0 and traces.time[1] == 1.0 and traces.offsets[1] == 3
    assert not np.shares_memory(traces.values, values)


def test_a_read_only_view_of_writable_memory_is_copied():
    time, values, offsets = _arrays()
    view = values.view()
    view.setflags(write=False)
    traces = TraceSet(("x", "y"), time, view, offsets, ("a", "b"))
    values[0, 0] = 99.0
    assert traces.values[0, 0] == 0.0


def test_read_only_arrays_and_handed_over_columns_are_kept_without_a_copy():
    time, values, offsets = _arrays()
    traces = TraceSet(("x", "y"), handed_over(time), handed_over(values), offsets, ("a", "b"))
    assert traces.time is time and traces.values is values
    again = TraceSet(traces.signals, traces.time, traces.values, traces.offsets, traces.run_ids)
    assert again.values is traces.values and again.offsets is traces.offsets


def test_built_sets_own_read_only_columns():
    one = TraceSet.from_runs([{"t": [0, 1], "x": [0.0, 1.0]}, {"t": [0, 1], "x": [2, 3]}])
    other = TraceSet.from_runs([{"t": [0, 1], "x": [4, 5]}], run_ids=["c"])
    for traces in (one, concat([one, other]), take(one, [1, 0])):
        assert not traces.time.flags.writeable and not traces.values.flags.writeable
