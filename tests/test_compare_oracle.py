"""The count-based comparison agrees with the literal sample-based oracle (tests/oracle.py)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from helpers import ar_set, random_walk_set, runs_of
from oracle import literal_compare, literal_permutation_statistics
from simcred.compare import compare
from simcred.compare.kernels import Kernel, distances, median_bandwidths
from simcred.compare.mmd import Estimator, batch_statistics

FEATURES = ["x", "y"]


def assert_same(result, oracle):
    assert [e.tolist() for e in result.space.edges] == [e.tolist() for e in oracle["edges"]]
    assert result.n_states == oracle["n_states"]
    for key in ("m", "n", "rejected"):
        assert getattr(result.start, key) == oracle["start"][key]
    np.testing.assert_allclose(result.start.statistic, oracle["start"]["statistic"],
                               rtol=1e-9, atol=1e-7)
    assert result.stopped == oracle["stopped"]
    assert sorted(u.state for u in result.untestable) == oracle["untestable"]
    tested = {s.state: s.result for s in result.states}
    assert set(tested) == set(oracle["states"])
    for state, expected in oracle["states"].items():
        got = tested[state]
        assert (got.m, got.n, got.rejected) == (expected["m"], expected["n"], expected["rejected"])
        # atol only matters where MMD is 0 in exact arithmetic (rounding noise ~1e-8 after sqrt)
        np.testing.assert_allclose(got.statistic, expected["statistic"], rtol=1e-9, atol=1e-7)
        np.testing.assert_allclose(got.threshold, expected["threshold"], rtol=1e-12)
    assert result.distance == oracle["distance"]


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("kernel", ["gaussian", "laplace", "linear"])
@pytest.mark.parametrize("estimator", ["biased", "unbiased"])
def test_matches_literal_oracle(seed, kernel, estimator):
    rng = np.random.default_rng(seed)
    a = random_walk_set(rng, runs=int(rng.integers(30, 60)), drift=0.0)
    b = random_walk_set(rng, runs=int(rng.integers(30, 60)), drift=0.3 * seed)
    bins = int(rng.integers(3, 7))
    result = compare(a, b, features=FEATURES, bins=bins, kernel=kernel, estimator=estimator,
                     test="bound",
                     continue_on_start_difference=bool(seed % 2))
    oracle = literal_compare(runs_of(a, FEATURES), runs_of(b, FEATURES), bins, kernel,
                             estimator=estimator, continue_on_start_difference=bool(seed % 2))
    assert_same(result, oracle)


@pytest.mark.parametrize("kernel", ["gaussian", "laplace", "linear"])
def test_matches_oracle_with_rejections(kernel):
    """Large, clearly different sets so that the paper's bound rejects some states."""
    rng = np.random.default_rng(7)
    a = ar_set(rng, runs=150, phi=0.8)
    b = ar_set(rng, runs=120, phi=-0.8)
    result = compare(a, b, features=FEATURES, bins=4, kernel=kernel, test="bound")
    oracle = literal_compare(runs_of(a, FEATURES), runs_of(b, FEATURES), 4, kernel)
    assert_same(result, oracle)
    assert len(result.rejected_states) > 0


def test_stops_when_start_distributions_differ():
    rng = np.random.default_rng(3)
    a = random_walk_set(rng, runs=200, drift=0.0)
    far = [dict(a.run(i)) for i in range(a.n_runs)]
    for run in far:
        run["x"] = run["x"] + 100.0
    b = type(a).from_runs(far)
    result = compare(a, b, features=FEATURES, bins=4, test="bound")
    oracle = literal_compare(runs_of(a, FEATURES), runs_of(b, FEATURES), 4, "gaussian")
    assert result.start.rejected and result.stopped and result.distance is None
    assert_same(result, oracle)


@settings(max_examples=60, deadline=None)
@given(
    counts=st.lists(st.tuples(st.integers(0, 6), st.integers(0, 6)), min_size=1, max_size=7),
    kernel=st.sampled_from(list(Kernel)),
    estimator=st.sampled_from(list(Estimator)),
    seed=st.integers(0, 2**32 - 1),
)
def test_permuted_statistics_match_literal(counts, kernel, estimator, seed):
    """Each permuted split's statistic (bandwidth recomputed) equals the literal one."""
    cx = np.array([c[0] for c in counts])
    cy = np.array([c[1] for c in counts])
    need = estimator.min_samples
    if cx.sum() < need or cy.sum() < need:
        return
    rng = np.random.default_rng(seed)
    vectors = rng.integers(0, 5, size=(len(counts), 2)).astype(float)
    vectors = np.unique(vectors, axis=0)[: len(counts)]
    cx, cy = cx[: len(vectors)], cy[: len(vectors)]
    if cx.sum() < need or cy.sum() < need:
        return
    drawn = rng.multivariate_hypergeometric(cx + cy, int(cx.sum()), size=5)
    rows_x = np.vstack([cx, drawn])
    rows_y = np.vstack([cy, cx + cy - drawn])
    got, _ = batch_statistics(vectors, rows_x, rows_y, kernel, estimator, (5, 5))

    x = np.repeat(vectors, cx, axis=0)
    y = np.repeat(vectors, cy, axis=0)
    owner = np.r_[np.repeat(np.arange(len(vectors)), cx), np.repeat(np.arange(len(vectors)), cy)]
    order = np.argsort(owner, kind="stable")
    rank = np.empty(len(owner), dtype=int)
    rank[order] = np.arange(len(owner)) - np.searchsorted(owner[order], owner[order])
    # the first row[u] pooled samples of state u go to the first sample
    assignments = [rank < row[owner] for row in rows_x]
    expected = literal_permutation_statistics(x, y, kernel.value, (5, 5), estimator.value,
                                              assignments)
    np.testing.assert_allclose(got, expected, rtol=1e-9, atol=1e-7)


@settings(max_examples=100, deadline=None)
@given(
    counts=st.lists(st.tuples(st.integers(0, 9), st.integers(0, 9)), min_size=1, max_size=8),
    points=st.lists(st.tuples(st.integers(0, 4), st.integers(0, 4)), min_size=8, max_size=8,
                    unique=True),
    kernel=st.sampled_from([Kernel.GAUSSIAN, Kernel.LAPLACE]),
)
def test_weighted_median_equals_numpy_median(counts, points, kernel):
    cx = np.array([c[0] for c in counts])
    cy = np.array([c[1] for c in counts])
    if cx.sum() == 0 or cy.sum() == 0:
        return
    vectors = np.array(points[: len(counts)], dtype=float)
    dist = distances(vectors, kernel)
    sigma = median_bandwidths(dist, cx[None], cy[None])[0]
    cross = dist[np.repeat(np.arange(len(cx)), cx)][:, np.repeat(np.arange(len(cy)), cy)].ravel()
    expected = np.median(cross)
    if expected == 0:
        expected = np.median(cross[cross > 0]) if (cross > 0).any() else np.nan
    np.testing.assert_equal(sigma, expected)
