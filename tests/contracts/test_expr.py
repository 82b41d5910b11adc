"""The assertion language (paper 003): parse/print round trips, the numpy back end against z3
(exact rationals), the robustness margin against the boolean value, and one-line parse errors.

Random ASTs are built in the parser's canonical form (``and``/``or`` flattened, a negated or
divided literal folded into one number), so ``parse(to_text(e)) == e`` is an exact equality.
"""

from fractions import Fraction

import numpy as np
import pytest
import z3
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from simcred.contracts.evaluate import evaluate, margin
from simcred.contracts.expr import (
    Arith,
    Bool,
    Compare,
    ExpressionError,
    Logic,
    Num,
    Var,
    is_boolean,
    to_text,
    variables,
)
from simcred.contracts.parse import parse
from simcred.contracts.smt import to_z3, z3_variables
from simcred.errors import SimcredError

# names that brush against keywords and function names, a dotted one, and plain ones
NAMES = ("x", "y", "ego.v", "andy", "not_x", "min_gap", "true_v")
COMPARE_OPS = ("<=", "<", ">=", ">", "==", "!=")
SETTINGS = settings(derandomize=True, database=None, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow])


def law(examples: int) -> settings:
    """Seeded (derandomized) hypothesis settings with ``examples`` examples."""
    return settings(SETTINGS, max_examples=examples)


# -- strategies: random ASTs in canonical (parsed) form ------------------------------------------


def _neg(t):
    return Num(-t.value) if isinstance(t, Num) else Arith("neg", (t,))


def _div(a, b):
    if isinstance(b, Num) and b.value == 0:  # a zero literal divisor is a parse error
        b = Num(Fraction(7, 2))
    if isinstance(a, Num) and isinstance(b, Num):  # `2 / 3` is the rational literal 2/3
        return Num(a.value / b.value)
    return Arith("/", (a, b))


def _logic(op):
    def build(operands):
        flat = tuple(a for o in operands
                     for a in (o.args if isinstance(o, Logic) and o.op == op else (o,)))
        return Logic(op, flat)
    return build


fractions = st.builds(Fraction, st.integers(-20, 20), st.integers(1, 6))
term_leaves = st.one_of(st.builds(Var, st.sampled_from(NAMES)), st.builds(Num, fractions))


def _term_nodes(t):
    return st.one_of(
        st.builds(lambda op, a, b: Arith(op, (a, b)), st.sampled_from("+-*"), t, t),
        st.builds(_div, t, t),
        st.builds(_neg, t),
        st.builds(lambda a: Arith("abs", (a,)), t),
        st.builds(lambda op, args: Arith(op, tuple(args)), st.sampled_from(["min", "max"]),
                  st.lists(t, min_size=2, max_size=3)),
        st.builds(lambda a, k: Arith("^", (a, Num(Fraction(k)))), t, st.integers(0, 3)),
    )


terms = st.recursive(term_leaves, _term_nodes, max_leaves=8)
condition_leaves = st.one_of(
    st.builds(Bool, st.booleans()),
    st.builds(Compare, st.sampled_from(COMPARE_OPS), terms, terms))


def _condition_nodes(c):
    return st.one_of(
        st.builds(_logic("and"), st.lists(c, min_size=2, max_size=3)),
        st.builds(_logic("or"), st.lists(c, min_size=2, max_size=3)),
        st.builds(lambda a: Logic("not", (a,)), c),
        st.builds(lambda a, b: Logic("implies", (a, b)), c, c),
    )


conditions = st.recursive(condition_leaves, _condition_nodes, max_leaves=6)


def _exact_points(seed: int) -> dict[str, list[Fraction]]:
    """Three rational points per variable in [-6, 6] (denominators up to 4: zeros and ties)."""
    rng = np.random.default_rng(seed)
    return {n: [Fraction(int(p), int(q)) for p, q in zip(rng.integers(-6, 7, 3),
                                                        rng.integers(1, 5, 3), strict=True)]
            for n in NAMES}


def _float_points(seed: int) -> dict[str, np.ndarray]:
    """Six float points per variable, half of them from a few round values (ties, zeros)."""
    rng = np.random.default_rng(seed)
    round_values = rng.choice([-2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 2.0, 3.0], size=(len(NAMES), 6))
    values = np.where(rng.random((len(NAMES), 6)) < 0.5, round_values,
                      rng.uniform(-10, 10, (len(NAMES), 6)))
    return dict(zip(NAMES, values, strict=True))


exact_points = st.integers(0, 2**32).map(_exact_points)
float_points = st.integers(0, 2**32).map(_float_points)


# -- printing and parsing -----------------------------------------------------------------------


@law(400)
@given(conditions)
def test_to_text_then_parse_gives_the_same_ast(e):
    text = to_text(e)
    assert parse(text, declared=dict.fromkeys(NAMES)) == e
    assert to_text(parse(text)) == text


@law(300)
@given(terms)
def test_a_printed_term_parses_back_inside_a_comparison(t):
    parsed = parse(f"{to_text(t)} <= x")
    assert parsed == Compare("<=", t, Var("x"))
    assert not is_boolean(t) and is_boolean(parsed)


@pytest.mark.parametrize(("text", "expected"), [
    ("x <= 0.2", Fraction(1, 5)), ("x <= 1e-3", Fraction(1, 1000)), ("x <= .5", Fraction(1, 2)),
    ("x <= 1.", Fraction(1)), ("x <= 2.5E2", Fraction(250)), ("x <= 0.1", Fraction(1, 10)),
    ("x <= 2/3", Fraction(2, 3)), ("x <= -1.25", Fraction(-5, 4)), ("x <= -(3/4)", -Fraction(3, 4)),
])
def test_numbers_are_parsed_exactly(text, expected):
    assert parse(text) == Compare("<=", Var("x"), Num(expected))


def test_comparison_chains_are_conjunctions_and_implications_nest_to_the_right():
    zero, one, thirty = (Num(Fraction(k)) for k in (0, 1, 30))
    assert parse("0 <= v <= 30") == Logic("and", (Compare("<=", zero, Var("v")),
                                                  Compare("<=", Var("v"), thirty)))
    assert parse("a < b <= c and d == 1") == Logic("and", (
        Compare("<", Var("a"), Var("b")), Compare("<=", Var("b"), Var("c")),
        Compare("==", Var("d"), one)))
    p, q, r = (Compare("<", Var(n), one) for n in "pqr")
    assert parse("p < 1 implies q < 1 implies r < 1") == Logic(
        "implies", (p, Logic("implies", (q, r))))
    assert parse("(p < 1 implies q < 1) implies r < 1") == Logic(
        "implies", (Logic("implies", (p, q)), r))


def test_precedence_and_associativity():
    one, two = Num(Fraction(1)), Num(Fraction(2))
    x, y, z = Var("x"), Var("y"), Var("z")
    assert parse("x - y - z <= 0").left == Arith("-", (Arith("-", (x, y)), z))
    assert parse("x - y * z <= 0").left == Arith("-", (x, Arith("*", (y, z))))
    assert parse("-x ^ 2 <= 0").left == Arith("neg", (Arith("^", (x, two)),))
    assert parse("(-x) ^ 2 <= 0").left == Arith("^", (Arith("neg", (x,)), two))
    assert parse("x <= 1 or y <= 1 and z <= 1") == Logic("or", (
        Compare("<=", x, one), Logic("and", (Compare("<=", y, one), Compare("<=", z, one)))))
    assert parse("not x <= 1 and y <= 1") == Logic("and", (
        Logic("not", (Compare("<=", x, one),)), Compare("<=", y, one)))
    assert parse("abs (x) <= max(x, y, z)").right == Arith("max", (x, y, z))
    assert variables(parse("ego.v <= andy + min_gap")) == {"ego.v", "andy", "min_gap"}


# -- numpy against z3 ---------------------------------------------------------------------------


def _z3_value(term, env, point):
    pairs = [(env[n], z3.RealVal(f"{v.numerator}/{v.denominator}")) for n, v in point.items()]
    return z3.simplify(z3.substitute(term, *pairs))


def _exact_columns(points, i=None):
    return {n: np.array(v if i is None else v[i:i + 1], dtype=object) for n, v in points.items()}


def _check_against_z3(e, points):
    env = z3_variables(NAMES)
    term = to_z3(e, env)
    try:
        vectorised = np.broadcast_to(evaluate(e, _exact_columns(points)), (3,))
    except ZeroDivisionError:
        vectorised = None
    compared = 0
    for i in range(3):
        try:
            value = np.broadcast_to(evaluate(e, _exact_columns(points, i)), (1,))[0]
        except ZeroDivisionError:  # z3 leaves x/0 uninterpreted: nothing to compare
            continue
        if vectorised is not None:
            assert vectorised[i] == value
        expected = _z3_value(term, env, {n: v[i] for n, v in points.items()})
        if is_boolean(e):
            assert z3.is_true(expected) or z3.is_false(expected), expected
            assert bool(value) is z3.is_true(expected), (to_text(e), i)
        else:
            assert z3.is_rational_value(expected), expected
            assert not isinstance(value, float | np.floating), value  # exact, never rounded
            assert Fraction(value) == Fraction(expected.numerator_as_long(),
                                               expected.denominator_as_long()), to_text(e)
        compared += 1
    return compared


@law(300)
@given(conditions, exact_points)
def test_exact_numpy_evaluation_agrees_with_z3_on_conditions(e, points):
    _check_against_z3(e, points)


@law(300)
@given(terms, exact_points)
def test_exact_numpy_evaluation_agrees_with_z3_on_terms(t, points):
    _check_against_z3(t, points)


def test_exact_evaluation_differs_from_floating_point_where_it_should():
    e = parse("x == 0.1 + 0.2")
    assert evaluate(e, {"x": np.array([Fraction(3, 10)], dtype=object)}).tolist() == [True]
    assert evaluate(e, {"x": np.array([0.3])}).tolist() == [False]  # 0.1 + 0.2 != 0.3 in floats
    assert evaluate(parse("x == 1/3"), {"x": Fraction(1, 3)})


def test_evaluate_is_vectorised_over_columns():
    e = parse("0 <= ego.v <= 30 and abs(a) < 2.5 or a ^ 2 == 9")
    got = evaluate(e, {"ego.v": np.array([-1.0, 10.0, 40.0, 10.0]),
                       "a": np.array([0.0, 1.0, 0.0, -3.0])})
    assert got.tolist() == [False, True, False, True]
    assert evaluate(parse("min(x, 3) + max(x, 1, 2) == 4"), {"x": np.array([2.0])}).tolist() \
        == [True]


# -- margin -------------------------------------------------------------------------------------


def _check_margin_sign(e, columns):
    with np.errstate(all="ignore"):
        m = np.broadcast_to(np.asarray(margin(e, columns)), (6,))
        v = np.broadcast_to(np.asarray(evaluate(e, columns), dtype=bool), (6,))
    assert np.all(v[m > 0]), to_text(e)
    assert not np.any(v[m < 0]), to_text(e)


@law(500)
@given(conditions, float_points)
def test_margin_sign_agrees_with_evaluate_on_floats(e, points):
    _check_margin_sign(e, points)


@pytest.mark.parametrize(("text", "expected"), [
    ("x <= 3", [2.0, 4.0]), ("x < 3", [2.0, 4.0]), ("x >= 3", [-2.0, -4.0]),
    ("x == 3", [-2.0, -4.0]), ("x != 3", [2.0, 4.0]), ("not x <= 3", [-2.0, -4.0]),
    ("x <= 3 and y >= 0", [-1.0, 4.0]), ("x <= 3 or y >= 0", [2.0, 5.0]),
    ("x <= 2 implies y >= 0", [-1.0, 5.0]), ("true", [np.inf, np.inf]),
    ("false", [-np.inf, -np.inf]), ("true and x <= 3", [2.0, 4.0]),
])
def test_margin_closed_forms(text, expected):
    columns = {"x": np.array([1.0, -1.0]), "y": np.array([-1.0, 5.0])}
    assert np.broadcast_to(margin(parse(text), columns), (2,)).tolist() == expected


def test_margin_is_exact_on_fractions():
    assert margin(parse("x <= 0.3"), {"x": np.array([Fraction(1, 10)], dtype=object)}).tolist() \
        == [Fraction(1, 5)]


# -- errors -------------------------------------------------------------------------------------


def _error(text, **kwargs) -> str:
    with pytest.raises(ExpressionError) as info:
        parse(text, **kwargs)
    message = str(info.value)
    assert isinstance(info.value, SimcredError) and isinstance(info.value, ValueError)
    assert len(message.splitlines()) == 1 and message.strip() == message, repr(message)
    return message


@pytest.mark.parametrize(("text", "where"), [
    ("x <= ", "line 1, column 3: unexpected end of input"),
    ("x <= $", "line 1, column 6: unexpected '$'"),
    ("x <= 1 2", "line 1, column 8: unexpected '2'"),
    ("x <= 1 and\n y >>= 2", "line 2, column 5: unexpected '>='"),
    ("x <=\n\n  1 1", "line 3, column 5: unexpected '1'"),
    ("(x <= 1", "line 1, column"),
    ("x <= 1)", "line 1, column 7: unexpected ')'"),
    ("not.x <= 1", "line 1, column 4: unexpected '.'"),
    ("x <= 1 and and y <= 2", "line 1, column 12: unexpected 'and'"),
    ("min() <= 1", "line 1, column 5: unexpected ')'"),
])
def test_syntax_errors_name_line_and_column(text, where):
    message = _error(text)
    assert message.startswith(where), message
    assert text.split()[-1] in message.partition(" in '")[2]  # the assertion itself is quoted


@pytest.mark.parametrize(("text", "fragment"), [
    ("x + 1", "'x + 1' is a number, not a condition"),
    ("3", "'3' is a number, not a condition"),
    ("(x < 1) + 2 <= 3", "+ needs a number, got the condition 'x < 1'"),
    ("x * (y > 0) <= 3", "* needs a number, got the condition 'y > 0'"),
    ("-(x < 1) <= 3", "- needs a number, got the condition 'x < 1'"),
    ("(x < 1) ^ 2 <= 3", "^ needs a number, got the condition 'x < 1'"),
    ("true <= 1", "a comparison needs a number, got the condition 'true'"),
    ("x == (y < 1)", "a comparison needs a number, got the condition 'y < 1'"),
    ("abs(x < 1) <= 2", "abs needs a number, got the condition 'x < 1'"),
    ("max(x, true) <= 2", "max needs a number, got the condition 'true'"),
    ("x and y <= 1", "and needs a condition, got the number 'x'"),
    ("x <= 1 or 2", "or needs a condition, got the number '2'"),
    ("not 3", "not needs a condition, got the number '3'"),
    ("x implies y < 1", "implies needs a condition, got the number 'x'"),
    ("x < 1 implies y", "implies needs a condition, got the number 'y'"),
    ("abs(x, y) <= 1", "abs takes 1 argument, got 2"),
    ("min(x) <= 1", "min takes at least 2 arguments, got 1"),
    ("x / 0 <= 1", "division by zero"),
    ("x / 0.0 <= 1", "division by zero"),
    ("1 / 0 <= x", "division by zero"),
    ("x ^ 1.5 <= 1", "the exponent of ^ must be a whole number from 0 to 16"),
    ("x ^ 17 <= 1", "the exponent of ^ must be a whole number from 0 to 16"),
    ("x ^ -1 <= 1", "the exponent of ^ must be a whole number from 0 to 16"),
    ("x ^ y <= 1", "the exponent of ^ must be a whole number from 0 to 16"),
    ("x ^ 2 ^ 3 <= 1", "the exponent of ^ must be a whole number from 0 to 16"),
    ("", "empty assertion"),
    ("  \n ", "empty assertion"),
])
def test_type_errors_are_one_line_and_say_what_is_wrong(text, fragment):
    message = _error(text, where="lib.yaml: M1: guarantee")
    assert message.startswith("lib.yaml: M1: guarantee: "), message
    assert fragment in message, message


def test_where_prefixes_every_kind_of_error():
    assert _error("x <=", where="w").startswith("w: line 1, column")
    assert _error("x < 1 and 2", where="w").startswith("w: and needs a condition")
    assert _error("x <= y", where="w", declared={"x": "real"}).startswith("w: undeclared")
    assert _error("").startswith("empty assertion")  # without where, no prefix


def test_undeclared_variables_are_named():
    message = _error("ego.v <= zeta + 1", declared={"ego.v": "real"}, where="tc")
    assert message == "tc: undeclared variable 'zeta' in 'ego.v <= zeta + 1'"
    assert parse("ego.v <= zeta", declared={"ego.v": 1, "zeta": 1}) is not None
    assert "'a'" in _error("b <= a and c <= 1", declared={"b": 1})  # the first one, sorted


def test_the_exponent_limits_are_inclusive():
    assert parse("x ^ 0 <= 1").left == Arith("^", (Var("x"), Num(Fraction(0))))
    assert parse("x ^ 16 <= 1").left.args[1] == Num(Fraction(16))
    value = evaluate(parse("x ^ 0 == 1"), {"x": np.array([0.0, 5.0])})
    assert np.broadcast_to(value, (2,)).tolist() == [True, True]  # x ^ 0 is the scalar 1


def test_a_division_by_a_zero_expression_is_not_a_parse_error_and_stays_uninterpreted():
    e = parse("x / (y - y) <= 1")  # only literal zeros are caught when parsing
    with np.errstate(all="ignore"):
        assert evaluate(e, {"x": np.array([1.0]), "y": np.array([2.0])}).tolist() == [False]


def test_x_to_the_zero_is_an_exact_one():
    """Regression: ``x ^ 0`` evaluated to the int 1, and int / int gave a float in exact mode."""
    exact = {"x": np.array([Fraction(5)], dtype=object)}
    assert evaluate(parse("x ^ 0 / (x ^ 0 + x ^ 0 + x ^ 0) == 1/3"), exact)
    assert isinstance(evaluate(parse("x ^ 0 <= 1").left, exact), Fraction)


def test_one_identifier_grammar_and_keyword_list():
    """Issue 27: the parser's names, a library's names and a validation file's names share one
    identifier pattern and one keyword list (``expr.IDENTIFIER``, ``expr.KEYWORDS``)."""
    import importlib
    import re

    from simcred.contracts.expr import IDENTIFIER, KEYWORDS, LOGIC_WORDS
    from simcred.contracts.library import NAME as LIBRARY_NAME
    from simcred.validate.spec import NAME as FILE_NAME
    from simcred.validate.spec import RESERVED

    parse_module = importlib.import_module("simcred.contracts.parse")
    assert f"NAME: /(?!({'|'.join(KEYWORDS)})\\b){IDENTIFIER}/" in parse_module.GRAMMAR
    for name in ("v", "ego.v", "_a1.b_2", "deviation.gap"):
        assert re.fullmatch(IDENTIFIER, name) and LIBRARY_NAME.fullmatch(name)
        assert FILE_NAME.match(name)
    for bad in ("1v", "ego.", "a..b", "a-b"):
        assert not LIBRARY_NAME.fullmatch(bad) and not FILE_NAME.match(bad)
    for word in LOGIC_WORDS:
        assert not LIBRARY_NAME.fullmatch(word) and word in RESERVED
    assert set(KEYWORDS) >= set(LOGIC_WORDS) and RESERVED - set(LOGIC_WORDS) == {"deviation"}
