"""Projection of contracts onto a subset of variables, by z3's quantifier elimination.

A contract over more variables than a component's ports is turned into one over the ports only:
A' = ∃ hidden. A and G' = ∀ hidden. (A → G). The result refines the original (A → A' and
G' → (A → G) hold by construction), so a model satisfying it satisfies the original: it is a
*sufficient* requirement over the ports. Used to state what a missing model must satisfy (the
quotient, paper 003 sec. V-B). Projection needs quantifier elimination, which z3 does for linear
real arithmetic; elsewhere it may not, and :func:`project` returns None.

Elimination (our design): first z3's QSAT-based recursive elimination (tactic ``qe_rec``;
Bjørner & Janota, "Playing with quantified satisfaction", LPAR 2015), then z3 checks that its
result is equivalent to the quantified formula (one solver call; an answer not proven
equivalent is discarded); otherwise, or if it fails, z3's classic ``qe``, the only path before
issue 28, whose answer is now checked the same way (if neither is proven equivalent, there is no
projection and the quotient is shown as it is). ``qe`` gives up after its 10 s limit on a
20-component chain with 19 given models; ``qe_rec`` with its check takes 0.16 s there
(benchmarks/contracts.py, section "quotient"). The check is not idle: on an 11-component chain
(``chain(11, 3, 1)``, the middle model missing) the classic ``qe`` of z3-solver 5.4.1 returned
an assumption that is *not* equivalent to the projection (it also holds at x5 = 7, x6 = 15,
where no behaviour of the given models puts x5 — weaker, so the requirement was still
sufficient, but not the exact one, and unreadable). ``qe_rec`` is used on quantified formulas
only: on a quantifier-free goal it decides satisfiability and returns ``true`` (``x > 0``
becomes ``true``), which is why an earlier attempt with ``qe2`` looked wrong.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from fractions import Fraction
from functools import cache

from simcred.contracts.algebra import Contract
from simcred.contracts.expr import (
    Arith,
    Bool,
    Compare,
    Expr,
    Logic,
    Num,
    Var,
    children,
    variables,
)
from simcred.contracts.smt import to_z3, z3_variables

METHODS = ("auto", "qe")


@dataclass(frozen=True, slots=True)
class Projection:
    """A projected contract and the elimination that answered: ``"qe_rec"`` (checked
    equivalent by z3) or ``"qe"`` for each of the assumption and the guarantee."""

    contract: Contract
    method: str


def project(contract: Contract, keep: Iterable[str], *, types: Mapping[str, str] | None = None,
            timeout_ms: int = 10_000, method: str = "auto") -> Contract | None:
    """The contract over ``keep`` that refines ``contract``, or None if z3 cannot eliminate.

    ``method="auto"``: ``qe_rec`` checked equivalent, else ``qe`` (module docs); ``"qe"``: only
    the classic tactic (the path before issue 28, kept for comparison)."""
    found = projection(contract, keep, types=types, timeout_ms=timeout_ms, method=method)
    return None if found is None else found.contract


def projection(contract: Contract, keep: Iterable[str], *,
               types: Mapping[str, str] | None = None, timeout_ms: int = 10_000,
               method: str = "auto") -> Projection | None:
    """:func:`project` with the elimination that answered."""
    import z3

    if method not in METHODS:
        raise ValueError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
    keep = set(keep)
    names = contract.variables
    env = z3_variables(names, types)
    hidden = [env[n] for n in sorted(names - keep)]
    assumption = to_z3(contract.assumption, env)
    saturated = to_z3(contract.saturated_guarantee, env)
    if hidden:
        assumption = z3.Exists(hidden, assumption)
        saturated = z3.ForAll(hidden, saturated)
    # a context of its own: z3's tactics answer in forms that depend on the terms created
    # before (solver history); in a fresh context the printed requirement is reproducible
    context = z3.Context()
    assumption, saturated = assumption.translate(context), saturated.translate(context)
    try:
        a, by_a = _eliminate_by(assumption, timeout_ms, method)
        g, by_g = _eliminate_by(saturated, timeout_ms, method)
        g = _within(g, a, timeout_ms)
        order = _first_mentions(contract.assumption, contract.guarantee)
        projected = Contract(_in_order(from_z3(a), order), _in_order(from_z3(g), order),
                             f"proj({contract.name})")
    except (z3.Z3Exception, NotImplementedError):
        return None
    if (variables(projected.assumption) | variables(projected.guarantee)) - keep:
        return None
    return Projection(projected, f"assumption by {by_a}, guarantee by {by_g}")


def _first_mentions(*exprs: Expr) -> dict[str, int]:
    """Variable → rank of its first mention in ``exprs`` (depth-first, left to right)."""
    order: dict[str, int] = {}
    stack = list(reversed(exprs))
    while stack:
        e = stack.pop()
        if isinstance(e, Var):
            order.setdefault(e.name, len(order))
        else:
            stack.extend(reversed(children(e)))
    return order


def _in_order(e: Expr, order: Mapping[str, int]) -> Expr:
    """``e`` with the operands of every ``and``/``or`` sorted (stably) by their variables'
    first mention in the contract being projected: the printed requirement follows the
    source, whichever elimination answered (``qe`` and ``qe_rec`` order clauses differently)."""
    if not (isinstance(e, Logic) and e.op in ("and", "or", "not")):
        return e
    args = [_in_order(a, order) for a in e.args]
    if e.op in ("and", "or"):
        last = len(order)
        args.sort(key=lambda c: min((order.get(n, last) for n in variables(c)), default=last))
    return Logic(e.op, tuple(args))


def _eliminate(formula, timeout_ms: int):
    """A quantifier-free formula equivalent to ``formula`` by the classic ``qe`` (model
    parameters, :mod:`.parameters`, use it as before)."""
    return _apply("qe", formula, timeout_ms)


def _eliminate_by(formula, timeout_ms: int, method: str = "auto"):
    """A quantifier-free formula equivalent to ``formula`` (module docs), and the tactic that
    gave it."""
    import z3

    if method == "auto" and z3.is_quantifier(formula):
        try:
            fast = _apply("qe_rec", formula, timeout_ms)
        except (z3.Z3Exception, NotImplementedError):
            fast = None
        if fast is not None and _equivalent(fast, formula, timeout_ms):
            return fast, "qe_rec"
    classic = _apply("qe", formula, timeout_ms)
    if method == "auto" and z3.is_quantifier(formula) \
            and not _equivalent(classic, formula, timeout_ms):
        raise NotImplementedError("no elimination proven equivalent")
    return classic, "qe"


def _equivalent(a, b, timeout_ms: int) -> bool:
    """z3 proves ``a == b`` (b may be quantified); False if it refutes or cannot decide."""
    import z3

    solver = z3.Solver(ctx=b.ctx)
    solver.set("timeout", int(timeout_ms))
    solver.add(z3.Xor(a, b))
    return solver.check() == z3.unsat


def _apply(elimination: str, formula, timeout_ms: int):
    import z3

    ctx = formula.ctx
    tactic = z3.TryFor(z3.Then(elimination, "simplify", "ctx-solver-simplify", ctx=ctx),
                       timeout_ms, ctx=ctx)
    goals = tactic(formula)
    parts = [z3.And(*g) if len(g) else z3.BoolVal(True, ctx) for g in goals]
    result = parts[0] if len(parts) == 1 else z3.Or(*parts)
    if z3.is_quantifier(result) or any(z3.is_quantifier(c) for c in _subterms(result)):
        raise NotImplementedError("quantifiers left after elimination")
    return result


def _within(guarantee, assumption, timeout_ms: int):
    """``guarantee`` simplified where ``assumption`` holds: the contracts (A, G) and (A, G*) with
    A ∧ G ≡ A ∧ G* are the same contract (saturation), so the clauses of A can be dropped."""
    import z3

    both = _eliminate(z3.And(assumption, guarantee), timeout_ms)
    context = {c.sexpr() for c in _clauses(assumption)}
    rest = [c for c in _clauses(both) if c.sexpr() not in context]
    if not rest:
        return z3.BoolVal(True, assumption.ctx)
    return rest[0] if len(rest) == 1 else z3.And(*rest)


def _clauses(term):
    import z3

    return term.children() if z3.is_and(term) else [term]


def _subterms(term):
    stack = [term]
    while stack:
        t = stack.pop()
        yield t
        if not hasattr(t, "children"):
            continue
        stack.extend(t.children())


@cache
def _comparison_ops() -> dict[int, str]:
    """z3 comparison kinds and our operators (built on first use: z3 is imported lazily)."""
    import z3

    return {z3.Z3_OP_LE: "<=", z3.Z3_OP_GE: ">=", z3.Z3_OP_LT: "<", z3.Z3_OP_GT: ">",
            z3.Z3_OP_EQ: "==", z3.Z3_OP_DISTINCT: "!="}


def _ite(term):
    """The first if-then-else inside an arithmetic term, or None."""
    import z3

    for t in _subterms(term):
        if z3.is_app_of(t, z3.Z3_OP_ITE):
            return t
    return None


def _lift_ite(comparison):
    """``f(If(c, a, b))`` → ``(c and f(a)) or (not c and f(b))``: our language has no if."""
    import z3

    ite = next(i for i in map(_ite, comparison.children()) if i is not None)
    condition, then, otherwise = ite.children()
    return z3.Or(z3.And(condition, z3.substitute(comparison, (ite, then))),
                 z3.And(z3.Not(condition), z3.substitute(comparison, (ite, otherwise))))


def from_z3(term) -> Expr:
    """Our AST of a quantifier-free z3 term of linear arithmetic and Boolean connectives."""
    import z3

    if z3.is_true(term):
        return Bool(True)
    if z3.is_false(term):
        return Bool(False)
    if z3.is_rational_value(term) or z3.is_int_value(term):
        value = term.as_fraction() if z3.is_rational_value(term) else Fraction(term.as_long())
        return Num(Fraction(value))
    if z3.is_const(term) and term.decl().kind() == z3.Z3_OP_UNINTERPRETED:
        return Var(term.decl().name())
    kind = term.decl().kind()
    compare = _comparison_ops()
    if kind in compare and any(_ite(c) is not None for c in term.children()):
        return from_z3(_lift_ite(term))
    args = [from_z3(c) for c in term.children()]
    logic = {z3.Z3_OP_AND: "and", z3.Z3_OP_OR: "or", z3.Z3_OP_NOT: "not",
             z3.Z3_OP_IMPLIES: "implies"}
    if kind in logic:
        return Logic(logic[kind], tuple(args))
    if kind in compare:
        return Compare(compare[kind], args[0], args[1])
    if kind == z3.Z3_OP_ITE and z3.is_bool(term):
        return Logic("or", (Logic("and", (args[0], args[1])),
                            Logic("and", (Logic("not", (args[0],)), args[2]))))
    arith = {z3.Z3_OP_ADD: "+", z3.Z3_OP_SUB: "-", z3.Z3_OP_MUL: "*", z3.Z3_OP_DIV: "/"}
    if kind in arith:
        out = args[0]
        for a in args[1:]:
            out = Arith(arith[kind], (out, a))
        return out
    if kind == z3.Z3_OP_UMINUS:
        return Num(-args[0].value) if isinstance(args[0], Num) else Arith("neg", (args[0],))
    raise NotImplementedError(f"cannot translate z3 term {term}")
