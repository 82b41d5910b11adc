"""Physical units of variables, ports and literals (pint), and dimensional analysis of assertions.

Every variable has a declared unit. Inside an assertion, :func:`resolve` checks that only like
dimensions are added, subtracted, compared or passed to ``min``/``max`` together, and converts
each literal with a unit (``100 km/h``, ``1 lux``) — and each variable declared in another unit of
the same dimension — to the unit of the first variable operand, *exactly*: pint's registry works
on :class:`~fractions.Fraction` here, so ``100 km/h`` becomes ``250/9`` m/s, not a float.

A bare number (``v <= 30``) takes the unit of what it meets (the usual engineering reading, and
what every library written before units in assertions means); in a product it is a pure number.
Units with an offset (``degC``) cannot be converted inside a linear assertion and are refused
where a conversion would be needed.
"""

from __future__ import annotations

from collections.abc import Mapping
from fractions import Fraction
from functools import cache

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
from simcred.errors import SimcredError

_ADDITIVE = ("+", "-", "min", "max")


@cache
def _registry():
    import pint

    return pint.UnitRegistry(non_int_type=Fraction)


def unit(text: str, *, where: str = ""):
    """The pint unit of ``text``; a one-line error naming ``where`` if it is not a unit."""
    try:
        return _registry().Unit(text)
    except Exception:  # pint raises several error types for unparsable units
        raise SimcredError(f"{where}: '{text}' is not a physical unit") from None


def same_unit(a: str, b: str) -> bool:
    """True when ``a`` and ``b`` name the same unit (``km/h`` == ``kilometer / hour``)."""
    return unit(a) == unit(b)


def factor(source, target, *, where: str = "") -> Fraction:
    """The exact factor f with ``x [source] = f·x [target]`` (same dimension, no offset)."""
    registry = _registry()
    if source == target:
        return Fraction(1)
    if source.dimensionality != target.dimensionality:
        raise ExpressionError(f"{where}: cannot convert {_name(source)} to {_name(target)}")
    try:
        one, two = (Fraction(registry.Quantity(Fraction(k), source).to(target).magnitude)
                    for k in (1, 2))
    except Exception:  # offset units (degC) in a product
        one, two = None, None
    if one is None or two != 2 * one:  # an offset (degF → degC): not a factor
        raise ExpressionError(f"{where}: cannot convert {_name(source)} to {_name(target)} "
                              "inside an assertion (a unit with an offset)")
    return one


def _name(u) -> str:
    """``m/s^2`` for a unit, ``[length]/[time]^2`` for a dimensionality (pint's own formatter
    fails on the Fraction exponents of this registry)."""
    items = sorted(dict(getattr(u, "_units", u).items()).items())
    up = [f"{k}^{_int(v)}" if v != 1 else k for k, v in items if v > 0]
    down = [f"{k}^{_int(-v)}" if v != -1 else k for k, v in items if v < 0]
    text = "*".join(up) or ("1" if down else "dimensionless")
    return text + "".join(f"/{d}" for d in down)


def _int(value) -> str:
    return str(int(value)) if Fraction(value).denominator == 1 else str(value)


def resolve(e: Expr, units: Mapping[str, str], *, where: str = "") -> Expr:
    """``e`` with every unit literal and every differently-declared variable converted to the
    unit of the operands it meets; one-line error on a sum or comparison of unlike dimensions.

    ``units`` maps each variable to its declared unit (missing: dimensionless).
    """
    declared = {name: unit(text, where=f"{where}: variable {name}") for name, text in
                units.items()}
    resolved, _ = _resolve(e, declared, where)
    return resolved


def _resolve(e: Expr, units, where: str):
    """(expression, unit or None): None for a bare number that adopts the unit it meets."""
    if isinstance(e, Num | Bool):
        return e, None
    if isinstance(e, Quantity):
        return Num(e.value), unit(e.unit, where=f"{where}: literal '{to_text(e)}'")
    if isinstance(e, Var):
        return e, None if e.boolean else units.get(e.name, _registry().dimensionless)
    if isinstance(e, Logic):
        return Logic(e.op, tuple(_resolve(a, units, where)[0] for a in e.args)), None
    if isinstance(e, Temporal):
        return Temporal(e.op, e.lo, e.hi, tuple(_resolve(a, units, where)[0] for a in e.args)), \
            None
    if isinstance(e, Compare):
        (left, right), _ = _alike([e.left, e.right], units, where, e.op)
        return Compare(e.op, left, right), None
    if e.op in _ADDITIVE:
        args, common = _alike(list(e.args), units, where, e.op)
        return Arith(e.op, tuple(args)), common
    parts = [_resolve(a, units, where) for a in e.args]
    args = tuple(p[0] for p in parts)
    if e.op in ("neg", "abs"):
        return Arith(e.op, args), parts[0][1]
    first, second = (p[1] for p in parts)
    if e.op == "^":
        return Arith(e.op, args), None if first is None else first ** int(e.args[1].value)
    if first is None and second is None:
        return Arith(e.op, args), None
    one = _registry().dimensionless
    first, second = first or one, second or one
    return Arith(e.op, args), first * second if e.op == "*" else first / second


def _alike(operands, units, where: str, op: str):
    """Resolve ``operands`` of an additive operation or comparison to one unit."""
    parts = [_resolve(a, units, where) for a in operands]
    literal = [isinstance(a, Quantity) for a in operands]
    # the target: the first operand that is not a unit literal (a variable's unit) if any
    typed = [i for i, (_, u) in enumerate(parts) if u is not None]
    if not typed:
        return [p[0] for p in parts], None
    target = next((parts[i][1] for i in typed if not literal[i]), parts[typed[0]][1])
    out = []
    for (expr, u), operand in zip(parts, operands, strict=True):
        if u is None or u == target:
            out.append(expr)
            continue
        if u.dimensionality != target.dimensionality:
            raise ExpressionError(
                f"{where}: '{to_text(operand)}' is in {_name(u)} but meets {_name(target)} "
                f"in '{op}' (unlike dimensions: {_name(u.dimensionality)} vs "
                f"{_name(target.dimensionality)})")
        scale = factor(u, target, where=where)
        out.append(Num(expr.value * scale) if isinstance(expr, Num)
                   else Arith("*", (Num(scale), expr)))
    return out, target
