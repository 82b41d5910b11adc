"""The assertion language's AST: one tree for every back end, and its exact text.

Assertions are arithmetic over declared variables (``+ - * / ^``, ``abs``, ``min``, ``max``,
numbers, numbers with units), comparisons (chains like ``0 <= v <= 30`` allowed), ``and``,
``or``, ``not``, ``implies``, ``true``, ``false`` and bounded temporal operators. Variable names
may be dotted (``ego.v``). Numbers are exact (``Fraction``), so ``x <= 0.2`` refines itself.

Modules: :mod:`.parse` (text → AST, with limits), :mod:`.units` (dimensional analysis),
:mod:`.smt` (AST → z3), :mod:`.evaluate` (AST → numpy values and robustness over runs).
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

from simcred.errors import SimcredError

_MOVED = {"parse": "parse", "to_z3": "smt", "z3_variables": "smt", "evaluate": "evaluate",
          "margin": "evaluate"}


def __getattr__(name: str):
    """``expr.parse`` etc. still work (they moved to their own modules)."""
    if name in _MOVED:
        import importlib

        return getattr(importlib.import_module(f"simcred.contracts.{_MOVED[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


class ExpressionError(SimcredError):
    """A malformed or ill-typed assertion; the message names line and column."""


# -- AST ---------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Num:
    value: Fraction


@dataclass(frozen=True, slots=True)
class Bool:
    value: bool


@dataclass(frozen=True, slots=True)
class Quantity:
    """A literal with a unit (``100 km/h``); :func:`simcred.contracts.units.resolve` turns it
    into a :class:`Num` in the unit of what it is compared with or added to."""

    value: Fraction
    unit: str


@dataclass(frozen=True, slots=True)
class Var:
    """A variable; ``boolean`` for variables declared ``bool`` (a condition, not a number)."""

    name: str
    boolean: bool = False


@dataclass(frozen=True, slots=True)
class Arith:
    """``op`` in ``+ - * / ^`` (binary), ``neg`` (unary), ``abs``/``min``/``max`` (calls)."""

    op: str
    args: tuple[Expr, ...]


@dataclass(frozen=True, slots=True)
class Compare:
    op: str
    left: Expr
    right: Expr


@dataclass(frozen=True, slots=True)
class Logic:
    """``op`` in ``and``, ``or`` (n-ary), ``not`` (unary), ``implies`` (binary)."""

    op: str
    args: tuple[Expr, ...]


@dataclass(frozen=True, slots=True)
class Temporal:
    """A bounded temporal operator (monitors only; see :mod:`simcred.contracts.temporal`):
    ``always``, ``eventually``, ``historically``, ``once`` (one operand), ``until``, ``since``
    (two), with the window [lo, hi] in seconds; ``previous`` (one operand, no window)."""

    op: str
    lo: Fraction
    hi: Fraction
    args: tuple[Expr, ...]


Expr = Num | Quantity | Bool | Var | Arith | Compare | Logic | Temporal
BOOLEAN = (Bool, Compare, Logic, Temporal)
TEMPORAL_OPS = ("always", "eventually", "historically", "once", "previous", "until", "since")
#: The identifier grammar, the one for every name the contracts and validate accept: a name, or
#: dotted names (``ego.v``, ``deviation.gap``). The parser's names are never a keyword;
#: a library refuses a name that is a logic word; validate reserves those and ``deviation``.
IDENTIFIER = r"[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*"
LOGIC_WORDS = ("and", "or", "not", "implies", "true", "false")
KEYWORDS = LOGIC_WORDS + TEMPORAL_OPS

# Limits that keep every later step (recursion, z3, exact arithmetic) bounded; see docs.
MAX_TEXT = 10_000  # characters of one assertion
MAX_DEPTH = 200  # nesting of operations (a sum of n terms nests n - 1 deep)
MAX_DEGREE = 16  # polynomial degree of any term
MAX_DIGITS = 40  # digits of a number literal
MAX_EXPONENT = 100  # |e| of a number literal's decimal exponent


def is_boolean(e: Expr) -> bool:
    return isinstance(e, BOOLEAN) or (isinstance(e, Var) and e.boolean)


def variables(e: Expr) -> frozenset[str]:
    """Names of the variables ``e`` mentions."""
    if isinstance(e, Var):
        return frozenset((e.name,))
    return frozenset().union(*(variables(c) for c in children(e)))


def conjuncts(e: Expr) -> tuple[Expr, ...]:
    """The top-level clauses of ``e`` (the operands of an outer ``and``)."""
    if isinstance(e, Logic) and e.op == "and":
        return tuple(c for arg in e.args for c in conjuncts(arg))
    return (e,)


def conjoin(*parts: Expr) -> Expr:
    """The conjunction of ``parts``, flattened (an empty one is ``true``)."""
    flat = tuple(c for p in parts for c in conjuncts(p))
    return Bool(True) if not flat else flat[0] if len(flat) == 1 else Logic("and", flat)


def disjoin(*parts: Expr) -> Expr:
    return parts[0] if len(parts) == 1 else Logic("or", tuple(parts))


def negate(e: Expr) -> Expr:
    return Logic("not", (e,))


def implies(a: Expr, b: Expr) -> Expr:
    return Logic("implies", (a, b))


def children(e: Expr) -> tuple[Expr, ...]:
    """The operands of ``e`` (none for leaves)."""
    if isinstance(e, Compare):
        return (e.left, e.right)
    return e.args if isinstance(e, Arith | Logic | Temporal) else ()


def is_temporal(e: Expr) -> bool:
    """Whether ``e`` uses a temporal operator anywhere."""
    return isinstance(e, Temporal) or any(is_temporal(c) for c in children(e))



def degree(e: Expr) -> int:
    """Polynomial degree of ``e`` (a quotient counts as the product of its operands)."""
    if isinstance(e, Var):
        return 0 if e.boolean else 1
    if isinstance(e, Num | Quantity | Bool):
        return 0
    if isinstance(e, Arith) and e.op in ("*", "/"):
        return degree(e.args[0]) + degree(e.args[1])
    if isinstance(e, Arith) and e.op == "^":
        return degree(e.args[0]) * int(e.args[1].value)
    return max(degree(c) for c in children(e))


# -- printing -----------------------------------------------------------------------------------

_PRECEDENCE = {"implies": 1, "or": 2, "and": 3, "not": 4, "compare": 5, "+": 6, "-": 6, "*": 7,
               "/": 7, "neg": 8, "^": 9}


def to_text(e: Expr) -> str:
    """Text that parses back to ``e`` (parenthesised where precedence needs it)."""
    return _text(e, 0)


def decimal_text(value: Fraction) -> str | None:
    """The exact decimal of ``value`` (``0.25``) when it has one (denominator 2^a 5^b)."""
    value = Fraction(value)
    d, twos, fives = value.denominator, 0, 0
    while d % 2 == 0:
        d, twos = d // 2, twos + 1
    while d % 5 == 0:
        d, fives = d // 5, fives + 1
    if d != 1:
        return None
    places = max(twos, fives)
    digits = str(abs(value.numerator) * 10 ** places // value.denominator).rjust(places + 1, "0")
    text = digits if places == 0 else f"{digits[:-places]}.{digits[-places:]}"
    return ("-" if value < 0 else "") + text


def _window_text(value: Fraction) -> str:
    exact = decimal_text(value)
    return exact if exact is not None else str(float(value))


def _number_text(value: Fraction) -> str:
    """Exact text of a non-negative literal: a decimal where there is one, else ``(p/q)``."""
    text = decimal_text(value)
    return text if text is not None else f"({value.numerator}/{value.denominator})"


def _text(e: Expr, outer: int) -> str:
    if isinstance(e, Num):
        return _number_text(e.value) if e.value >= 0 else f"(-{_number_text(-e.value)})"
    if isinstance(e, Quantity):
        sign, size = ("-" if e.value < 0 else ""), abs(e.value)
        exact = decimal_text(size)
        if exact is not None:
            return f"{sign}{exact} [{e.unit}]" if not sign else f"(-{exact} [{e.unit}])"
        return f"({sign}{size.numerator} [{e.unit}] / {size.denominator})"
    if isinstance(e, Bool):
        return "true" if e.value else "false"
    if isinstance(e, Var):
        return e.name
    if isinstance(e, Arith) and e.op in ("abs", "min", "max"):
        return f"{e.op}({', '.join(_text(a, 0) for a in e.args)})"
    if isinstance(e, Temporal):
        window = f"[{_window_text(e.lo)}, {_window_text(e.hi)}]"
        if e.op == "previous":
            prec, text = 4, f"previous {_text(e.args[0], 4)}"
        elif e.op in ("until", "since"):
            prec, text = 2, f"{_text(e.args[0], 3)} {e.op}{window} {_text(e.args[1], 3)}"
        else:
            prec, text = 4, f"{e.op}{window} {_text(e.args[0], 4)}"
        return f"({text})" if prec < outer else text
    if isinstance(e, Compare):
        prec, text = 5, f"{_text(e.left, 6)} {e.op} {_text(e.right, 6)}"
    elif e.op == "neg":
        prec, text = 8, f"-{_text(e.args[0], 8)}"
    elif e.op == "not":
        prec, text = 4, f"not {_text(e.args[0], 4)}"
    elif e.op == "implies":
        prec, text = 1, f"{_text(e.args[0], 2)} implies {_text(e.args[1], 1)}"
    else:
        prec = _PRECEDENCE[e.op]
        right = prec + 1  # left-associative: a right operand of equal precedence needs parens
        if e.op == "^":
            text = f"{_text(e.args[0], prec + 1)} ^ {_text(e.args[1], prec)}"
        else:
            text = f" {e.op} ".join([_text(e.args[0], prec)]
                                    + [_text(a, right) for a in e.args[1:]])
    return f"({text})" if prec < outer or (prec == outer == 5) else text
