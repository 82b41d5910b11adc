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
    pair_weights = (counts_x[:, :, None] * counts_y[:, None, :]).reshape(len(counts_x), -1)
    weights = np.add.reduceat(pair_weights[:, order], starts, axis=1)
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
