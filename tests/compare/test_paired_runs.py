"""The pairs' run summaries against a literal per-run computation."""

from __future__ import annotations

import numpy as np
import pytest

from simcred.compare.paired_runs import QUANTILES, run_summaries


@pytest.mark.parametrize("seed", range(3))
def test_run_summaries_equal_per_run_literal(seed):
    """Runs of several lengths (one of a single row), ties and a constant run: mean, sd, the
    quantiles and the mean absolute step of each run's rows, per feature, in that order."""
    rng = np.random.default_rng(seed)
    lengths = np.array([1, 5, 5, 12, 3, 12, 7])
    values = np.round(rng.normal(size=(lengths.sum(), 2)), 1)  # ties
    offsets = np.r_[0, np.cumsum(lengths)]
    values[offsets[2]:offsets[3]] = 0.5  # a constant run
    got = run_summaries(values, offsets)
    for r, (lo, hi) in enumerate(zip(offsets[:-1], offsets[1:], strict=True)):
        block = values[lo:hi]
        step = np.abs(np.diff(block, axis=0)).mean(axis=0) if hi - lo > 1 else np.zeros(2)
        expected = np.concatenate([block.mean(axis=0), block.std(axis=0),
                                   *[np.quantile(block, q, axis=0) for q in QUANTILES], step])
        np.testing.assert_array_equal(got[r], expected)
