"""Calibration of the MMD two-sample tests (size under H0, power against a small shift).

Everything is seeded, so the numbers are reproducible; docs/calibration.md records them. Run
``python tests/test_calibration.py`` to print the same measurements as a table.

Design. States are bin indices of a 7×7 grid (``n_bins = (7, 7)``), as ``space.vectors`` gives
them. The law is "successor-like": a discretised Gaussian centred at (3, 3) with a spread of one
bin, so ~21 states carry ≥ 1 % of the mass and a sample of a few dozen visits 10–25 distinct
states. Samples are multinomial counts: i.i.d. draws, so under H0 the pooled labels are
exchangeable and the permutation test is exact (its bandwidth is recomputed on every permuted
split). With B = 199 the p-value lives on the grid k / 200 and P(p ≤ α) = ⌊α(B+1)⌋ / (B+1) = α
exactly for α ∈ {0.05, 0.1, 0.2} — *provided the permuted statistics do not tie with the observed
one*. Ties make the test conservative (size < α). With ~20 distinct states and m + n ≥ 75 the
number of distinct splits is astronomically larger than B, so ties are rare and the p-values are
close to uniform; a design with very few states and samples (3 states, m = n = 5) is tie-heavy
and is only checked for validity (size ≤ α), see ``test_size_tie_heavy_design_is_conservative``.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from simcred.compare.kernels import Kernel
from simcred.compare.mmd import Estimator, MMDTestSpec, mmd_test
from simcred.compare.mmd import Test as Method  # aliased: pytest would try to collect `Test*`

ALPHA = 0.05
PERMUTATIONS = 199
SIZE_TRIALS = 2000
POWER_TRIALS = 500
#: (m, n) of the size designs: equal and unequal sample sizes.
SIZE_DESIGNS = ((40, 40), (30, 45))
#: Power design: both samples of size POWER_M, the second law's centre moved by SHIFT bins in x.
POWER_M = 150
SHIFT = 0.4

SHAPE = (7, 7)
GRID = np.array([(i, j) for i in range(SHAPE[0]) for j in range(SHAPE[1])], dtype=np.float64)
CENTRE = np.array([3.0, 3.0])


def law(shift: float = 0.0, spread: float = 1.0) -> np.ndarray:
    """Discretised Gaussian over the grid, centred at CENTRE + (shift, 0)."""
    d2 = ((GRID - CENTRE - np.array([shift, 0.0])) ** 2).sum(axis=1)
    p = np.exp(-d2 / (2 * spread * spread))
    return p / p.sum()


def one_test(rng, p, q, m, n, spec, vectors=GRID, shape=SHAPE):
    """Draw X ~ p (m), Y ~ q (n) as counts, keep the states seen, run one test."""
    cx, cy = rng.multinomial(m, p), rng.multinomial(n, q)
    seen = (cx + cy) > 0
    return mmd_test(vectors[seen], cx[seen], cy[seen], spec, shape, rng)


def run_trials(seed, p, q, m, n, spec, trials, **kwargs):
    rng = np.random.default_rng(seed)
    return [one_test(rng, p, q, m, n, spec, **kwargs) for _ in range(trials)]


def null_pvalues(kernel, estimator, m, n, trials=SIZE_TRIALS, seed=0):
    # all permutations: the uniformity checks look at p-values above alpha too
    spec = MMDTestSpec(kernel, estimator, Method.PERMUTATION, ALPHA, PERMUTATIONS,
                       stop_early=False)
    p = law()
    return np.array([r.pvalue for r in run_trials(seed, p, p, m, n, spec, trials)])


def power(kernel, estimator, test, seed=1, trials=POWER_TRIALS, m=POWER_M, shift=SHIFT):
    spec = MMDTestSpec(kernel, estimator, test, ALPHA, PERMUTATIONS)
    results = run_trials(seed, law(), law(shift), m, m, spec, trials)
    return float(np.mean([r.rejected for r in results]))


def cdf_excess(pvalues, permutations=PERMUTATIONS):
    """F̂(u) − u on the grid u = k/(B+1): the deviation from the exact null law of the p-value.

    Under H0 without ties, p is uniform on {1, …, B+1}/(B+1); comparing the empirical CDF on that
    grid (instead of with U(0, 1)) removes the 1/(B+1) discreteness error. Its max |·| is a KS
    distance (the usual critical values are conservative for a discrete law); a valid test has
    F̂(u) ≤ u up to noise, i.e. a small positive part.
    """
    grid = np.arange(1, permutations + 2) / (permutations + 1)
    ecdf = np.searchsorted(np.sort(pvalues), grid + 1e-12, side="right") / len(pvalues)
    return ecdf - grid


def seed_of(*parts) -> int:
    """A stable seed per configuration: all of its bytes (str hashes are salted per process)."""
    return int.from_bytes("/".join(map(str, parts)).encode(), "little")


SIZE_CASES = [
    (kernel, estimator, m, n)
    for kernel in Kernel
    for estimator in Estimator
    for m, n in SIZE_DESIGNS
]


@pytest.mark.slow
@pytest.mark.parametrize(("kernel", "estimator", "m", "n"), SIZE_CASES,
                         ids=[f"{k}-{e}-{m}x{n}" for k, e, m, n in SIZE_CASES])
def test_permutation_size_and_uniform_pvalues(kernel, estimator, m, n):
    pvalues = null_pvalues(kernel, estimator, m, n, seed=seed_of(kernel, estimator, m, n))
    assert len(pvalues) >= 1000
    size = np.mean(pvalues <= ALPHA)
    assert 0.5 * ALPHA <= size <= 1.5 * ALPHA, size
    # Roughly uniform p-values: the rejection rate at other levels within ±50 % ...
    for level in (0.1, 0.2, 0.5):
        rate = np.mean(pvalues <= level)
        assert 0.5 * level <= rate <= 1.5 * level, (level, rate)
    # ... and the empirical CDF close to the exact null law: below the 0.1 % KS critical value
    # 1.95/√N (generous, as 12 configurations are checked). One-sided (never anti-conservative)
    # for every kernel; two-sided only for Gaussian and Laplace. The linear statistic depends on
    # the samples only through the sum of X's integer bin vectors, a lattice point, so permuted
    # statistics tie with the observed one (up to ≈ 2.6 % of them at m = n = 40, none for
    # Gaussian/Laplace): the p-values are then conservative, most visibly for large p.
    excess = cdf_excess(pvalues)
    critical = 1.95 / math.sqrt(len(pvalues))
    assert excess.max() < critical, excess.max()
    if kernel.has_bandwidth:
        assert np.abs(excess).max() < critical, np.abs(excess).max()


def tie_heavy_size(kernel, trials=SIZE_TRIALS):
    """3 states, m = n = 5: many permuted splits tie with the observed one."""
    vectors = np.array([(0, 0), (0, 1), (1, 0)], dtype=np.float64)
    p = np.array([0.5, 0.3, 0.2])
    spec = MMDTestSpec(kernel, Estimator.BIASED, Method.PERMUTATION, ALPHA, PERMUTATIONS)
    results = run_trials(seed_of("ties", kernel), p, p, 5, 5, spec, trials,
                         vectors=vectors, shape=(2, 2))
    return float(np.mean([r.rejected for r in results]))


@pytest.mark.slow
@pytest.mark.parametrize("kernel", list(Kernel))
def test_size_tie_heavy_design_is_conservative(kernel):
    size = tie_heavy_size(kernel)
    assert size <= 1.5 * ALPHA, size  # measured 0.010–0.021: conservative, not anti-conservative


@pytest.mark.slow
@pytest.mark.parametrize("kernel", list(Kernel))
def test_permutation_power_beats_bound(kernel):
    """Shift of 0.4 bin, m = n = 150: the bound test never rejects, the permutation test does."""
    perm = power(kernel, Estimator.BIASED, Method.PERMUTATION, seed=seed_of("power", kernel))
    bound = power(kernel, Estimator.BIASED, Method.BOUND, seed=seed_of("power", kernel))
    bound_u = power(kernel, Estimator.UNBIASED, Method.BOUND, seed=seed_of("power", kernel))
    assert perm >= 0.6, perm  # measured 0.73 (Laplace) – 0.86 (linear)
    assert bound <= 0.05, bound  # measured 0
    assert bound_u <= 0.05, bound_u  # measured 0
    assert perm >= bound + 0.5


def test_same_seed_same_pvalue():
    p = law()
    rng = np.random.default_rng(7)
    cx, cy = rng.multinomial(40, p), rng.multinomial(30, law(0.5))
    seen = (cx + cy) > 0
    args = (GRID[seen], cx[seen], cy[seen])
    for kernel in Kernel:
        for estimator in Estimator:
            spec = MMDTestSpec(kernel, estimator, Method.PERMUTATION, ALPHA, PERMUTATIONS)
            first = mmd_test(*args, spec, SHAPE, np.random.default_rng(123))
            again = mmd_test(*args, spec, SHAPE, np.random.default_rng(123))
            assert first == again
            assert first.pvalue is not None
            pvalues = {mmd_test(*args, spec, SHAPE, np.random.default_rng(s)).pvalue
                       for s in range(5)}
            assert len(pvalues) > 1  # the permutations really come from the rng


def main() -> None:
    """Print the measurements recorded in docs/calibration.md."""
    print(f"size at alpha = {ALPHA}, B = {PERMUTATIONS}, {SIZE_TRIALS} trials each")
    print("| kernel | estimator | m | n | size | rate at 0.1 | rate at 0.2 | KS | max(F̂−u) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for kernel, estimator, m, n in SIZE_CASES:
        pv = null_pvalues(kernel, estimator, m, n, seed=seed_of(kernel, estimator, m, n))
        excess = cdf_excess(pv)
        print(f"| {kernel} | {estimator} | {m} | {n} | {np.mean(pv <= ALPHA):.3f} | "
              f"{np.mean(pv <= 0.1):.3f} | {np.mean(pv <= 0.2):.3f} | "
              f"{np.abs(excess).max():.3f} | {max(excess.max(), 0):.3f} |")
    print("\ntie-heavy design (3 states, m = n = 5, biased): size "
          + ", ".join(f"{k} {tie_heavy_size(k):.3f}" for k in Kernel))
    print(f"\npower at shift {SHIFT} bin, m = n = {POWER_M}, {POWER_TRIALS} trials each")
    print("| kernel | permutation (biased) | bound (biased) | bound (unbiased) |")
    print("|---|---|---|---|")
    for kernel in Kernel:
        seed = seed_of("power", kernel)
        row = [power(kernel, e, t, seed=seed) for e, t in (
            (Estimator.BIASED, Method.PERMUTATION), (Estimator.BIASED, Method.BOUND),
            (Estimator.UNBIASED, Method.BOUND))]
        print(f"| {kernel} | " + " | ".join(f"{x:.3f}" for x in row) + " |")


if __name__ == "__main__":
    start = time.perf_counter()
    main()
    print(f"\n({time.perf_counter() - start:.1f} s)")
