"""The engine: shared values per map call, also when maps nest."""

from simcred.engine import Engine, shared


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
