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
        columns = [values[lo:hi, j] for j in range(2)]  # one run's one feature at a time
        expected = [f(x) for f in (np.mean, np.std, *[lambda x, q=q: np.quantile(x, q)
                                                       for q in QUANTILES],
                                   lambda x: np.abs(np.diff(x)).mean() if len(x) > 1 else 0.0)
                    for x in columns]
        np.testing.assert_array_equal(got[r], expected)
