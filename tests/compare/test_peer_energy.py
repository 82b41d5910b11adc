"""The peer energy test (tests/peer_energy.py): literal oracle, size and power."""

from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest

from peer_energy import energy_statistic, energy_test, run_summaries
from response_designs import FEATURES, HUMAN, defect, draw_leaders, driving_set
from simcred.traces import TraceSet


def tiny(rng: np.random.Generator, runs: int, shift: float = 0.0) -> TraceSet:
    lengths = rng.integers(4, 9, size=runs)
    return TraceSet.from_runs([{"t": np.arange(n), "x": rng.normal(shift, 1, n),
                                "y": rng.exponential(1, n)} for n in lengths])


def literal_summaries(ts: TraceSet, features) -> np.ndarray:
    rows = []
    for i in range(ts.n_runs):
        run = ts.run(i)
        row = []
        for f in features:
            x = np.asarray(run[f])
            row += [sum(x) / len(x), np.sqrt(sum((x - sum(x) / len(x)) ** 2) / len(x)),
                    np.quantile(x, 0.1), np.quantile(x, 0.5), np.quantile(x, 0.9),
                    sum(abs(x[k + 1] - x[k]) for k in range(len(x) - 1)) / (len(x) - 1)]
        rows.append(row)
    return np.array(rows)


def literal_energy(x: np.ndarray, y: np.ndarray) -> float:
    m, n = len(x), len(y)
    dist = lambda u, v: float(np.sqrt(np.sum((u - v) ** 2)))  # noqa: E731
    xy = sum(dist(u, v) for u in x for v in y) / (m * n)
    xx = sum(dist(u, v) for u in x for v in x) / m ** 2
    yy = sum(dist(u, v) for u in y for v in y) / n ** 2
    return m * n / (m + n) * (2 * xy - xx - yy)


def test_energy_agrees_with_a_literal_computation_on_every_labeling():
    rng = np.random.default_rng(7)
    a, b = tiny(rng, 3), tiny(rng, 4, shift=0.7)
    sa, sb = run_summaries(a, ["x", "y"]), run_summaries(b, ["x", "y"])
    np.testing.assert_allclose(sa, literal_summaries(a, ["x", "y"]), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(sb, literal_summaries(b, ["x", "y"]), rtol=1e-12, atol=1e-12)
    pooled = np.vstack([sa, sb])
    z = (pooled - pooled.mean(axis=0)) / pooled.std(axis=0)
    d = np.sqrt(((z[:, None] - z[None]) ** 2).sum(axis=2))
    labelings = []
    for chosen in itertools.combinations(range(7), 3):
        lab = np.zeros(7, bool)
        lab[list(chosen)] = True
        labelings.append(lab)
        assert energy_statistic(d, lab) == pytest.approx(literal_energy(z[lab], z[~lab]),
                                                          rel=1e-10)
    # the permutation p-value converges to the exact one over all 35 labelings
    stats = energy_statistic(d, np.array(labelings))
    observed = literal_energy(z[:3], z[3:])
    exact = np.mean(stats >= observed - 1e-12)
    assert energy_test(a, b, ["x", "y"], permutations=19999, seed=1) == pytest.approx(exact,
                                                                                     abs=0.01)


def test_pvalue_is_a_permutation_pvalue():
    rng = np.random.default_rng(3)
    a, b = tiny(rng, 5), tiny(rng, 5)
    p = energy_test(a, b, ["x", "y"], permutations=99, seed=0)
    assert 0.01 <= p <= 1 and round(p * 100) == pytest.approx(p * 100)
    assert p == energy_test(a, b, ["x", "y"], permutations=99, seed=0)  # seeded


def test_size_on_two_draws_of_one_design():
    """200 comparisons of two independent draws of the human-like driver: rejection ~ α."""
    alpha, reps = 0.05, 200
    rejected = 0
    for seed in range(reps):
        d = defect(np.random.default_rng(seed), "none", paired=False)
        rejected += energy_test(d.a, d.b, d.features, permutations=199, seed=seed) <= alpha
    assert 0.02 <= rejected / reps <= 0.09, rejected / reps  # measured 0.045


def test_detects_a_gross_shift():
    """Time headway 1.5 s → 2.5 s for every run of B: found every time."""
    for seed in range(10):
        rng = np.random.default_rng(seed)
        a = driving_set(rng, draw_leaders(rng, 40), replace(HUMAN, T=1.5), [f"a{i}" for i in
                                                                          range(40)], "A")
        b = driving_set(rng, draw_leaders(rng, 40), replace(HUMAN, T=2.5), [f"b{i}" for i in
                                                                          range(40)], "B")
        assert energy_test(a, b, FEATURES, permutations=199, seed=seed) <= 0.01
