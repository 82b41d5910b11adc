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
