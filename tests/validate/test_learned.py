"""The learned assertions' text (contracts.yaml) is printed from their ASTs and parses back to
the same trees, negative edges and grouped bounds included (issue 27)."""

from __future__ import annotations

from fractions import Fraction

import pytest

from simcred.contracts.expr import Compare, Logic, Num, Var, conjoin, implies
from simcred.contracts.library import VariableSpec
from simcred.contracts.parse import parse
from simcred.validate.learned import assertion_text

V, G, D, E = Var("v"), Var("g"), Var("deviation.x"), Var("deviation.y")
DECLARED = {n: VariableSpec(type="real", unit="m") for n in ("v", "g", "deviation.x",
                                                              "deviation.y")}


def _box(variable, lo, hi):
    return [Compare("<=", Num(Fraction(lo)), variable), Compare("<=", variable, Num(Fraction(hi)))]


def _bounds(x, y):
    return conjoin(Compare("<=", D, Num(Fraction(x))), Compare("<=", E, Num(Fraction(y))))


CASES = [
    (conjoin(*_box(V, "-2.5", "3")), "-2.5 <= v <= 3"),
    (Logic("or", (conjoin(*_box(V, "-7", "-2.5")), conjoin(*_box(V, "0", "1e-05")))),
     "(-7 <= v <= -2.5) or (0 <= v <= 0.00001)"),
    (conjoin(*_box(V, "-1", "2"), *_box(G, "0", "0.5")), "(-1) <= v <= 2 and 0 <= g <= 0.5"),
    (Compare("<=", D, Num(Fraction("0.25"))), "deviation.x <= 0.25"),
    (_bounds("0.25", "-0.5"), "deviation.x <= 0.25 and deviation.y <= -0.5"),
    (Logic("and", (implies(conjoin(*_box(V, "0", "1")), _bounds("0.25", "1")),
                   implies(conjoin(*_box(V, "1", "2")), Compare("<=", D, Num(Fraction(3)))))),
     "(0 <= v <= 1 implies (deviation.x <= 0.25 and deviation.y <= 1)) and "
     "(1 <= v <= 2 implies deviation.x <= 3)"),
]


@pytest.mark.parametrize(("tree", "text"), CASES)
def test_text_of_a_learned_assertion_parses_back_to_its_tree(tree, text):
    assert assertion_text(tree) == text
    assert parse(text, declared=DECLARED) == tree
