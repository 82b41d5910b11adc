"""Two-sample MMD tests on states given as counts.

Neurohr et al. 2023 [1], sec. IV-B, after Gretton et al. 2012 [2]. Samples X (m of them) and Y
(n) live on U distinct states with counts ``c_x``, ``c_y``; with the kernel matrix ``K`` over
those states:

* biased estimator (the paper's): ``MMD_b² = sᵀ K s`` with ``s = c_x/m − c_y/n`` — the three
  double sums of [1] reduce to this quadratic form;
* unbiased estimator [2] eq. (3): the same sums without the diagonal terms ``i = j``.

Tests:

* ``bound`` — the paper's acceptance region: reject iff
  ``MMD_b > 2(√(K/m) + √(K/n)) + √(2K(m+n) ln(1/α) / (mn))`` (K = 1). For ``MMD²_u``, Hoeffding's
  bound for two-sample U-statistics [3] sec. 5 with a kernel of range 4K: reject iff
  ``MMD²_u > √(8K² ln(1/α) / k)``, ``k = min(⌊m/2⌋, ⌊n/2⌋)`` ([2] Cor. 11 for m = n).
* ``permutation`` — the labels of the pooled sample are permuted B times; a permutation is one
  multivariate hypergeometric draw of ``m`` out of ``c_x + c_y`` ([4]); the statistic, *including
  its median bandwidth*, is recomputed on each permuted split, so the test is exact:
  ``p = (1 + #{T* ≥ T}) / (B + 1)`` ([5]), reject iff ``p ≤ α``. By default the permutations
  stop as soon as rejection has become impossible ([6]); the verdict is unchanged.

Nothing is O(number of samples): the cost is O(B · U²) for U distinct states.

References
----------
[1] Neurohr et al., Determining the Validity of Simulation Models for the Verification of
    ADSs, IEEE Access, 2023.
[2] Gretton et al., A Kernel Two-Sample Test, JMLR 13, 2012.
[3] Hoeffding, Probability Inequalities for Sums of Bounded Random Variables, JASA 58, 1963.
[4] numpy.random.Generator.multivariate_hypergeometric.
[5] Phipson & Smyth, Permutation P-values Should Never Be Zero, SAGMB 9, 2010.
[6] Besag & Clifford, Sequential Monte Carlo p-values, Biometrika 78, 1991.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from simcred.compare.kernels import (
    DENSE_LIMIT,
    Kernel,
    KernelOperator,
    cross_bandwidths,
    distances,
    gram,
    median_bandwidths,
)

KERNEL_BOUND = 1.0
#: Relative tolerance when counting permuted statistics ≥ the observed one (float ties).
TIE_RTOL = 1e-12
#: Permutations in the first batch of a permutation test; later batches double.
FIRST_BATCH = 32


class Estimator(StrEnum):
    BIASED = "biased"
    UNBIASED = "unbiased"

    @property
    def min_samples(self) -> int:
        """Fewest samples per side for which the estimator is defined."""
        return 1 if self is Estimator.BIASED else 2


class Test(StrEnum):
    __test__ = False  # not a pytest test class

    RESPONSE = "response"  # conditional response test (simcred.compare.conditional)
    RUNS = "runs"  # run-level permutation test (simcred.compare.runs)
    BOUND = "bound"
    PERMUTATION = "permutation"


@dataclass(frozen=True, slots=True)
class MMDTestSpec:
    """How to test: kernel, estimator, test, level and (permutation test) resamples."""

    kernel: Kernel = Kernel.GAUSSIAN
    estimator: Estimator = Estimator.BIASED
    test: Test = Test.BOUND
    alpha: float = 0.01
    permutations: int = 999
    stop_early: bool = True


@dataclass(frozen=True, slots=True)
class MMDTestResult:
    """One two-sample test.

    ``statistic`` is MMD_b (not squared) for the biased estimator and MMD²_u for the unbiased one.
    ``n_resamples`` is the number of permutations actually drawn (permutation test only).
    ``threshold`` is set by the bound test, ``pvalue`` by the permutation test. ``bandwidth`` is
    the median-heuristic σ on the observed samples (None for the linear kernel or when both
    samples are one single state).
    """

    m: int
    n: int
    statistic: float
    rejected: bool
    threshold: float | None = None
    pvalue: float | None = None
    bandwidth: float | None = None
    n_resamples: int | None = None
    adjusted_pvalue: float | None = None


def bound_threshold(m: int, n: int, alpha: float, estimator: Estimator) -> float:
    """Acceptance-region bound of the biased ([1] sec. IV-B) or unbiased ([2], [3]) statistic."""
    k = KERNEL_BOUND
    if estimator is Estimator.BIASED:
        return 2 * (math.sqrt(k / m) + math.sqrt(k / n)) + math.sqrt(
            2 * k * (m + n) * math.log(1 / alpha) / (m * n)
        )
    pairs = min(m // 2, n // 2)
    return math.sqrt(8 * k * k * math.log(1 / alpha) / pairs)


def statistics(
    kernel_matrix: np.ndarray, counts_x: np.ndarray, counts_y: np.ndarray, estimator: Estimator
) -> np.ndarray:
    """Statistic for each row of counts (B, U) under one kernel matrix (U, U)."""
    m = counts_x.sum(axis=1, keepdims=True).astype(np.float64)
    n = counts_y.sum(axis=1, keepdims=True).astype(np.float64)
    if estimator is Estimator.BIASED:
        s = counts_x / m - counts_y / n
        return np.sqrt(np.maximum(_quadratic(s, kernel_matrix, s), 0.0))
    diag = np.diag(kernel_matrix)
    xx = _quadratic(counts_x, kernel_matrix, counts_x) - counts_x @ diag
    yy = _quadratic(counts_y, kernel_matrix, counts_y) - counts_y @ diag
    xy = _quadratic(counts_x, kernel_matrix, counts_y)
    m, n = m[:, 0], n[:, 0]
    return xx / (m * (m - 1)) + yy / (n * (n - 1)) - 2 * xy / (m * n)


def kernel_statistics(kernel: KernelOperator, x: np.ndarray, y: np.ndarray,
                      estimator: Estimator, floor: float = 0.0) -> np.ndarray:
    """Statistic per column of counts ``x``, ``y`` (U, B), with ``K`` applied by an operator.

    Same formulas as :func:`statistics`; never forms more of ``K`` than the operator does.
    ``floor``: ``MMD_b²`` below it counts as 0 (rounding noise of an exact 0).
    """
    m, n = x.sum(axis=0), y.sum(axis=0)
    if estimator is Estimator.BIASED:
        d = x / m - y / n
        quadratic = np.einsum("ub,ub->b", d, kernel.apply(d))
        return np.sqrt(np.where(quadratic <= floor, 0.0, quadratic))
    diag = kernel.diagonal()
    kx, ky = kernel.apply(x), kernel.apply(y)
    xx = np.einsum("ub,ub->b", x, kx) - diag @ x
    yy = np.einsum("ub,ub->b", y, ky) - diag @ y
    xy = np.einsum("ub,ub->b", x, ky)
    return xx / (m * (m - 1)) + yy / (n * (n - 1)) - 2 * xy / (m * n)


def _quadratic(a: np.ndarray, kernel_matrix: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise ``a[i] @ K @ b[i]``."""
    return np.einsum("bu,bu->b", a @ kernel_matrix, b)


def batch_statistics(
    vectors: np.ndarray,
    counts_x: np.ndarray,
    counts_y: np.ndarray,
    kernel: Kernel,
    estimator: Estimator,
    n_bins: tuple[int, ...],
) -> tuple[np.ndarray, np.ndarray]:
    """Statistics and bandwidths for each row of counts, each with its own median bandwidth.

    Above ``DENSE_LIMIT`` distinct states the kernel matrix is never formed (memory
    O(ROW_BLOCK · U), see :class:`KernelOperator`).
    """
    if len(vectors) > DENSE_LIMIT:
        return _large_batch_statistics(vectors, counts_x, counts_y, kernel, estimator, n_bins)
    if not kernel.has_bandwidth:
        k = gram(vectors, None, kernel, 0.0, n_bins)
        return statistics(k, counts_x, counts_y, estimator), np.full(len(counts_x), np.nan)
    dist = distances(vectors, kernel)
    sigma = median_bandwidths(dist, counts_x, counts_y)
    out = np.zeros(len(counts_x))  # no bandwidth: X and Y are one single state, MMD = 0
    for value in np.unique(sigma[~np.isnan(sigma)]):
        rows = sigma == value
        k = gram(vectors, dist, kernel, float(value), n_bins)
        out[rows] = statistics(k, counts_x[rows], counts_y[rows], estimator)
    return out, sigma


def _large_batch_statistics(vectors, counts_x, counts_y, kernel, estimator, n_bins):
    grid = np.rint(vectors).astype(np.int64)
    x, y = counts_x.astype(np.float64), counts_y.astype(np.float64)
    if not kernel.has_bandwidth:
        operator = KernelOperator(grid, kernel, None, n_bins)
        return kernel_statistics(operator, x.T, y.T, estimator), np.full(len(x), np.nan)
    sigma = cross_bandwidths(grid, x, y, kernel)
    out = np.zeros(len(x))
    for value in np.unique(sigma[~np.isnan(sigma)]):
        rows = sigma == value
        operator = KernelOperator(grid, kernel, float(value), n_bins)
        out[rows] = kernel_statistics(operator, x[rows].T, y[rows].T, estimator)
    return out, sigma


def mmd_test(
    vectors: np.ndarray,
    counts_x: np.ndarray,
    counts_y: np.ndarray,
    spec: MMDTestSpec,
    n_bins: tuple[int, ...],
    rng: np.random.Generator | None = None,
) -> MMDTestResult:
    """Test H0: P = Q for samples given as counts over the distinct states ``vectors`` (U, F).

    ``rng`` is needed by the permutation test only.
    """
    m, n = int(counts_x.sum()), int(counts_y.sum())
    stats, sigma = batch_statistics(vectors, counts_x[None, :], counts_y[None, :], spec.kernel,
                                    spec.estimator, n_bins)
    observed = float(stats[0])
    bandwidth = None if np.isnan(sigma[0]) else float(sigma[0])
    if spec.test is Test.BOUND:
        threshold = bound_threshold(m, n, spec.alpha, spec.estimator)
        return MMDTestResult(m, n, observed, observed > threshold, threshold=threshold,
                             bandwidth=bandwidth)
    pvalue, used = _permutation_pvalue(observed, vectors, counts_x, counts_y, spec, n_bins, rng)
    return MMDTestResult(m, n, observed, pvalue <= spec.alpha, pvalue=pvalue,
                         bandwidth=bandwidth, n_resamples=used)


def _permutation_pvalue(
    observed: float,
    vectors: np.ndarray,
    counts_x: np.ndarray,
    counts_y: np.ndarray,
    spec: MMDTestSpec,
    n_bins: tuple[int, ...],
    rng: np.random.Generator,
) -> tuple[float, int]:
    """p-value and number of permutations used.

    Permutations are drawn in doubling batches from one stream, so the draws are the same as one
    batch of ``spec.permutations``. With ``spec.stop_early``, drawing stops as soon as so many
    permuted statistics reach the observed one that ``p <= alpha`` has become impossible; the
    verdict is then the one the full test would give, and the p-value is the sequential
    Besag-Clifford estimate ``h / L`` ([6]) for ``h`` exceedances in ``L`` permutations.
    Rejected tests always run all permutations and report the exact ``(1 + #{T* >= T})/(B + 1)``.
    """
    total = spec.permutations
    pooled = counts_x + counts_y
    m = int(counts_x.sum())
    tolerance = TIE_RTOL * abs(observed)
    exceed, done, batch = 0, 0, FIRST_BATCH
    while done < total:
        size = min(batch, total - done)
        drawn = rng.multivariate_hypergeometric(pooled, m, size=size)
        stats, _ = batch_statistics(vectors, drawn, pooled - drawn, spec.kernel, spec.estimator,
                                    n_bins)
        hits = exceed + np.cumsum(stats >= observed - tolerance)
        if spec.stop_early:
            hopeless = (1 + hits) / (total + 1) > spec.alpha
            if hopeless.any():
                k = int(np.argmax(hopeless))
                return int(hits[k]) / (done + k + 1), done + k + 1
        exceed, done, batch = int(hits[-1]), done + size, 2 * batch
    return (1 + exceed) / (total + 1), total
