"""Per-(state, unit) sums of the response test's transition values.

The transitions are sorted by state, then unit; a run of equal (state, unit) is a *pair*
(:class:`StatePairs`), and every statistic of the response test is built from per-pair column
sums laid out as a (states · width) × units matrix (:class:`SumTarget`: dense where most
positions hold a value, else the CSR arrays of :class:`SumLayout`), so that every assignment of
the units to the sides is one product (:mod:`simcred.compare.side_counts`,
:mod:`simcred.compare.unit_sums`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import scipy.sparse as sp

from simcred.compare.run_counts import RunCounts
from simcred.compare.unit_sums import DENSE_SHARE

if TYPE_CHECKING:
    from simcred.compare.transitions import Transitions

#: Transitions per chunk when the features are computed and summed.
CHUNK = 2**16


@dataclass(frozen=True, slots=True, eq=False)
class StatePairs:
    """Runs of equal (state, unit) in the sorted transitions."""

    starts: np.ndarray  # first transition of every (state, unit) pair, and the total at the end
    state: np.ndarray
    unit: np.ndarray
    block: np.ndarray  # block (distinct state) of every pair
    blocks: np.ndarray  # state code of every block

    @classmethod
    def of(cls, data: Transitions) -> StatePairs:
        new = np.r_[True, (np.diff(data.state) != 0) | (np.diff(data.unit) != 0)]
        first = np.flatnonzero(new)
        state = data.state[first]
        block_start = np.r_[True, np.diff(state) != 0]
        return cls(np.r_[first, len(data.state)], state, data.unit[first],
                   np.cumsum(block_start) - 1, state[block_start])


def pair_chunks(starts: np.ndarray, p0: int, p1: int):
    """(first, last) pair ranges of pairs p0:p1 of about ``CHUNK`` transitions each."""
    first = p0
    while first < p1:
        last = int(np.searchsorted(starts, starts[first] + CHUNK, side="right"))
        last = min(max(last - 1, first + 1), p1)
        yield first, last
        first = last


class SumTarget:
    """The (blocks · width) × units matrix of per-(state, unit) sums being written: dense
    where at least ``DENSE_SHARE`` of the positions hold a value (float32 where ``peak``
    bounds every entry and every difference of two entries below 2**24: exact), else the
    CSR arrays of :class:`SumLayout`."""

    def __init__(self, pairs: StatePairs, width: int, n_units: int, peak: int | None) -> None:
        n_blocks = len(pairs.blocks)
        self.pairs, self.width, self.n_units = pairs, width, n_units
        self.layout, self.matrix = None, None
        if len(pairs.unit) >= DENSE_SHARE * n_units * n_blocks:
            dtype = np.float32 if peak is not None and peak < 2**24 else np.float64
            self.matrix = np.zeros((n_blocks * width, n_units), dtype)
        else:
            self.layout = SumLayout(pairs, width, n_units)

    def put(self, b: int, column: int, first: int, last: int, sums: np.ndarray) -> None:
        """Pair sums (pairs first:last of block b, k) at columns column:column + k."""
        k = sums.shape[1]
        if self.matrix is not None:
            row = b * self.width + column
            # rows contiguous in the matrix's type first: a strided scatter is ~5x slower
            self.matrix[row:row + k, self.pairs.unit[first:last]] = np.ascontiguousarray(
                sums.T, dtype=self.matrix.dtype)
        else:
            p0 = self.layout.first[b]
            self.layout.view(b)[column:column + k, first - p0:last - p0] = sums.T

    @property
    def dtype(self) -> type:
        """The type the sums are kept in (float32 only where that is exact)."""
        return np.float64 if self.matrix is None else self.matrix.dtype.type

    def counts(self) -> RunCounts:
        if self.layout is not None:
            return self.layout.counts()
        n_blocks = len(self.pairs.blocks)
        return RunCounts(self.matrix, self.pairs.blocks, np.arange(n_blocks + 1) * self.width,
                         np.zeros(n_blocks * self.width, dtype=np.int64))


class SumLayout:
    """The CSR arrays of the (blocks · width) × units matrix of per-pair sums: block ``b``'s
    entries are one (width, pairs of b) array, row by row, each row's units ascending."""

    def __init__(self, pairs: StatePairs, width: int, n_units: int) -> None:
        n_blocks = len(pairs.blocks)
        per_block = np.bincount(pairs.block, minlength=n_blocks)
        self.first = np.r_[0, np.cumsum(per_block)]
        nnz = len(pairs.unit) * width
        index = np.int32 if max(nnz, n_units) < 2**31 else np.int64
        self.data = np.empty(nnz)
        self.indices = np.empty(nnz, dtype=index)
        self.indptr = np.r_[0, np.cumsum(np.repeat(per_block, width))].astype(index)
        self.pairs, self.width, self.n_units = pairs, width, n_units
        for b in range(n_blocks):
            self._segment(self.indices, b)[:] = pairs.unit[self.first[b]:self.first[b + 1]]

    def _segment(self, array: np.ndarray, b: int) -> np.ndarray:
        lo, hi = self.first[b] * self.width, self.first[b + 1] * self.width
        return array[lo:hi].reshape(self.width, -1)

    def view(self, b: int) -> np.ndarray:
        """(width, pairs of block b): the writable entries of block ``b``."""
        return self._segment(self.data, b)

    def counts(self) -> RunCounts:
        n_blocks = len(self.pairs.blocks)
        matrix = sp.csr_matrix((self.data, self.indices, self.indptr),
                               shape=(n_blocks * self.width, self.n_units))
        return RunCounts(matrix, self.pairs.blocks, np.arange(n_blocks + 1) * self.width,
                         np.zeros(n_blocks * self.width, dtype=np.int64))
