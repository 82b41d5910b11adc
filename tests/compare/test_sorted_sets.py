"""A pair compared from its sets' parts (sorted columns, sketches, tallies, per-set counts) gives
the comparison of the prepared sets, byte for byte; the per-set counts join to the pooled ones."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from helpers import ar_set, tied_set
from simcred.compare import compare, matrix
from simcred.compare.discretize import StateSpace
from simcred.compare.encoding import encode
from simcred.compare.facts import SetFacts
from simcred.compare.method import Method
from simcred.compare.process import Prepared, compare_prepared, comparison_options
from simcred.compare.run_counts import joined_counts, keyed_counts
from simcred.compare.sorted_sets import SortedSet, compare_sorted, supports
from simcred.engine import Engine
from simcred.traces import TraceSet


def both_ways(a: TraceSet, b: TraceSet, **options) -> tuple[str, str]:
    settings_ = comparison_options([SetFacts.of(a), SetFacts.of(b)], Method.of(None, **options))
    pa, pb = (Prepared.for_options(x, settings_) for x in (a, b))
    direct = compare_prepared(pa, pb, settings_)
    parts = compare_sorted(SortedSet.of(pa, settings_.bins), SortedSet.of(pb, settings_.bins),
                           settings_)
    return direct.to_json(), parts.to_json()


OPTIONS = [
    dict(features=["x", "y"], bins=5, permutations=99, seed=1, baseline=2, bootstrap=2),
    dict(features=["x", "y"], bins=[3, 7], permutations=49, seed=2, chain="max",
         one_sided="neutral", multiplicity="fdr", estimator="unbiased", kernel="laplace"),
]


@pytest.mark.parametrize("options", OPTIONS)
@pytest.mark.parametrize("data", ["continuous", "tied"])
def test_same_json_as_the_prepared_sets(data, options):
    """Continuous data, and data whose edges drop a bin (an atom at the minimum: the candidate
    grid is relabelled) or are midpoints (three values)."""
    rng = np.random.default_rng(11)
    if data == "continuous":
        a, b = ar_set(rng, 70, 0.5, source="A"), ar_set(rng, 90, -0.2, length=17, source="B")
    else:
        a, b = tied_set(rng, 80, 0.0, "A"), tied_set(rng, 60, 0.3, "B")
    direct, parts = both_ways(a, b, **options)
    assert parts == direct


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), runs=st.tuples(st.integers(2, 30), st.integers(2, 30)),
       bins=st.tuples(st.integers(2, 6), st.integers(2, 6)), levels=st.integers(2, 12))
def test_same_json_on_ties_and_unequal_lengths(seed, runs, bins, levels):
    """Few runs of unequal lengths, values on a coarse grid (many ties, sometimes fewer values
    than bins), different sizes per side."""
    rng = np.random.default_rng(seed)

    def side(n, shift, source):
        out = []
        for _ in range(n):
            k = int(rng.integers(2, 15))
            out.append({"t": np.arange(k) * 0.1,
                        "x": np.floor(rng.normal(shift, 1, k) * levels / 4) / levels,
                        "y": rng.integers(0, levels, k) * 0.5})
        return TraceSet.from_runs(out, source=source)

    a, b = side(runs[0], 0.0, "A"), side(runs[1], 0.4, "B")
    direct, parts = both_ways(a, b, features=["x", "y"], bins=list(bins), permutations=19,
                              seed=seed % 1000)
    assert parts == direct


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n_states=st.sampled_from([3, 7, 2100]),
       sizes=st.lists(st.integers(1, 12), min_size=1, max_size=3))
def test_joined_counts_equal_counting_the_joined_codes(seed, n_states, sizes):
    """Literal oracle: the per-part matrices side by side are the matrix of all runs' codes
    (2100 states: the sorting path of ``keyed_counts``)."""
    rng = np.random.default_rng(seed)
    parts = []
    for runs in sizes:
        lengths = rng.integers(1, 9, runs)
        codes = rng.integers(0, min(n_states, 5), int(lengths.sum())) * (n_states // 5 or 1)
        parts.append((codes.astype(np.int64), np.r_[0, np.cumsum(lengths)].astype(np.int64)))
    expected, columns = keyed_counts(parts, n_states)
    got, got_columns = joined_counts([keyed_counts([p], n_states) for p in parts])
    assert np.array_equal(got_columns, columns)
    assert (got != expected).nnz == 0 and got.shape == expected.shape
    assert np.array_equal(got.indptr, expected.indptr)
    assert np.array_equal(got.indices, expected.indices)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), rows=st.integers(1, 60), levels=st.integers(1, 6),
       n_edges=st.lists(st.integers(0, 8), min_size=1, max_size=3))
def test_codes_by_rank_equal_encoding_the_values(seed, rows, levels, n_edges):
    """Literal oracle: the codes read through the rank tables are ``encode``'s (a value's bin
    counts the edges at or below it), on heavy ties, signed zeros and edges equal to values."""
    rng = np.random.default_rng(seed)
    values = rng.integers(-levels, levels + 1, (rows, len(n_edges))) * 0.5
    values[rng.random(values.shape) < 0.2] = -0.0
    edges = tuple(np.unique(np.r_[rng.choice(values[:, j], n), rng.integers(-4, 5, n) * 0.25])
                  for j, n in enumerate(n_edges))
    offsets = np.array([0, rows])
    prepared = Prepared(values, np.empty(0), offsets, None)
    space = StateSpace(tuple(f"f{j}" for j in range(len(edges))), edges,
                       tuple((-9.0, 9.0) for _ in edges))
    expected = encode(space, values, np.empty(0), offsets).codes
    got = SortedSet.of(prepared, [2] * len(edges)).codes(edges)
    assert np.array_equal(got, expected)


def test_matrix_of_the_runs_test_equals_pairwise_compare():
    rng = np.random.default_rng(4)
    sets = [ar_set(rng, 50, phi, source=f"s{i}") for i, phi in enumerate((0.6, 0.6, -0.3))]
    options = dict(features=["x", "y"], bins=4, permutations=49, seed=6)
    result = matrix(sets, **options)
    for (i, j), comparison in zip(result.pairs, result.comparisons, strict=True):
        assert comparison.to_json() == compare(sets[i], sets[j], **options).to_json()


class HeldBy(Engine):
    """In-process, but "distributed" with set k held by worker ``owners[k]``: the distributed
    split of the pairs runs here; the sets, the tasks kept and the pairs' placements recorded."""

    distributed = True

    def __init__(self, owners: list[str | None]) -> None:
        self.owners, self.kept, self.sets, self.near = owners, [], [], None

    def holders(self, handles):
        return list(self.owners)

    def keep(self, task, items, near=None):
        results = super().keep(task, items, near)
        self.kept.extend([task.__name__] * len(items))
        if task.__name__ == "_prepare_sorted":
            self.sets = results
        return results

    def map(self, task, items, **options):
        self.near = options.get("near")
        return super().map(task, items, **options)


@pytest.mark.parametrize("owners", [["w1", "w1", "w2", "w2", "w1"], ["w1"] * 5,
                                    ["w1", "w2", "w3", "w4", "w5"],
                                    [None, "w1", None, "w2", "w2"]])
def test_split_pairs_equal_pairwise_compare_wherever_the_sets_are_held(owners):
    """Pairs whose sets one worker holds (one task there), and pairs tested on either set's
    worker with the other set counted where it is held, give ``compare``'s JSON."""
    rng = np.random.default_rng(8)
    sets = [ar_set(rng, 30 + 5 * k, 0.6 - 0.2 * k, length=12 + k, source=f"s{k}")
            for k in range(5)]
    options = dict(features=["x", "y"], bins=4, permutations=29, seed=2)
    runner = HeldBy(owners)
    result = matrix(sets, runner=runner, **options)
    for (i, j), comparison in zip(result.pairs, result.comparisons, strict=True):
        assert comparison.to_json() == compare(sets[i], sets[j], **options).to_json()
    tested_on = [[id(s) for s in runner.sets].index(id(h)) for h in runner.near]
    together = [owners[i] is not None and owners[i] == owners[j] for i, j in result.pairs]
    for (i, j), k, local in zip(result.pairs, tested_on, together, strict=True):
        assert k == i if local else k in (i, j)
    assert runner.kept.count("_pair_side") == together.count(False)
    if together.count(False) > 2:  # the tests go to both sets' workers, not only the first's
        assert {k == j for (_, j), k in zip(result.pairs, tested_on, strict=True)} == {0, 1}


@pytest.mark.parametrize("option", [dict(history=2), dict(time_bins=3), dict(resample=0.2),
                                    dict(test="permutation"), dict(test="response")])
def test_other_options_are_not_split(option):
    facts = SetFacts.of(ar_set(np.random.default_rng(1), 10, 0.5))
    method = Method.of(None, **{"features": ["x"], **option})
    assert not supports(comparison_options([facts, facts], method))
    assert supports(comparison_options([facts, facts], Method.of(None, features=["x"])))
