"""The lower-memory paths of the in-memory comparison (issue 25, 40 B per row) equal the plain
computations they replace: the median step taken in place, first-order codes in int32 chunk by
chunk, the counts of blocks of runs stacked into one output, codes dropped before the runs
test."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from helpers import random_walk_set
from simcred.compare import compare, encoding, run_counts
from simcred.compare.discretize import StateSpace
from simcred.compare.encoding import code_dtype, encode
from simcred.compare.resample import sample_period, within_run_steps
from simcred.compare.run_counts import RunCounts, count_dtype
from simcred.traces import TraceSet


@pytest.mark.parametrize("seed", range(6))
def test_period_in_place_is_the_median_of_the_steps_within_runs(seed):
    rng = np.random.default_rng(seed)
    lengths = rng.integers(2, 9, size=int(rng.integers(1, 12)))  # odd and even step counts
    runs = [{"t": np.cumsum(rng.choice([0.1, 0.1, 0.2, 0.05], size=n)) + rng.uniform(0, 50),
             "x": rng.normal(size=n)} for n in lengths]
    traces = TraceSet.from_runs(runs)
    assert sample_period(traces) == float(np.median(within_run_steps(traces)))


def test_period_ignores_the_jumps_between_runs():
    first, second = [0.0, 1.0, 2.0], [10.0, 10.1, 10.2, 10.3]  # the jump 8 would make it 0.55
    traces = TraceSet.from_runs([{"t": first, "x": [0, 1, 2]}, {"t": second, "x": [0, 1, 2, 3]}])
    within = np.r_[np.diff(first), np.diff(second)]
    assert sample_period(traces) == float(np.median(within)) < 0.2


def plain_codes(space: StateSpace, values: np.ndarray) -> np.ndarray:
    """``ravel_multi_index`` of every row's bins, all rows at once (int64)."""
    return np.ravel_multi_index(
        tuple(np.searchsorted(e, values[:, j], side="right") for j, e in enumerate(space.edges)),
        space.shape)


@pytest.mark.parametrize("chunk", [encoding.CODE_CHUNK, 7, 1])
def test_chunked_codes_equal_the_whole_column_codes(monkeypatch, chunk):
    monkeypatch.setattr(encoding, "CODE_CHUNK", chunk)
    traces = random_walk_set(np.random.default_rng(1), 20, 0.1)
    space = StateSpace.equal_frequency(traces.values, [4, 3], ["x", "y"])
    encoded = encode(space, traces.values, traces.time, traces.offsets)
    assert encoded.codes.dtype == np.int32
    assert np.array_equal(encoded.codes, plain_codes(space, traces.values))
    assert np.array_equal(encoded.offsets, traces.offsets)


def test_codes_with_history_are_int32_and_the_int64_ones():
    traces = random_walk_set(np.random.default_rng(2), 15, 0.0, min_len=3)
    space = StateSpace.equal_frequency(traces.values, [3, 3], ["x", "y"]).lagged(2)
    codes = encode(space, traces.values, traces.time, traces.offsets, history=2).codes
    first = plain_codes(StateSpace(("x", "y"), space.edges[:2], space.bounds[:2]), traces.values)
    keep = np.ones(traces.n_rows, dtype=bool)
    keep[traces.offsets[:-1]] = False  # a run's first row has no history of 2
    expected = np.flatnonzero(keep)
    assert codes.dtype == np.int32
    assert np.array_equal(codes, first[expected - 1] * 9 + first[expected])


def test_code_dtype_is_int32_while_every_code_fits():
    assert code_dtype(2**31) == np.int32  # codes 0 .. 2**31 - 1
    assert code_dtype(2**31 + 1) == np.int64
    assert np.iinfo(np.int32).max == 2**31 - 1


@pytest.mark.parametrize("compact", [False, True])
@pytest.mark.parametrize("seed", range(8))
def test_stacked_blocks_are_scipy_hstack(seed, compact):
    rng = np.random.default_rng(seed)
    rows = int(rng.integers(0, 6))
    blocks = []
    for i in range(int(rng.integers(1, 5))):
        block = sp.random(rows, int(rng.integers(1, 7)), density=0.4, format="csr",
                          random_state=int(rng.integers(10**6)))
        large = 2**25 if seed % 2 and i == 0 else 3  # a float64 block: counts ≥ 2**24
        data = np.ceil(block.data * large).astype(np.float64 if large > 3 else np.float32)
        blocks.append(sp.csr_matrix((data, block.indices, block.indptr), shape=block.shape))
    dtype = np.result_type(*(count_dtype(b.data) for b in blocks))
    expected = sp.hstack([b.astype(dtype) for b in blocks], format="csr", dtype=dtype)
    given = [run_counts._compact(b) for b in blocks] if compact else list(blocks)
    if compact:
        assert all(g.data.dtype.kind == g.indices.dtype.kind == "u" for g in given)
        assert all(g.data.itemsize <= (4 if seed % 2 else 1) for g in given)
    stacked = run_counts._stacked(given)
    assert stacked.shape == expected.shape and stacked.dtype == expected.dtype
    for name in ("indptr", "indices", "data"):
        assert np.array_equal(getattr(stacked, name), getattr(expected, name))
        assert getattr(stacked, name).dtype == getattr(expected, name).dtype


def test_stacking_releases_every_block():
    blocks = [sp.csr_matrix(np.eye(3, dtype=np.float32)) for _ in range(3)]
    run_counts._stacked(blocks)
    assert blocks == [None, None, None]


def test_counts_of_int32_codes_are_those_of_int64_codes(monkeypatch):
    monkeypatch.setattr(run_counts, "BLOCK_ROWS", 16)  # several blocks of runs
    rng = np.random.default_rng(4)
    offsets = np.r_[0, np.cumsum(rng.integers(1, 20, size=40))]
    codes = rng.integers(0, 5, size=offsets[-1])
    wide = RunCounts.from_codes(codes, offsets, 5)
    narrow = RunCounts.from_codes(codes.astype(np.int32), offsets, 5)
    assert (wide.matrix != narrow.matrix).nnz == 0
    assert np.array_equal(wide.blocks, narrow.blocks)
    assert np.array_equal(wide.successors, narrow.successors)


@pytest.mark.parametrize("options", [dict(), dict(test="permutation", permutations=19),
                                     dict(test="bound"), dict(history=2, bins=3),
                                     dict(time_bins=2, bins=3)])
def test_comparison_of_int32_codes_is_that_of_int64_codes(monkeypatch, options):
    rng = np.random.default_rng(6)
    a, b = random_walk_set(rng, 30, 0.0, min_len=4), random_walk_set(rng, 30, 0.3, min_len=4)
    plain = dict(bins=4, permutations=49, seed=2) | options
    narrow = compare(a, b, **plain).to_json()
    monkeypatch.setattr(encoding, "code_dtype", lambda n_states: np.int64)
    assert compare(a, b, **plain).to_json() == narrow
