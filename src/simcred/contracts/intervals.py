"""The interval fragment: assertions that are conjunctions of bounds on single real variables.

Most validity domains in practice are boxes (``0 <= ego.v <= 40 and abs(ego.a_lat) <= 4``), and
most guarantees are bounds on an error (``dyn.error <= 0.2``). For them, satisfiability and the
refinement of a setup are decided by exact interval arithmetic on rationals (no solver), which is
what makes configuration scale (:mod:`simcred.contracts.search`).

:func:`box` returns the box of an assertion (variable → :class:`Interval`) or None when the
assertion is not in the fragment (then the caller falls back to z3).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from fractions import Fraction

from simcred.contracts.expr import (
    Arith,
    Bool,
    Compare,
    Expr,
    Num,
    Var,
    conjuncts,
    decimal_text,
)

_FLIP = {"<=": ">=", "<": ">", ">=": "<=", ">": "<", "==": "=="}


@dataclass(frozen=True, slots=True)
class Interval:
    """{x : lo (<|<=) x (<|<=) hi}; None is unbounded (±inf); ``*_open`` marks strict bounds."""

    lo: Fraction | None = None
    hi: Fraction | None = None
    lo_open: bool = False
    hi_open: bool = False

    @property
    def empty(self) -> bool:
        if self.lo is None or self.hi is None:
            return False
        return self.lo > self.hi or (self.lo == self.hi and (self.lo_open or self.hi_open))

    def meet(self, other: Interval) -> Interval:
        lo, lo_open = _tighter(self.lo, self.lo_open, other.lo, other.lo_open, max)
        hi, hi_open = _tighter(self.hi, self.hi_open, other.hi, other.hi_open, min)
        return Interval(lo, hi, lo_open, hi_open)

    def within(self, other: Interval) -> bool:
        """self ⊆ other (an empty interval is within everything)."""
        if self.empty:
            return True
        return _lower_ok(self, other) and _upper_ok(self, other)

    def text(self, name: str) -> str:
        """``0 <= v <= 40`` (decimals where exact, else fractions)."""
        parts = []
        if self.lo is not None:
            parts.append(f"{decimal(self.lo)} {'<' if self.lo_open else '<='} ")
        parts.append(name)
        if self.hi is not None:
            parts.append(f" {'<' if self.hi_open else '<='} {decimal(self.hi)}")
        return "".join(parts) if len(parts) > 1 else "true"


REAL_LINE = Interval()


def decimal(value: Fraction) -> str:
    """A rational as its exact decimal when it has one (``0.25``), else ``p/q``."""
    value = Fraction(value)
    return decimal_text(value) or f"{value.numerator}/{value.denominator}"


def _tighter(a, a_open, b, b_open, pick):
    if a is None:
        return b, b_open
    if b is None:
        return a, a_open
    if a == b:
        return a, a_open or b_open
    return (a, a_open) if pick(a, b) == a else (b, b_open)


def _lower_ok(inner: Interval, outer: Interval) -> bool:
    if outer.lo is None:
        return True
    if inner.lo is None:
        return False
    return inner.lo > outer.lo or (inner.lo == outer.lo and (inner.lo_open or not outer.lo_open))


def _upper_ok(inner: Interval, outer: Interval) -> bool:
    if outer.hi is None:
        return True
    if inner.hi is None:
        return False
    return inner.hi < outer.hi or (inner.hi == outer.hi and (inner.hi_open or not outer.hi_open))


def _atom(clause: Expr, real: set[str]) -> tuple[str, Interval] | None:
    """The interval of one bound ``x op c``, ``c op x`` or ``abs(x) <= c``, else None."""
    if not isinstance(clause, Compare) or clause.op == "!=":
        return None
    left, right, op = clause.left, clause.right, clause.op
    if isinstance(left, Num):
        left, right, op = right, left, _FLIP[op]
    if not isinstance(right, Num):
        return None
    c = right.value
    if isinstance(left, Var) and left.name in real:
        return left.name, {"<=": Interval(hi=c), "<": Interval(hi=c, hi_open=True),
                           ">=": Interval(lo=c), ">": Interval(lo=c, lo_open=True),
                           "==": Interval(c, c)}[op]
    if (isinstance(left, Arith) and left.op == "abs" and isinstance(left.args[0], Var)
            and left.args[0].name in real and op in ("<=", "<")):
        return left.args[0].name, Interval(-c, c, op == "<", op == "<")
    return None


def box(expr: Expr, types: Mapping[str, str] | None = None) -> dict[str, Interval] | None:
    """The box {variable: interval} equivalent to ``expr``, or None if it is not one."""
    types = types or {}
    out: dict[str, Interval] = {}
    for clause in conjuncts(expr):
        if clause == Bool(True):
            continue
        names = {v for v in _names(clause)}
        real = {n for n in names if types.get(n, "real") == "real"}
        atom = _atom(clause, real)
        if atom is None:
            return None
        name, interval = atom
        out[name] = out.get(name, REAL_LINE).meet(interval)
    return out


def _names(e: Expr):
    if isinstance(e, Var):
        yield e.name
    elif isinstance(e, Compare):
        yield from _names(e.left)
        yield from _names(e.right)
    elif isinstance(e, Arith):
        for a in e.args:
            yield from _names(a)


def satisfiable(expr: Expr, types: Mapping[str, str] | None = None) -> bool | None:
    """Whether some point satisfies ``expr``; None when it is not in the interval fragment."""
    if expr == Bool(False):
        return False
    b = box(expr, types)
    return None if b is None else not any(i.empty for i in b.values())


def box_text(b: Mapping[str, Interval]) -> str:
    """``0 <= v <= 40 and q <= 3`` (variables sorted)."""
    parts = [b[n].text(n) for n in sorted(b) if b[n] != REAL_LINE]
    return " and ".join(parts) or "true"
