"""Physical units of variables, ports and literals (pint), and dimensional analysis of assertions.

Every variable has a declared unit. Inside an assertion, :func:`resolve` checks that only like
dimensions are added, subtracted, compared or passed to ``min``/``max`` together, and converts
each literal with a unit (``100 km/h``, ``1 lux``) — and each variable declared in another unit of
the same dimension — to the unit of the first variable operand, *exactly*: pint's registry works
on :class:`~fractions.Fraction` here, so ``100 km/h`` becomes ``250/9`` m/s, not a float.

A bare number (``v <= 30``) takes the unit of what it meets (the usual engineering reading, and
what every library written before units in assertions means); in a product it is a pure number.
Among operands of *different* units (``v_kmh + v_ms <= 100``) a bare number is an error: its
unit would be whichever operand came first, so operand order would change the meaning; give it
a unit (``100 km/h``). A bare ``0`` is allowed everywhere (0 in every unit without an offset).
Units with an offset (``degC``) cannot be converted inside a linear assertion and are refused
where a conversion would be needed; a temperature *difference* is ``delta_degC`` (or
``delta_degF``, ``K``), which converts by a factor (1 delta_degC = 9/5 delta_degF = 1 K).
``%`` (pint's ``percent``) is dimensionless with the factor 1/100: ``ratio <= 5 %`` is
``ratio <= 0.05``. Unit texts are parsed once each (:func:`parsed_unit`, cached).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from fractions import Fraction
from functools import cache, lru_cache
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
from simcred.errors import SimcredError


@cache
def _registry():
    import pint

    return pint.UnitRegistry(non_int_type=Fraction)


def unit(text: str, *, where: str = ""):
    """The pint unit of ``text``; a one-line error naming ``where`` if it is not a unit."""
    parsed = parsed_unit(text)
    if parsed is None:
        raise SimcredError(f"{where}: '{text}' is not a physical unit")
    return parsed


@lru_cache(maxsize=4096)
def parsed_unit(text: str):
    """The pint unit of ``text``, or None if pint cannot read it; cached per text (a library
    names the same few units thousands of times, and pint parses a unit in ~50 µs)."""
    try:
        return _registry().Unit(text)
    except Exception:  # pint raises several error types for unparsable units
        return None


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
                              "inside an assertion (a unit with an offset: declare temperatures "
                              "in kelvin, or differences of temperatures in delta_degC)")
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
    unit of the operands it meets; one-line error on a sum or comparison of unlike dimensions,
    and on a bare number among operands of different units (module docs).

    ``units`` maps each variable to its declared unit (missing: dimensionless).
    """
    declared = {name: unit(text, where=f"{where}: variable {name}")
                for name, text in units.items()}
    return _resolve(e, declared, where).expr


@dataclass(frozen=True, slots=True)
class _Resolved:
    """A resolved term: its unit (None for a bare number, which adopts the unit it meets) and
    whether that unit was picked among terms of different units (``v_kmh + v_ms``: km/h or
    m/s, whichever comes first) — then a bare number next to it would mean different things in
    different operand orders. ``constant``: no variable in it (a literal, converted exactly to
    the unit of the variables it meets)."""

    expr: Expr
    unit: Any = None
    mixed: bool = False
    constant: bool = True


def _resolve(e: Expr, units, where: str) -> _Resolved:
    if isinstance(e, Num | Bool):
        return _Resolved(e)
    if isinstance(e, Quantity):
        return _Resolved(Num(e.value), unit(e.unit, where=f"{where}: literal '{to_text(e)}'"))
    if isinstance(e, Var):
        return _Resolved(e, None if e.boolean else units.get(e.name, _registry().dimensionless),
                         constant=False)
    if isinstance(e, Logic):
        return _Resolved(Logic(e.op, tuple(_resolve(a, units, where).expr for a in e.args)))
    if isinstance(e, Temporal):
        return _Resolved(Temporal(e.op, e.lo, e.hi,
                                  tuple(_resolve(a, units, where).expr for a in e.args)))
    if isinstance(e, Compare) or e.op in ("+", "-", "neg"):
        return _sum(e, units, where)
    parts = [_resolve(a, units, where) for a in e.args]
    constant = all(p.constant for p in parts)
    if e.op in ("min", "max"):
        args, common, mixed = _alike(e.args, parts, where, e.op)
        return _Resolved(Arith(e.op, tuple(args)), common, mixed, constant)
    args = tuple(p.expr for p in parts)
    mixed = any(p.mixed for p in parts)
    if e.op == "abs":
        return _Resolved(Arith(e.op, args), parts[0].unit, mixed, constant)
    first, second = (p.unit for p in parts)
    if e.op == "^":
        return _Resolved(Arith(e.op, args),
                         None if first is None else first ** int(e.args[1].value), mixed,
                         constant)
    if first is None and second is None:
        return _Resolved(Arith(e.op, args))
    one = _registry().dimensionless
    first, second = first or one, second or one
    return _Resolved(Arith(e.op, args), first * second if e.op == "*" else first / second,
                     mixed, constant)


def _terms(e: Expr) -> list[Expr]:
    """The terms of a chain of ``+``, ``-`` and unary ``-`` (a comparison: both sides): one sum
    however the parser grouped it (``1 + v1 + v2`` is ``(1 + v1) + v2``)."""
    if isinstance(e, Compare):
        return _terms(e.left) + _terms(e.right)
    if isinstance(e, Arith) and e.op in ("+", "-", "neg"):
        return [t for a in e.args for t in _terms(a)]
    return [e]


def _rebuild(e: Expr, terms) -> Expr:
    """``e`` with the terms of its chain replaced, in order, from the iterator ``terms``."""
    if isinstance(e, Compare):
        return Compare(e.op, _rebuild(e.left, terms), _rebuild(e.right, terms))
    if isinstance(e, Arith) and e.op in ("+", "-", "neg"):
        return Arith(e.op, tuple(_rebuild(a, terms) for a in e.args))
    return next(terms)


def _sum(e: Expr, units, where: str) -> _Resolved:
    """A chain of + and - or a comparison: all its terms to one unit (:func:`_alike`)."""
    terms = _terms(e)
    parts = [_resolve(t, units, where) for t in terms]
    op = e.op if isinstance(e, Compare) else "+" if e.op == "neg" else e.op
    converted, common, mixed = _alike(terms, parts, where, op)
    out = _rebuild(e, iter(converted))
    if isinstance(e, Compare):
        return _Resolved(out)
    return _Resolved(out, common, mixed, all(p.constant for p in parts))


def _alike(operands, parts: list[_Resolved], where: str, op: str):
    """Resolve ``operands`` (resolved: ``parts``) of an additive operation or comparison to one
    unit: (expressions, unit, mixed). A bare number (other than 0, which is 0 in every unit)
    among operands of different units is refused: which unit it would take depended on the
    operand order."""
    # the target: the first operand with a variable, if any (constants are converted to it)
    typed = [i for i, p in enumerate(parts) if p.unit is not None]
    bare = [a for a, p in zip(operands, parts, strict=True)
            if p.unit is None and p.expr != Num(Fraction(0))]
    if not typed:
        return [p.expr for p in parts], None, False
    deciding = [i for i in typed if not parts[i].constant] or typed
    target = parts[deciding[0]].unit
    kinds = {parts[i].unit for i in deciding}
    mixed = len(kinds) > 1 or any(parts[i].mixed for i in deciding)
    out = []
    for p, operand in zip(parts, operands, strict=True):
        expr, u = p.expr, p.unit
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
    if bare and mixed:
        inner = next(operands[i] for i in deciding if parts[i].mixed) if len(kinds) == 1 \
            else None
        meets = (f"operands in {' and '.join(sorted(_name(u) for u in kinds))}"
                 if len(kinds) > 1 else f"'{to_text(inner)}', whose operands are in different "
                 "units")
        raise ExpressionError(
            f"{where}: the bare number '{to_text(bare[0])}' meets {meets} in '{op}': its unit "
            f"would depend on the operand order — give it one (e.g. '{to_text(bare[0])} "
            f"{_name(target)}')")
    return out, target, mixed
