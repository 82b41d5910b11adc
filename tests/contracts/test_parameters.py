"""Parameters of a model (issue 15, item 4): the contract used for reasoning is refined by the
model's contract at every parameter value in the range (sound), and its assumption is the
largest such one (tight), checked with z3 at sampled parameter values and on a grid."""

from __future__ import annotations

from fractions import Fraction

import numpy as np
import pytest

from simcred.contracts.algebra import Contract, refines
from simcred.contracts.configure import configure
from simcred.contracts.evaluate import evaluate
from simcred.contracts.expr import Num, Var, to_text
from simcred.contracts.library import Library
from simcred.errors import SimcredError


def library(assumption: str, guarantee: str, **extra) -> dict:
    return {"variables": {"v": {"unit": "m/s"}, "e": {"unit": "m"}},
            "components": {"I": {"inputs": ["v"], "outputs": ["e"]}},
            "models": {"M": {"implements": "I", "cost": 1,
                             "parameters": {"mu": {"range": [0.5, 1.0]},
                                            "k": {"range": [1, 2], "unit": "m"}},
                             "contract": {"assumption": assumption, "guarantee": guarantee},
                             **extra}},
            "test_cases": {"tc": {"assumption": "0 <= v <= 18", "guarantee": "e <= 0.2"}}}


def substitute(e, values):
    from simcred.contracts.expr import Arith, Compare, Logic

    if isinstance(e, Var) and e.name in values:
        return Num(values[e.name])
    if isinstance(e, Compare):
        return Compare(e.op, substitute(e.left, values), substitute(e.right, values))
    if isinstance(e, Arith | Logic):
        return type(e)(e.op, tuple(substitute(a, values) for a in e.args))
    return e


CASES = [("v <= 40 m/s * mu", "e <= 0.1 * k"),
         ("v <= 40 m/s * mu and v >= 10 m/s * (mu - 0.5)", "e <= 0.1 * k + 0.05 m * mu"),
         ("v <= 30", "e <= 0.1 m + 0.05 * k")]


@pytest.mark.parametrize(("assumption", "guarantee"), CASES)
def test_every_parameter_value_refines_the_contract_used(assumption, guarantee):
    lib = Library.from_dict(library(assumption, guarantee))
    effective = lib.model_contracts["M"]
    units = {"v": "m/s", "e": "m", "mu": "dimensionless", "k": "m"}
    raw = Contract.from_strings(assumption, guarantee, units=units)
    for mu in (Fraction(1, 2), Fraction(3, 4), Fraction(1)):
        for k in (Fraction(1), Fraction(3, 2), Fraction(2)):
            at = Contract(substitute(raw.assumption, {"mu": mu, "k": k}),
                          substitute(raw.guarantee, {"mu": mu, "k": k}))
            assert refines(at, effective).holds, (mu, k, str(effective))


def test_the_assumption_is_the_largest_valid_for_every_value():
    lib = Library.from_dict(library("v <= 40 m/s * mu", "e <= 0.1 * k"))
    effective = lib.model_contracts["M"]
    assert to_text(effective.assumption) == "v <= 20"
    assert to_text(effective.guarantee) == "e <= 0.2"
    grid = np.linspace(0, 45, 181)
    mus = np.linspace(0.5, 1.0, 11)
    every = np.array([all(v <= 40 * mu for mu in mus) for v in grid])
    assert (np.asarray(evaluate(effective.assumption, {"v": grid})) == every).all()


def test_parameters_make_configuration_robust():
    assert configure(Library.from_dict(library("v <= 40 m/s * mu", "e <= 0.1 * k")),
                     "tc").status.value == "holds"
    wide = library("v <= 40 m/s * mu", "e <= 0.1 * k")
    wide["test_cases"]["tc"]["assumption"] = "0 <= v <= 25"  # beyond 20: not for every mu
    assert configure(Library.from_dict(wide), "tc").status.value == "fails"


@pytest.mark.parametrize(("change", "fragment"), [
    ({"parameters": {"mu": {"range": [1.0, 0.5]}}}, "parameters.mu.range"),
    ({"parameters": {"mu": {"range": [0, float("inf")]}}}, "parameters.mu.range"),
    ({"parameters": {"v": {"range": [0, 1]}}}, "also a variable"),
])
def test_bad_parameters_are_one_line_errors(change, fragment):
    spec = library("v <= 30", "e <= 1")
    spec["models"]["M"].update(change)
    with pytest.raises(SimcredError) as info:
        Library.from_dict(spec)
    assert fragment in str(info.value)


def test_nonlinear_parameters_are_refused():
    with pytest.raises(SimcredError, match="cannot eliminate"):
        Library.from_dict(library("v * mu <= 40 m/s", "e <= 1"))
