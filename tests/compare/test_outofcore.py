"""Parquet data sets compared out of core give the in-memory comparison, byte for byte; bad data
sets and unsupported options fail with one line."""

from __future__ import annotations

import json

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from helpers import ar_set, tied_set
from simcred.compare import compare
from simcred.compare.outofcore import compare_datasets
from simcred.compare.process import Prepared, common_space, comparison_options
from simcred.compare.run_level import pooled_counts
from simcred.errors import OptionError, TraceSetError
from simcred.io.dataset import ParquetDataset, is_dataset, read_dataset
from simcred.io.parquet import to_table
from simcred.traces import TraceSet, take


def write_partitions(traces: TraceSet, folder, cuts, *, empty_at=None, hive=False):
    """``traces`` cut into partitions at run indices ``cuts`` (hive: two ``part=`` folders);
    ``empty_at``: also a partition with the schema and no rows, at that place in path order."""
    bounds = [0, *cuts, traces.n_runs]
    for i, (lo, hi) in enumerate(zip(bounds[:-1], bounds[1:], strict=True)):
        sub = folder / f"part={i % 2}" if hive else folder
        sub.mkdir(parents=True, exist_ok=True)
        take(traces, range(lo, hi)).write(sub / f"p{i:03d}.parquet")
        if empty_at == i:
            table = to_table(take(traces, [lo]), where="test").slice(0, 0)
            pq.write_table(table, sub / f"p{i:03d}e.parquet")
    return folder


OPTIONS = [
    dict(bins=5, permutations=99, seed=1, baseline=2, bootstrap=2),
    dict(bins=[3, 7], permutations=49, seed=2, chain="max", one_sided="neutral",
         multiplicity="fdr", estimator="unbiased", kernel="laplace"),
]


@pytest.mark.parametrize("options", OPTIONS)
def test_same_json_as_in_memory(tmp_path, options):
    rng = np.random.default_rng(3)
    a = write_partitions(ar_set(rng, 120, 0.5), tmp_path / "a", [10, 11, 70], empty_at=1,
                         hive=True)
    b = write_partitions(ar_set(rng, 100, -0.3), tmp_path / "b", [50])
    assert is_dataset(a) and is_dataset(b)
    ooc = compare(a, b, **options)
    memory = compare(read_dataset(a), read_dataset(b), **options)
    assert ooc.to_json() == memory.to_json()
    assert ooc.inputs[0].runs == 120 and ooc.inputs[0].rows == 120 * 30


def test_ties_and_few_values_give_the_same_edges_and_counts(tmp_path):
    rng = np.random.default_rng(4)
    a_set, b_set = tied_set(rng, 80, 0.0, "A"), tied_set(rng, 90, 0.3, "B")
    a = write_partitions(a_set, tmp_path / "a", [5, 40])
    b = write_partitions(b_set, tmp_path / "b", [1, 2, 3, 60])
    ooc = compare(a, b, bins=10, permutations=99, seed=1)
    memory = compare(read_dataset(a), read_dataset(b), bins=10, permutations=99, seed=1)
    assert ooc.to_json() == memory.to_json()
    assert ooc.space.shape == (4, 3)  # x: 0 dropped from the distinct quantiles; y: midpoints


def test_count_matrix_is_from_codes(tmp_path, monkeypatch):
    """The partition-by-partition matrix is RunCounts.from_codes' (entries, order, dtypes)."""
    import simcred.compare.outofcore as ooc_module

    rng = np.random.default_rng(6)
    a_set, b_set = tied_set(rng, 40, 0.0, "A"), ar_set(rng, 30, 0.2)
    a_set = TraceSet(a_set.signals, a_set.time, a_set.values * 3.1, a_set.offsets,
                     a_set.run_ids)
    b_set = TraceSet(("x", "y"), b_set.time, b_set.values, b_set.offsets, b_set.run_ids)
    a = write_partitions(a_set, tmp_path / "a", [7, 8, 20])
    seen = {}
    original = ooc_module.counts_comparison

    def spy(counts, n_a, space, options, inputs):
        seen["counts"], seen["space"] = counts, space
        return original(counts, n_a, space, options, inputs)

    monkeypatch.setattr(ooc_module, "counts_comparison", spy)
    b_file = b_set.write(tmp_path / "b.parquet")  # not a data set: read in memory, one partition
    compare_datasets(a, b_file, bins=6, permutations=9, seed=0)
    options = comparison_options([a_set, b_set], bins=6, permutations=9, seed=0)
    prepared = [Prepared.of(s, options.features)
                for s in (read_dataset(a), TraceSet.read(b_file))]
    space = common_space(*prepared, options)
    expected = pooled_counts(*(p.encoded(space, options) for p in prepared), space)
    got = seen["counts"]
    for name in ("data", "indices", "indptr"):
        x, y = getattr(got.matrix, name), getattr(expected.matrix, name)
        assert x.dtype == y.dtype and np.array_equal(x, y)
    for name in ("blocks", "bounds", "successors"):
        assert np.array_equal(getattr(got, name), getattr(expected, name))
    assert all(np.array_equal(e, f) for e, f in zip(seen["space"].edges, space.edges,
                                                    strict=True))


def test_glob_and_fsspec_uri(tmp_path):
    fsspec = pytest.importorskip("fsspec")
    rng = np.random.default_rng(5)
    a_set, b_set = ar_set(rng, 40, 0.5), ar_set(rng, 40, 0.5)
    write_partitions(a_set, tmp_path / "a", [20])
    memory = fsspec.filesystem("memory")
    for i, (lo, hi) in enumerate([(0, 15), (15, 40)]):
        with memory.open(f"/simcred-test/b/p{i}.parquet", "wb") as f:
            pq.write_table(to_table(take(b_set, range(lo, hi)), where="test"), f)
    try:
        ooc = compare(str(tmp_path / "a" / "p*.parquet"), "memory://simcred-test/b", bins=4,
                      permutations=19, seed=1)
        memory_result = compare(read_dataset(str(tmp_path / "a" / "p*.parquet")),
                                read_dataset("memory://simcred-test/b"), bins=4,
                                permutations=19, seed=1)
    finally:
        memory.rm("/simcred-test", recursive=True)
    assert ooc.to_json() == memory_result.to_json()


@pytest.mark.parametrize("options, named", [
    (dict(test="bound"), "test"), (dict(history=2), "history"), (dict(time_bins=3), "time_bins"),
    (dict(resample=0.2), "resample"), (dict(relevance=True), "relevance"),
])
def test_unsupported_options_are_refused(tmp_path, options, named):
    a = write_partitions(ar_set(np.random.default_rng(1), 10, 0.1), tmp_path / "a", [5])
    with pytest.raises(OptionError, match=f"support the runs test .*; got {named}$"):
        compare(a, a, **options)


def test_bad_data_sets_fail_with_one_line(tmp_path):
    rng = np.random.default_rng(2)
    traces = ar_set(rng, 12, 0.1)
    good = write_partitions(traces, tmp_path / "good", [6])
    with pytest.raises(TraceSetError, match=r"no\*such.*: no Parquet partitions"):
        ParquetDataset.open(str(tmp_path / "no*such" / "*.parquet"))
    with pytest.raises(TraceSetError, match="missing: no such file or directory"):
        ParquetDataset.open("file://" + str(tmp_path / "missing"))
    split = write_partitions(traces, tmp_path / "split", [6])
    take(traces, [5, 6]).write(split / "p002.parquet")  # run 5 again
    with pytest.raises(TraceSetError, match=r"run '5' is split across partitions "
                                            r".*p000.parquet and .*p002.parquet"):
        compare(split, good, bins=3, permutations=9)
    other = write_partitions(traces, tmp_path / "other", [6])
    renamed = TraceSet(("x", "z"), traces.time, traces.values, traces.offsets, traces.run_ids)
    take(renamed, [0]).write(other / "p001.parquet")
    with pytest.raises(TraceSetError, match=r"p001.parquet: signals \['x', 'z'\] differ"):
        compare(other, good, bins=3, permutations=9)
    broken = write_partitions(traces, tmp_path / "broken", [6])
    (broken / "p001.parquet").write_bytes(b"not parquet")
    with pytest.raises(TraceSetError, match=r"p001.parquet: unreadable Parquet"):
        compare(broken, good, bins=3, permutations=9)
    nan = write_partitions(traces, tmp_path / "nan", [6])
    table = pa.table({"run": ["n1"] * 3, "t": [0.0, 0.1, 0.2], "x": [1.0, 2.0, 3.0],
                      "y": [1.0, np.nan, 0.0]})
    pq.write_table(table, nan / "p002.parquet")
    with pytest.raises(TraceSetError, match=r"p002.parquet: run 'n1': column 'y', row 2"):
        compare(nan, good, bins=3, permutations=9)


def test_cli_compares_a_folder_and_exits_2_on_bad_input(tmp_path, capsys):
    from simcred.cli import run

    rng = np.random.default_rng(7)
    a = write_partitions(ar_set(rng, 30, 0.5), tmp_path / "a", [10, 20])
    b = write_partitions(ar_set(rng, 30, 0.5), tmp_path / "b", [15])
    args = ["--bins", "4", "--permutations", "19", "--seed", "3", "--baseline", "0"]
    assert run(["compare", str(a), str(b), *args, "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    memory = compare(read_dataset(a), read_dataset(b), bins=4, permutations=19, seed=3)
    assert doc == json.loads(memory.to_json())
    assert run(["compare", str(a), str(tmp_path / "none" / "*.parquet"), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "no Parquet partitions" in err
    assert run(["compare", str(a), str(b), "--history", "2", *args]) == 2
    assert "support the runs test" in capsys.readouterr().err


def test_options_are_checked_before_any_partition_is_read(tmp_path):
    a = write_partitions(ar_set(np.random.default_rng(1), 10, 0.1), tmp_path / "a", [5])
    table = pa.table({"run": ["n1"] * 3, "t": [0.0, 0.1, 0.2], "x": [1.0, 2.0, 3.0],
                      "y": [1.0, np.nan, 0.0]})
    pq.write_table(table, a / "p002.parquet")  # refused in the first pass
    for options, message in ((dict(alpha=2.0), "alpha must be"), (dict(bins=1), "bins must"),
                             (dict(features=["x", "w"]), "unknown signal 'w'")):
        with pytest.raises(OptionError if "signal" not in message else TraceSetError,
                           match=message):
            compare_datasets(a, a, **options)
