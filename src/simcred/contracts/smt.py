"""AST → z3 (exact rationals): the reasoning back end of the contract algebra."""

from __future__ import annotations

import operator
from collections.abc import Callable, Mapping
from typing import Any

from simcred.contracts.expr import (
    Arith,
    Bool,
    Compare,
    Expr,
    ExpressionError,
    Logic,
    Num,
    Quantity,
    Temporal,
    Var,
    to_text,
)

# -- z3 back end --------------------------------------------------------------------------------


def z3_variables(names, types: Mapping[str, str] | None = None) -> dict[str, Any]:
    """z3 constants for ``names``: ``Real`` unless ``types`` says ``int`` or ``bool``."""
    import z3

    makers = {"real": z3.Real, "int": z3.Int, "bool": z3.Bool}
    types = types or {}
    return {n: makers[types.get(n, "real")](n) for n in sorted(names)}


def to_z3(e: Expr, env: Mapping[str, Any]):
    """The z3 term of ``e`` with variables taken from ``env`` (exact rational numbers)."""
    import z3

    if isinstance(e, Quantity):
        raise ExpressionError(f"'{to_text(e)}': resolve units first (units.resolve)")
    if isinstance(e, Temporal):
        raise ExpressionError(
            f"'{to_text(e)}' is temporal: the contract algebra (z3) reasons about the "
            "instantaneous fragment only; temporal clauses are checked by monitors on runs")
    if isinstance(e, Num):
        return z3.RealVal(f"{e.value.numerator}/{e.value.denominator}")
    if isinstance(e, Bool):
        return z3.BoolVal(e.value)
    if isinstance(e, Var):
        return env[e.name]
    if isinstance(e, Compare):
        left, right = to_z3(e.left, env), to_z3(e.right, env)
        return _Z3_COMPARE[e.op](left, right)
    args = [to_z3(a, env) for a in e.args]
    if isinstance(e, Logic):
        return {"and": lambda: z3.And(*args), "or": lambda: z3.Or(*args),
                "not": lambda: z3.Not(args[0]),
                "implies": lambda: z3.Implies(args[0], args[1])}[e.op]()
    return _z3_arith(e.op, args, e)


_Z3_COMPARE: dict[str, Callable] = {
    "<=": lambda a, b: a <= b, ">=": lambda a, b: a >= b, "<": lambda a, b: a < b,
    ">": lambda a, b: a > b, "==": lambda a, b: a == b, "!=": lambda a, b: a != b}


def _z3_arith(op: str, args, e: Arith):
    import z3

    if op == "neg":
        return -args[0]
    if op == "abs":
        return z3.If(args[0] >= 0, args[0], -args[0])
    if op in ("min", "max"):
        out = args[0]
        for a in args[1:]:
            out = z3.If(a < out, a, out) if op == "min" else z3.If(a > out, a, out)
        return out
    if op == "^":
        out = z3.RealVal(1)
        for _ in range(int(e.args[1].value)):
            out = out * args[0]
        return out
    a, b = args
    return _Z3_BINARY[op](a, b)  # only the one term asked for (building all four was 4x slower)


_Z3_BINARY: dict[str, Callable] = {"+": operator.add, "-": operator.sub, "*": operator.mul,
                                   "/": operator.truediv}


# -- quantified queries ---------------------------------------------------------------------------

# z3's default solver instantiates quantifiers incompletely on nonlinear real arithmetic
# (∀ x ∃ y with products of variables) and answers "unknown" — often after its whole time
# limit — where nlqsat (complete for quantified nonlinear real arithmetic, once min/max/abs are
# lifted out of the terms) or quantifier elimination followed by a quantifier-free check decide
# in milliseconds (issue 28). On a quantified nonlinear formula nlqsat goes first, with a short
# budget (it answers or gives up at once on most formulas); then the default solver; then both
# tactics again after an "unknown".
NLQSAT = ("simplify", "elim-term-ite", "nlqsat")
QE = ("qe", "smt")
QUICK_SHARE = 10  # nlqsat's first try gets 1/10 of the time limit


def check_quantified(formula, timeout_ms: int, *, nonlinear: bool = False):
    """Satisfiability of the z3 formula ``formula`` (quantifiers allowed): ``(result, model,
    reason)``, the model (None unless sat) in ``formula``'s context; ``reason`` names the
    tactics that decided after the default solver gave up, or why all gave up. Time:
    ``timeout_ms`` for the default solver, 1/10 of it before on a quantified ``nonlinear``
    formula, half of it for each tactic after an unknown (at most 2.1 × ``timeout_ms``)."""
    import z3

    quantified = z3.is_quantifier(formula)
    timeout_ms = int(timeout_ms)
    if quantified and nonlinear:
        answer, model = _tactic(NLQSAT, formula, max(1, timeout_ms // QUICK_SHARE))
        if answer != z3.unknown:
            return answer, model, "decided by " + " + ".join(NLQSAT)
    solver = z3.Solver()
    solver.set("timeout", timeout_ms)
    solver.add(formula)
    result = solver.check()
    if result != z3.unknown:
        return result, solver.model() if result == z3.sat else None, ""
    reason = solver.reason_unknown()
    if not quantified:
        return result, None, reason
    for names in (QE, NLQSAT):
        answer, model = _tactic(names, formula, max(1, timeout_ms // 2))
        if answer != z3.unknown:
            return answer, model, f"default solver: {reason}; decided by {' + '.join(names)}"
    return result, None, f"{reason}; quantifier elimination did not decide it either"


def _tactic(names, formula, timeout_ms: int):
    """(result, model or None) of the z3 tactics ``names`` in sequence on ``formula``, within
    ``timeout_ms``; unknown if a tactic cannot take the formula. Run in a fresh z3 context:
    what ``qe`` finds depends on the order of the terms, which in the shared context depends
    on every formula built before in the process (the same query was decided in a fresh
    process and not after 400 other tests); a fresh context makes the answer reproducible."""
    import z3

    context = z3.Context()
    solver = z3.TryFor(z3.Then(*names, ctx=context), timeout_ms, ctx=context).solver()
    solver.add(formula.translate(context))
    try:
        answer = solver.check()
    except z3.Z3Exception:
        return z3.unknown, None
    return answer, solver.model().translate(formula.ctx) if answer == z3.sat else None
