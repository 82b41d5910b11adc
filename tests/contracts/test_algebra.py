"""Contract algebra (paper 003, sec. III; docs/contracts.md "Algebra"): laws on random linear
contracts, verdicts against closed forms and a brute-force oracle, counterexamples checked by
evaluation.

Oracles (all but the last check of receptiveness independent of z3):

* **counterexamples** are substituted into the failing implication and evaluated exactly (numpy
  object arrays of ``Fraction``): the premises must hold and the claim must not;
* **interval contracts** (atoms ``v <= k``, ``v < k``, ``v >= k``, ``v > k`` with integer ``k`` in
  [-3, 3], combined with ``and``/``or``/chains) are decided by brute force: whether a point
  satisfies any such assertion depends only on the cell of each coordinate among the integers
  -3..3, so the 15 values -3.5, -3, ..., 3.5 per variable represent all reals, and "valid" means
  "true on the 15^n grid". The same grid decides receptiveness (∀ free ∃ others), and a failed
  receptiveness check's values are confirmed to admit no completion (a quantifier-free query);
* **closed forms** for one-interval contracts (subset conditions, empty intervals included) and for
  receptiveness of ``a*x + b*y <= c``.

Every property test runs twice: a quick sample (fast suite) and the full, seeded run
(``@pytest.mark.slow``, still in CI). The full runs draw 11,385 random linear contracts (7,352 of
them interval contracts), not counting those derived from them; ``pytest -s`` prints the count.
"""

import itertools
import json
import math
from collections import Counter
from fractions import Fraction

import numpy as np
import pytest
import z3
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from simcred.contracts.algebra import (
    Contract,
    Status,
    Verdict,
    compatible,
    compose_all,
    consistent,
    equivalent,
    receptive,
    refines,
    valid,
)
from simcred.contracts.evaluate import evaluate
from simcred.contracts.expr import (
    ExpressionError,
    conjoin,
    conjuncts,
    disjoin,
    implies,
    negate,
    to_text,
    variables,
)
from simcred.contracts.parse import parse
from simcred.contracts.smt import to_z3, z3_variables

SETTINGS = settings(derandomize=True, database=None, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much,
                                           HealthCheck.data_too_large])
GENERATED = Counter()
VARIABLE_SETS = (("x", "y"), ("x", "y", "z"))
GRID = np.arange(-3.5, 3.75, 0.5)  # one representative per cell of the reals cut at -3..3


def law(examples: int) -> settings:
    return settings(SETTINGS, max_examples=examples)


def sizes(full: int, quick: int = 10):
    """A quick sample for the fast suite and the full seeded run (slow, still in CI)."""
    return [pytest.param(quick, id="quick"),
            pytest.param(full, id="full", marks=pytest.mark.slow)]


@pytest.fixture(scope="module", autouse=True)
def _count_generated_contracts():
    yield
    print(f"\n{__name__}: {GENERATED['linear']} random linear contracts, "
          f"{GENERATED['interval']} of them interval contracts")


# -- strategies ---------------------------------------------------------------------------------


@st.composite
def linear_atoms(draw, names):
    """``a*x + b*y + c*z <= d`` (sometimes ``<``) with small integer coefficients."""
    coefficients = draw(st.lists(st.integers(-3, 3), min_size=len(names), max_size=len(names)))
    lhs = " + ".join(f"{a}*{n}" for a, n in zip(coefficients, names, strict=True) if a) or "0"
    return f"{lhs} {draw(st.sampled_from(('<=', '<=', '<=', '<')))} {draw(st.integers(-4, 4))}"


@st.composite
def interval_atoms(draw, names):
    name = draw(st.sampled_from(names))
    lo, hi = draw(st.integers(-3, 3)), draw(st.integers(-3, 3))
    return draw(st.sampled_from([f"{name} <= {hi}", f"{name} < {hi}", f"{name} >= {lo}",
                                 f"{name} > {lo}", f"{lo} <= {name} <= {hi}"]))


@st.composite
def assertions(draw, atoms):
    """``true`` (one time in seven) or an and/or of one to three atoms."""
    if draw(st.integers(0, 6)) == 0:
        return "true"
    parts = draw(st.lists(atoms, min_size=1, max_size=3))
    return f" {draw(st.sampled_from(('and', 'or')))} ".join(parts)


@st.composite
def contract_tuples(draw, count, kind="linear"):
    """``count`` random contracts over the same two or three variables."""
    names = draw(st.sampled_from(VARIABLE_SETS))
    atoms = (linear_atoms if kind == "linear" else interval_atoms)(names)
    out = tuple(Contract.from_strings(draw(assertions(atoms)), draw(assertions(atoms)))
                for _ in range(count))
    GENERATED["linear"] += count  # interval contracts are linear contracts too
    if kind == "interval":
        GENERATED["interval"] += count
    return names, out


@st.composite
def refining(draw, contract, names):
    """A contract that refines ``contract`` by construction (assumption weakened by ``or``,
    guarantee strengthened by ``and``), and whether it was built that way (else it is random)."""
    atoms = linear_atoms(names)
    if draw(st.integers(0, 3)) == 0:
        GENERATED["linear"] += 1
        return Contract.from_strings(draw(assertions(atoms)), draw(assertions(atoms))), False
    a, g = contract.assumption, contract.guarantee
    if draw(st.booleans()):
        a = disjoin(a, parse(draw(assertions(atoms))))
    if draw(st.booleans()):
        g = conjoin(g, parse(draw(assertions(atoms))))
    return Contract(a, g), True


@st.composite
def refined(draw, contract, names):
    """A contract that ``contract`` refines by construction (assumption strengthened, guarantee
    weakened), or a random one."""
    atoms = linear_atoms(names)
    if draw(st.integers(0, 3)) == 0:
        GENERATED["linear"] += 1
        return Contract.from_strings(draw(assertions(atoms)), draw(assertions(atoms))), False
    a, g = contract.assumption, contract.guarantee
    if draw(st.booleans()):
        a = conjoin(a, parse(draw(assertions(atoms))))
    if draw(st.booleans()):
        g = disjoin(g, parse(draw(assertions(atoms))))
    return Contract(a, g), True


# -- oracles ------------------------------------------------------------------------------------


def _exact(point):
    return {n: np.array([Fraction(v)], dtype=object) for n, v in point.items()}


def _true_at(e, point) -> bool:
    return bool(np.all(evaluate(e, _exact(point))))


def assert_real_counterexample(verdict: Verdict, premises, claim):
    """A FAILS verdict of ``∧ premises → claim``: the counterexample satisfies every premise,
    violates the claim, and the reported clauses are exactly the violated conjuncts of the claim.
    """
    assert verdict.status is Status.FAILS
    point = verdict.counterexample
    assert point is not None and all(isinstance(v, Fraction) for v in point.values())
    assert set(point) == set().union(variables(claim), *(variables(p) for p in premises))
    assert all(_true_at(p, point) for p in premises), (point, [to_text(p) for p in premises])
    assert not _true_at(claim, point), (point, to_text(claim))
    violated = tuple(to_text(c) for c in conjuncts(claim) if not _true_at(c, point))
    assert verdict.clauses == violated and violated


def check_refines_verdict(verdict: Verdict, refining_c: Contract, refined_c: Contract):
    """A definite refinement verdict whose counterexample (if any) is real."""
    assert verdict.status is not Status.UNKNOWN, verdict.reason
    if verdict.status is Status.FAILS:
        if "assumes more" in verdict.reason:
            assert_real_counterexample(verdict, [refined_c.assumption], refining_c.assumption)
        else:
            assert "guarantees less" in verdict.reason
            assert_real_counterexample(verdict, [refining_c.saturated_guarantee],
                                       refined_c.saturated_guarantee)


def _grid_columns(names):
    mesh = np.meshgrid(*([GRID] * len(names)), indexing="ij")
    return {n: m.ravel() for n, m in zip(names, mesh, strict=True)}


def grid_valid(names, premise, claim) -> bool:
    """``premise → claim`` on every grid point (valid over the reals for interval assertions)."""
    cols = _grid_columns(names)
    shape = cols[names[0]].shape
    p = np.broadcast_to(evaluate(premise, cols), shape)
    c = np.broadcast_to(evaluate(claim, cols), shape)
    return bool(np.all(~p | c))


def grid_refines(names, c2: Contract, c1: Contract) -> bool:
    return (grid_valid(names, c1.assumption, c2.assumption)
            and grid_valid(names, c2.saturated_guarantee, c1.saturated_guarantee))


def grid_receptive(names, assertion, free) -> bool:
    """∀ free ∃ others: assertion, on the grid (one axis per variable)."""
    cols = _grid_columns(names)
    value = np.broadcast_to(evaluate(assertion, cols), cols[names[0]].shape)
    value = value.reshape((len(GRID),) * len(names))
    others = tuple(i for i, n in enumerate(names) if n not in free)
    exists = value.any(axis=others) if others else value
    return bool(np.all(exists))


def assert_no_completion(assertion, free_values, types=None):
    """No values of the other variables satisfy ``assertion`` at ``free_values`` (a quantifier-
    free z3 query, unlike the quantified one of :func:`receptive`)."""
    env = z3_variables(variables(assertion), types)
    solver = z3.Solver()
    solver.add(to_z3(assertion, env))
    for name, value in free_values.items():
        solver.add(env[name] == (z3.RealVal(f"{value.numerator}/{value.denominator}")
                                 if isinstance(value, Fraction) else value))
    assert solver.check() == z3.unsat, (to_text(assertion), free_values)


def _sample_points(names, seed, n=64):
    rng = np.random.default_rng(seed)
    return {name: np.array([Fraction(int(p), int(q)) for p, q in zip(
        rng.integers(-12, 13, n), rng.integers(1, 4, n), strict=True)], dtype=object)
        for name in names}


def assert_holds_on_samples(names, seed, premises, claim):
    """A HOLDS verdict cannot be contradicted at random rational points."""
    cols = _sample_points(names, seed)
    ok = np.broadcast_to(evaluate(implies(conjoin(*premises), claim), cols), (64,))
    assert ok.all(), {n: c[~ok][0] for n, c in cols.items()}


# -- laws on random linear contracts ------------------------------------------------------------


@pytest.mark.parametrize("examples", sizes(400))
def test_refinement_is_reflexive(examples):
    @law(examples)
    @given(contract_tuples(1))
    def check(drawn):
        (c,) = drawn[1]
        assert refines(c, c).holds

    check()


@pytest.mark.parametrize("examples", sizes(150))
def test_saturation_preserves_meaning(examples):
    @law(examples)
    @given(contract_tuples(1))
    def check(drawn):
        (c,) = drawn[1]
        assert equivalent(c, c.saturate()).holds

    check()


@pytest.mark.parametrize("examples", sizes(300))
def test_refinement_is_transitive(examples):
    seen = Counter()

    @law(examples)
    @given(st.data())
    def check(data):
        names, (c3,) = data.draw(contract_tuples(1))
        c2, built2 = data.draw(refining(c3, names))
        c1, built1 = data.draw(refining(c2, names))
        r12, r23, r13 = refines(c1, c2), refines(c2, c3), refines(c1, c3)
        for verdict, low, high in ((r12, c1, c2), (r23, c2, c3), (r13, c1, c3)):
            check_refines_verdict(verdict, low, high)
        assert r12.holds or not built1  # by construction
        assert r23.holds or not built2
        if r12.holds and r23.holds:
            assert r13.holds
        seen[r12.holds, r23.holds, r13.holds] += 1

    check()
    assert seen[True, True, True] >= examples / 4  # the premise is not vacuous
    assert sum(v for k, v in seen.items() if not k[2]) >= 1 or examples < 100


@pytest.mark.parametrize("examples", sizes(150))
def test_composition_is_commutative_up_to_mutual_refinement(examples):
    @law(examples)
    @given(contract_tuples(2))
    def check(drawn):
        c1, c2 = drawn[1]
        assert equivalent(c1.compose(c2), c2.compose(c1)).holds

    check()


@pytest.mark.parametrize("examples", sizes(80))
def test_composition_is_associative_up_to_mutual_refinement(examples):
    @law(examples)
    @given(contract_tuples(3))
    def check(drawn):
        c1, c2, c3 = drawn[1]
        left, right = c1.compose(c2).compose(c3), c1.compose(c2.compose(c3))
        assert equivalent(left, right).holds
        assert equivalent(compose_all([c1, c2, c3]), left).holds  # the flat form (z3)

    check()


@pytest.mark.parametrize("examples", sizes(40))
def test_flat_composition_equals_the_nested_one_and_grows_linearly(examples):
    """compose_all of n contracts is equivalent (z3, mutual refinement) to the pairwise nesting,
    and its tree has 2·Σ|Ci'| + |∧Ai| + O(1) nodes, while the nesting roughly doubles per
    contract."""
    @law(examples)
    @given(contract_tuples(4))
    def check(drawn):
        items = list(drawn[1])
        nested = items[0]
        for c in items[1:]:
            nested = nested.compose(c)
        flat = compose_all(items)
        assert equivalent(flat, nested).holds
        parts = sum(_size(c.saturated_guarantee) for c in items)
        assert _size(flat.guarantee) <= parts + 1
        assert _size(flat.assumption) <= sum(_size(c.assumption) for c in items) + parts + 4

    check()


def _size(e) -> int:
    from simcred.contracts.expr import children

    return 1 + sum(_size(c) for c in children(e))


def test_flat_composition_of_20_contracts_is_linear():
    items = [Contract.from_strings(f"0 <= x{k} <= 10", f"x{k + 1} <= x{k} + 1")
             for k in range(20)]
    sizes_ = [_size(compose_all(items[:n]).assumption) for n in (5, 10, 20)]
    step = sizes_[1] - sizes_[0]
    assert sizes_[2] - sizes_[1] == 2 * step  # exactly linear: equal increments per contract


@pytest.mark.parametrize("examples", sizes(100))
def test_composition_is_monotone_under_refinement(examples):
    @law(examples)
    @given(st.data())
    def check(data):
        names, (c1, c2) = data.draw(contract_tuples(2))
        c1_refined, built = data.draw(refining(c1, names))
        if refines(c1_refined, c1).holds:
            assert refines(c1_refined.compose(c2), c1.compose(c2)).holds
        else:
            assert not built

    check()


@pytest.mark.parametrize("examples", sizes(200))
def test_quotient_composes_to_a_refinement_of_the_top_contract_and_is_the_largest(examples):
    seen = Counter()

    @law(examples)
    @given(contract_tuples(3))
    def check(drawn):
        top, c1, c2 = drawn[1]
        q = top.quotient(c1)
        assert refines(c1.compose(q), top).holds  # C1 ⊗ (Ctop / C1) ≼ Ctop
        fits = refines(c1.compose(c2), top)
        check_refines_verdict(fits, c1.compose(c2), top)
        if fits.holds:  # any C2 with C1 ⊗ C2 ≼ Ctop refines the quotient
            assert refines(c2, q).holds
        seen[fits.holds] += 1

    check()
    assert seen[True] >= 1 or examples < 100


@pytest.mark.parametrize("examples", sizes(200))
def test_conjunction_refines_both_operands(examples):
    @law(examples)
    @given(contract_tuples(2))
    def check(drawn):
        c1, c2 = drawn[1]
        both = c1.conjoin(c2)
        assert refines(both, c1).holds and refines(both, c2).holds

    check()


@pytest.mark.parametrize("examples", sizes(100))
def test_conjunction_is_the_greatest_shared_refinement(examples):
    seen = Counter()

    @law(examples)
    @given(st.data())
    def check(data):
        names, (c,) = data.draw(contract_tuples(1))
        c1, _ = data.draw(refined(c, names))
        c2, _ = data.draw(refined(c, names))
        if refines(c, c1).holds and refines(c, c2).holds:
            assert refines(c, c1.conjoin(c2)).holds
            seen["premise"] += 1

    check()
    assert seen["premise"] >= examples / 3


@pytest.mark.parametrize("examples", sizes(500))
def test_every_counterexample_is_real_and_every_proof_survives_sampling(examples):
    seen = Counter()

    @law(examples)
    @given(contract_tuples(2), st.integers(0, 2**32))
    def check(drawn, seed):
        names, (c1, c2) = drawn
        verdict = refines(c1, c2)
        check_refines_verdict(verdict, c1, c2)
        if verdict.holds:
            assert_holds_on_samples(names, seed, [c2.assumption], c1.assumption)
            assert_holds_on_samples(names, seed, [c1.saturated_guarantee],
                                    c2.saturated_guarantee)
        direct = valid([c1.assumption, c2.guarantee], c1.guarantee)
        premises = [c for p in (c1.assumption, c2.guarantee) for c in conjuncts(p)]
        assert direct.status is not Status.UNKNOWN
        if direct.status is Status.FAILS:
            assert_real_counterexample(direct, premises, c1.guarantee)
        else:  # the unsat core names premises, and it alone implies the claim
            assert set(direct.clauses) <= {to_text(p) for p in premises}
            assert valid([parse(t) for t in direct.clauses], c1.guarantee).holds
            assert_holds_on_samples(names, seed, premises, c1.guarantee)
        seen[verdict.status, direct.status] += 1

    check()
    if examples >= 100:
        assert all(seen[a, b] >= 1 for a, b in itertools.product(
            (Status.HOLDS, Status.FAILS), repeat=2)), seen


# -- interval contracts: closed forms and brute force -------------------------------------------


bounds = st.none() | st.integers(-3, 3)
intervals = st.tuples(bounds, bounds)


def _interval_text(name, interval):
    lo, hi = interval
    if lo is None and hi is None:
        return "true"
    if lo is None:
        return f"{name} <= {hi}"
    if hi is None:
        return f"{name} >= {lo}"
    return f"{lo} <= {name} <= {hi}"


def _lo(i):
    return -math.inf if i[0] is None else i[0]


def _hi(i):
    return math.inf if i[1] is None else i[1]


def _empty(i):
    return _lo(i) > _hi(i)


def _subset(i, j):
    return _empty(i) or (_lo(j) <= _lo(i) and _hi(i) <= _hi(j))


def _meet(i, j):
    lo, hi = max(_lo(i), _lo(j)), min(_hi(i), _hi(j))
    return (None if lo == -math.inf else lo, None if hi == math.inf else hi)


def _inside(value, i):
    return _lo(i) <= value <= _hi(i)


def _interval_contract(a_name, a, g_name, g):
    GENERATED["linear"] += 1
    GENERATED["interval"] += 1
    return Contract.from_strings(_interval_text(a_name, a), _interval_text(g_name, g))


@pytest.mark.parametrize("examples", sizes(1800))
def test_interval_refinement_matches_the_closed_form(examples):
    """C = (x ∈ A, y ∈ G). With saturated guarantees G' = (x ∉ A) ∨ (y ∈ G):
    C2 ≼ C1  iff  A1 ⊆ A2  and  (A1 = ∅ or G2 ⊆ G1)."""
    seen = Counter()

    @law(examples)
    @given(intervals, intervals, intervals, intervals)
    def check(a1, g1, a2, g2):
        c1, c2 = _interval_contract("x", a1, "y", g1), _interval_contract("x", a2, "y", g2)
        verdict = refines(c2, c1)
        check_refines_verdict(verdict, c2, c1)
        assumption_ok = _subset(a1, a2)
        expected = assumption_ok and (_empty(a1) or _subset(g2, g1))
        assert verdict.holds is expected, (str(c2), str(c1))
        seen[expected, _empty(a1), _empty(g2)] += 1
        if not expected:
            cex = verdict.counterexample
            if not assumption_ok:  # x ∈ A1 \ A2
                assert "assumes more" in verdict.reason
                assert _inside(cex["x"], a1) and not _inside(cex["x"], a2)
            else:  # x ∈ A1 and y ∈ G2 \ G1
                assert "guarantees less" in verdict.reason
                assert "x" not in cex or _inside(cex["x"], a1)
                assert _inside(cex["y"], g2) and not _inside(cex["y"], g1)

    check()
    if examples >= 100:
        # holds with and without empty intervals; fails only when A1 is not empty
        assert len(seen) == 6 and not any(k[0] is False and k[1] for k in seen), seen


@pytest.mark.parametrize("examples", sizes(1500))
def test_interval_refinement_on_one_variable_matches_the_closed_form(examples):
    """C = (x ∈ A, x ∈ G): G' = (x ∉ A) ∨ (x ∈ G), so
    C2 ≼ C1  iff  A1 ⊆ A2  and  A1 ∩ G2 ⊆ G1."""

    @law(examples)
    @given(intervals, intervals, intervals, intervals)
    def check(a1, g1, a2, g2):
        c1, c2 = _interval_contract("x", a1, "x", g1), _interval_contract("x", a2, "x", g2)
        verdict = refines(c2, c1)
        check_refines_verdict(verdict, c2, c1)
        expected = _subset(a1, a2) and _subset(_meet(a1, g2), g1)
        assert verdict.holds is expected, (str(c2), str(c1))
        if not expected and _subset(a1, a2):  # x ∈ (A1 ∩ G2) \ G1
            x = verdict.counterexample["x"]
            assert _inside(x, _meet(a1, g2)) and not _inside(x, g1)

    check()


@pytest.mark.parametrize("examples", sizes(200))
def test_interval_contract_operations_match_brute_force(examples):
    """Refinement of random interval contracts and of their compositions, quotients and
    conjunctions: z3's verdict equals the grid oracle's."""
    seen = Counter()

    @law(examples)
    @given(contract_tuples(3, kind="interval"))
    def check(drawn):
        names, (c1, c2, c3) = drawn
        claims = [(c1, c2), (c1.compose(c2), c3), (c3.quotient(c1), c2),
                  (c2, c3.quotient(c1)), (c1.conjoin(c2), c3), (c3, c1.compose(c2))]
        for low, high in claims:
            verdict = refines(low, high)
            check_refines_verdict(verdict, low, high)
            assert verdict.holds is grid_refines(names, low, high), (str(low), str(high))
            seen[verdict.holds] += 1

    check()
    assert seen[True] >= 1 and seen[False] >= 1


@pytest.mark.parametrize("examples", sizes(150))
def test_receptiveness_of_interval_assertions_matches_brute_force(examples):
    @law(examples)
    @given(contract_tuples(1, kind="interval"), st.data())
    def check(drawn, data):
        names, (c,) = drawn
        free = data.draw(st.sets(st.sampled_from(names)))
        for assertion in (c.assumption, c.saturated_guarantee):
            verdict = receptive(assertion, free)
            assert verdict.status is not Status.UNKNOWN
            assert verdict.holds is grid_receptive(names, assertion, free), (
                to_text(assertion), free)
            if not verdict.holds:
                assert set(verdict.counterexample) == free & variables(assertion)
                assert_no_completion(assertion, verdict.counterexample)
        assert compatible(c, free).holds is grid_receptive(names, c.assumption, free)
        assert consistent(c, free).holds is grid_receptive(names, c.saturated_guarantee, free)

    check()


# -- receptiveness: closed forms ----------------------------------------------------------------


@pytest.mark.parametrize("examples", sizes(100))
def test_receptiveness_of_a_half_plane_matches_the_closed_form(examples):
    """a*x + b*y <= c is receptive to {x} iff b != 0 or (a == 0 and c >= 0) (some y always
    exists, or the constraint does not involve x and holds); to {x, y} iff a == b == 0 and
    c >= 0; to {} iff it is satisfiable."""

    @law(examples)
    @given(st.integers(-2, 2), st.integers(-2, 2), st.integers(-2, 2),
           st.sampled_from(["<=", "=="]))
    def check(a, b, c, op):
        e = parse(f"{a}*x + {b}*y {op} {c}")
        holds_at_zero = c >= 0 if op == "<=" else c == 0
        expected = {
            frozenset(): a != 0 or b != 0 or holds_at_zero,
            frozenset("x"): b != 0 or (a == 0 and holds_at_zero),
            frozenset("y"): a != 0 or (b == 0 and holds_at_zero),
            frozenset("xy"): a == 0 and b == 0 and holds_at_zero,
        }
        for free, holds in expected.items():
            verdict = receptive(e, free)
            assert verdict.holds is holds, (to_text(e), set(free))
            if not holds:
                assert set(verdict.counterexample) == set(free)
                assert_no_completion(e, verdict.counterexample)

    check()


@pytest.mark.parametrize(("assertion", "free", "holds"), [
    ("x <= u", ["u"], True),  # any u: take x = u
    ("x <= u", ["x"], True),  # any x: take u = x (u is unbounded too)
    ("x <= u", ["x", "u"], False),
    ("x <= u", [], True),
    ("1 <= x - u <= 2", ["u"], True),  # a tracking error bound: any input can be followed
    ("2 <= x - u <= 1", ["u"], False),  # an empty band
    ("0 <= x <= 10", ["x"], False),
    ("0 <= x <= 10", ["u"], True),  # u does not occur: nothing to choose
    ("0 <= x <= 10 and y >= 0", ["y"], False),
    ("x >= v and x <= u", ["u"], True),
    ("x >= v and x <= u", ["u", "v"], False),
    ("x * x == u", ["u"], False),  # no real square root of a negative u
    ("x * x * x == u", ["u"], True),
    ("false", [], False),
    ("true", ["x"], True),
])
def test_receptiveness_closed_forms(assertion, free, holds):
    e = parse(assertion)
    verdict = receptive(e, free)
    assert verdict.holds is holds
    if not holds:
        assert set(verdict.counterexample) == set(free) & variables(e)
        assert_no_completion(e, verdict.counterexample)


def test_compatibility_and_consistency_closed_forms():
    # a component controlling y: it may not assume anything about y
    assert compatible(Contract.from_strings("0 <= u <= 10", "y == 2 * u"), ["y"]).holds
    incompatible = compatible(Contract.from_strings("0 <= u <= 10 and y >= 0", "y == u"), ["y"])
    assert incompatible.status is Status.FAILS and incompatible.counterexample["y"] < 0
    # consistency: the saturated guarantee can be met for every input u
    assert consistent(Contract.from_strings("0 <= u <= 10", "y == 2 * u"), ["u"]).holds
    assert consistent(Contract.from_strings("u >= 0", "0 <= y <= u"), ["u"]).holds  # u < 0: ¬A
    inconsistent = consistent(Contract.from_strings("true", "0 <= y <= u"), ["u"])
    assert inconsistent.status is Status.FAILS and inconsistent.counterexample["u"] < 0
    # saturation makes the paper's remark concrete: G' = ¬A ∨ G constrains nothing outside A
    assert consistent(Contract.from_strings("u >= 0", "false"), ["u"]).status is Status.FAILS
    assert consistent(Contract.from_strings("u >= 0", "false"), []).holds


# -- exact numbers, types, messages, timeouts ---------------------------------------------------


def test_numbers_are_exact_in_refinement():
    c = Contract.from_strings("true", "x <= 0.2")
    assert refines(c, c).holds
    assert equivalent(Contract.from_strings("true", "x <= 0.1 + 0.2"),
                      Contract.from_strings("true", "x <= 0.3")).holds
    tighter = Contract.from_strings("true", "x <= 0.3")
    looser = Contract.from_strings("true", "x <= 0.30000000000000004")  # float(0.1 + 0.2)
    assert refines(tighter, looser).holds
    verdict = refines(looser, tighter)
    assert verdict.status is Status.FAILS
    assert Fraction(3, 10) < verdict.counterexample["x"] <= Fraction("0.30000000000000004")


def test_integer_types_change_the_verdict():
    premise, claim = parse("0 < n and n < 1"), parse("false")
    assert valid([premise], claim, types={"n": "int"}).holds
    real = valid([premise], claim)
    assert_real_counterexample(real, [premise], claim)
    premise, claim = parse("2 * n == x"), parse("x != 3")
    assert valid([premise], claim, types={"n": "int"}).holds  # x is even
    fails = valid([premise], claim)
    assert_real_counterexample(fails, [premise], claim)
    assert fails.counterexample == {"n": Fraction(3, 2), "x": Fraction(3)}
    with_ints = valid([premise], parse("x != 4"), types={"n": "int", "x": "int"})
    assert with_ints.status is Status.FAILS and with_ints.counterexample == {"n": 2, "x": 4}
    assert all(type(v) is int for v in with_ints.counterexample.values())


def test_a_holding_refinement_names_the_clauses_it_used():
    top = Contract.from_strings("0 <= v <= 30", "e <= 0.5")
    impl = Contract.from_strings("0 <= v <= 40", "e <= 0.1 and d >= 0")
    verdict = refines(impl, top)
    assert verdict.holds and verdict.counterexample is None
    assert "0 <= v" in verdict.clauses and "v <= 30" in verdict.clauses
    data = verdict.to_dict()
    assert json.loads(json.dumps(data)) == data and data["verdict"] == "holds"
    failing = refines(top, impl)
    assert failing.status is Status.FAILS and "assumes more" in failing.reason
    data = failing.to_dict()
    assert json.loads(json.dumps(data)) == data
    assert all(isinstance(v, float) for v in data["counterexample"].values())


def test_contract_parse_errors_name_the_contract_and_the_part():
    with pytest.raises(ExpressionError) as info:
        Contract.from_strings("0 <= v <= 30", "e <=", name="M1")
    assert str(info.value).startswith("M1: guarantee: line 1, column")
    with pytest.raises(ExpressionError) as info:
        Contract.from_strings("v <= w", "e <= 1", declared={"v": 1, "e": 1})
    assert str(info.value).startswith("contract: assumption: undeclared variable 'w'")
    with pytest.raises(ExpressionError) as info:
        Contract.from_strings("v + 1", "e <= 1", where="lib.yaml: models.M2")
    assert str(info.value).startswith("lib.yaml: models.M2: assumption: 'v + 1' is a number")


HARD = "x >= 1 and y >= 1 and z >= 1 and x^3 + y^3 == z^3"  # no integer solutions (Fermat)
INTS = dict.fromkeys("xyz", "int")


def test_timeouts_give_unknown_or_a_sound_answer_and_never_raise():
    premise, claim = parse(HARD), parse("false")
    verdict = valid([premise], claim, types=INTS, timeout_ms=1)
    assert verdict.status in (Status.UNKNOWN, Status.HOLDS)  # a counterexample would be false
    json.dumps(verdict.to_dict())
    if verdict.status is Status.UNKNOWN:
        assert not verdict.holds and verdict.counterexample is None and verdict.reason

    nonlinear = Contract.from_strings("x^2 + y^2 <= 4 and x*y*z >= 1",
                                      "x^3 * y - z^5 * x <= 3 or x^4 * z^2 >= y^7")
    other = Contract.from_strings("x^2 * y^3 <= z", "x^5 - y^3 * z^2 >= 1 or z^3 * x <= 2")
    for verdict in (refines(nonlinear, other, timeout_ms=1),
                    refines(other, nonlinear, timeout_ms=1),
                    equivalent(nonlinear, other, timeout_ms=1),
                    receptive(parse("x^5 + u*x^3 - u^2*x*y == 7 and x*u^3 >= y^2"), ["u"],
                              timeout_ms=1),
                    compatible(nonlinear, ["z"], timeout_ms=1),
                    consistent(other, ["x", "y"], timeout_ms=1),
                    refines(Contract(parse(HARD), parse("false")),
                            Contract(parse(HARD), parse("x >= 2")), types=INTS, timeout_ms=1)):
        assert verdict.status in tuple(Status)
        json.dumps(verdict.to_dict())


def test_operations_follow_the_saturated_definitions():
    """The ASTs the operations build, against the formulas of docs/contracts.md "Algebra"."""
    c1 = Contract.from_strings("u >= 0", "y <= u")
    c2 = Contract.from_strings("y >= 0", "z == y")
    g1, g2 = implies(c1.assumption, c1.guarantee), implies(c2.assumption, c2.guarantee)
    assert c1.saturated_guarantee == g1
    assert Contract.from_strings("true", "y <= u").saturated_guarantee == parse("y <= u")
    composed = c1.compose(c2)
    assert composed.guarantee == conjoin(g1, g2)
    assert composed.assumption == disjoin(conjoin(c1.assumption, c2.assumption),
                                          negate(conjoin(g1, g2)))
    q = composed.quotient(c1)
    a_q = conjoin(composed.assumption, g1)
    assert q.assumption == a_q
    assert q.guarantee == disjoin(conjoin(c1.assumption, composed.saturated_guarantee),
                                  negate(a_q))
    both = c1.conjoin(c2)
    assert both.assumption == disjoin(c1.assumption, c2.assumption)
    assert both.guarantee == conjoin(g1, g2)
    assert equivalent(c1.saturate(), c1).holds and c1.saturate() != c1


def test_nonlinear_counterexamples_are_decimal_approximations_of_algebraic_numbers():
    """Documented limitation: an irrational model value comes back as a 20-digit decimal, so it
    satisfies a nonlinear premise only approximately."""
    verdict = valid([parse("x * x == 2")], parse("x < 0"))
    assert verdict.status is Status.FAILS
    x = verdict.counterexample["x"]
    assert abs(x * x - 2) < Fraction(1, 10**18) and x > 0
