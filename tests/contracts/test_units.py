"""Dimensional analysis inside assertions (issue 15, item 2).

Property tests: random assertions built dimension by dimension are accepted, and their resolved
form (literals and variables converted exactly to one unit per sum or comparison) has the truth
value of the same assertion computed in SI base units by a literal oracle; random assertions
with one unlike operand are refused.
"""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from simcred.contracts.evaluate import evaluate
from simcred.contracts.expr import Arith, Compare, ExpressionError, Num, Quantity, Var, to_text
from simcred.contracts.parse import parse
from simcred.contracts.units import _registry

UNITS = {"d1": "m", "d2": "km", "t1": "s", "t2": "min", "v1": "m/s", "v2": "km/h",
         "a1": "m/s^2", "lx": "lux", "r1": "dimensionless", "r2": "%", "r3": "percent",
         "dT1": "delta_degC", "dT2": "delta_degF", "dT3": "K"}
VARIABLES = {"length": ["d1", "d2"], "time": ["t1", "t2"], "speed": ["v1", "v2"],
             "acceleration": ["a1"], "illuminance": ["lx"], "ratio": ["r1", "r2", "r3"],
             "temperature difference": ["dT1", "dT2", "dT3"]}
LITERAL_UNITS = {"length": ["m", "km", "cm", "mile", "ft"], "time": ["s", "min", "h", "ms"],
                 "speed": ["m/s", "km/h", "mph", "knot"], "acceleration": ["m/s^2", "g0"],
                 "illuminance": ["lux", "lm/m^2"], "ratio": ["%", "percent", "permille"],
                 "temperature difference": ["delta_degC", "delta_degF", "K", "Δ°C"]}
PRODUCTS = {"length": [("*", "speed", "time")], "speed": [("/", "length", "time"),
                                                          ("*", "acceleration", "time")],
            "time": [("/", "length", "speed")], "acceleration": [("/", "speed", "time")],
            "illuminance": [], "ratio": [("*", "ratio", "ratio"), ("/", "length", "length")],
            "temperature difference": [("*", "ratio", "temperature difference")]}
SETTINGS = settings(derandomize=True, database=None, deadline=None, max_examples=300,
                    suppress_health_check=[HealthCheck.too_slow])

positive = st.builds(Fraction, st.integers(1, 60), st.integers(1, 8))


@st.composite
def term(draw, dim: str, depth: int = 0):
    kinds = ["var", "literal"] + (["sum", "minmax", "unary", "product"] if depth < 3 else [])
    kind = draw(st.sampled_from(kinds))
    if kind == "product" and not PRODUCTS[dim]:
        kind = "var"
    if kind == "var":
        return Var(draw(st.sampled_from(VARIABLES[dim])))
    if kind == "literal":
        return Quantity(draw(positive), draw(st.sampled_from(LITERAL_UNITS[dim])))
    if kind == "sum":
        return Arith(draw(st.sampled_from("+-")), (draw(term(dim, depth + 1)),
                                                   draw(term(dim, depth + 1))))
    if kind == "minmax":
        return Arith(draw(st.sampled_from(["min", "max"])), (draw(term(dim, depth + 1)),
                                                             draw(term(dim, depth + 1))))
    if kind == "unary":
        return Arith(draw(st.sampled_from(["abs", "neg"])), (draw(term(dim, depth + 1)),))
    op, left, right = draw(st.sampled_from(PRODUCTS[dim]))
    return Arith(op, (draw(term(left, depth + 1)), draw(term(right, depth + 1))))


dimensions = st.sampled_from(sorted(VARIABLES))


@st.composite
def well_dimensioned(draw):
    dim = draw(dimensions)
    return Compare(draw(st.sampled_from(["<=", "<", ">=", ">"])), draw(term(dim)),
                   draw(term(dim)))


@st.composite
def ill_dimensioned(draw):
    """A comparison or a sum somewhere with operands of two different dimensions."""
    first, second = draw(st.lists(dimensions, min_size=2, max_size=2, unique=True))
    where = draw(st.sampled_from(["compare", "sum-left", "sum-right"]))
    if where == "compare":
        return Compare("<=", draw(term(first)), draw(term(second)))
    bad = Arith(draw(st.sampled_from("+-")), (draw(term(first)), draw(term(second))))
    return Compare("<=", bad, draw(term(first))) if where == "sum-left" else \
        Compare("<=", draw(term(first)), Arith("max", (draw(term(first)), bad)))


# -- the SI oracle -------------------------------------------------------------------------------


def si(unit_text: str) -> Fraction:
    """Factor from ``unit_text`` to SI base units (pint, exact)."""
    q = _registry().Quantity(Fraction(1), unit_text).to_base_units()
    return Fraction(q.magnitude)


def si_value(e, point):
    """Value of a term in SI base units: variables from ``point`` (in their declared unit)."""
    if isinstance(e, Var):
        return point[e.name] * si(UNITS[e.name])
    if isinstance(e, Quantity):
        return e.value * si(e.unit)
    args = [si_value(a, point) for a in e.args]
    return {"+": lambda: args[0] + args[1], "-": lambda: args[0] - args[1],
            "*": lambda: args[0] * args[1], "/": lambda: args[0] / args[1],
            "min": lambda: min(args), "max": lambda: max(args), "abs": lambda: abs(args[0]),
            "neg": lambda: -args[0]}[e.op]()


def si_truth(c: Compare, point) -> bool:
    a, b = si_value(c.left, point), si_value(c.right, point)
    return {"<=": a <= b, "<": a < b, ">=": a >= b, ">": a > b}[c.op]


@SETTINGS
@given(well_dimensioned(), st.integers(0, 2**32 - 1))
def test_well_dimensioned_assertions_are_accepted_and_mean_what_si_says(c, seed):
    text = to_text(c)
    resolved = parse(text, units=UNITS)
    rng = np.random.default_rng(seed)
    point = {n: Fraction(int(rng.integers(1, 200)), int(rng.integers(1, 7))) for n in UNITS}
    try:
        expected = si_truth(c, point)
    except ZeroDivisionError:
        assume(False)
    columns = {n: np.array([v], dtype=object) for n, v in point.items()}
    assert bool(evaluate(resolved, columns)) == expected, (text, point)


@SETTINGS
@given(ill_dimensioned())
def test_ill_dimensioned_assertions_are_refused(c):
    with pytest.raises(ExpressionError, match="unlike dimensions"):
        parse(to_text(c), units=UNITS)


@pytest.mark.parametrize(("text", "expected"), [
    ("v1 <= 100 km/h", "v1 <= (250/9)"),
    ("v2 <= 10 m/s", "v2 <= 36"),
    ("lx >= 1 lux", "lx >= 1"),
    ("d1 <= 1 mile", "d1 <= 1609.344"),
    ("v1 + v2 <= 3 m/s", "v1 + (5/18) * v2 <= 3"),  # another unit is scaled exactly
    ("v1 + v2 <= 0", "v1 + (5/18) * v2 <= 0"),  # 0 is 0 in every unit
    ("v1 + 18 km/h <= 30", "v1 + 5 <= 30"),  # a literal's unit is converted: 30 is m/s
    ("18 km/h + v1 <= 30", "5 + v1 <= 30"),  # in either order
    ("a1 <= 1 g0", "a1 <= 9.80665"),
    ("v1 <= 30", "v1 <= 30"),  # a bare number takes the unit of what it meets
    ("d1 <= v1 * 2 s", "d1 <= v1 * 2"),
    ("d1 <= 3 [km]", "d1 <= 3000"),
])
def test_literals_are_converted_exactly(text, expected):
    assert to_text(parse(text, units=UNITS)) == expected


def test_unit_literals_need_declared_units():
    with pytest.raises(ExpressionError, match="needs the units of the variables"):
        parse("v <= 100 km/h")


def test_library_assertions_are_dimension_checked():
    from simcred.contracts.library import Library
    from simcred.errors import SimcredError

    spec = {"variables": {"v": {"unit": "m/s"}, "q": {"unit": "m"}},
            "components": {"I": {"inputs": ["v"], "outputs": ["q"]}},
            "models": {"M": {"implements": "I", "cost": 1,
                             "contract": {"assumption": "v <= 100 km/h", "guarantee": "q <= v"}}}}
    with pytest.raises(SimcredError, match="models.M.contract: guarantee: .*unlike dimensions"):
        Library.from_dict(spec)
    spec["models"]["M"]["contract"]["guarantee"] = "q <= v * 1 s + 5 cm"
    lib = Library.from_dict(spec)
    assert to_text(lib.model_contracts["M"].guarantee) == "q <= v * 1 + 0.05"
    assert to_text(lib.model_contracts["M"].assumption) == "v <= (250/9)"


# -- operand order never changes meaning (issue 28, item 6) ------------------------------------


@pytest.mark.parametrize("text", ["v1 + v2 <= 3", "v2 + v1 <= 3", "3 >= v1 + v2",
                                  "max(v1, v2) <= 3", "(v1 + v2) * 2 <= 3",
                                  "1 km/h + 1 mph + 3 <= 9 m/s", "v1 - v2 + 1 <= 2 m/s",
                                  "v1 + 1 <= v2"])
def test_a_bare_number_among_operands_of_different_units_is_refused(text):
    with pytest.raises(ExpressionError, match="bare number .* operand order"):
        parse(text, units=UNITS)


def family_terms(dim: str):
    """Operands of one dimension: its variables, literals in its units and bare numbers."""
    return st.one_of(st.sampled_from([Var(v) for v in VARIABLES[dim]]),
                     st.builds(Quantity, positive, st.sampled_from(LITERAL_UNITS[dim])),
                     st.builds(Num, positive))


SPEED_TERMS = family_terms("speed")


def _sum(terms):
    out = terms[0]
    for t in terms[1:]:
        out = Arith("+", (out, t))
    return out


def _meaning(terms, op, right, points):
    """'refused', or the truth values at ``points`` of ``sum(terms) op right``."""
    try:
        resolved = parse(to_text(Compare(op, _sum(terms), right)), units=UNITS)
    except ExpressionError as exc:
        assert "operand order" in str(exc), str(exc)
        return "refused"
    columns = {n: np.array([p[n] for p in points], dtype=object) for n in UNITS}
    return tuple(bool(x) for x in np.asarray(evaluate(resolved, columns)).reshape(-1))


@SETTINGS
@given(st.lists(SPEED_TERMS, min_size=2, max_size=5), SPEED_TERMS,
       st.sampled_from(["<=", "<", ">=", ">"]), st.randoms(use_true_random=False))
def test_operand_order_never_changes_meaning(terms, right, op, rnd):
    """Every permutation of a sum's operands (and the mirrored comparison) is refused alike or
    true at the same points (exact rationals, no rounding)."""
    _check_order(terms, right, op, rnd)


@SETTINGS
@given(st.sampled_from(["ratio", "temperature difference"]).flatmap(
    lambda dim: st.tuples(st.lists(family_terms(dim), min_size=2, max_size=5),
                          family_terms(dim))),
    st.sampled_from(["<=", "<", ">=", ">"]), st.randoms(use_true_random=False))
def test_operand_order_never_changes_meaning_with_percent_and_delta_units(sum_and_right, op,
                                                                           rnd):
    """The same with ratios (dimensionless, %, percent, permille) and temperature differences
    (delta_degC, delta_degF, K, Δ°C)."""
    terms, right = sum_and_right
    _check_order(terms, right, op, rnd)


def _check_order(terms, right, op, rnd):
    points = [{n: Fraction(rnd.randint(0, 300), rnd.randint(1, 7)) for n in UNITS}
              for _ in range(6)]
    mirror = {"<=": ">=", "<": ">", ">=": "<=", ">": "<"}
    first = _meaning(terms, op, right, points)
    orders = [terms[::-1], rnd.sample(terms, len(terms)), rnd.sample(terms, len(terms))]
    for order in orders:
        assert _meaning(order, op, right, points) == first, (terms, order)
    try:  # right op sum(terms)
        resolved = parse(to_text(Compare(mirror[op], right, _sum(terms))), units=UNITS)
    except ExpressionError:
        assert first == "refused"
        return
    columns = {n: np.array([p[n] for p in points], dtype=object) for n in UNITS}
    assert tuple(bool(x) for x in np.asarray(evaluate(resolved, columns)).reshape(-1)) == first


def test_the_order_test_sees_accepted_sums_with_bare_numbers():
    """Not every case is refused: a bare number next to one unit is accepted in any order."""
    points = [{n: Fraction(k) for n in UNITS} for k in range(6)]
    terms = [Var("v1"), Num(Fraction(3)), Quantity(Fraction(18), "km/h")]
    meaning = _meaning(terms, "<=", Num(Fraction(10)), points)
    assert meaning == (True, True, True, False, False, False)  # v1 + 3 + 5 <= 10 ⇔ v1 <= 2
    assert _meaning(terms[::-1], "<=", Num(Fraction(10)), points) == meaning


# -- % and delta_degC (issue 28, item 6) ---------------------------------------------------------


@pytest.mark.parametrize(("source", "target", "by_hand"), [
    ("%", "dimensionless", Fraction(1, 100)), ("percent", "dimensionless", Fraction(1, 100)),
    ("%", "permille", 10), ("delta_degC", "K", 1), ("delta_degC", "delta_degF", Fraction(9, 5)),
    ("delta_degF", "K", Fraction(5, 9)), ("Δ°C", "kelvin", 1), ("%/s", "1/min", Fraction(6, 10)),
    ("delta_degC/s", "delta_degF/min", 108)])
def test_percent_and_delta_conversions_are_pints_own_numbers(source, target, by_hand):
    from simcred.contracts.units import factor, unit

    expected = Fraction(_registry().Quantity(Fraction(1), source).to(target).magnitude)
    assert factor(unit(source), unit(target)) == expected == by_hand


@pytest.mark.parametrize(("text", "expected"), [
    ("r1 <= 5 %", "r1 <= 0.05"),  # % is a unit wherever a unit can be written
    ("r1 <= 5%", "r1 <= 0.05"),
    ("r2 <= 5 %", "r2 <= 5"),
    ("r2 <= 5", "r2 <= 5"),  # a bare number next to a % variable is in %
    ("r1 <= 5 [%]", "r1 <= 0.05"),
    ("r2 <= r1", "r2 <= 100 * r1"),
    ("r3 <= r2", "r3 <= r2"),  # percent and % are one unit
    ("d1 <= 5 % * d2", "d1 <= 10 * (5 * d2)"),  # 5 % of d2 km in m: 50 d2
    ("dT1 <= 9 delta_degF", "dT1 <= 5"),
    ("dT1 <= 2 K", "dT1 <= 2"),
    ("dT2 <= dT1", "dT2 <= 1.8 * dT1"),
    ("dT1 <= 3 Δ°C", "dT1 <= 3"),
])
def test_percent_and_delta_units_in_assertions(text, expected):
    assert to_text(parse(text, units=UNITS)) == expected


@pytest.mark.parametrize("text", ["T <= 300 K", "T <= dT1", "T - T0 <= 1 delta_degC"])
def test_degC_offsets_stay_refused_where_a_conversion_is_needed(text):
    with pytest.raises(ExpressionError, match="offset: declare temperatures in kelvin"):
        parse(text, units={**UNITS, "T": "degC", "T0": "degC"})


def test_unit_texts_are_parsed_once():
    from simcred.contracts.units import parsed_unit

    parsed_unit.cache_clear()
    for _ in range(200):
        parse("v1 + 18 km/h <= 30 m/s and r2 <= 5 %", units=UNITS)
    info = parsed_unit.cache_info()
    distinct = len(UNITS) + 3  # the declared units and km/h, m/s, %
    assert info.misses <= distinct, info
    assert info.hits >= 199 * distinct, info
