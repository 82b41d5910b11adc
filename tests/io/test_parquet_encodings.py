"""Parquet columns are decoded by value: dictionary-encoded (with each chunk's own dictionary,
unordered or partly unused), categorical and chunked columns read as ``to_pylist()`` says."""

from __future__ import annotations

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from simcred.io import parquet

LABELS = ["a", "b", "c", "run_7", "z"]


@st.composite
def encoded_tables(draw) -> pa.Table:
    """A table whose ``run`` (and maybe ``x``) column is chunked, and per chunk plain or
    dictionary-encoded with a shuffled dictionary holding unused and repeated entries."""
    runs = draw(st.lists(st.sampled_from(LABELS[:3]), min_size=1, max_size=3, unique=True))
    lengths = draw(st.lists(st.integers(2, 4), min_size=len(runs), max_size=len(runs)))
    labels = [r for r, n in zip(runs, lengths, strict=True) for _ in range(n)]
    order = draw(st.permutations(range(len(labels))))  # rows of a run need not be contiguous
    labels = [labels[i] for i in order]
    x = [float(12 + i) for i in range(len(labels))]
    cuts = sorted(draw(st.sets(st.integers(1, len(labels) - 1), max_size=3))) \
        if len(labels) > 1 else []
    bounds = [0, *cuts, len(labels)]

    def chunk(values, pieces_type, dictionary):
        if draw(st.booleans()):  # plain
            return pa.array(values, type=pieces_type)
        extra = draw(st.lists(st.sampled_from(dictionary), unique=True))
        entries = list(dict.fromkeys([*extra, *values]))
        entries = draw(st.permutations(entries + draw(st.lists(st.sampled_from(entries)))))
        codes = [draw(st.sampled_from([i for i, e in enumerate(entries) if e == v]))
                 for v in values]  # an entry may repeat: any copy stands for its value
        codes = pa.array(codes, type=pa.int32())
        return pa.DictionaryArray.from_arrays(codes, pa.array(entries, type=pieces_type))

    def column(values, pieces_type, dictionary):
        pieces = [chunk(values[a:b], pieces_type, dictionary)
                  for a, b in zip(bounds, bounds[1:], strict=False)]
        if any(pa.types.is_dictionary(p.type) for p in pieces):  # one type for all chunks
            kind = pa.dictionary(pa.int32(), pieces_type)
            pieces = [p if pa.types.is_dictionary(p.type) else p.dictionary_encode().cast(kind)
                      for p in pieces]
        return pa.chunked_array(pieces)

    t = [0.0] * len(labels)
    seen: dict[str, int] = {}
    for i, label in enumerate(labels):
        t[i] = float(seen.get(label, 0))
        seen[label] = seen.get(label, 0) + 1
    return pa.table({"run": column(labels, pa.string(), LABELS),
                     "t": pa.chunked_array([t]),
                     "x": column(x, pa.float64(), [-1.0, 99.0])})


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(table=encoded_tables())
def test_every_encoding_reads_the_values_pyarrow_lists(table, tmp_path):
    path = tmp_path / "a.parquet"
    pq.write_table(table, path)
    stored = pq.read_table(path)
    runs, times, xs = (stored.column(n).to_pylist() for n in ("run", "t", "x"))
    traces = parquet.read(path)
    assert list(traces.run_ids) == list(dict.fromkeys(runs))
    for index, run in enumerate(traces.run_ids):
        rows = [i for i, r in enumerate(runs) if r == run]
        lo, hi = traces.offsets[index], traces.offsets[index + 1]
        assert traces.time[lo:hi].tolist() == [times[i] for i in rows]
        assert traces.values[lo:hi, 0].tolist() == [xs[i] for i in rows]


def test_unused_dictionary_entries_do_not_shift_runs(tmp_path):
    """The reported case: a dictionary whose first entries no row uses."""
    codes = pa.array([2, 2, 2, 3, 3, 3], type=pa.int32())
    run = pa.DictionaryArray.from_arrays(codes, pa.array(["u", "v", "a", "b"]))
    table = pa.table({"run": run, "t": [0.0, 1, 2, 0, 1, 2],
                      "x": np.arange(12.0, 18.0)})
    path = tmp_path / "a.parquet"
    pq.write_table(table, path)
    traces = parquet.read(path)
    assert traces.run_ids == ("a", "b")
    assert traces.values[:3, 0].tolist() == [12.0, 13.0, 14.0]


@settings(max_examples=60, deadline=None)
@given(table=encoded_tables())
def test_run_labels_are_decoded_by_value_before_parquet_normalises_them(table):
    """In memory, before a Parquet round trip merges chunks and drops repeated entries."""
    labels, codes = parquet._run_codes(table.column("run"), "<memory>")
    assert [labels[c] for c in codes] == table.column("run").to_pylist()
    assert list(labels) == list(dict.fromkeys(table.column("run").to_pylist()))


@settings(max_examples=30, deadline=None)
@given(st.lists(st.integers(2, 9), min_size=1, max_size=8), st.integers(1, 12),
       st.booleans())
def test_runs_grouped_across_row_groups_read_as_written(lengths, row_group, shuffled):
    """Rows grouped by run (read without reordering, a run may span row groups) and rows in any
    order (reordered by run) read back as the set that was written."""
    from simcred.traces import TraceSet

    rng = np.random.default_rng(len(lengths) * 100 + row_group)
    runs = [{"t": np.arange(n) * 0.1, "x": rng.normal(size=n)} for n in lengths]
    traces = TraceSet.from_runs(runs, run_ids=[f"r{9 - i}" for i in range(len(runs))])
    table = parquet.to_table(traces, where="mem")
    if shuffled:  # runs interleaved, each run's rows still in time order
        owner = rng.permutation(np.repeat(np.arange(len(lengths)), lengths))
        starts = np.r_[0, np.cumsum(lengths)[:-1]]
        step = np.array([np.sum(owner[:i] == r) for i, r in enumerate(owner)])
        table = table.take(pa.array(starts[owner] + step))
    back = parquet.from_table(pa.Table.from_batches(table.to_batches(max_chunksize=row_group)),
                              "mem")
    assert back.run_ids == traces.run_ids or shuffled
    for run_id in traces.run_ids:
        i, k = traces.run_ids.index(run_id), back.run_ids.index(run_id)
        assert np.array_equal(back.run(k)["x"], traces.run(i)["x"])
        assert np.array_equal(back.run(k)["t"], traces.run(i)["t"])
