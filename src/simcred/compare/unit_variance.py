"""The response test's studentisation: each side's variance from its own units.

The pooled statistics of :mod:`simcred.compare.response` compare per-state means of the two
sides, ``d_s = μ̂_A,s − μ̂_B,s``. Their variance under an assignment is estimated from the units
(runs, groups, pairs' members) of each side, not from single transitions:

    Var(μ̂_A,s) ≈ Σ_{u ∈ A} ‖X_u,s‖² / m_s²,    X_u,s = S_u,s − c_u,s μ̂_s

(``S_u,s``: unit u's sum of the feature's values in state s, ``c_u,s`` its transitions there,
``μ̂_s`` the pooled state mean, label-free). This is the cluster-robust variance of a mean over
clusters [1], centred at the pooled mean as H0 has it, and unpooled between the sides: under an
assignment that puts all short runs on one side it is that side's own variance, which the
permutation distribution (balanced mixtures of short and long runs) does not show. A statistic
studentised this way has the same limit under every assignment, so the permutation test is
asymptotically valid also where the units are not exchangeable [2] — measured on runs of 10 vs
100 steps, the leaders split and the others (docs/calibration.md, session 13).

``‖X_u,s‖²`` is stored as an integer count of a per-feature quantum (at most 2⁵⁰ in all), so
its sums over any set of units are exact in float64, whatever the order.

References
----------
[1] Liang & Zeger, Longitudinal data analysis using generalized linear models, Biometrika 73,
    1986 (the sandwich variance over clusters).
[2] Chung & Romano, Exact and asymptotically robust permutation tests, Annals of Statistics 41,
    2013.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from simcred.compare.run_counts import RunCounts
from simcred.compare.runs import batch_size
from simcred.compare.side_counts import SideCounts, is_paired
from simcred.compare.threads import in_threads
from simcred.compare.unit_sums import DenseSides

#: Every sum of the integer squares stays below this, so float64 holds it exactly.
TOTAL = 2.0**50


@dataclass(frozen=True, slots=True, eq=False)
class UnitSquares:
    """(blocks · features) × units: ``‖X_u,s,j‖²`` in units of ``1 / scale[j]`` (integers);
    ``totals`` (blocks, features): their sums over all units."""

    matrix: np.ndarray | sp.csr_matrix
    scale: np.ndarray
    totals: np.ndarray
    n_features: int

    @classmethod
    def of(cls, sums: RunCounts, n_features: int, dims: int) -> UnitSquares:
        """From the per-(state, unit) sums ``[count, features (n_features · dims)]`` of
        :class:`simcred.compare.state_sums.SumTarget`, block by block (no temporary of the
        whole matrix's size)."""
        width = 1 + n_features * dims
        n_blocks, n_units = len(sums.blocks), sums.matrix.shape[1]
        blocks = in_threads(lambda b: _block_squares(sums.matrix[b * width:(b + 1) * width],
                                                     n_features, dims), range(n_blocks))
        raw = np.array([q.sum(axis=1) for _, q in blocks]).reshape(n_blocks, n_features)
        total = raw.sum(axis=0)
        scale = np.where(total > 0, TOTAL / np.where(total > 0, total, 1.0), 1.0)
        quantised = [np.rint(q * scale[:, None]) for _, q in blocks]
        totals = np.array([q.sum(axis=1) for q in quantised]).reshape(n_blocks, n_features)
        if isinstance(sums.matrix, np.ndarray):
            return cls(np.concatenate(quantised, axis=0), scale, totals, n_features)
        columns = [units for units, _ in blocks]
        data = np.concatenate([q.ravel() for q in quantised])
        indices = np.concatenate([np.tile(u, n_features) for u in columns])
        indptr = np.r_[0, np.cumsum(np.repeat([len(u) for u in columns], n_features))]
        matrix = sp.csr_matrix((data, indices, indptr), shape=(n_blocks * n_features, n_units))
        return cls(matrix, scale, totals, n_features)

    def sides(self, assignments: np.ndarray, blocks: np.ndarray) -> SideSquares:
        """``Σ_{u ∈ A} ‖X_u,s,j‖²`` of every assignment (row 0 observed), through the same exact
        products as the sums themselves (:class:`SideCounts`, paired or not)."""
        n_blocks = len(self.totals)
        counts = RunCounts(self.matrix, blocks, np.arange(n_blocks + 1) * self.n_features,
                           np.zeros(n_blocks * self.n_features, dtype=np.int64))
        sides = DenseSides if isinstance(self.matrix, np.ndarray) else SideCounts
        product = sides(counts, paired=is_paired(assignments))
        side_a = np.empty((n_blocks * self.n_features, len(assignments)))
        batch = batch_size(*self.matrix.shape)
        for _, _, lo, hi in product.chunks:
            rows = product.rows(lo, hi)

            def one_batch(start: int, rows=rows, lo=lo, hi=hi) -> None:
                here = slice(start, start + batch)
                side_a[lo:hi, here] = product.product(rows, assignments[here])

            in_threads(one_batch, range(0, len(assignments), batch))
        return SideSquares(side_a.reshape(n_blocks, self.n_features, -1), self)


@dataclass(frozen=True, slots=True, eq=False)
class SideSquares:
    """The A-side sums of :class:`UnitSquares` of every assignment (blocks, features, P + 1)."""

    side_a: np.ndarray
    squares: UnitSquares

    def __call__(self, first: int, last: int, here: slice) -> tuple[np.ndarray, np.ndarray]:
        """Blocks first:last, assignments ``here``: ``Σ_{u ∈ A} ‖X_u,s,j‖²`` and the same over
        B, (blocks, features, assignments), in the features' units."""
        side_a = self.side_a[first:last, :, here]
        side_b = self.squares.totals[first:last, :, None] - side_a
        scale = self.squares.scale[:, None]
        return side_a / scale, side_b / scale


def _block_squares(rows, n_features: int, dims: int) -> tuple[np.ndarray, np.ndarray]:
    """One block's rows ``[count, features]``: the units it holds (all of them for a dense
    block) and their ``‖X_u,j‖²`` (features, units)."""
    if isinstance(rows, np.ndarray):
        units, values = np.arange(rows.shape[1]), rows.astype(np.float64)
    else:
        lengths = np.diff(rows.indptr)
        grid = rows.indices.reshape(len(lengths), -1) if lengths.min() == lengths.max() else None
        if grid is not None and (grid == grid[0]).all():  # every row the same units (SumLayout)
            units = grid[0]
            values = rows.data.reshape(len(lengths), -1).astype(np.float64)
        else:
            units = np.unique(rows.indices)
            values = rows[:, units].toarray().astype(np.float64)
    count = values[0]
    mean = values[1:].sum(axis=1) / max(count.sum(), 1.0)
    centred = values[1:] - mean[:, None] * count[None, :]
    return units, (centred**2).reshape(n_features, dims, -1).sum(axis=1)
