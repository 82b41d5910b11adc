"""Quotient messages that are true (issue 28, item 4).

"No missing model can help" used to be printed whenever a given model assumed something the test
case does not guarantee — also when the clause is about a missing component's output (which the
missing model can ensure: a requirement, not a dead end) and when every component is given and
the setup is valid. Oracles: a constructed missing model that makes the setup valid (z3's
refinement of the composition), and the quotient's guarantee evaluated at the reported point.
"""

from __future__ import annotations

import copy
from pathlib import Path

import yaml

from simcred.cli import run
from simcred.contracts.algebra import valid
from simcred.contracts.configure import (
    missing_model_requirement,
    setup_refines,
    uncovered_assumptions,
)
from simcred.contracts.expr import negate
from simcred.contracts.library import Library

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "contracts"
FIGURE2 = EXAMPLES / "figure2.yaml"
VEHICLE = EXAMPLES / "vehicle.yaml"


def _text(capsys) -> str:
    return " ".join(capsys.readouterr().out.split())  # rich wraps lines


def test_an_assumption_on_a_missing_output_is_a_requirement_not_a_dead_end(capsys):
    """Figure 2, given I2 = M2b: M2b assumes 0 <= q <= 20, q is I1's output. A model of I1
    that guarantees it exists and makes the setup valid — so "no missing model can help" would
    be false."""
    library = Library.read(FIGURE2)
    items = uncovered_assumptions(library, "C_tc", {"I2": "M2b"})
    assert items and {i["kind"] for i in items} == {"requirement"}
    spec = copy.deepcopy(yaml.safe_load(FIGURE2.read_text()))
    spec["models"]["M1_narrow"] = {"implements": "I1", "cost": 1, "contract": {
        "assumption": "0 <= v <= 40", "guarantee": "0 <= q <= 20"}}
    helped = Library.from_dict(spec)
    assert setup_refines(helped, {"I1": "M1_narrow", "I2": "M2b"},
                         helped.test_case("C_tc")).holds
    assert run(["contracts", "quotient", str(FIGURE2), "--test-case", "C_tc", "--given",
                "I2=M2b"]) == 0
    out = _text(capsys)
    assert "no missing model can help" not in out
    assert "must ensure '0 <= q and q <= 20' (M2b assumes it" in out


def test_a_valid_setup_with_every_component_given_has_no_message(capsys):
    library = Library.read(FIGURE2)
    given = {"I1": "M1", "I2": "M2a"}
    assert setup_refines(library, given, library.test_case("C_tc")).holds
    assert uncovered_assumptions(library, "C_tc", given) == []
    assert run(["contracts", "quotient", str(FIGURE2), "--test-case", "C_tc",
                "--given", "I1=M1", "--given", "I2=M2a"]) == 0
    out = _text(capsys)
    assert "no missing model" not in out and "must ensure" not in out


def test_an_invalid_setup_with_every_component_given_is_a_dead_end():
    """M2b with M1: M1 may give q up to 50 > 20 (the setup is invalid; nothing is missing)."""
    library = Library.read(FIGURE2)
    items = uncovered_assumptions(library, "C_tc", {"I1": "M1", "I2": "M2b"})
    assert {i["kind"] for i in items} == {"dead end"}
    assert all(i["at"]["q"] > 20 for i in items)


def test_a_dead_end_is_where_the_quotient_guarantee_is_false():
    """Vehicle, given KS: KS assumes |a_long| <= 4 on an environment variable; at the point
    reported, the quotient (before projection) admits no behaviour of the missing models."""
    library = Library.read(VEHICLE)
    given = {"dynamics": "KS"}
    items = [i for i in uncovered_assumptions(library, "cutin", given)
             if i["kind"] == "dead end"]
    assert items and items[0]["clause"] == "abs(ego.a_long) <= 4"
    quotient = missing_model_requirement(library, "cutin", given)
    at = items[0]["at"]
    # within the quotient's assumption at that point, its guarantee cannot hold (z3)
    fixed = [_equals(k, v) for k, v in at.items()]
    assert valid([quotient.assumption, *fixed], negate(quotient.guarantee),
                 types=library.types).holds


def _equals(name, value):
    """``name == value`` exactly (a rational)."""
    from simcred.contracts.parse import parse

    return parse(f"{name} == {value.numerator} / {value.denominator}")

