"""The A-side counts ``R @ Z`` of many assignments of runs (permutations, pair flips), chunk by
chunk through dense BLAS or a sparse product, exactly (integer counts)."""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from simcred.compare.run_counts import RunCounts

#: Elements of one dense chunk of the count matrix (float32: 128 MB).
CHUNK_BUDGET = 2**25
#: Columns of R shown by fewer than 1/SPARSE_RATIO of the runs go through the sparse product.
SPARSE_RATIO = 64


class SideCounts:
    """``R @ Z``: the A-side counts of assignments ``Z`` (runs × batch, 0/1), chunk by chunk.

    Columns of R that at least 1/``SPARSE_RATIO`` of the runs show go through dense BLAS,
    in chunks of at most ``CHUNK_BUDGET`` dense elements aligned to state blocks; rarer columns
    through the sparse product, which is faster for them. R holds integers (counts, or integer
    feature sums), so every product is an exact integer: float32 is used wherever every partial
    sum stays within 2**24 (where it is exact), the dense product split into slices of runs
    that each keep within it (the slices' results added in float64, exactly); float64 else.

    ``paired``: every assignment puts exactly one of runs ``i`` and ``h + i`` in A (``h`` = half
    the runs; :func:`is_paired`). Then ``R Z = R_1 1 + (R_2 − R_1) F`` with ``F`` the second
    half of ``Z``: the dense product over half the runs.
    """

    def __init__(self, counts: RunCounts, paired: bool = False) -> None:
        self.matrix = counts.matrix
        n_cols, n_runs = self.matrix.shape
        self.paired = paired
        self.dense_columns = self.matrix.getnnz(axis=1) * SPARSE_RATIO >= n_runs
        per_block = np.add.reduceat(self.dense_columns.astype(np.int64), counts.bounds[:-1]) \
            if n_cols else np.zeros(0, dtype=np.int64)
        self.chunks = _block_chunks(counts.bounds, per_block,
                                    max(1, CHUNK_BUDGET // max(n_runs, 1)))

    def rows(self, lo: int, hi: int) -> tuple:
        """Columns lo:hi of R split into a dense array (with its slices of runs; paired: the
        first half's row sums and the halves' difference) and a sparse matrix, with their
        places."""
        dense = np.flatnonzero(self.dense_columns[lo:hi])
        sparse = np.flatnonzero(~self.dense_columns[lo:hi])
        dense_rows, slices, base, sparse_rows = None, None, None, None
        if len(dense):
            dense_rows = _dense_rows(self.matrix, lo, hi, dense, paired=self.paired)
            if self.paired:
                half = dense_rows.shape[1] // 2
                base = dense_rows[:, :half].sum(axis=1)
                dense_rows = dense_rows[:, half:] - dense_rows[:, :half]
            dense_rows, slices = _exact_slices(dense_rows)
        if len(sparse):
            sparse_rows = self.matrix[lo + sparse]
            exact32 = abs(sparse_rows).sum(axis=1, dtype=np.float64).max() < 2**24
            sparse_rows = sparse_rows.astype(np.float32 if exact32 else np.float64, copy=False)
        return dense, dense_rows, slices, base, sparse, sparse_rows

    def product(self, rows: tuple, assignment: np.ndarray) -> np.ndarray:
        """(columns, batch) float64 counts for bool assignments (batch, runs)."""
        dense, dense_rows, slices, base, sparse, sparse_rows = rows
        out = np.empty((len(dense) + len(sparse), len(assignment)))
        if dense_rows is not None:
            z = assignment[:, assignment.shape[1] // 2:] if self.paired else assignment
            z = z.astype(dense_rows.dtype).T  # converted untransposed: 10x faster, same product
            if len(slices) == 1:
                part = dense_rows @ z
            else:
                part = np.zeros((len(dense), len(assignment)))
                for u0, u1 in slices:
                    part += dense_rows[:, u0:u1] @ z[u0:u1]
            if base is not None:
                part = part + base[:, None]
            out[dense] = part
        if sparse_rows is not None:
            out[sparse] = sparse_rows @ np.ascontiguousarray(assignment.T,
                                                             dtype=sparse_rows.dtype)
        return out


def _dense_rows(matrix: sp.csr_matrix, lo: int, hi: int, rows: np.ndarray,
                paired: bool = False) -> np.ndarray:
    """``matrix[lo:hi][rows].toarray()`` through a view of the CSR arrays (no copy of the rows
    lo:hi): float32 where every entry is an integer below 2**24 (exact) and the rows are not
    differenced (``paired``), float64 else."""
    a, b = matrix.indptr[lo], matrix.indptr[hi]
    view = sp.csr_matrix((matrix.data[a:b], matrix.indices[a:b], matrix.indptr[lo:hi + 1] - a),
                         shape=(hi - lo, matrix.shape[1]), copy=False)
    if len(rows) < hi - lo:
        view = view[rows]
    if not paired and view.has_canonical_format and (view.nnz == 0 or (
            np.abs(view.data).max() < 2**24 and (view.data == np.rint(view.data)).all())):
        return view.astype(np.float32, copy=False).toarray()
    return view.toarray().astype(np.float64, copy=False)


def is_paired(assignments: np.ndarray) -> bool:
    """Whether every row puts exactly one of columns ``i`` and ``h + i`` in A (``h`` = half the
    columns): the assignments of a paired design."""
    half, odd = divmod(assignments.shape[1], 2)
    return not odd and half > 0 and bool(
        (assignments[:, :half] != assignments[:, half:]).all())


def _exact_slices(dense: np.ndarray) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """``dense`` (integer-valued) and slices of its columns (runs) in each of which every
    row's absolute sum is below 2**24: as float32, exact in products, if each slice's sum of
    per-run maxima stays below that; else float64 and one slice."""
    n_runs = dense.shape[1]
    peak = np.maximum(dense.max(axis=0), -dense.min(axis=0)).astype(np.float64) \
        if n_runs and len(dense) else np.zeros(n_runs)  # |dense|.max without a copy of it
    if n_runs == 0 or peak.max() >= 2**24 or (
            dense.dtype != np.float32 and not (dense == np.rint(dense)).all()):
        return dense, [(0, n_runs)]
    running = np.r_[0.0, np.cumsum(peak)]
    slices, u0 = [], 0
    while u0 < n_runs:
        u1 = int(np.searchsorted(running, running[u0] + 2**24, side="left")) - 1
        u1 = max(u1, u0 + 1)
        slices.append((u0, u1))
        u0 = u1
    return dense.astype(np.float32, copy=False), slices


def _block_chunks(bounds: np.ndarray, weights: np.ndarray, budget: int
                  ) -> list[tuple[int, int, int, int]]:
    """(first block, last block + 1, first column, last column + 1) of consecutive blocks whose
    ``weights`` sum to at most ``budget`` (a single heavier block is a chunk of its own)."""
    chunks, first, total = [], 0, 0
    for b in range(len(bounds) - 1):
        if total + weights[b] > budget and b > first:
            chunks.append((first, b, int(bounds[first]), int(bounds[b])))
            first, total = b, 0
        total += weights[b]
    chunks.append((first, len(bounds) - 1, int(bounds[first]), int(bounds[-1])))
    return chunks
