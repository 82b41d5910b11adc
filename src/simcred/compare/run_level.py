"""The run-level comparison and what makes its distance readable: baseline, interval, relevance.

* :func:`counts_comparison` — the run-permutation test of every state and of the chain
  (:mod:`simcred.compare.runs`), turned into a :class:`Comparison` with a chain verdict and
  multiplicity-controlled per-state verdicts; distance = rejected states / |S| ([1] eq. (6)).
* Same-model **baseline**: set A's runs split into random halves, compared with the same options
  (same state space): the distance "no difference" gives.
* **Re-test spread** (bootstrap): runs resampled with replacement within each set, the whole
  test redone; percentile range of the distance. Biased upward (duplicated runs make the sets
  look more different), so it is a spread of re-tests, not a confidence interval.
* **Feature relevance**: the chain test on each feature alone and with each feature left out, on
  the same bin edges.

References
----------
[1] Neurohr et al., Determining the Validity of Simulation Models for the Verification of ADSs,
    IEEE Access, 2023.
[2] Efron & Tibshirani, An Introduction to the Bootstrap, Chapman & Hall, 1993 (percentile
    interval, ch. 13).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from simcred.compare.discretize import StateSpace
from simcred.compare.encoding import EncodedRuns
from simcred.compare.mmd import Estimator, MMDTestResult
from simcred.compare.result import (
    Baseline,
    ChainVerdict,
    Comparison,
    ComparisonOptions,
    DistanceInterval,
    FeatureRelevance,
    InputInfo,
    StateTest,
    UntestableState,
)
from simcred.compare.run_counts import START, RunCounts
from simcred.compare.runs import AssignmentDraw, RunLevelOutcome, RunTestSpec, run_level_test
from simcred.seeds import stream

#: Seed-stream keys of the run-level test and its companions (spawn keys of the seed).
RUNS_KEY, BASELINE_KEY, BOOTSTRAP_KEY, RELEVANCE_KEY = 2**40, 2**40 + 1, 2**40 + 2, 2**40 + 3
#: Permutations per test inside baseline, bootstrap and relevance (at most the main test's).
COMPANION_PERMUTATIONS = 199
INTERVAL_LEVEL = 0.95


def run_spec(options: ComparisonOptions, permutations: int | None = None) -> RunTestSpec:
    return options.run_spec(permutations)


def pooled_counts(a: EncodedRuns, b: EncodedRuns, space: StateSpace) -> RunCounts:
    return RunCounts.from_parts([(a.codes, a.offsets), (b.codes, b.offsets)], space.n_states)


def counts_comparison(counts: RunCounts, n_a: int, space: StateSpace,
                      options: ComparisonOptions, inputs: tuple[InputInfo, InputInfo],
                      draw: AssignmentDraw | None = None) -> Comparison:
    """The run-level comparison of pooled per-run counts whose first ``n_a`` runs are set A
    (counts built in memory or partition by partition, :mod:`simcred.compare.outofcore`);
    ``draw``: its permutations drawn before (:func:`assignment_draw`), where they fit."""
    in_a = np.arange(counts.n_runs) < n_a
    outcome = run_level_test(counts, in_a, space.decode, run_spec(options), space.shape,
                             stream(options.seed, RUNS_KEY), draw=draw)
    result = _comparison(outcome, space, options, inputs)
    companions = min(options.permutations, COMPANION_PERMUTATIONS)
    if options.baseline:
        result = dataclasses.replace(result, baseline=same_model_baseline(
            counts, n_a, space, options, companions))
    if options.bootstrap:
        result = dataclasses.replace(result, interval=distance_interval(
            counts, n_a, space, options, companions))
    return result


def assignment_draw(n_a: int, n_runs: int, options: ComparisonOptions) -> AssignmentDraw:
    """The permutations of the run-level test of ``n_runs`` runs (the first ``n_a`` from A)
    with ``options``, for every comparison of that size (:func:`counts_comparison`)."""
    return AssignmentDraw.of(n_a, n_runs, options.permutations, stream(options.seed, RUNS_KEY))


def _comparison(outcome: RunLevelOutcome, space: StateSpace, options: ComparisonOptions,
                inputs: tuple[InputInfo, InputInfo]) -> Comparison:
    rejected = outcome.rejected(options.alpha)
    minimum = Estimator(options.estimator).min_samples
    start, tested, untestable = None, [], []
    for i, state in enumerate(outcome.blocks):
        test = MMDTestResult(
            int(outcome.m[i]), int(outcome.n[i]),
            float(outcome.statistic[i]) if np.isfinite(outcome.statistic[i]) else float("nan"),
            bool(rejected[i]), pvalue=float(outcome.pvalue[i]),
            bandwidth=None if np.isnan(outcome.bandwidth[i]) else float(outcome.bandwidth[i]),
            n_resamples=outcome.permutations, adjusted_pvalue=float(outcome.adjusted[i]))
        if state == START:
            start = test
            continue
        cell = tuple(int(v) for v in space.decode([state])[0])
        if min(test.m, test.n) < minimum:
            untestable.append(UntestableState(cell, test.m, test.n))
        else:
            tested.append(StateTest(cell, test))
    chain = ChainVerdict("runs", options.chain, outcome.chain_statistic, outcome.chain_pvalue,
                         outcome.chain_pvalue <= options.alpha, outcome.permutations,
                         int(outcome.in_family.sum()))
    return Comparison(options, inputs, space, start, False, tuple(tested), tuple(untestable),
                      chain=chain)


def outcome_distance(outcome: RunLevelOutcome, alpha: float, n_states: int,
                     estimator: Estimator) -> float:
    """Rejected two-sided transition states / |S| ([1] eq. (6))."""
    testable = (outcome.blocks != START) & (np.minimum(outcome.m, outcome.n)
                                            >= estimator.min_samples)
    return float((outcome.rejected(alpha) & testable).sum() / n_states)


def same_model_baseline(counts: RunCounts, n_a: int, space: StateSpace,
                        options: ComparisonOptions, permutations: int) -> Baseline:
    """Distances of ``options.baseline`` random half-splits of set A (runs ``0 .. n_a-1``)."""
    spec = run_spec(options, permutations)
    distances, pvalues = [], []
    for rep in range(options.baseline):
        rng = stream(options.seed, BASELINE_KEY, rep)
        order = rng.permutation(n_a)
        outcome = run_level_test(counts.subset(order), np.arange(n_a) < n_a // 2,
                                 space.decode, spec, space.shape, rng)
        distances.append(outcome_distance(outcome, options.alpha, space.n_states,
                                          spec.estimator))
        pvalues.append(outcome.chain_pvalue)
    return Baseline("a", tuple(distances), tuple(pvalues))


def distance_interval(counts: RunCounts, n_a: int, space: StateSpace,
                      options: ComparisonOptions, permutations: int) -> DistanceInterval:
    """Percentile range ([2]) of the distance over ``options.bootstrap`` run resamples: the
    re-test spread (biased upward; not a confidence interval)."""
    spec = run_spec(options, permutations)
    n_b = counts.n_runs - n_a
    replicates = []
    for rep in range(options.bootstrap):
        rng = stream(options.seed, BOOTSTRAP_KEY, rep)
        rows = np.concatenate([rng.integers(0, n_a, n_a), n_a + rng.integers(0, n_b, n_b)])
        outcome = run_level_test(counts.subset(rows), np.arange(len(rows)) < n_a,
                                 space.decode, spec, space.shape, rng)
        replicates.append(outcome_distance(outcome, options.alpha, space.n_states,
                                           spec.estimator))
    tail = (1 - INTERVAL_LEVEL) / 2
    low, high = np.quantile(replicates, [tail, 1 - tail])
    return DistanceInterval(INTERVAL_LEVEL, float(low), float(high), tuple(replicates))


def feature_relevance(result: Comparison, a, b) -> Comparison:
    """Chain test per feature alone and per feature left out, on the result's bin edges.

    ``a``, ``b`` are the :class:`~simcred.compare.process.Prepared` sets of ``result``.
    """
    options = result.options
    features = options.features
    rows = []
    for j, name in enumerate(features):
        alone = _chain_on(a, b, [j], result)
        without = _chain_on(a, b, [k for k in range(len(features)) if k != j], result) \
            if len(features) > 1 else None
        rows.append(FeatureRelevance(name, alone.chain_pvalue, alone.chain_statistic,
                                     None if without is None else without.chain_pvalue,
                                     None if without is None else without.chain_statistic))
    return dataclasses.replace(result, relevance=tuple(rows))


def _chain_on(a, b, columns: list[int], result: Comparison) -> RunLevelOutcome:
    from simcred.compare.encoding import encode

    options = result.options
    base = len(options.features)
    space = result.space
    keep = [lag * base + j for lag in range(options.history) for j in columns]
    if options.time_bins is not None:
        keep.append(len(space.edges) - 1)
    sub = StateSpace(tuple(space.features[i] for i in keep), tuple(space.edges[i] for i in keep),
                     tuple(space.bounds[i] for i in keep))
    encoded = [encode(sub, p.values[:, columns], p.time, p.offsets, options.history,
                      options.time_bins is not None, p.info.source) for p in (a, b)]
    counts = pooled_counts(encoded[0], encoded[1], sub)
    n_a = len(encoded[0].offsets) - 1
    spec = run_spec(options, min(options.permutations, COMPANION_PERMUTATIONS))
    return run_level_test(counts, np.arange(counts.n_runs) < n_a, sub.decode, spec, sub.shape,
                          stream(options.seed, RELEVANCE_KEY, *columns))
