"""Assume-guarantee contracts and their algebra (Braun et al., paper 003, sec. III; Benveniste et
al. 2018), decided with z3.

A contract is C = (A, G) over declared variables; its saturation is (A, A → G). With saturated
guarantees G' (docs/contracts.md, "Algebra"):

* refinement  C2 ≼ C1  iff  A1 → A2  and  G2' → G1'  are valid;
* composition C1 ⊗ C2 = (A1 ∧ A2 ∨ ¬(G1' ∧ G2'),  G1' ∧ G2');
* quotient    Ctop / C1 = (Atop ∧ G1',  A1 ∧ Gtop' ∨ ¬(Atop ∧ G1'));
* conjunction C1 ∧ C2 = (A1 ∨ A2,  G1' ∧ G2');
* compatibility: A is receptive to the controlled variables (∀ controlled ∃ the others: A);
  consistency: G' is receptive to the uncontrolled variables.

Every check returns a three-valued :class:`Verdict` — holds, fails with a counterexample, or
unknown when the solver gives up or times out — and names the clauses involved. Nothing raises on
a timeout.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from enum import StrEnum
from fractions import Fraction
from typing import Any

from simcred.contracts.expr import (
    Bool,
    Expr,
    conjoin,
    conjuncts,
    degree,
    disjoin,
    implies,
    negate,
    to_text,
    variables,
)
from simcred.contracts.parse import parse
from simcred.contracts.smt import check_quantified, to_z3, z3_variables

DEFAULT_TIMEOUT_MS = 10_000


class Status(StrEnum):
    HOLDS = "holds"
    FAILS = "fails"
    UNKNOWN = "unknown"


@dataclass(frozen=True, slots=True)
class Verdict:
    """Outcome of a check: ``counterexample`` (variable → value) when it fails; ``clauses``: the
    unsat core when it holds, the violated clauses when it fails."""

    status: Status
    counterexample: Mapping[str, Fraction | int | bool] | None = None
    clauses: tuple[str, ...] = ()
    reason: str = ""

    @property
    def holds(self) -> bool:
        return self.status is Status.HOLDS

    def to_dict(self) -> dict[str, Any]:
        def plain(v):
            return v if isinstance(v, bool | int) else float(v)

        def exact(v):
            return v if isinstance(v, bool | int) else str(Fraction(v))

        example = self.counterexample
        return {"verdict": self.status.value,
                "counterexample": None if example is None
                else {k: plain(v) for k, v in example.items()},
                "counterexample_exact": None if example is None
                else {k: exact(v) for k, v in example.items()},
                "clauses": list(self.clauses), "reason": self.reason}


@dataclass(frozen=True, slots=True)
class Contract:
    """C = (A, G). Equality is structural (same ASTs); use :func:`equivalent` for semantics."""

    assumption: Expr
    guarantee: Expr
    name: str = field(default="", compare=False)

    @classmethod
    def from_strings(cls, assumption: str, guarantee: str, *, name: str = "",
                     declared: Mapping[str, Any] | None = None, where: str = "",
                     types: Mapping[str, str] | None = None,
                     units: Mapping[str, str] | None = None) -> Contract:
        """``Contract.from_strings("0 <= v <= 30", "e <= 0.1")``; ``types`` and ``units`` as
        in :func:`~simcred.contracts.expr.parse`."""
        where = where or name or "contract"
        options = {"declared": declared, "types": types, "units": units}
        return cls(parse(assumption, where=f"{where}: assumption", **options),
                   parse(guarantee, where=f"{where}: guarantee", **options), name)

    @property
    def variables(self) -> frozenset[str]:
        return variables(self.assumption) | variables(self.guarantee)

    @property
    def saturated_guarantee(self) -> Expr:
        if self.assumption == Bool(True):
            return self.guarantee
        return implies(self.assumption, self.guarantee)

    def saturate(self) -> Contract:
        return Contract(self.assumption, self.saturated_guarantee, self.name)

    def compose(self, other: Contract) -> Contract:
        """Parallel composition C1 ⊗ C2."""
        g = conjoin(self.saturated_guarantee, other.saturated_guarantee)
        a = disjoin(conjoin(self.assumption, other.assumption), negate(g))
        return Contract(a, g, _join(self.name, "⊗", other.name))

    def quotient(self, part: Contract) -> Contract:
        """Ctop / C1: what a missing part must satisfy so that C1 ⊗ (Ctop / C1) ≼ Ctop."""
        a = conjoin(self.assumption, part.saturated_guarantee)
        g = disjoin(conjoin(part.assumption, self.saturated_guarantee), negate(a))
        return Contract(a, g, _join(self.name, "/", part.name))

    def conjoin(self, other: Contract) -> Contract:
        """Conjunction C1 ∧ C2: refines both (shared refinement)."""
        return Contract(disjoin(self.assumption, other.assumption),
                        conjoin(self.saturated_guarantee, other.saturated_guarantee),
                        _join(self.name, "∧", other.name))

    def __str__(self) -> str:
        label = f"{self.name}: " if self.name else ""
        return f"{label}A: {to_text(self.assumption)} | G: {to_text(self.guarantee)}"


def _join(a: str, op: str, b: str) -> str:
    return f"({a} {op} {b})" if a and b else ""


def compose_all(contracts: Iterable[Contract]) -> Contract:
    """C1 ⊗ … ⊗ Cn in flat form: (∧ Ai ∨ ¬∧ Gi', ∧ Gi'), linear in the contracts' size.

    Equal to the pairwise nesting (composition is associative): nesting gives the guarantee
    (A12 → G12) ∧ G3' with A12 = A1 ∧ A2 ∨ ¬G12, and A12 → G12 is G12; its assumption
    (A1 ∧ A2 ∨ ¬G12) ∧ A3 ∨ ¬G differs from the flat one only by ¬G12 ∧ A3, which ¬G contains.
    The nested closed forms repeat every guarantee in each assumption (the tree grew 2.6× per
    model; 15.6 M nodes at 15 models)."""
    items = list(contracts)
    if len(items) == 1:
        return items[0]
    g = conjoin(*(c.saturated_guarantee for c in items))
    a = disjoin(conjoin(*(c.assumption for c in items)), negate(g))
    names = [c.name for c in items]
    return Contract(a, g, f"({' ⊗ '.join(names)})" if all(names) else "")


# -- checks -------------------------------------------------------------------------------------


def valid(premises: Iterable[Expr], claim: Expr, *, types: Mapping[str, str] | None = None,
          timeout_ms: int = DEFAULT_TIMEOUT_MS) -> Verdict:
    """Is ``∧ premises → claim`` valid? Holds with the premises used (unsat core); fails with a
    counterexample and the clauses of ``claim`` it violates."""
    import z3

    premises = [c for p in premises for c in conjuncts(p)]
    names = set().union(variables(claim), *(variables(p) for p in premises))
    env = z3_variables(names, types)
    solver = z3.Solver()
    solver.set("timeout", int(timeout_ms))
    labels = {}
    for i, clause in enumerate(premises):
        label = z3.Bool(f"__premise_{i}")
        labels[str(label)] = to_text(clause)
        solver.assert_and_track(to_z3(clause, env), label)
    solver.assert_and_track(z3.Not(to_z3(claim, env)), z3.Bool("__claim"))
    result = solver.check()
    if result == z3.unsat:
        core = tuple(labels[str(c)] for c in solver.unsat_core() if str(c) in labels)
        return Verdict(Status.HOLDS, clauses=core)
    if result == z3.sat:
        example = _model_values(solver.model(), env)
        violated = tuple(to_text(c) for c in conjuncts(claim)
                         if z3.is_false(solver.model().eval(to_z3(c, env),
                                                            model_completion=True)))
        return Verdict(Status.FAILS, example, violated)
    return Verdict(Status.UNKNOWN, reason=solver.reason_unknown())


def _model_values(model, env: Mapping[str, Any]) -> dict[str, Fraction | int | bool]:
    import z3

    out = {}
    for name, var in env.items():
        value = model.eval(var, model_completion=True)
        if z3.is_bool(value):
            out[name] = z3.is_true(value)
        elif z3.is_int_value(value):
            out[name] = value.as_long()
        elif z3.is_rational_value(value):
            out[name] = Fraction(value.numerator_as_long(), value.denominator_as_long())
        else:  # an algebraic number (nonlinear constraints): its decimal approximation
            out[name] = Fraction(value.approx(20).as_decimal(20).rstrip("?"))
    return out


def refines(refining: Contract, refined: Contract, *, types: Mapping[str, str] | None = None,
            timeout_ms: int = DEFAULT_TIMEOUT_MS) -> Verdict:
    """C2 ≼ C1: A1 → A2 (the refining contract assumes no more) and G2' → G1' (guarantees no
    less). Fails with the counterexample of the first query that fails."""
    assumption = valid([refined.assumption], refining.assumption, types=types,
                       timeout_ms=timeout_ms)
    if assumption.status is Status.FAILS:
        return _tag(assumption, "the refining contract assumes more (A1 → A2 fails)")
    guarantee = valid([refining.saturated_guarantee], refined.saturated_guarantee, types=types,
                      timeout_ms=timeout_ms)
    if guarantee.status is Status.FAILS:
        return _tag(guarantee, "the refining contract guarantees less (G2' → G1' fails)")
    if Status.UNKNOWN in (assumption.status, guarantee.status):
        return Verdict(Status.UNKNOWN, reason=assumption.reason or guarantee.reason)
    return Verdict(Status.HOLDS, clauses=assumption.clauses + guarantee.clauses)


def _tag(verdict: Verdict, reason: str) -> Verdict:
    return Verdict(verdict.status, verdict.counterexample, verdict.clauses, reason)


def equivalent(a: Contract, b: Contract, **kwargs) -> Verdict:
    """Mutual refinement."""
    first = refines(a, b, **kwargs)
    return first if not first.holds else refines(b, a, **kwargs)


def receptive(assertion: Expr, free: Iterable[str], *, types: Mapping[str, str] | None = None,
              timeout_ms: int = DEFAULT_TIMEOUT_MS) -> Verdict:
    """Is ``assertion`` receptive to the variables ``free``: for every value of them, do values
    of the other variables exist that satisfy it? Fails with values of ``free`` that admit none."""
    import z3

    free = set(free) & variables(assertion)
    names = variables(assertion)
    env = z3_variables(names, types)
    others = [env[n] for n in sorted(names - free)]
    body = to_z3(assertion, env)
    # ∃ free ∀ others: ¬assertion — a model gives the free values that admit no completion
    negation = z3.ForAll(others, z3.Not(body)) if others else z3.Not(body)
    # nonlinear and quantified: quantifier elimination where the default solver gives up
    result, model, reason = check_quantified(negation, timeout_ms,
                                             nonlinear=degree(assertion) > 1)
    if result == z3.unsat:
        return Verdict(Status.HOLDS, reason=reason)
    if result == z3.sat:
        example = _model_values(model, {n: env[n] for n in sorted(free)})
        return Verdict(Status.FAILS, example, (to_text(assertion),), reason)
    return Verdict(Status.UNKNOWN, reason=reason)


def compatible(contract: Contract, controlled: Iterable[str], **kwargs) -> Verdict:
    """The assumption does not constrain the component's outputs (receptive to them)."""
    return receptive(contract.assumption, controlled, **kwargs)


def consistent(contract: Contract, uncontrolled: Iterable[str], **kwargs) -> Verdict:
    """The saturated guarantee can be met for every input (receptive to the inputs)."""
    return receptive(contract.saturated_guarantee, uncontrolled, **kwargs)
