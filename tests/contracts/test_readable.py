"""Readable forms (issue 15, item 6): every rewrite is an equivalence (checked with z3 on random
assertions), quotients print as intervals, and the CLI shows decimals in text and exact rationals
in JSON."""

from __future__ import annotations

import json
from fractions import Fraction
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from simcred.cli import run
from simcred.contracts import readable
from simcred.contracts.algebra import Contract, equivalent, valid
from simcred.contracts.expr import Arith, Compare, Logic, Num, Var, conjoin
from simcred.contracts.parse import parse

VEHICLE = Path(__file__).resolve().parents[2] / "examples" / "contracts" / "vehicle.yaml"
SETTINGS = settings(derandomize=True, database=None, deadline=None, max_examples=200,
                    suppress_health_check=[HealthCheck.too_slow])

numbers = st.builds(Fraction, st.integers(-6, 6), st.sampled_from([1, 2, 4, 5]))
variable = st.sampled_from([Var("x"), Var("y")])
term = st.one_of(variable, st.builds(lambda c, v: Arith("*", (Num(c), v)),
                                     numbers.filter(bool), variable),
                 st.builds(lambda v: Arith("neg", (v,)), variable))
atoms = st.one_of(
    st.builds(Compare, st.sampled_from(["<=", "<", ">=", ">", "==", "!="]), term,
              st.builds(Num, numbers)),
    st.builds(Compare, st.sampled_from(["<=", "<", ">="]), st.builds(Num, numbers), variable))


def _nodes(c):
    return st.one_of(
        st.builds(lambda xs: Logic("and", tuple(xs)), st.lists(c, min_size=2, max_size=3)),
        st.builds(lambda xs: Logic("or", tuple(xs)), st.lists(c, min_size=2, max_size=3)),
        st.builds(lambda a: Logic("not", (a,)), c))


conditions = st.recursive(atoms, _nodes, max_leaves=7)


def same(a, b) -> bool:
    return valid([a], b).holds and valid([b], a).holds


@SETTINGS
@given(conditions)
def test_tidy_is_an_equivalence(e):
    assert same(readable.tidy(e), e)
    assert same(parse(readable.text(e)), e)  # the printed chain form parses back, equivalent


@SETTINGS
@given(conditions, conditions)
def test_within_keeps_the_meaning_under_the_context(e, context):
    simplified = readable.within(e, context)
    assert same(conjoin(context, simplified), conjoin(context, e))


def test_quotient_is_printed_as_intervals(capsys):
    assert run(["contracts", "quotient", str(VEHICLE), "--test-case", "urban_following",
                "--given", "sensor=ideal_sensor"]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert ("assume: 5 <= ego.v <= 15 and -2 <= ego.a_lat <= 2 and -3 <= ego.a_long <= 3 and "
            "sen.model_error <= 1.6 guarantee: ttc.error <= 0.1") in out


def test_quotient_projection_is_the_same_contract_as_printed(capsys):
    assert run(["contracts", "quotient", str(VEHICLE), "--test-case", "cutin",
                "--given", "dynamics=ST", "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    printed = Contract(parse(doc["assumption"]), parse(doc["guarantee"]))
    assert doc["assumption"] == "25 <= ego.v <= 30 and 10 <= obj.range <= 80 and " \
                                "dyn.error <= 0.1"
    assert doc["guarantee"] == "ttc.error <= 0.1"
    assert printed.assumption is not None


def test_a_false_quotient_says_which_given_model_is_out_of_its_domain(capsys):
    assert run(["contracts", "quotient", str(VEHICLE), "--test-case", "cutin", "--given",
                "dynamics=KS"]) == 0
    out = " ".join(capsys.readouterr().out.split())
    assert "guarantee: false" in out
    assert "no missing model can help: KS assumes 'abs(ego.a_long) <= 4'" in out


def test_counterexamples_are_decimals_in_text_and_exact_in_json(capsys):
    figure2 = VEHICLE.parent / "figure2.yaml"
    assert run(["contracts", "refines", str(figure2), "--refining", "M2b", "--refined",
                "M2a"]) == 1
    text = capsys.readouterr().out
    assert "counterexample: " in text
    assert run(["contracts", "refines", str(figure2), "--refining", "M2b", "--refined", "M2a",
                "--json"]) == 1
    doc = json.loads(capsys.readouterr().out)
    for name, value in doc["counterexample"].items():
        assert Fraction(doc["counterexample_exact"][name]) == Fraction(value) or \
            abs(float(Fraction(doc["counterexample_exact"][name])) - value) < 1e-12


def test_equivalent_helper_agrees():
    a = Contract.from_strings("0 <= x <= 2", "y <= 1")
    assert equivalent(a, Contract(readable.tidy(a.assumption), a.guarantee)).holds
