"""The two-pass mergeable quantile gives feature_edges' edges bit for bit (numpy is the oracle)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from simcred.compare.discretize import feature_edges
from simcred.compare.quantiles import Sketch, exact_median, partitioned_edges

# -0.0 is left out: its sign in an edge may differ from numpy's pick (module Notes)
finite = st.floats(min_value=-1e12, max_value=1e12, allow_nan=False, allow_infinity=False,
                   allow_subnormal=True).map(lambda v: v + 0.0)
few = st.sampled_from([0.0, 1.0, 2.5, -3.0, 7.0, 1e-300, 1e300])


def split(values: np.ndarray, cuts: list[int]) -> list[np.ndarray]:
    points = sorted(min(c, len(values)) for c in cuts)
    return np.split(values, points)


@st.composite
def partitioned(draw):
    """Values (continuous, tied, or a few distinct) cut into partitions, some of them empty."""
    kind = draw(st.sampled_from(["continuous", "ties", "few"]))
    n = draw(st.integers(1, 400))
    if kind == "few":
        values = draw(st.lists(few, min_size=n, max_size=n))
    elif kind == "ties":
        pool = draw(st.lists(finite, min_size=1, max_size=12))
        values = draw(st.lists(st.sampled_from(pool), min_size=n, max_size=n))
    else:
        values = draw(st.lists(finite, min_size=n, max_size=n))
    cuts = draw(st.lists(st.integers(0, n), max_size=12))
    return split(np.array(values, dtype=np.float64), cuts)


@settings(max_examples=300, deadline=None)
@given(parts=partitioned(), bins=st.integers(2, 12), size=st.sampled_from([2, 3, 7, 64]))
def test_edges_bit_identical_to_feature_edges(parts, bins, size):
    expected = feature_edges(np.concatenate(parts), bins)
    got = partitioned_edges(parts, bins, size=size)
    assert got.dtype == expected.dtype
    assert got.tobytes() == expected.tobytes()


@settings(max_examples=100, deadline=None)
@given(parts=partitioned(), size=st.sampled_from([2, 5, 64]))
def test_median_is_numpys(parts, size):
    sketch = Sketch.empty(2)
    for p in parts:
        sketch = sketch.merge(Sketch.of(p, cap=2, size=size))
    assert exact_median(sketch, parts) == np.median(np.concatenate(parts))


def test_many_partitions_large_spread():
    rng = np.random.default_rng(5)
    values = np.round(rng.standard_t(2, 200_000), 3)  # heavy tails and many ties
    parts = split(values, sorted(rng.integers(0, len(values), 150).tolist()))
    for bins in (2, 10, 97):
        expected = feature_edges(values, bins)
        assert partitioned_edges(parts, bins, size=256).tobytes() == expected.tobytes()


def test_merge_order_does_not_matter():
    rng = np.random.default_rng(1)
    parts = [rng.normal(size=n) for n in (10, 0, 500, 33)]
    one = Sketch.empty(10)
    for p in parts:
        one = one.merge(Sketch.of(p, cap=10, size=8))
    other = Sketch.of(parts[2], cap=10, size=8).merge(
        Sketch.of(parts[0], cap=10, size=8).merge(Sketch.of(parts[3], cap=10, size=8)))
    ranks = [0, 100, 542]
    a, b = one.brackets(ranks), other.brackets(ranks)
    assert np.array_equal(a.lower, b.lower) and np.array_equal(a.upper, b.upper)


def test_ranks_outside_the_data_are_refused():
    with pytest.raises(ValueError, match="ranks must lie in"):
        Sketch.of(np.arange(3.0), cap=2).brackets([3])
