"""The assertion language: a small safe grammar (lark, never ``eval``) and one AST, two back ends.

Assertions are arithmetic over declared variables (``+ - * / ^``, ``abs``, ``min``, ``max``,
numbers), comparisons (chains like ``0 <= v <= 30`` allowed) and ``and``, ``or``, ``not``,
``implies``, ``true``, ``false``. Variable names may be dotted (``ego.v``). Numbers are parsed
exactly (``Fraction``), so ``x <= 0.2`` refines itself.

Back ends: :func:`to_z3` (reasoning, exact rationals) and :func:`evaluate` (vectorised numpy over
columns of recorded runs), plus :func:`margin`, the signed distance to violation (STL-style
robustness: positive where an assertion holds, negative where it is violated).
"""

from __future__ import annotations

import operator
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from fractions import Fraction
from functools import cache
from typing import Any

import numpy as np
from lark import Lark, Token, Transformer, v_args
from lark.exceptions import LarkError, UnexpectedInput

from simcred.errors import SimcredError

KEYWORDS = ("and|or|not|implies|true|false|always|eventually|historically|once|previous|until"
            "|since")
GRAMMAR = r"""
?start: implication
?implication: binary_temporal ("implies" implication)?
?binary_temporal: disjunction (BINARY_TEMPORAL window disjunction)?
?disjunction: conjunction ("or" conjunction)*
?conjunction: negation ("and" negation)*
?negation: "not" negation -> logical_not
         | UNARY_TEMPORAL window negation -> temporal
         | "previous" negation -> previous
         | comparison
window: "[" signed "," signed "]"
signed: NUMBER | "-" NUMBER -> minus
?comparison: sum (COMPARE sum)*
?sum: product (ADD product)*
?product: unary (MUL unary)*
?unary: "-" unary -> negative
      | power
?power: atom ("^" unary)?
?atom: NUMBER UNIT -> quantity
     | NUMBER -> number
     | "true" -> true
     | "false" -> false
     | FUNCTION "(" implication ("," implication)* ")" -> call
     | NAME -> variable
     | "(" implication ")"
COMPARE: "<=" | ">=" | "==" | "!=" | "<" | ">"
ADD: "+" | "-"
MUL: "*" | "/"
FUNCTION.2: /(abs|min|max)(?=\s*\()/
UNARY_TEMPORAL.2: /(always|eventually|historically|once)\b/
BINARY_TEMPORAL.2: /(until|since)\b/
NAME: /(?!(KEYWORDS)\b)[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*/
UNIT: /\[[^\[\]]*\]/ | /(?!(KEYWORDS)\b)/ UNIT_FACTOR (/[\/*]/ UNIT_FACTOR)*
UNIT_FACTOR: /[A-Za-z_°µΩ][A-Za-z0-9_]*(\^-?\d+)?/
NUMBER: /\d+(\.\d*)?([eE][+-]?\d+)?|\.\d+([eE][+-]?\d+)?/
%import common.WS
%ignore WS
""".replace("KEYWORDS", KEYWORDS)


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


# -- parsing ------------------------------------------------------------------------------------


@cache
def _parser() -> Lark:
    return Lark(GRAMMAR, parser="lalr", propagate_positions=True)


def _literal(text: str) -> Fraction:
    """The exact value of a number literal, within the digit and exponent limits."""
    mantissa, _, exponent = text.lower().partition("e")
    digits = len(mantissa.replace(".", "").lstrip("0"))
    if digits > MAX_DIGITS:
        raise ExpressionError(f"the number {text[:20]}... has {digits} digits (at most "
                              f"{MAX_DIGITS})")
    if exponent and abs(int(exponent)) > MAX_EXPONENT:
        raise ExpressionError(f"the exponent of {text[:40]} is beyond ±{MAX_EXPONENT}")
    return Fraction(text)


@v_args(meta=True)
class _ToAst(Transformer):
    def __init__(self, booleans: frozenset[str] = frozenset()):
        super().__init__()
        self.booleans = booleans

    def number(self, meta, children):
        return Num(_literal(str(children[0])))

    def quantity(self, meta, children):
        unit = str(children[1]).strip("[]").strip()
        return Quantity(_literal(str(children[0])), unit)

    def true(self, meta, children):
        return Bool(True)

    def false(self, meta, children):
        return Bool(False)

    def variable(self, meta, children):
        name = str(children[0])
        return Var(name, name in self.booleans)

    def call(self, meta, children):
        name, args = str(children[0]), tuple(children[1:])
        if name == "abs" and len(args) != 1:
            raise ExpressionError(f"abs takes 1 argument, got {len(args)}")
        if name in ("min", "max") and len(args) < 2:
            raise ExpressionError(f"{name} takes at least 2 arguments, got {len(args)}")
        return Arith(name, tuple(_arith(a, name) for a in args))

    def negative(self, meta, children):
        operand = _arith(children[0], "-")
        if isinstance(operand, Num):
            return Num(-operand.value)
        if isinstance(operand, Quantity):
            return Quantity(-operand.value, operand.unit)
        return Arith("neg", (operand,))

    def power(self, meta, children):
        base, exponent = _arith(children[0], "^"), _arith(children[1], "^")
        if not (isinstance(exponent, Num) and exponent.value.denominator == 1
                and 0 <= exponent.value <= 16):
            raise ExpressionError("the exponent of ^ must be a whole number from 0 to 16")
        return Arith("^", (base, exponent))

    def sum(self, meta, children):
        return _fold(children)

    product = sum

    def comparison(self, meta, children):
        terms = [_arith(c, "a comparison") for c in children[0::2]]
        ops = [str(op) for op in children[1::2]]
        return conjoin(*(Compare(op, a, b) for op, a, b in zip(ops, terms, terms[1:],
                                                                strict=False)))

    def window(self, meta, children):
        lo, hi = children
        if lo < 0 or hi < lo:
            raise ExpressionError(f"a window [a, b] needs 0 <= a <= b, got [{lo}, {hi}]")
        return lo, hi

    def signed(self, meta, children):
        return _literal(str(children[0]))

    def minus(self, meta, children):
        return -_literal(str(children[0]))

    def temporal(self, meta, children):
        op, (lo, hi), operand = str(children[0]), children[1], children[2]
        return Temporal(op, lo, hi, (_boolean(operand, op),))

    def previous(self, meta, children):
        return Temporal("previous", Fraction(0), Fraction(0),
                        (_boolean(children[0], "previous"),))

    def binary_temporal(self, meta, children):
        left, op, (lo, hi), right = children
        return Temporal(str(op), lo, hi, (_boolean(left, str(op)), _boolean(right, str(op))))

    def logical_not(self, meta, children):
        return Logic("not", (_boolean(children[0], "not"),))

    def conjunction(self, meta, children):
        return _flat("and", [_boolean(c, "and") for c in children])

    def disjunction(self, meta, children):
        return _flat("or", [_boolean(c, "or") for c in children])

    def implication(self, meta, children):
        return Logic("implies", tuple(_boolean(c, "implies") for c in children))


def _flat(op: str, operands: list[Expr]) -> Expr:
    """An n-ary ``and``/``or`` with nested operands of the same operator spliced in."""
    flat = [a for o in operands for a in (o.args if isinstance(o, Logic) and o.op == op
                                          else (o,))]
    return Logic(op, tuple(flat))


def _fold(children) -> Expr:
    expr = _arith(children[0], str(children[1]))
    for op, operand in zip(children[1::2], children[2::2], strict=True):
        operand = _arith(operand, str(op))
        if op == "/" and isinstance(operand, Num) and operand.value == 0:
            raise ExpressionError("division by zero")
        if op == "/" and isinstance(expr, Num) and isinstance(operand, Num):
            expr = Num(expr.value / operand.value)  # a rational literal such as 1/3
        elif op == "/" and isinstance(expr, Quantity) and isinstance(operand, Num):
            expr = Quantity(expr.value / operand.value, expr.unit)  # (1 [m] / 3)
        else:
            expr = Arith(str(op), (expr, operand))
    return expr


def _arith(e: Expr, where: str) -> Expr:
    if is_boolean(e):
        raise ExpressionError(f"{where} needs a number, got the condition '{to_text(e)}'")
    return e


def _boolean(e: Expr, where: str) -> Expr:
    if not is_boolean(e):
        raise ExpressionError(f"{where} needs a condition, got the number '{to_text(e)}'")
    return e


def parse(text: str, *, declared: Mapping[str, Any] | None = None, where: str = "",
          types: Mapping[str, str] | None = None, units: Mapping[str, str] | None = None
          ) -> Expr:
    """Parse an assertion; ``declared`` (if given) must contain every variable it uses.

    ``types`` (variable → ``real``/``int``/``bool``) makes ``bool`` variables conditions;
    ``units`` (variable → pint unit) checks the dimensions of every sum and comparison and
    converts literals with units (``100 km/h``) exactly to the unit of what they meet
    (:func:`simcred.contracts.units.resolve`). Size, nesting, degree and literal limits
    (``MAX_*``) are checked before anything else can recurse or overflow.

    >>> to_text(parse("0 <= ego.v <= 30 and abs(a) < 2.5"))
    '0 <= ego.v and ego.v <= 30 and abs(a) < 2.5'
    """
    prefix = f"{where}: " if where else ""
    if not isinstance(text, str) or not text.strip():
        raise ExpressionError(f"{prefix}empty assertion")
    if len(text) > MAX_TEXT:
        raise ExpressionError(f"{prefix}the assertion has {len(text):,} characters (at most "
                              f"{MAX_TEXT:,})")
    shown = _shown(text)
    try:
        tree = _parser().parse(text)
    except UnexpectedInput as exc:
        raise ExpressionError(
            f"{prefix}line {exc.line}, column {exc.column}: unexpected "
            f"{_describe(exc, text)} in '{shown}'") from None
    except LarkError as exc:
        raise ExpressionError(f"{prefix}cannot parse '{shown}' ({exc})") from None
    if _depth(tree, lambda t: getattr(t, "children", ())) > MAX_DEPTH:
        raise ExpressionError(f"{prefix}'{shown}' nests more than {MAX_DEPTH} levels "
                              "deep")
    booleans = frozenset(n for n, t in (types or {}).items() if t == "bool")
    try:
        expr = _ToAst(booleans).transform(tree)
    except LarkError as exc:  # errors raised inside the transformer come wrapped
        cause = exc.__context__ if isinstance(exc.__context__, ExpressionError) else exc
        raise ExpressionError(f"{prefix}{cause} in '{shown}'") from None
    _check_size(expr, prefix, shown)
    if not is_boolean(expr):
        raise ExpressionError(f"{prefix}'{shown}' is a number, not a condition")
    if declared is not None:
        unknown = sorted(variables(expr) - set(declared))
        if unknown:
            raise ExpressionError(f"{prefix}undeclared variable '{unknown[0]}' in '{shown}'")
    if units is not None:
        from simcred.contracts.units import resolve

        expr = resolve(expr, units, where=f"{prefix}'{shown}'")
    elif _has_quantity(expr):
        raise ExpressionError(f"{prefix}a number with a unit in '{shown}' needs the units of "
                              "the variables (declare them in a library)")
    return expr


def _shown(text: str) -> str:
    """The assertion as quoted in an error: stripped, long ones shortened."""
    text = " ".join(text.split())
    return text if len(text) <= 120 else f"{text[:100]} ... {text[-15:]}"


def children(e: Expr) -> tuple[Expr, ...]:
    """The operands of ``e`` (none for leaves)."""
    if isinstance(e, Compare):
        return (e.left, e.right)
    return e.args if isinstance(e, Arith | Logic | Temporal) else ()


def is_temporal(e: Expr) -> bool:
    """Whether ``e`` uses a temporal operator anywhere."""
    return isinstance(e, Temporal) or any(is_temporal(c) for c in children(e))


def _depth(root, kids) -> int:
    """Nesting depth of a tree, without recursion (the tree may be too deep to recurse)."""
    deepest, stack = 0, [(root, 1)]
    while stack:
        node, level = stack.pop()
        deepest = max(deepest, level)
        if level <= MAX_DEPTH + 1:  # deeper is refused anyway; stop walking there
            stack.extend((k, level + 1) for k in kids(node))
    return deepest


def _check_size(expr: Expr, prefix: str, shown: str) -> None:
    if _depth(expr, children) > MAX_DEPTH:
        raise ExpressionError(f"{prefix}'{shown}' nests more than {MAX_DEPTH} "
                              "operations deep (split long sums into several clauses)")
    worst = degree(expr)
    if worst > MAX_DEGREE:
        raise ExpressionError(f"{prefix}'{shown}' has polynomial degree {worst} (at most "
                              f"{MAX_DEGREE})")


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


def _has_quantity(e: Expr) -> bool:
    return isinstance(e, Quantity) or any(_has_quantity(c) for c in children(e))


def _describe(exc: UnexpectedInput, text: str) -> str:
    token = getattr(exc, "token", None)
    if isinstance(token, Token) and token.type == "$END":
        return "end of input"
    if token is not None:
        return f"'{token}'"
    char = getattr(exc, "char", None)
    return f"'{char}'" if char else "input"


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
    start, stop = timeline.window(float(e.lo), float(e.hi), past=past)
    if e.op in ("until", "since"):
        return temporal.until(args[0], args[1], start, stop, past=past, boolean=boolean)
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
