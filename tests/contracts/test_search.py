"""Configuration by interval propagation (issue 15, item 5) against z3.

Oracles: for random DAG libraries in the interval fragment (one- and two-sided, strict and
non-strict bounds, ``abs``, negative ranges, test-case guarantees on environment variables too),
(1) the interval decision of each setup equals z3's verdict of the setup's refinement, and
(2) the configured cost equals the minimum over all setups checked one by one with z3, and
equals the cost found by the CEGIS search.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from simcred.contracts.algebra import Status
from simcred.contracts.configure import configure, setup_refines
from simcred.contracts.intervals import box
from simcred.contracts.library import Library
from simcred.contracts.search import branch_and_bound, interval_problem


def _bound(rng, name: str, wide: bool = False) -> str:
    """A random bound on ``name``: wide ones (assumptions) usually contain narrow ones."""
    lo = int(rng.integers(-9, 0)) if wide else int(rng.integers(-3, 1))
    hi = int(rng.integers(3, 12)) if wide else int(rng.integers(0, 6))
    kind = rng.integers(0, 5)
    if kind == 0:
        return f"{lo} <= {name} <= {hi}"
    if kind == 1:
        return f"{lo} < {name} <= {hi + 1}"
    if kind == 2:
        return f"{name} <= {hi}" if rng.random() < 0.5 else f"{lo} <= {name}"
    if kind == 3:
        return f"abs({name}) <= {abs(hi) + 1}"
    return f"{name} < {hi + 1} and {name} >= {lo}"


def random_dag(seed: int, components: int = 3, models: int = 3) -> Library:
    rng = np.random.default_rng(seed)
    spec = {"variables": {"e0": {"unit": "m"}, "e1": {"unit": "m"}}, "components": {},
            "models": {}, "architecture": []}
    sources = ["e0", "e1"]
    for k in range(components):
        inputs = sorted(set(rng.choice(sources, size=int(rng.integers(1, 3)))))
        spec["variables"][f"y{k}"] = {"unit": "m"}
        spec["components"][f"C{k}"] = {"inputs": inputs, "outputs": [f"y{k}"]}
        spec["architecture"].append(f"C{k}")
        for j in range(models):
            assumption = " and ".join(_bound(rng, x, wide=True) for x in inputs
                                      if rng.random() < 0.8)
            spec["models"][f"M{k}{j}"] = {
                "implements": f"C{k}", "cost": int(rng.integers(1, 6)),
                "contract": {"assumption": assumption or "true",
                             "guarantee": _bound(rng, f"y{k}")}}
        sources.append(f"y{k}")
    used = sorted({x for c in spec["components"].values() for x in c["inputs"]
                   if x.startswith("e")})
    goal = [_bound(rng, f"y{components - 1}", wide=True)]
    if rng.random() < 0.3:
        goal.append(_bound(rng, used[0], wide=True))
    spec["test_cases"] = {"tc": {"assumption": " and ".join(f"-2 <= {e} <= 5" for e in used),
                                 "guarantee": " and ".join(goal)}}
    return Library.from_dict(spec, source=f"dag({seed})")


def _setups(lib):
    components = lib.components()
    for models in itertools.product(*(lib.candidates(c) for c in components)):
        yield dict(zip(components, models, strict=True))


@pytest.mark.parametrize("seed", range(40))
def test_interval_decision_equals_z3_on_every_setup(seed):
    lib = random_dag(seed)
    target = lib.test_case("tc")
    for setup in _setups(lib):
        choices = {c: [m] for c, m in setup.items()}
        problem = interval_problem(lib, target, choices)
        assert problem is not None
        decided = branch_and_bound(problem).setup is not None
        assert decided == setup_refines(lib, setup, target).holds, setup


@pytest.mark.parametrize("seed", range(40, 70))
def test_configuration_is_the_cheapest_by_z3_enumeration_and_cegis(seed):
    lib = random_dag(seed)
    target = lib.test_case("tc")
    costs = [sum(lib.spec.models[m].cost for m in s.values()) for s in _setups(lib)
             if setup_refines(lib, s, target).holds]
    result = configure(lib, "tc")
    assert "interval propagation" in result.method
    cegis = configure(lib, "tc", search="cegis")
    if not costs:
        assert result.status is Status.FAILS and cegis.status is Status.FAILS
    else:
        assert result.status is Status.HOLDS and result.cost == min(costs) == cegis.cost
        assert result.proof.holds


def test_outside_the_fragment_optimisation_or_cegis_is_used():
    """A sum in an assumption with box guarantees: 0-1 optimisation; a guarantee that is not a
    box: counterexample-guided."""
    lib = random_dag(3)
    spec = lib.spec.model_dump()
    spec["models"]["M00"]["contract"] = {"assumption": "e0 + e1 <= 20" if "e1" in
                                         spec["components"]["C0"]["inputs"] else "e0 * 2 <= 9",
                                         "guarantee": "y0 <= 3"}
    assert "0-1 optimisation" in configure(Library.from_dict(spec), "tc").method
    spec["models"]["M00"]["contract"]["guarantee"] = "y0 <= 3 or y0 >= 100"
    assert "CEGIS" in configure(Library.from_dict(spec), "tc").method


@pytest.mark.parametrize(("text", "expected"), [
    ("0 <= x <= 3 and x < 2", {"x": "0 <= x < 2"}),
    ("abs(x) < 2", {"x": "-2 < x < 2"}),
    ("x == 1", {"x": "1 <= x <= 1"}),
    ("x <= 1 or x >= 2", None),
    ("x + y <= 1", None),
    ("x != 1", None),
])
def test_boxes_of_assertions(text, expected):
    from simcred.contracts.parse import parse

    found = box(parse(text))
    assert (None if found is None else {k: v.text(k) for k, v in found.items()}) == expected


def random_linear(seed: int) -> Library:
    """A random DAG whose contracts are outside the interval fragment: sums of inputs in the
    assumptions, outputs bounded by inputs in the guarantees."""
    rng = np.random.default_rng(seed)
    lib = random_dag(seed)
    spec = lib.spec.model_dump()
    for model in spec["models"].values():
        inputs = spec["components"][model["implements"]]["inputs"]
        output = spec["components"][model["implements"]]["outputs"][0]
        if rng.random() < 0.5:
            total = " + ".join(inputs)
            model["contract"]["assumption"] = f"-8 <= {total} and {total} <= {rng.integers(3, 14)}"
        if rng.random() < 0.5:
            model["contract"]["guarantee"] = (f"{output} <= {inputs[0]} * 0.5 + "
                                              f"{rng.integers(0, 5)} and {output} >= -3")
    return Library.from_dict(spec, source=f"linear({seed})")


@pytest.mark.parametrize("seed", range(100, 125))
def test_cegis_is_the_cheapest_by_z3_enumeration_outside_the_fragment(seed):
    lib = random_linear(seed)
    target = lib.test_case("tc")
    costs = [sum(lib.spec.models[m].cost for m in s.values()) for s in _setups(lib)
             if setup_refines(lib, s, target).holds]
    result = configure(lib, "tc")
    if not costs:
        assert result.status is Status.FAILS
    else:
        assert result.status is Status.HOLDS and result.cost == min(costs), result.method
