"""Text → AST: the grammar (lark, LALR, never ``eval``) and the limits that keep every later
step bounded (length, nesting, degree, literal digits and exponents)."""

from __future__ import annotations

from collections.abc import Mapping
from fractions import Fraction
from functools import cache
from typing import Any

from lark import Lark, Token, Transformer, v_args
from lark.exceptions import LarkError, UnexpectedInput

from simcred.contracts.expr import (
    IDENTIFIER,
    MAX_DEGREE,
    MAX_DEPTH,
    MAX_DIGITS,
    MAX_EXPONENT,
    MAX_TEXT,
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
    children,
    conjoin,
    degree,
    is_boolean,
    to_text,
    variables,
)
from simcred.contracts.expr import KEYWORDS as LANGUAGE_KEYWORDS

KEYWORDS = "|".join(LANGUAGE_KEYWORDS)
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
NAME: /(?!(KEYWORDS)\b)IDENTIFIER/
UNIT: /\[[^\[\]]*\]/ | /(?!(KEYWORDS)\b)/ UNIT_FACTOR (/[\/*]/ UNIT_FACTOR)*
UNIT_FACTOR: /(%|[A-Za-z_°µΩΔ][A-Za-z0-9_°]*)(\^-?\d+)?/
NUMBER: /\d+(\.\d*)?([eE][+-]?\d+)?|\.\d+([eE][+-]?\d+)?/
%import common.WS
%ignore WS
""".replace("KEYWORDS", KEYWORDS).replace("IDENTIFIER", IDENTIFIER)


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
