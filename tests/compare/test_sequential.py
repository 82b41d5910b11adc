"""Early stopping of the permutation test never changes a verdict (Besag & Clifford 1991)."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from simcred.compare.kernels import Kernel
from simcred.compare.mmd import Estimator, MMDTestSpec, mmd_test
from simcred.compare.mmd import Test as Method

VECTORS = np.array([[i, j] for i in range(3) for j in range(3)], dtype=float)


@settings(max_examples=80, deadline=None)
@given(
    counts=st.lists(st.tuples(st.integers(0, 30), st.integers(0, 30)), min_size=9, max_size=9),
    kernel=st.sampled_from(list(Kernel)),
    alpha=st.sampled_from([0.01, 0.05, 0.2]),
    seed=st.integers(0, 2**32 - 1),
)
def test_stop_early_gives_the_full_tests_verdict(counts, kernel, alpha, seed):
    cx = np.array([c[0] for c in counts])
    cy = np.array([c[1] for c in counts])
    seen = (cx + cy) > 0
    if cx.sum() == 0 or cy.sum() == 0:
        return
    results = {}
    for stop_early in (False, True):
        spec = MMDTestSpec(kernel, Estimator.BIASED, Method.PERMUTATION, alpha, 199, stop_early)
        results[stop_early] = mmd_test(VECTORS[seen], cx[seen], cy[seen], spec, (3, 3),
                                       np.random.default_rng(seed))
    full, early = results[False], results[True]
    assert full.n_resamples == 199
    assert early.rejected == full.rejected
    assert early.statistic == full.statistic
    if full.rejected:
        assert early.pvalue == full.pvalue and early.n_resamples == 199
    else:
        assert early.pvalue > alpha and 1 <= early.n_resamples <= 199


def test_stop_early_saves_permutations_under_h0():
    rng = np.random.default_rng(0)
    spec = MMDTestSpec(Kernel.GAUSSIAN, Estimator.BIASED, Method.PERMUTATION, 0.01, 999)
    used = []
    for _ in range(50):
        cx, cy = rng.multinomial(200, np.full(9, 1 / 9)), rng.multinomial(150, np.full(9, 1 / 9))
        used.append(mmd_test(VECTORS, cx, cy, spec, (3, 3), rng).n_resamples)
    assert np.median(used) < 100
