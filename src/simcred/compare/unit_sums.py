"""Per-unit sums laid out for products with many weight columns (bootstrap, permutations).

The response effect keeps, per (state, unit), a row of sums; every resample or assignment of
the units is then one product ``matrix @ weights`` with a (width · states) × units matrix. With
a few hundred states and runs of some hundred steps almost every unit visits almost every
state (74–92 % of the positions filled in benchmarks/response.py), and there a dense array
multiplied by BLAS is 10–20× faster than a sparse product and no larger (a sparse value carries
a 4-byte index besides its 8 bytes). Sparse sets (many states, short runs) stay sparse.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import scipy.sparse as sp

from simcred.compare.run_counts import RunCounts
from simcred.compare.side_counts import (
    CHUNK_BUDGET,
    SPARSE_RATIO,
    SideCounts,
    _block_chunks,
    _exact_slices,
)

#: Fill share from which the matrix is dense: 8 bytes a position against 12 a stored value.
DENSE_SHARE = 2 / 3
#: Elements of the product columns formed at once (:class:`ProductColumns`; 64 MB).
CHUNK_ELEMENTS = 2**23


def unique_inverse(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(values, return_inverse=True)`` of a 1-D array, by counting instead of
    sorting where the values are non-negative integers whose range is at most about four
    times their number (state codes, unit × state keys): same values, same dtypes."""
    if values.size and values.dtype.kind in "iu" and values.min() >= 0 \
            and values.max() < 4 * values.size + 1024:
        present = np.bincount(values) > 0
        return np.flatnonzero(present).astype(values.dtype), (np.cumsum(present) - 1)[values]
    return np.unique(values, return_inverse=True)


def unit_matrix(parts: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray]], n_units: int,
                n_blocks: int, products: tuple[np.ndarray, np.ndarray] | None = None
                ) -> np.ndarray | sp.csc_matrix | ProductColumns:
    """The (width · n_blocks) × n_units matrix of per-(unit, block) rows, row ``c · n_blocks +
    b`` of column ``u`` holding column ``c`` of (unit ``u``, block ``b``)'s row, empty positions
    0. ``parts``: ``(unit, block, values)`` triples whose columns lie side by side (a (unit,
    block) at most once per part, in any number of parts: e.g. the two members of a pair). Given
    ``products = (one, two)``, column ``c`` is instead ``row[one[c]] · row[two[c]]`` (``two[c]``
    < 0: ``row[one[c]]`` alone). Where at least :data:`DENSE_SHARE` of the positions hold a
    row: a dense C-ordered array, or with ``products`` a :class:`ProductColumns` (the values
    scattered once, the products formed when multiplied); else CSC."""
    offsets = np.r_[0, np.cumsum([values.shape[1] for _, _, values in parts])]
    keys = [unit * n_blocks + block for unit, block, _ in parts]
    dense = DENSE_SHARE * n_units * n_blocks
    if sum(map(len, keys)) >= dense and (  # distinct positions counted only where it matters
            len(parts) == 1 or len(unique_inverse(np.concatenate(keys))[0]) >= dense):
        base = np.zeros((offsets[-1], n_blocks, n_units))
        for (unit, block, values), lo in zip(parts, offsets, strict=False):
            base[lo:lo + values.shape[1], block, unit] = values.T
        return base.reshape(-1, n_units) if products is None else ProductColumns(base, *products)
    key, inverse = unique_inverse(np.concatenate(keys))
    rows = np.zeros((len(key), offsets[-1]))
    at = np.split(inverse, np.cumsum([len(unit) for unit, _, _ in parts])[:-1])
    for (_, _, values), lo, where in zip(parts, offsets, at, strict=False):
        rows[where, lo:lo + values.shape[1]] = values
    if products is not None:
        one, two = products
        rows = rows[:, one] * np.where(two >= 0, rows[:, np.maximum(two, 0)], 1.0)
    width = rows.shape[1]
    row_index = (np.arange(width)[:, None] * n_blocks + key % n_blocks).ravel()
    return sp.csc_matrix((rows.T.ravel(), (row_index, np.tile(key // n_blocks, width))),
                         shape=(width * n_blocks, n_units))


class ProductColumns:
    """The dense (products · blocks) × units matrix of :func:`unit_matrix` with ``products``,
    never held whole (it is several times the sums it is made of: 49 columns from 11 for a
    paired design, and its first touch of fresh memory cost more than the products): ``self @
    weights`` forms the product columns :data:`CHUNK_ELEMENTS` at a time in one buffer, each
    one contiguous multiply of two (blocks × units) slabs of ``base`` (sums, blocks, units)."""

    def __init__(self, base: np.ndarray, one: np.ndarray, two: np.ndarray) -> None:
        self.base, self.one, self.two = base, one, two
        self.shape = (len(one) * base.shape[1], base.shape[2])

    def __matmul__(self, weights: np.ndarray) -> np.ndarray:
        width, (_, n_blocks, n_units) = len(self.one), self.base.shape
        out = np.empty((width, n_blocks, weights.shape[1]))
        step = max(1, min(n_blocks, CHUNK_ELEMENTS // max(width * n_units, 1)))
        buffer = np.empty(width * step * n_units)
        for b0 in range(0, n_blocks, step):
            b1 = min(b0 + step, n_blocks)
            part = buffer[:width * (b1 - b0) * n_units].reshape(width, b1 - b0, n_units)
            for row, (i, k) in enumerate(zip(self.one, self.two, strict=True)):
                if k >= 0:
                    np.multiply(self.base[i, b0:b1], self.base[k, b0:b1], out=part[row])
                else:
                    part[row] = self.base[i, b0:b1]
            out[:, b0:b1] = (part.reshape(-1, n_units) @ weights).reshape(width, b1 - b0, -1)
        return out.reshape(-1, weights.shape[1])


def side_sums(matrix: np.ndarray | sp.spmatrix, paired: bool
              ) -> Callable[[np.ndarray], np.ndarray]:
    """``Z ↦ matrix @ Z.T`` (rows × batch) for bool assignments ``Z`` (batch, units) of a
    float (rows × units) matrix; ``paired`` (:func:`~simcred.compare.side_counts.is_paired`):
    through half the units, ``M Z = M_1 1 + (M_2 − M_1) F`` with ``F`` the second half of Z."""
    if not paired:
        return lambda z: np.asarray(matrix @ z.T.astype(np.float64))
    half = matrix.shape[1] // 2
    base = np.asarray(matrix[:, :half].sum(axis=1)).reshape(-1, 1)
    difference = matrix[:, half:] - matrix[:, :half]
    return lambda z: np.asarray(difference @ z[:, half:].T.astype(np.float64)) + base


class DenseSides(SideCounts):
    """:class:`~simcred.compare.side_counts.SideCounts` of a dense integer-valued (columns ×
    units) matrix (``RunCounts.matrix`` an ndarray, float32 only where its entries and their
    pairwise differences are exact): the same chunks of state blocks (a block's columns count
    as dense where the block's count row is nonzero for at least 1/``SPARSE_RATIO`` of the
    units, as the sparse layout's stored entries would), every product through BLAS on
    slices of units that keep it exact."""

    def __init__(self, counts: RunCounts, paired: bool = False) -> None:
        self.matrix = counts.matrix
        n_runs = self.matrix.shape[1]
        self.paired = paired
        visits = np.count_nonzero(self.matrix[counts.bounds[:-1]], axis=1)
        heavy = visits * SPARSE_RATIO >= n_runs
        per_block = np.where(heavy, np.diff(counts.bounds), 0)
        self.chunks = _block_chunks(counts.bounds, per_block,
                                    max(1, CHUNK_BUDGET // max(n_runs, 1)))

    def rows(self, lo: int, hi: int) -> tuple:
        """Columns lo:hi as :meth:`SideCounts.rows` gives them, all dense."""
        rows = self.matrix[lo:hi]
        base = None
        if self.paired:
            half = rows.shape[1] // 2
            base = rows[:, :half].sum(axis=1, dtype=np.float64)
            rows = rows[:, half:] - rows[:, :half]
        rows, slices = _exact_slices(rows)
        return np.arange(hi - lo), rows, slices, base, np.zeros(0, dtype=np.int64), None
