"""The engine: shared values per map call, also when maps nest; placement of tasks near
their inputs."""

from collections import Counter
from itertools import combinations

from hypothesis import given, settings
from hypothesis import strategies as st

from simcred.engine import Engine, balanced, shared


def test_a_nested_map_does_not_overwrite_the_outer_shared_values():
    runner = Engine()

    def inner(item):
        return shared("scale") * item

    def outer(item):
        before = shared("scale")
        inner_results = runner.map(inner, [1, 2], shared_values={"scale": 100})
        return before, inner_results, shared("scale")  # the outer value again

    results = runner.map(outer, [0, 1], shared_values={"scale": 3})
    assert results == [(3, [100, 200], 3), (3, [100, 200], 3)]


def test_shared_outside_a_map_is_a_key_error():
    import pytest

    with pytest.raises(KeyError, match="no shared value 'x'"):
        shared("x")


@settings(max_examples=200, deadline=None)
@given(st.lists(st.lists(st.sampled_from("abcdef"), max_size=3, unique=True), max_size=40))
def test_placements_take_an_option_and_no_single_move_evens_them_more(options):
    """``balanced``: every item on one of its options (None without one), and no item could
    move to another of its options and lower the spread (local optimum of the moves)."""
    chosen = balanced(options)
    load = Counter(w for w in chosen if w is not None)
    for opts, w in zip(options, chosen, strict=True):
        assert (w is None) == (not opts)
        if opts:
            assert w in opts
            assert all(load[o] + 1 >= load[w] for o in opts)


def test_pairs_of_a_complete_graph_spread_within_one():
    """The matrix's case: pair (i, j) runs where set i or set j is held."""
    names = [f"w{k:02d}" for k in range(16)]
    chosen = balanced([[names[i], names[j]] for i, j in combinations(range(16), 2)])
    counts = Counter(chosen).values()
    assert max(counts) - min(counts) <= 1
