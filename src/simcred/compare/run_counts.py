"""Per run, the counts of (state, successor) pairs: the sparse (columns × runs) matrix every
run-level and response test permutes, counted block by block of runs from the state codes:
by a stable radix sort of 16-bit pair keys where ``(|S| + 1)·|S| ≤ 2**16``, through a table
over the key space up to :data:`DIRECT_KEYS`, by a sort of int64 keys beyond (all three give
the same matrix, tested).

The counts are integers stored as float32 (4 bytes per entry instead of 8) wherever every count
is below 2**24, where float32 holds them exactly; float64 else (:func:`count_dtype`). Sums over
them are taken in float64 (:func:`row_sums`, :func:`matvec`): exact integers either way.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

START = -1  # state code of the start-distribution block

#: Largest key space ``(|S| + 1)·|S|`` whose keys fit 16 bits: counted by a radix sort.
SORTED_KEYS = 2**16
#: Largest key space ``(|S| + 1)·|S|`` counted through a lookup table rather than a sort.
DIRECT_KEYS = 2**22
#: Rows per block of runs when counting through the lookup table.
BLOCK_ROWS = 2**20
#: Counts below this are exact in float32 (its 24-bit significand).
EXACT_FLOAT32 = 2**24
#: Entries per slice in :func:`row_sums` and :func:`matvec` (their float64 working copies).
SUM_ENTRIES = 2**22


@dataclass(frozen=True, slots=True, eq=False)
class RunCounts:
    """Per run, the counts of (state, successor) pairs: a sparse (columns × runs) matrix.

    ``blocks[b]`` is the state of column block ``b`` (``START`` for the start distribution),
    ``bounds[b]:bounds[b + 1]`` its columns, ``successors[c]`` the successor state of column
    ``c``. Columns are sorted by (state, successor), the start block first. Built from codes,
    the matrix holds its counts as float32 where they are all below :data:`EXACT_FLOAT32`
    (:func:`count_dtype`); sum them with :func:`row_sums` and :func:`matvec` (float64).
    """

    matrix: sp.csr_matrix
    blocks: np.ndarray
    bounds: np.ndarray
    successors: np.ndarray

    @classmethod
    def from_codes(cls, codes: np.ndarray, offsets: np.ndarray, n_states: int) -> RunCounts:
        """Count start states and within-run transitions of state ``codes`` split by ``offsets``."""
        return cls.from_parts([(codes, offsets)], n_states)

    @classmethod
    def from_parts(cls, parts: Sequence[tuple[np.ndarray, np.ndarray]], n_states: int
                   ) -> RunCounts:
        """:meth:`from_codes` of the parts' runs one after the other (set A's, then B's),
        without joining them: small state spaces are counted block by block of runs
        (:data:`BLOCK_ROWS` rows), so the working memory does not grow with the data."""
        return cls.from_matrix(*keyed_counts(parts, n_states), n_states)

    @classmethod
    def from_matrix(cls, matrix: sp.csr_matrix, columns: np.ndarray, n_states: int
                    ) -> RunCounts:
        """The counts ``matrix`` (columns × runs, entries sorted by (column, run)) whose column
        ``c`` is the pair key ``columns[c] = (state + 1) · n_states + successor`` (sorted)."""
        size = np.int64(n_states)
        origin = columns // size - 1
        bounds = np.r_[0, np.flatnonzero(np.diff(origin)) + 1, len(columns)]
        return cls(matrix, origin[bounds[:-1]], bounds, columns % size)

    @property
    def n_runs(self) -> int:
        return self.matrix.shape[1]

    def subset(self, runs: np.ndarray) -> RunCounts:
        """The counts of the runs ``runs`` (repeats allowed: a bootstrap sample), unused columns
        dropped."""
        matrix = self.matrix[:, runs].tocsr()
        used = np.flatnonzero(matrix.getnnz(axis=1) > 0)
        block = np.repeat(np.arange(len(self.blocks)), np.diff(self.bounds))[used]
        bounds = np.r_[0, np.flatnonzero(np.diff(block)) + 1, len(used)]
        return RunCounts(matrix[used], self.blocks[block[bounds[:-1]]], bounds,
                         self.successors[used])


def keyed_counts(parts: Sequence[tuple[np.ndarray, np.ndarray]], n_states: int
                 ) -> tuple[sp.csr_matrix, np.ndarray]:
    """The (columns × runs) counts of :meth:`RunCounts.from_parts` and the columns' pair keys
    ``(state + 1) · n_states + successor`` (sorted)."""
    size = np.int64(n_states)
    if (size + 1) * size <= SORTED_KEYS:
        return joined_counts([_sorted_block_counts(*_block(codes, offsets, lo, hi), int(size))
                              for codes, offsets in parts for lo, hi in _run_blocks(offsets)])
    if (size + 1) * size > DIRECT_KEYS:
        codes = np.concatenate([c for c, _ in parts])
        starts = np.cumsum([0] + [len(c) for c, _ in parts[:-1]])
        offsets = np.concatenate([[0]] + [o[1:] + s for (_, o), s in zip(parts, starts,
                                                                         strict=True)])
        keys, runs = _pair_keys(codes, offsets, size)
        columns, column_of, run_of, count = _pair_counts(keys, runs, len(offsets) - 1)
        indptr = np.r_[0, np.cumsum(np.bincount(column_of, minlength=len(columns)))]
        matrix = sp.csr_matrix((count.astype(count_dtype(count)), run_of, indptr),
                               shape=(len(columns), len(offsets) - 1))  # (column, run)
        return matrix, columns
    blocks = [(codes, offsets, lo, hi) for codes, offsets in parts
              for lo, hi in _run_blocks(offsets)]
    # two passes over the blocks (their keys computed twice) rather than keeping every
    # block's keys: the columns must be known before any block's counts are placed
    present = np.zeros(int((size + 1) * size), dtype=bool)
    for block in blocks:
        present[_pair_keys(*_block(*block), size)[0]] = True
    columns = np.flatnonzero(present)
    column_index = np.cumsum(present) - 1
    del present
    counted = [_compact(_block_counts(*_block(*block), size, column_index, len(columns)))
               for block in blocks]
    return _stacked(counted), columns


def joined_counts(parts: Sequence[tuple[sp.csr_matrix | CompactBlock, np.ndarray]]
                  ) -> tuple[sp.csr_matrix, np.ndarray]:
    """:func:`keyed_counts` of several parts' runs one after the other, from each part's own
    (matrix, columns): the same matrix and columns as counting the joined codes."""
    columns = np.unique(np.concatenate([c for _, c in parts]))
    placed: list[sp.csr_matrix | CompactBlock | None] = []
    for matrix, own in parts:
        per_row = np.zeros(len(columns), dtype=np.int64)
        per_row[np.searchsorted(columns, own)] = np.diff(matrix.indptr)
        placed.append(CompactBlock(np.r_[0, np.cumsum(per_row)], matrix.indices, matrix.data,
                                   (len(columns), matrix.shape[1])))
    return _stacked(placed), columns


@dataclass(frozen=True, slots=True, eq=False)
class CompactBlock:
    """A block's (column × run) counts as CSR arrays in the smallest unsigned types that hold
    its counts and run indices (a block of runs of a few thousand runs, counts up to the
    longest run: 3 bytes an entry rather than 8 while every block waits to be stacked)."""

    indptr: np.ndarray
    indices: np.ndarray
    data: np.ndarray
    shape: tuple[int, int]

    @property
    def nnz(self) -> int:
        return len(self.data)


def _compact(matrix: sp.csr_matrix) -> CompactBlock:
    counts = matrix.data.astype(np.min_scalar_type(int(matrix.data.max()) if matrix.nnz else 0))
    runs = matrix.indices.astype(np.min_scalar_type(max(matrix.shape[1] - 1, 0)))
    return CompactBlock(matrix.indptr, runs, counts, matrix.shape)


def _stacked(matrices: list[sp.csr_matrix | CompactBlock]) -> sp.csr_matrix:
    """The matrices (or compact blocks) side by side (``scipy.sparse.hstack``), their counts in
    the type that holds all of them exactly (:func:`count_dtype`). Each matrix's entries are
    placed into the output and the matrix is released from the list (which ends empty of
    them): the counts are never held twice."""
    dtype = np.result_type(*(count_dtype(m.data) for m in matrices))
    n_rows, n_cols = matrices[0].shape[0], sum(m.shape[1] for m in matrices)
    per_row = [np.diff(m.indptr) for m in matrices]
    indptr = np.r_[0, np.cumsum(np.sum(per_row, axis=0, dtype=np.int64))]
    index = np.int32 if max(int(indptr[-1]), n_cols) < 2**31 else np.int64
    indices = np.empty(int(indptr[-1]), dtype=index)
    data = np.empty(int(indptr[-1]), dtype=dtype)
    cursor, first = indptr[:-1].copy(), 0
    for i, counts in enumerate(per_row):
        matrix, matrices[i] = matrices[i], None
        at = np.repeat(cursor - matrix.indptr[:-1], counts)  # entry k of row r goes to
        at += np.arange(matrix.nnz)  # cursor[r] + k - indptr[r]
        indices[at] = np.add(matrix.indices, first, dtype=index)
        data[at] = matrix.data
        cursor += counts
        first += matrix.shape[1]
    return sp.csr_matrix((data, indices, indptr.astype(index)), shape=(n_rows, n_cols))


def relabelled_keys(keys: np.ndarray, shape: tuple[int, ...], kept: Sequence[np.ndarray],
                    new_shape: tuple[int, ...]) -> np.ndarray:
    """Pair keys on a grid of ``shape`` as keys on the grid whose edges are the kept ones
    (``kept[j]``: per edge of feature ``j``, whether it stays). A dropped edge merges an empty
    bin into its right neighbour: the map of bins is increasing on the bins that hold data, so
    the keys of data keep their order."""
    if all(k.all() for k in kept):
        return keys
    size = np.int64(np.prod(shape))
    origin, successor = keys // size - 1, keys % size
    maps = [np.r_[0, np.cumsum(k)] for k in kept]

    def moved(codes: np.ndarray) -> np.ndarray:
        coordinates = np.unravel_index(codes, shape)
        return np.ravel_multi_index(tuple(m[c] for m, c in zip(maps, coordinates, strict=True)),
                                    new_shape).astype(np.int64)

    start = origin < 0
    new_origin = np.full(len(keys), -1, dtype=np.int64)
    new_origin[~start] = moved(origin[~start])
    return (new_origin + 1) * np.int64(np.prod(new_shape)) + moved(successor)

def count_dtype(counts: np.ndarray) -> type:
    """float32 where every one of the (non-negative integer) ``counts`` is below
    :data:`EXACT_FLOAT32`, so that float32 holds them exactly; float64 else."""
    return np.float32 if len(counts) == 0 or counts.max() < EXACT_FLOAT32 else np.float64


def row_sums(matrix: sp.csr_matrix) -> np.ndarray:
    """Per row, the sum of a CSR matrix's entries in float64 (exact for integer counts; no
    float64 copy of the whole matrix: :data:`SUM_ENTRIES` entries at a time)."""
    return _sliced(matrix)


def matvec(matrix: sp.csr_matrix, vector: np.ndarray) -> np.ndarray:
    """``matrix @ vector`` in float64, :data:`SUM_ENTRIES` entries at a time (scipy would copy
    a float32 matrix's entries to float64 whole)."""
    vector = np.asarray(vector, dtype=np.float64)
    return _sliced(matrix, vector)


def _sliced(matrix: sp.csr_matrix, vector: np.ndarray | None = None) -> np.ndarray:
    """Per row the float64 sum of its entries (times ``vector`` at their columns), slices of
    whole rows of about :data:`SUM_ENTRIES` entries each, summed in entry order per row."""
    indptr = matrix.indptr
    out = np.zeros(matrix.shape[0])
    cuts = np.unique(np.r_[0, np.searchsorted(indptr, np.arange(SUM_ENTRIES, indptr[-1],
                                                                SUM_ENTRIES)),
                           matrix.shape[0]])
    for lo, hi in zip(cuts[:-1], cuts[1:], strict=True):
        a, b = int(indptr[lo]), int(indptr[hi])
        if a == b:
            continue
        values = matrix.data[a:b].astype(np.float64)
        if vector is not None:
            values *= vector[matrix.indices[a:b]]
        rows = np.repeat(np.arange(hi - lo), np.diff(indptr[lo:hi + 1]))
        out[lo:hi] = np.bincount(rows, weights=values, minlength=hi - lo)
    return out


def _run_blocks(offsets: np.ndarray) -> list[tuple[int, int]]:
    """Consecutive ranges of runs of about :data:`BLOCK_ROWS` rows each (at least one run)."""
    n_runs = len(offsets) - 1
    cuts = np.searchsorted(offsets, np.arange(BLOCK_ROWS, offsets[-1], BLOCK_ROWS))
    bounds = np.unique(np.r_[0, np.clip(cuts, 1, n_runs), n_runs])
    return list(zip(bounds[:-1].tolist(), bounds[1:].tolist(), strict=True))


def _block(codes: np.ndarray, offsets: np.ndarray, lo: int, hi: int
           ) -> tuple[np.ndarray, np.ndarray]:
    """The codes and offsets of runs ``lo .. hi - 1`` (views, offsets from 0)."""
    return codes[offsets[lo]:offsets[hi]], offsets[lo:hi + 1] - offsets[lo]


def _sorted_block_counts(codes: np.ndarray, offsets: np.ndarray, size: int
                         ) -> tuple[CompactBlock, np.ndarray]:
    """The (column × run) counts of one block of runs and its columns' keys, for key spaces of
    at most :data:`SORTED_KEYS`: the 16-bit keys are radix-sorted (stable, so each key's runs
    stay in order) and equal (key, run) neighbours counted; no table over the key space and
    2 bytes a key instead of 8."""
    n_runs = len(offsets) - 1
    keys, runs = _pair_keys(codes, offsets, size, np.uint16,
                            np.int32 if n_runs < 2**31 else np.int64)
    order = np.argsort(keys, kind="stable")
    keys, runs = keys[order], runs[order]
    del order
    new_key = np.ones(len(keys) + 1, dtype=bool)
    np.not_equal(keys[1:], keys[:-1], out=new_key[1:-1])
    new_entry = new_key.copy()
    new_entry[1:-1] |= runs[1:] != runs[:-1]
    at = np.flatnonzero(new_entry)
    counts, at = np.diff(at), at[:-1]
    indptr = np.r_[np.flatnonzero(new_key[at]), len(at)]
    block = CompactBlock(indptr, runs[at].astype(np.min_scalar_type(max(n_runs - 1, 0))),
                         counts.astype(np.min_scalar_type(int(counts.max()))), (len(indptr) - 1,
                                                                                n_runs))
    return block, keys[at[indptr[:-1]]].astype(np.int64)


def _pair_keys(codes: np.ndarray, offsets: np.ndarray, size: int | np.int64,
               key: type = np.int64, run: type = np.int64) -> tuple[np.ndarray, np.ndarray]:
    """Per start state and per transition: its key ``(from + 1) · |S| + to`` (a start: its
    state, block START = origin START + 1 = 0) and its run, of types ``key`` and ``run`` (that
    hold them); starts first, run by run."""
    n_runs = len(offsets) - 1
    keys = np.empty(len(codes) - 1, dtype=key)
    np.add(codes[:-1], key(1), out=keys, casting="unsafe")
    keys *= key(size)
    np.add(keys, codes[1:], out=keys, casting="unsafe")
    within = np.ones(len(keys), dtype=bool)
    within[offsets[1:-1] - 1] = False  # a run's last row starts no transition
    keys = np.concatenate([codes[offsets[:-1]].astype(key), keys[within]])
    runs = np.concatenate([np.arange(n_runs, dtype=run),
                           np.repeat(np.arange(n_runs, dtype=run), np.diff(offsets) - 1)])
    return keys, runs


def _block_counts(codes: np.ndarray, offsets: np.ndarray, size: np.int64,
                  column_index: np.ndarray, n_columns: int) -> sp.csr_matrix:
    """The (column × run) counts of one block of runs, without sorting; float32 where no run
    has :data:`EXACT_FLOAT32` rows (every count, a sum of ones, is then exact in float32).

    Runs never decrease within one key (starts and transitions are listed run by run), so the
    COO → CSR conversion leaves each row's runs sorted and adding up duplicates is one linear
    pass.
    """
    keys, runs = _pair_keys(codes, offsets, size)
    longest = int(np.diff(offsets).max()) if len(offsets) > 1 else 0
    ones = np.ones(len(keys), dtype=np.float32 if longest < EXACT_FLOAT32 else np.float64)
    matrix = sp.csr_matrix((ones, (column_index[keys], runs)),
                           shape=(n_columns, len(offsets) - 1))
    matrix.sum_duplicates()
    return matrix


def _pair_counts(keys: np.ndarray, runs: np.ndarray, n_runs: int):
    """Distinct keys (sorted), and per distinct (key, run), sorted by (key, run): key index, run,
    count.

    One sort of ``key · runs + run`` when that fits into int64, else two.
    """
    if len(keys) and (int(keys.max()) + 1) * n_runs < 2**62:
        combined = keys * np.int64(n_runs)
        combined += runs
        combined, count = np.unique(combined, return_counts=True)
        key, run_of = np.divmod(combined, np.int64(n_runs))
        del combined
        new = np.r_[True, key[1:] != key[:-1]]
        return key[new], np.cumsum(new) - 1, run_of, count
    columns, inverse = np.unique(keys, return_inverse=True)
    combined, count = np.unique(inverse.ravel() * np.int64(n_runs) + runs, return_counts=True)
    column_of, run_of = np.divmod(combined, np.int64(n_runs))
    return columns, column_of, run_of, count
