"""Configuration says which path answered and why cheaper setups fail (issue 28, item 2).

Oracles: brute-force enumeration of every setup (itertools.product) for the order by cost and
for which setups are cheaper than the optimum; the algebra's own ``refines`` on the composition
(a different query from the one the explanation uses) for "fails"; z3 directly for each reported
point (the test case's assumption and the setup's saturated guarantees hold there, the named
clause does not); the closed form of interval chains for which kind of clause fails.
"""

from __future__ import annotations

import copy
import itertools
import json
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest
import yaml

from helpers import benchmark_module
from simcred.cli import run
from simcred.contracts.algebra import refines
from simcred.contracts.configure import configure, setup_contract
from simcred.contracts.explain import by_cost
from simcred.contracts.library import Library, LibraryError
from simcred.contracts.parse import parse
from simcred.contracts.smt import to_z3, z3_variables

ROOT = Path(__file__).resolve().parents[2]
FIGURE2 = ROOT / "examples" / "contracts" / "figure2.yaml"
UNITS = ROOT / "examples" / "contracts" / "units_and_time.yaml"




_libraries = benchmark_module("contract_libraries")
chain, fan_in, non_convex = _libraries.chain, _libraries.fan_in, _libraries.non_convex


def _all_setups(library):
    components = library.components()
    for models in itertools.product(*(library.candidates(c) for c in components)):
        setup = dict(zip(components, models, strict=True))
        yield sum(Fraction(library.spec.models[m].cost) for m in models), setup


@pytest.mark.parametrize("seed", range(5))
def test_by_cost_lists_every_setup_once_in_cost_order(seed):
    rng = np.random.default_rng(seed)
    choices = {f"C{k}": [f"M{k}_{j}" for j in range(int(rng.integers(1, 5)))]
               for k in range(int(rng.integers(1, 5)))}
    costs = {m: Fraction(int(rng.integers(0, 7)), int(rng.integers(1, 4)))
             for ms in choices.values() for m in ms}
    listed = list(by_cost(choices, costs))
    brute = [(sum(costs[m] for m in models), dict(zip(choices, models, strict=True)))
             for models in itertools.product(*choices.values())]
    assert [c for c, _ in listed] == sorted(c for c, _ in brute)
    assert sorted(map(str, (s for _, s in listed))) == sorted(map(str, (s for _, s in brute)))
    assert all(c == sum(costs[m] for m in s.values()) for c, s in listed)


def _libraries_cases():
    cases = [("figure2", Library.read(FIGURE2))]
    cases += [(f"chain{s}", chain(5, 3, s)[0]) for s in range(3)]
    cases += [(f"non_convex{s}", non_convex(3, 3, s)[0]) for s in range(3)]
    cases += [(f"fan_in{s}", fan_in(3, 3, s)[0]) for s in range(3)]
    return cases


@pytest.mark.parametrize(("name", "library"), _libraries_cases(),
                         ids=[n for n, _ in _libraries_cases()])
def test_the_cheaper_setups_are_the_cheapest_ones_below_the_optimum_and_fail(name, library):
    test_case = next(iter(library.spec.test_cases))
    target = library.test_case(test_case)
    result = configure(library, test_case)
    setups = sorted(_all_setups(library), key=lambda cs: cs[0])
    if result.status.value == "holds":
        optimum = Fraction(str(result.cost))
        below = [(c, s) for c, s in setups if c < optimum]
    else:
        below = setups
    expected = [c for c, _ in below][:3]
    assert [r.cost for r in result.cheaper] == expected
    for rejection in result.cheaper:
        assert (rejection.cost, rejection.setup) in below
        assert not refines(setup_contract(library, rejection.setup), target,
                           types=library.types).holds
        _assert_point_explains(library, target, rejection)


def _assert_point_explains(library, target, rejection):
    """z3: at the reported point the test case's assumption and every saturated guarantee of
    the setup hold, and each named clause is false."""
    import z3

    assert rejection.kind in ("model assumption", "test case guarantee")
    assert rejection.clauses
    premises = [target.assumption, *(library.model_contracts[m].saturated_guarantee
                                     for m in rejection.setup.values())]
    names = set(rejection.point)
    env = z3_variables(names, library.types)
    fixed = [env[k] == (z3.BoolVal(v) if isinstance(v, bool) else
                        z3.IntVal(v) if isinstance(v, int) else
                        z3.RealVal(f"{Fraction(v).numerator}/{Fraction(v).denominator}"))
             for k, v in rejection.point.items()]
    solver = z3.Solver()
    solver.add(*fixed, *(to_z3(p, env) for p in premises))
    assert solver.check() == z3.sat
    for owner, clause in rejection.clauses:
        solver = z3.Solver()
        solver.add(*fixed, to_z3(parse(clause, types=library.types), env))
        assert solver.check() == z3.unsat, (owner, clause)
        if owner != "test case":
            assert owner in rejection.setup.values()
    first_owner = rejection.clauses[0][0]
    assert (rejection.kind == "test case guarantee") == (first_owner == "test case")


@pytest.mark.parametrize("seed", range(4))
def test_chain_rejections_name_the_kind_the_closed_form_gives(seed):
    """Interval chain: a model is fed outside its domain iff some domain does not contain the
    bound propagated into it; otherwise the last output exceeds the test case's bound."""
    library, table = chain(6, 3, seed)
    result = configure(library, "tc")
    rows = {m: (hi, out) for row in table for m, hi, out, _ in row}
    assert result.cheaper
    for rejection in result.cheaper:
        bound, outside = 10, False
        for model in rejection.setup.values():
            hi, out = rows[model]
            outside = outside or bound > hi
            bound = out
        assert rejection.kind == ("model assumption" if outside else "test case guarantee")


def test_the_path_that_answered_is_named():
    assert configure(Library.read(FIGURE2), "C_tc").path == "interval fast path"
    assert configure(non_convex(3, 3, 0)[0], "tc").path == "0-1 program"
    assert configure(Library.read(UNITS), "night_approach").path == \
        "counterexample-guided search (CEGIS)"


def test_a_cheaper_setup_with_contradicting_guarantees_is_named_as_such():
    """A cheaper I2 model whose guarantee is ``false`` refines everything vacuously."""
    spec = yaml.safe_load(FIGURE2.read_text())
    spec["models"]["M2false"] = {"implements": "I2", "cost": 1, "contract": {
        "assumption": "0 <= q <= 60", "guarantee": "false"}}
    library = Library.from_dict(copy.deepcopy(spec))
    result = configure(library, "C_tc")
    assert result.setup == {"I1": "M1", "I2": "M2a"}
    kinds = {r.setup["I2"]: r.kind for r in result.cheaper}
    assert kinds == {"M2false": "contradiction", "M2b": "model assumption"}
    assert "contradict" in next(r.reason for r in result.cheaper if r.kind == "contradiction")


def test_without_a_valid_setup_the_cheapest_setups_are_explained():
    spec = yaml.safe_load(FIGURE2.read_text())
    spec["test_cases"]["C_tc"]["guarantee"] = "err <= 0.05"  # no model guarantees this
    library = Library.from_dict(spec)
    result = configure(library, "C_tc")
    assert result.status.value == "fails"
    assert [r.cost for r in result.cheaper] == [3, 6]  # both setups, cheapest first
    assert [r.kind for r in result.cheaper] == ["model assumption", "test case guarantee"]
    assert result.cheaper[1].clauses == (("test case", "err <= 0.05"),)
    target = library.test_case("C_tc")
    for rejection in result.cheaper:
        _assert_point_explains(library, target, rejection)


def test_explain_must_be_a_count():
    with pytest.raises(LibraryError, match="explain must be a count"):
        configure(Library.read(FIGURE2), "C_tc", explain=-1)
    assert configure(Library.read(FIGURE2), "C_tc", explain=0).cheaper == []


def test_cli_configure_prints_the_path_and_the_cheaper_setups(capsys):
    assert run(["contracts", "configure", str(FIGURE2), "--test-case", "C_tc"]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "answered by: interval fast path" in out
    assert ("I2 = M2b (instead of M2a); cost 3: M2b assumes 'q <= 20', but the test case "
            "and the setup's guarantees allow q = ") in out
    assert run(["contracts", "configure", str(FIGURE2), "--test-case", "C_tc", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["path"] == "interval fast path"
    (cheaper,) = doc["cheaper_setups"]
    assert cheaper["setup"] == {"I1": "M1", "I2": "M2b"} and cheaper["cost"] == 3
    assert cheaper["kind"] == "model assumption"
    assert cheaper["clauses"][0] == {"owner": "M2b", "clause": "q <= 20"}
    assert Fraction(cheaper["at_exact"]["q"]) > 20


def test_cli_explain_option(capsys):
    assert run(["contracts", "configure", str(FIGURE2), "--test-case", "C_tc", "--explain", "0",
                "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["cheaper_setups"] == []
    assert run(["contracts", "configure", str(FIGURE2), "--test-case", "C_tc", "--explain",
                "0"]) == 0
    assert "cheaper setups" not in capsys.readouterr().out


@pytest.mark.parametrize("value", ["-1", "101", "some", "1.5"])
def test_cli_explain_out_of_range_is_one_line_exit_2(value, capsys):
    code = run(["contracts", "configure", str(FIGURE2), "--test-case", "C_tc", "--explain",
                value])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and "Traceback" not in err and "--explain" in err, err
