"""AST → numpy: vectorised values and robustness (margins) over the rows of recorded runs."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

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

# -- numpy back end -----------------------------------------------------------------------------


def evaluate(e: Expr, columns: Mapping[str, Any], timeline=None) -> Any:
    """Vectorised value of ``e``: booleans for conditions, numbers for terms.

    ``columns`` maps each variable to an array (or scalar). Object arrays of ``Fraction`` give an
    exact evaluation. Temporal operators need the rows' ``timeline``
    (:class:`simcred.contracts.temporal.Timeline`).
    """
    if isinstance(e, Quantity):
        raise ExpressionError(f"'{to_text(e)}': resolve units first (units.resolve)")
    if isinstance(e, Num):
        return e.value if _exact(columns) else float(e.value)
    if isinstance(e, Bool):
        return np.bool_(e.value)
    if isinstance(e, Var):
        return columns[e.name]
    if isinstance(e, Compare):
        return _NP_COMPARE[e.op](evaluate(e.left, columns, timeline),
                                 evaluate(e.right, columns, timeline))
    args = [evaluate(a, columns, timeline) for a in e.args]
    if isinstance(e, Temporal):
        return _temporal(e, args, timeline, boolean=True)
    if isinstance(e, Logic):
        if e.op == "not":
            return np.logical_not(args[0])
        if e.op == "implies":
            return np.logical_or(np.logical_not(args[0]), args[1])
        combine = np.logical_and if e.op == "and" else np.logical_or
        out = args[0]
        for a in args[1:]:
            out = combine(out, a)
        return out
    return _np_arith(e.op, args, e)


def _temporal(e: Temporal, args, timeline, *, boolean: bool):
    """A temporal operator over its operands' values (booleans or robustness)."""
    from simcred.contracts import temporal

    if timeline is None:
        raise ExpressionError(f"'{to_text(e)}' is temporal: it needs recorded runs (monitor)")
    n = len(timeline.time)
    args = [np.broadcast_to(np.asarray(a, dtype=bool if boolean else float), (n,)) for a in args]
    top, bottom = (True, False) if boolean else (np.inf, -np.inf)
    if e.op == "previous":
        return temporal.previous(args[0], timeline, first=top)
    past = e.op in ("historically", "once", "since")
    if e.op in ("until", "since"):
        return temporal.until(args[0], args[1], timeline, e.lo, e.hi, past=past,
                              boolean=boolean)
    start, stop = timeline.window(e.lo, e.hi, past=past)
    universal = e.op in ("always", "historically")
    return temporal.window_reduce(args[0], start, stop, maximum=not universal,
                                  empty=top if universal else bottom)


def _exact(columns: Mapping[str, Any]) -> bool:
    return any(np.asarray(v).dtype == object for v in columns.values())


_NP_COMPARE: dict[str, Callable] = {
    "<=": np.less_equal, ">=": np.greater_equal, "<": np.less, ">": np.greater,
    "==": np.equal, "!=": np.not_equal}


def _np_arith(op: str, args, e: Arith):
    if op == "neg":
        return np.negative(args[0])
    if op == "abs":
        return np.abs(args[0])
    if op in ("min", "max"):
        combine = np.minimum if op == "min" else np.maximum
        out = args[0]
        for a in args[1:]:
            out = combine(out, a)
        return out
    if op == "^":
        out = args[1] ** 0  # the number 1: a Fraction when the evaluation is exact
        for _ in range(int(e.args[1].value)):
            out = out * args[0]
        return out
    a, b = args
    return {"+": np.add, "-": np.subtract, "*": np.multiply, "/": np.true_divide}[op](a, b)


def margin(e: Expr, columns: Mapping[str, Any], timeline=None) -> Any:
    """Signed distance to violation of the condition ``e`` (robustness semantics).

    ``a <= b`` has margin ``b - a``; ``and`` the minimum, ``or`` the maximum of its operands';
    ``not`` flips the sign; ``a implies b`` is ``not a or b``. Equalities have margin
    ``-|a - b|`` (0 when they hold); ``true``/``false`` are ±inf. Temporal operators take the
    minimum/maximum over their windows (as rtamt's discrete-time STL).
    """
    if isinstance(e, Bool):
        return np.inf if e.value else -np.inf
    if isinstance(e, Var):  # a bool variable: ±inf as for true/false
        return np.where(np.asarray(columns[e.name], dtype=bool), np.inf, -np.inf)
    if isinstance(e, Compare):
        a, b = evaluate(e.left, columns), evaluate(e.right, columns)
        if e.op in ("<=", "<"):
            return np.subtract(b, a)
        if e.op in (">=", ">"):
            return np.subtract(a, b)
        gap = np.abs(np.subtract(a, b))
        return -gap if e.op == "==" else gap
    if isinstance(e, Temporal):
        return _temporal(e, [margin(a, columns, timeline) for a in e.args], timeline,
                         boolean=False)
    if e.op == "not":
        return np.negative(margin(e.args[0], columns, timeline))
    if e.op == "implies":
        return np.maximum(np.negative(margin(e.args[0], columns, timeline)),
                          margin(e.args[1], columns, timeline))
    combine = np.minimum if e.op == "and" else np.maximum
    out = margin(e.args[0], columns, timeline)
    for a in e.args[1:]:
        out = combine(out, margin(a, columns, timeline))
    return out
