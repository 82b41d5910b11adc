"""The compact forms of the run-level test's arrays equal their plain forms (issue 25 memory):
permutation assignments packed as bits, counts held as float32, sums over them in float64."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.sparse as sp

from helpers import random_walk_set
from simcred.compare import compare, run_counts, runs, side_counts
from simcred.compare.process import Prepared, common_space, comparison_options
from simcred.compare.run_counts import RunCounts, count_dtype, matvec, row_sums
from simcred.compare.run_level import pooled_counts, run_spec
from simcred.compare.runs import PackedAssignments


def literal_counts(codes: np.ndarray, offsets: np.ndarray, n_states: int) -> dict:
    """{(run, key): count} by a plain loop: the start state (key = state) and every transition
    (key = (from + 1) · n_states + to) of each run."""
    out: dict = {}
    for run, (lo, hi) in enumerate(zip(offsets[:-1], offsets[1:], strict=True)):
        states = [int(s) for s in codes[lo:hi]]
        keys = [states[0]] + [(s + 1) * n_states + u
                              for s, u in zip(states[:-1], states[1:], strict=True)]
        for key in keys:
            out[run, key] = out.get((run, key), 0) + 1
    return out


def matrix_counts(counts: RunCounts, n_states: int) -> dict:
    coo = counts.matrix.tocoo()
    keys = (counts.blocks[np.repeat(np.arange(len(counts.blocks)), np.diff(counts.bounds))]
            + 1) * n_states + counts.successors
    return {(int(r), int(keys[c])): float(v) for c, r, v in zip(coo.row, coo.col, coo.data,
                                                                 strict=True)}


def test_packbits_literal():
    rows = np.array([[1, 0, 1, 1, 0, 0, 0, 0, 1], [0, 1, 0, 0, 0, 0, 0, 1, 0]], dtype=bool)
    packed = PackedAssignments.pack(rows)
    assert packed.bits.tolist() == [[0b10110000, 0b10000000], [0b01000001, 0]]
    assert packed.shape == (2, 9) and len(packed) == 2
    unpacked = packed[0:2]
    assert unpacked.dtype == bool and np.array_equal(unpacked, rows)
    assert np.array_equal(packed[1:2], rows[1:2])


@pytest.mark.parametrize("n_runs, n_a, permutations", [(9, 4, 5), (64, 30, 99), (203, 101, 37)])
def test_packed_random_assignments_are_the_unpacked_ones(n_runs, n_a, permutations):
    in_a = np.zeros(n_runs, dtype=bool)
    in_a[np.random.default_rng(n_runs).permutation(n_runs)[:n_a]] = True
    plain = runs.random_assignments(in_a, permutations, 17, np.random.default_rng(3))
    packed = PackedAssignments.random(in_a, permutations, 17, np.random.default_rng(3))
    assert packed.bits.nbytes == (permutations + 1) * ((n_runs + 7) // 8)
    assert np.array_equal(packed[0:len(packed)], plain)
    assert np.array_equal(plain[0], in_a) and (plain.sum(axis=1) == n_a).all()
    for start in range(0, permutations + 1, 8):  # the batches the statistics unpack
        assert np.array_equal(packed[start:start + 8], plain[start:start + 8])


def test_statistics_of_packed_assignments_are_the_same():
    rng = np.random.default_rng(8)
    a = random_walk_set(rng, runs=23, drift=0.0, max_len=15)
    b = random_walk_set(rng, runs=19, drift=0.4, max_len=15)
    options = comparison_options([a, b], features=["x", "y"], bins=3, permutations=20, seed=0)
    prepared = [Prepared.of(s, options.features) for s in (a, b)]
    space = common_space(*prepared, options)
    counts = pooled_counts(*(p.encoded(space, options) for p in prepared), space)
    spec = run_spec(options)
    models = runs.StateModels.build(counts, space.decode, spec, space.shape)
    in_a = np.arange(counts.n_runs) < a.n_runs
    plain = runs.random_assignments(in_a, 20, 5, np.random.default_rng(1))
    got = runs.assignment_statistics(counts, models, PackedAssignments.pack(plain),
                                     spec.estimator, batch=8)
    expected = runs.assignment_statistics(counts, models, plain, spec.estimator, batch=8)
    assert np.array_equal(got, expected, equal_nan=True)


def test_count_dtype_is_float32_only_below_2_24():
    assert count_dtype(np.array([0, 2**24 - 1])) is np.float32
    assert count_dtype(np.array([3, 2**24])) is np.float64
    assert count_dtype(np.array([], dtype=np.int64)) is np.float32
    assert float(np.float32(2**24 - 1)) == 2**24 - 1  # the largest count it admits is exact


@pytest.mark.parametrize("entries", [1, 3, 1 << 22])
def test_row_sums_and_matvec_are_float64_exact(monkeypatch, entries):
    monkeypatch.setattr(run_counts, "SUM_ENTRIES", entries)  # slices of any size, one row each
    data = np.array([2**23, 2**23, 1, 7, 2**23 + 1, 5], dtype=np.float32)  # float32 sums: inexact
    matrix = sp.csr_matrix((data, np.array([0, 1, 2, 0, 2, 1]), np.array([0, 3, 3, 5, 6])),
                           shape=(4, 3))
    assert row_sums(matrix).tolist() == [2**24 + 1, 0, 2**23 + 8, 5]
    assert row_sums(matrix).dtype == np.float64
    assert matvec(matrix, np.array([True, False, True])).tolist() == [2**23 + 1, 0, 2**23 + 8,
                                                                      0]
    reference = matrix.astype(np.float64)
    vector = np.array([1.0, 1.0, 0.0])
    assert np.array_equal(matvec(matrix, vector), reference @ vector)


@pytest.mark.parametrize("sorted_keys, direct_keys", [  # radix, table, then sort branch
    (run_counts.SORTED_KEYS, run_counts.DIRECT_KEYS), (1, run_counts.DIRECT_KEYS), (1, 1)])
@pytest.mark.parametrize("exact", [run_counts.EXACT_FLOAT32, 3])  # 3: counts ≥ 3 need float64
def test_counts_equal_a_literal_count(monkeypatch, sorted_keys, direct_keys, exact):
    monkeypatch.setattr(run_counts, "SORTED_KEYS", sorted_keys)
    monkeypatch.setattr(run_counts, "DIRECT_KEYS", direct_keys)
    monkeypatch.setattr(run_counts, "EXACT_FLOAT32", exact)
    monkeypatch.setattr(run_counts, "BLOCK_ROWS", 16)  # several blocks of runs
    rng = np.random.default_rng(5)
    lengths = rng.integers(1, 20, size=30)
    offsets = np.r_[0, np.cumsum(lengths)]
    codes = rng.integers(0, 2, size=offsets[-1])  # of 4 states: repeated pairs
    counts = RunCounts.from_codes(codes, offsets, 4)
    expected = literal_counts(codes, offsets, 4)
    assert matrix_counts(counts, 4) == {k: float(v) for k, v in expected.items()}
    largest = max(expected.values())
    assert counts.matrix.dtype == (np.float32 if largest < exact else np.float64)
    assert largest >= 3  # the float64 case is exercised


def test_exact_slices_of_negative_differences():
    dense = np.array([[3.0, -5.0, 0.0, 2.0], [-1.0, 4.0, -7.0, 0.0]])
    got, slices = side_counts._exact_slices(dense)
    assert got.dtype == np.float32 and slices == [(0, 4)]
    peak = np.abs(dense).max(axis=0)
    assert peak.tolist() == [3, 5, 7, 2]
    big = np.array([[2.0**23, -(2.0**23) - 2, 1.0]])
    _, slices = side_counts._exact_slices(big)  # |x| sums: 2^23, 2^23 + 2 do not fit together
    assert slices == [(0, 1), (1, 3)]


def test_float64_counts_give_the_same_comparison(monkeypatch):
    """Above the float32 limit (made small here) the counts stay float64: same JSON."""
    rng = np.random.default_rng(2)
    a = random_walk_set(rng, runs=30, drift=0.0, max_len=20)
    b = random_walk_set(rng, runs=30, drift=0.3, max_len=20)
    options = dict(features=["x", "y"], bins=3, permutations=49, seed=4, baseline=1)
    float32 = compare(a, b, **options).to_json()
    monkeypatch.setattr(run_counts, "EXACT_FLOAT32", 2)
    assert compare(a, b, **options).to_json() == float32

