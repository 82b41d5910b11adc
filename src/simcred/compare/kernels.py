"""Kernels on state vectors and the median bandwidth heuristic, computed from counts.

Neurohr et al. 2023 [1], sec. IV-C: Gaussian (eq. 3) and Laplace (eq. 4) kernels with the bandwidth
σ = median of the cross distances {‖x − y‖ : x ∈ X, y ∈ Y}, and the linear kernel (eq. 5) scaled
to [0, 1]. Every kernel is bounded by K = 1.

Samples are states from a finite grid, so X and Y are given as counts over ``U`` distinct states;
the median of the m·n cross distances (with multiplicity) is a weighted median over the U×U
distance matrix with weights ``c_x[i] * c_y[j]``, equal to ``numpy.median`` of the multiset.
"""

from __future__ import annotations

from enum import StrEnum

import numpy as np

#: Elements of the (rows × U²) pair-weight array formed at once by :func:`median_bandwidths`.
PAIR_BUDGET = 2**22


class Kernel(StrEnum):
    GAUSSIAN = "gaussian"
    LAPLACE = "laplace"
    LINEAR = "linear"

    @property
    def has_bandwidth(self) -> bool:
        return self is not Kernel.LINEAR


def distances(vectors: np.ndarray, kernel: Kernel) -> np.ndarray:
    """Pairwise distances of the distinct states: ‖·‖₂ for Gaussian, ‖·‖₁ for Laplace.

    Bin indices are small integers, so the sums are exact and the distances equal those of a
    sample-based computation bit for bit.
    """
    diff = vectors[:, None, :] - vectors[None, :, :]
    if kernel is Kernel.LAPLACE:
        return np.abs(diff).sum(axis=2)
    return np.sqrt((diff * diff).sum(axis=2))


def weighted_medians(values: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Row-wise median of the multisets ``values[v]`` repeated ``weights[b, v]`` times.

    ``values`` is sorted ascending, shape (V,); ``weights`` is an integer array (B, V). Same
    convention as ``numpy.median``: for an even total the mean of the two middle elements. Rows
    with zero total weight give NaN.
    """
    cumulative = np.cumsum(weights, axis=1)
    total = cumulative[:, -1]
    lower = _kth(values, cumulative, (total - 1) // 2)
    upper = _kth(values, cumulative, total // 2)
    out = (lower + upper) / 2
    out[total == 0] = np.nan
    return out


def _kth(values: np.ndarray, cumulative: np.ndarray, k: np.ndarray) -> np.ndarray:
    """The k-th smallest (0-based) element of each row's multiset."""
    return values[np.argmax(cumulative > k[:, None], axis=1)]


def median_bandwidths(
    dist: np.ndarray, counts_x: np.ndarray, counts_y: np.ndarray
) -> np.ndarray:
    """Median-heuristic σ for each row of counts (B, U), with the zero-median rule.

    σ = median of the cross distances; if that is 0, the median of the non-zero cross distances;
    if there is none (X and Y are one and the same single state), NaN: the MMD is then 0.
    """
    levels, index = np.unique(dist, return_inverse=True)
    order = np.argsort(index.ravel(), kind="stable")
    starts = np.searchsorted(index.ravel()[order], np.arange(len(levels)))
    chunk = max(1, PAIR_BUDGET // dist.size)  # rows per chunk: never B × U² at once
    weights = np.concatenate([
        np.add.reduceat((x[:, :, None] * y[:, None, :]).reshape(len(x), -1)[:, order], starts,
                        axis=1)
        for x, y in ((counts_x[i:i + chunk], counts_y[i:i + chunk])
                     for i in range(0, len(counts_x), chunk))])
    sigma = weighted_medians(levels, weights)
    zero = sigma == 0
    if zero.any():
        nonzero = weights[zero]
        nonzero[:, levels == 0] = 0
        sigma[zero] = weighted_medians(levels, nonzero)
    return sigma


def gram(
    vectors: np.ndarray,
    dist: np.ndarray | None,
    kernel: Kernel,
    sigma: float,
    n_bins: tuple[int, ...],
) -> np.ndarray:
    """Kernel matrix over the distinct states for one bandwidth (ignored by the linear kernel)."""
    if kernel is Kernel.GAUSSIAN:
        return np.exp(-(dist * dist) / (2.0 * sigma * sigma))  # [1] eq. (3)
    if kernel is Kernel.LAPLACE:
        return np.exp(-dist / sigma)  # [1] eq. (4)
    scale = float(sum((b - 1) ** 2 for b in n_bins))  # max <x, y> on the grid, [1] eq. (5)
    return (vectors @ vectors.T) / scale


# -- run-level tests: one fixed bandwidth per state, kernel applied in bounded memory ------------

#: Largest number of distinct states whose full kernel matrix is formed at once; above it the
#: kernel is applied in row blocks, so memory stays O(block · U) instead of O(U²).
DENSE_LIMIT = 1024
#: Largest grid |S| on which a separable kernel is applied feature by feature.
SEPARABLE_LIMIT = 2**18
#: Rows per block when the kernel is applied blockwise.
ROW_BLOCK = 256


def integer_levels(grid_a: np.ndarray, grid_b: np.ndarray, kernel: Kernel) -> np.ndarray:
    """Distances between integer bin vectors as exact integers: ‖·‖₂² (Gaussian) or ‖·‖₁.

    ``grid_a`` (I, F) and ``grid_b`` (J, F) hold bin indices; the result is (I, J) int64.
    """
    diff = grid_a[:, None, :].astype(np.int64) - grid_b[None, :, :].astype(np.int64)
    if kernel is Kernel.LAPLACE:
        return np.abs(diff).sum(axis=2)
    return (diff * diff).sum(axis=2)


def level_histograms(grid: np.ndarray, left: np.ndarray, right: np.ndarray,
                     kernel: Kernel) -> np.ndarray:
    """Per row b, the weight ``Σ left[b, i]·right[b, j]`` of every integer distance level.

    ``grid`` (U, F) holds integer bin vectors; ``left``, ``right`` are (B, U) counts. Computed in
    row blocks of :data:`ROW_BLOCK` states: memory O(ROW_BLOCK · U), never B × U².
    """
    span = grid.max(axis=0) - grid.min(axis=0)
    top = int(span.sum() if kernel is Kernel.LAPLACE else (span * span).sum())
    out = np.zeros((len(left), top + 1))
    for lo in range(0, len(grid), ROW_BLOCK):
        levels = integer_levels(grid[lo:lo + ROW_BLOCK], grid, kernel).ravel()
        for b in range(len(left)):
            weights = (left[b, lo:lo + ROW_BLOCK, None] * right[b, None, :]).ravel()
            out[b] += np.bincount(levels, weights, minlength=top + 1)
    return out


def median_of_levels(histograms: np.ndarray, kernel: Kernel) -> np.ndarray:
    """Median distance per row of level histograms, with the zero-median rule (NaN: none)."""
    values = np.arange(histograms.shape[1], dtype=np.float64)
    if kernel is not Kernel.LAPLACE:
        values = np.sqrt(values)  # levels are squared Euclidean distances
    sigma = weighted_medians(values, histograms)
    zero = sigma == 0
    if zero.any():
        nonzero = histograms[zero].copy()
        nonzero[:, 0] = 0
        sigma[zero] = weighted_medians(values, nonzero)
    sigma[sigma == 0] = np.nan
    return sigma


def cross_bandwidths(grid: np.ndarray, counts_x: np.ndarray, counts_y: np.ndarray,
                     kernel: Kernel) -> np.ndarray:
    """:func:`median_bandwidths` in bounded memory, on integer bin vectors."""
    return median_of_levels(level_histograms(grid, counts_x, counts_y, kernel), kernel)


def pooled_bandwidth(grid: np.ndarray, totals: np.ndarray, kernel: Kernel) -> float | None:
    """Median of the pairwise distances within the pooled sample, from counts, in O(ROW_BLOCK·U).

    The pooled sample has ``totals[u]`` copies of state ``grid[u]``; its ``N(N-1)`` ordered pairs
    of distinct elements have distance levels with weights ``totals[i]·totals[j]`` (``i ≠ j``) and
    ``totals[i]·(totals[i]-1)`` (``i = j``, distance 0). The median follows ``numpy.median`` (mean
    of the two middle elements) on the distances (square roots of the ‖·‖₂² levels for the
    Gaussian kernel). Zero-median rule as for :func:`median_bandwidths`. None when the sample has
    fewer than two elements or only one state (every kernel then gives MMD = 0).

    The pooled sample does not change when runs are reassigned between the sets, so this
    bandwidth is the same for every permutation.
    """
    totals = np.asarray(totals, dtype=np.float64)[None, :]
    if totals.sum() < 2 or totals.shape[1] < 2:
        return None
    histogram = level_histograms(grid, totals, totals, kernel)
    histogram[0, 0] -= totals.sum()  # pairs of an element with itself
    sigma = float(median_of_levels(histogram, kernel)[0])
    return None if np.isnan(sigma) else sigma


class KernelOperator:
    """``d ↦ K d`` for the kernel matrix over ``U`` distinct states, in bounded memory.

    Three ways, whichever is cheapest:

    * dense: up to :data:`DENSE_LIMIT` states the U×U matrix is formed once;
    * separable: Gaussian and Laplace kernels factor over features,
      ``k(x, y) = Π_j exp(−(x_j − y_j)²/(2σ²))`` resp. ``Π_j exp(−|x_j − y_j|/σ)``, so on the grid
      ``K`` is the Kronecker product of one small ``B_j × B_j`` matrix per feature. ``d`` is
      placed on the full grid (|S| entries) and multiplied feature by feature: cost
      O(|S| · Σ_j B_j) per column instead of O(U²); used when that is smaller and |S| ≤
      :data:`SEPARABLE_LIMIT`, in column chunks of at most ``PAIR_BUDGET`` grid entries;
    * row blocks: otherwise, recomputed in blocks of :data:`ROW_BLOCK` rows on every
      application (memory O(ROW_BLOCK · U), never batch × U²).

    The linear kernel never forms it: ``K d = V (Vᵀ d) / scale``.
    """

    def __init__(self, grid: np.ndarray, kernel: Kernel, sigma: float | None,
                 n_bins: tuple[int, ...]) -> None:
        self.grid, self.kernel, self.sigma, self.n_bins = grid, kernel, sigma, tuple(n_bins)
        self.vectors = grid.astype(np.float64)
        self.scale = float(sum((b - 1) ** 2 for b in n_bins)) or 1.0
        self.dense = None
        self.factors = None
        if not kernel.has_bandwidth or sigma is None:
            return
        u, size = len(grid), int(np.prod(self.n_bins, dtype=np.int64))
        if size <= SEPARABLE_LIMIT and size * sum(self.n_bins) < u * u:
            self.flat = np.ravel_multi_index(tuple(grid.T), self.n_bins)
            self.factors = [self._factor(b) for b in self.n_bins]
        elif u <= DENSE_LIMIT:
            self.dense = self._rows(0, u)

    def _factor(self, n: int) -> np.ndarray:
        steps = np.abs(np.arange(n)[:, None] - np.arange(n)[None, :]).astype(np.float64)
        if self.kernel is Kernel.GAUSSIAN:
            return np.exp(-(steps * steps) / (2.0 * self.sigma * self.sigma))
        return np.exp(-steps / self.sigma)

    def _rows(self, lo: int, hi: int) -> np.ndarray:
        levels = integer_levels(self.grid[lo:hi], self.grid, self.kernel).astype(np.float64)
        if self.kernel is Kernel.GAUSSIAN:
            return np.exp(-levels / (2.0 * self.sigma * self.sigma))  # [1] eq. (3)
        return np.exp(-levels / self.sigma)  # [1] eq. (4)

    def diagonal(self) -> np.ndarray:
        if self.kernel is Kernel.LINEAR:
            return (self.vectors * self.vectors).sum(axis=1) / self.scale
        return np.ones(len(self.grid))

    def apply(self, d: np.ndarray) -> np.ndarray:
        """``K @ d`` for ``d`` of shape (U, batch)."""
        if self.kernel is Kernel.LINEAR:
            return self.vectors @ (self.vectors.T @ d) / self.scale  # [1] eq. (5)
        if self.sigma is None:  # one single state or a one-element sample: any kernel is 1
            return np.broadcast_to(d.sum(axis=0), d.shape).copy()
        if self.factors is not None:
            return self._separable(d)
        if self.dense is not None:
            return self.dense @ d
        out = np.empty_like(d, dtype=np.float64)
        for lo in range(0, len(self.grid), ROW_BLOCK):
            hi = min(lo + ROW_BLOCK, len(self.grid))
            out[lo:hi] = self._rows(lo, hi) @ d
        return out

    def _separable(self, d: np.ndarray) -> np.ndarray:
        size = len(self.factors[0]) if len(self.factors) == 1 else int(np.prod(self.n_bins))
        step = max(1, PAIR_BUDGET // size)
        out = np.empty_like(d, dtype=np.float64)
        for lo in range(0, d.shape[1], step):
            part = d[:, lo:lo + step]
            full = np.zeros((size, part.shape[1]))
            full[self.flat] = part
            tensor = full.reshape(*self.n_bins, part.shape[1])
            for axis, factor in enumerate(self.factors):
                tensor = np.moveaxis(np.tensordot(factor, tensor, axes=(1, axis)), 0, axis)
            out[:, lo:lo + step] = tensor.reshape(size, -1)[self.flat]
        return out
