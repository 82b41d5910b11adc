"""Configuration as 0-1 optimisation (issue 28, item 2) against independent optima.

Generated libraries (benchmarks/contract_libraries.py): non-convex validity domains along a chain
and a fan-in of sensors into an AD function with an error budget (a sum). Oracles: every setup
checked one by one with z3's refinement query (small libraries), the generator's own dynamic
programme over its numbers (larger ones), and the counterexample-guided path.
"""

from __future__ import annotations

import itertools
from fractions import Fraction

import pytest

from helpers import benchmark_module
from simcred.contracts.algebra import Status, valid
from simcred.contracts.configure import configure, setup_refines
from simcred.contracts.intervals import Interval
from simcred.contracts.optimise import _within_union
from simcred.contracts.parse import parse

_libraries = benchmark_module("contract_libraries")
fan_in, non_convex = _libraries.fan_in, _libraries.non_convex


def brute_force(library) -> float | None:
    target = library.test_case("tc")
    components = library.components()
    costs = [sum(library.spec.models[m].cost for m in setup)
             for setup in itertools.product(*(library.candidates(c) for c in components))
             if setup_refines(library, dict(zip(components, setup, strict=True)),
                              target).holds]
    return min(costs) if costs else None


@pytest.mark.parametrize(("make", "size", "seed"),
                         [(non_convex, (3, 3), s) for s in range(6)]
                         + [(fan_in, (3, 3), s) for s in range(6)])
def test_optimum_equals_brute_force_and_the_generator(make, size, seed):
    library, oracle = make(*size, seed)
    found = configure(library, "tc")
    assert "0-1 optimisation" in found.method
    expected = brute_force(library)
    assert expected == oracle
    if expected is None:
        assert found.status is Status.FAILS
    else:
        assert found.status is Status.HOLDS and found.cost == expected
        assert setup_refines(library, found.setup, library.test_case("tc")).holds


@pytest.mark.parametrize(("make", "size", "seed"),
                         [(non_convex, (12, 5), s) for s in range(3)]
                         + [(fan_in, (12, 5), s) for s in range(3)])
def test_optimum_equals_the_generators_dynamic_programme_at_scale(make, size, seed):
    library, oracle = make(*size, seed)
    found = configure(library, "tc")
    assert "0-1 optimisation" in found.method
    assert (found.cost if found.status is Status.HOLDS else None) == oracle


def test_optimum_equals_the_counterexample_guided_path():
    library, _ = fan_in(4, 3, 5)
    assert configure(library, "tc").cost == configure(library, "tc", search="cegis").cost


@pytest.mark.parametrize("seed", range(60))
def test_a_box_within_a_union_of_intervals_agrees_with_z3(seed):
    import numpy as np

    rng = np.random.default_rng(seed)
    pieces = []
    for _ in range(int(rng.integers(1, 4))):
        lo, hi = sorted(int(v) for v in rng.integers(0, 10, size=2))
        pieces.append(f"{lo} {'<' if rng.random() < 0.3 else '<='} x "
                      f"{'<' if rng.random() < 0.3 else '<='} {hi}")
    assumption = parse(" or ".join(pieces))
    lo, hi = sorted(int(v) for v in rng.integers(0, 10, size=2))
    inner = Interval(Fraction(lo), Fraction(hi), bool(rng.random() < 0.3),
                     bool(rng.random() < 0.3))
    decided = _within_union({"x": inner}, assumption, {})
    expected = inner.empty or valid([parse(inner.text("x"))], assumption).holds
    assert decided == expected, (inner, pieces)
