"""Readable forms of derived assertions (quotients, projections): what a person can sign.

Quantifier elimination and the algebra's formulas produce correct but unreadable text
(``(1/5) >= e or (1/5) >= d and (1/5) >= e``). :func:`tidy` rewrites an assertion into an
equivalent one, by rules that are each a law of Boolean algebra or of order:

* a constant on the left of a comparison moves to the right (``0.2 >= e`` → ``e <= 0.2``);
* absorption: ``a or (a and b)`` → ``a``; ``a and (a or b)`` → ``a``; duplicates dropped;
* bounds on one variable in a conjunction merge to the tightest (``x <= 3 and x <= 5`` →
  ``x <= 3``); contradictory bounds make the conjunction ``false``;
* ``true``/``false`` operands are folded away.

:func:`text` then prints a variable with a lower and an upper bound as a chain
``25 <= v <= 30`` (which parses back to the same conjunction) and numbers as exact decimals.
"""

from __future__ import annotations

from fractions import Fraction

from simcred.contracts.expr import (
    Arith,
    Bool,
    Compare,
    Expr,
    Logic,
    Num,
    Var,
    conjoin,
    decimal_text,
    to_text,
)
from simcred.contracts.intervals import REAL_LINE, Interval

_FLIP = {"<=": ">=", "<": ">", ">=": "<=", ">": "<", "==": "==", "!=": "!="}
_NEGATED = {"<=": ">", "<": ">=", ">=": "<", ">": "<=", "==": "!=", "!=": "=="}


def tidy(e: Expr) -> Expr:
    """An equivalent, shorter assertion (module docs)."""
    if isinstance(e, Compare):
        if isinstance(e.left, Num) and not isinstance(e.right, Num):
            e = Compare(_FLIP[e.op], e.right, e.left)
        return _scaled(e)
    if not isinstance(e, Logic):
        return e
    args = [tidy(a) for a in e.args]
    if e.op == "not":
        return _negation(args[0])
    if e.op == "implies":
        return Logic("implies", tuple(args))
    return _junction(e.op, args)


def _scaled(e: Compare) -> Compare:
    """``c * x op d`` and ``-x op d`` → ``x op' d / c`` (the order flips for c < 0)."""
    left, right = e.left, e.right
    if not isinstance(right, Num):
        return e
    if isinstance(left, Arith) and left.op == "neg" and isinstance(left.args[0], Var):
        scale, var = Fraction(-1), left.args[0]
    elif (isinstance(left, Arith) and left.op == "*" and isinstance(left.args[0], Num)
          and isinstance(left.args[1], Var) and left.args[0].value != 0):
        scale, var = left.args[0].value, left.args[1]
    else:
        return e
    op = e.op if scale > 0 else _FLIP[e.op]
    return Compare(op, var, Num(right.value / scale))


def _union(parts: list[Expr]) -> Expr | None:
    """A disjunction of bounds on one variable whose union is one interval, as that interval;
    with gaps, the disjuncts in ascending order (whatever order the solver gave them in)."""
    found = []
    for p in parts:
        clauses = p.args if isinstance(p, Logic) and p.op == "and" else (p,)
        bounds = [_bound(c) for c in clauses]
        if any(b is None or b[1] is None for b in bounds) or len({b[0] for b in bounds}) != 1:
            return None
        interval = REAL_LINE
        for _, i in bounds:
            interval = interval.meet(i)
        found.append((bounds[0][0], interval))
    if len({name for name, _ in found}) != 1:
        return None
    spans = sorted((i for _, i in found if not i.empty), key=_lower_key)
    merged = spans[0] if spans else None
    for span in spans[1:]:
        if merged.hi is None:
            break  # already unbounded above: the rest lies inside
        if span.lo is not None and (span.lo > merged.hi or (
                span.lo == merged.hi and merged.hi_open and span.lo_open)):
            # a gap: not one interval; the intervals in ascending order
            ranked = sorted(zip(found, parts, strict=True), key=lambda f: _lower_key(f[0][1]))
            return Logic("or", tuple(p for _, p in ranked))
        if span.hi is None or span.hi > merged.hi or (span.hi == merged.hi and not span.hi_open):
            merged = Interval(merged.lo, span.hi, merged.lo_open, span.hi_open)
    if merged is None:
        return Bool(False)
    return conjoin(*_clauses(found[0][0], merged))


def _common_factor(disjuncts: list[Expr]) -> Expr | None:
    """(c and a) or (c and b) → c and (a or b) (distributivity), then tidied; None if the
    disjuncts share no conjunct."""
    parts = [d.args if isinstance(d, Logic) and d.op == "and" else (d,) for d in disjuncts]
    common = [c for c in parts[0] if all(c in p for p in parts[1:])]
    if not common:
        return None
    rests = [conjoin(*(c for c in p if c not in common)) for p in parts]
    if Bool(True) in rests:
        return tidy(conjoin(*common))  # one disjunct is the common part: absorption
    return tidy(Logic("and", (*common, Logic("or", tuple(rests)))))


def _lower_key(i: Interval):
    return (float("-inf"), 0) if i.lo is None else (i.lo, int(i.lo_open))


def _negation(inner: Expr) -> Expr:
    """``not inner`` pushed inwards (De Morgan; negated comparisons flip)."""
    if isinstance(inner, Bool):
        return Bool(not inner.value)
    if isinstance(inner, Compare) and inner.op in _NEGATED:
        return Compare(_NEGATED[inner.op], inner.left, inner.right)
    if isinstance(inner, Logic) and inner.op == "not":
        return inner.args[0]
    if isinstance(inner, Logic) and inner.op in ("and", "or"):
        return _junction("or" if inner.op == "and" else "and",
                         [_negation(a) for a in inner.args])
    return Logic("not", (inner,))


TRUE = Bool(True)


def within(e: Expr, context: Expr = TRUE, *, types=None, timeout_ms: int = 2_000
           ) -> Expr:
    """``e`` simplified where ``context`` holds: conjuncts implied by the context and the other
    conjuncts are dropped, disjuncts that contradict the context too, recursively; the result
    E* satisfies context ∧ E ≡ context ∧ E*. For a guarantee under its contract's assumption
    this is the same contract (same saturation); for an assumption (context ``true``) the same
    assertion. Solver calls are time-limited; an undecided part is kept as it is."""
    from simcred.contracts.algebra import Status, valid

    def proves(premises, claim) -> bool:
        return valid(premises, claim, types=types, timeout_ms=timeout_ms).status is Status.HOLDS

    e = tidy(e)
    if not isinstance(e, Logic) or e.op not in ("and", "or"):
        return e
    parts = list(e.args)
    if e.op == "and":
        kept: list[Expr] = []
        for i, part in enumerate(parts):
            others = [context, *kept, *parts[i + 1:]]
            if not proves(others, part):
                kept.append(within(part, conjoin(*others), types=types, timeout_ms=timeout_ms))
        return tidy(conjoin(*kept))
    kept = [within(p, context, types=types, timeout_ms=timeout_ms) for p in parts
            if not proves([context, p], Bool(False))]
    return tidy(Logic("or", tuple(kept))) if len(kept) > 1 else kept[0] if kept else Bool(False)


def _junction(op: str, args: list[Expr]) -> Expr:
    unit, zero = (Bool(True), Bool(False)) if op == "and" else (Bool(False), Bool(True))
    flat: list[Expr] = []
    for a in args:
        for part in (a.args if isinstance(a, Logic) and a.op == op else (a,)):
            if part == zero:
                return zero
            if part != unit and part not in flat:
                flat.append(part)
    other = "or" if op == "and" else "and"
    # absorption: an operand that is an `other`-junction containing another operand goes
    flat = [a for a in flat if not (isinstance(a, Logic) and a.op == other
                                    and any(b in a.args for b in flat if b is not a))]
    if op == "and":
        merged = _merge_bounds(flat)
        if merged is None:
            return Bool(False)
        flat = merged
    elif len(flat) > 1:
        union = _union(flat)
        if union is not None:
            return union
        factored = _common_factor(flat)
        if factored is not None:
            return factored
    if not flat:
        return unit
    return flat[0] if len(flat) == 1 else Logic(op, tuple(flat))


def _bound(e: Expr) -> tuple[str, Interval] | None:
    if not (isinstance(e, Compare) and isinstance(e.left, Var) and isinstance(e.right, Num)):
        return None
    c = e.right.value
    return e.left.name, {"<=": Interval(hi=c), "<": Interval(hi=c, hi_open=True),
                         ">=": Interval(lo=c), ">": Interval(lo=c, lo_open=True),
                         "==": Interval(c, c)}.get(e.op)


def _merge_bounds(clauses: list[Expr]) -> list[Expr] | None:
    """Clauses with the bounds on each variable merged (None: they contradict)."""
    boxes: dict[str, Interval] = {}
    rest: list[Expr] = []
    order: list[str] = []
    for clause in clauses:
        found = _bound(clause)
        if found is None or found[1] is None:
            rest.append(clause)
            continue
        name, interval = found
        if name not in boxes:
            order.append(name)
        boxes[name] = boxes.get(name, REAL_LINE).meet(interval)
    if any(i.empty for i in boxes.values()):
        return None
    out = [c for name in order for c in _clauses(name, boxes[name])]
    return out + rest


def _clauses(name: str, interval: Interval) -> list[Expr]:
    var = Var(name)
    if interval.lo is not None and interval.lo == interval.hi:
        return [Compare("==", var, Num(interval.lo))]
    out = []
    if interval.lo is not None:
        out.append(Compare(">" if interval.lo_open else ">=", var, Num(interval.lo)))
    if interval.hi is not None:
        out.append(Compare("<" if interval.hi_open else "<=", var, Num(interval.hi)))
    return out


def _plain(e: Expr) -> str:
    """A number without the parentheses ``to_text`` puts around negative ones."""
    if isinstance(e, Num):
        return decimal_text(e.value) or to_text(e)
    return to_text(e)


def text(e: Expr) -> str:
    """``tidy(e)`` as text, with two-sided bounds printed as chains (``25 <= v <= 30``)."""
    e = tidy(e)
    if not (isinstance(e, Logic) and e.op == "and"):
        return to_text(e)
    parts, args, i = [], list(e.args), 0
    while i < len(args):
        a = args[i]
        b = args[i + 1] if i + 1 < len(args) else None
        if (b is not None and isinstance(a, Compare) and isinstance(b, Compare)
                and a.op in (">=", ">") and b.op in ("<=", "<") and a.left == b.left
                and isinstance(a.left, Var)):
            parts.append(f"{_plain(a.right)} {_FLIP[a.op]} {to_text(a.left)} {b.op} "
                         f"{_plain(b.right)}")
            i += 2
            continue
        parts.append(f"({to_text(a)})" if isinstance(a, Logic) and a.op in ("or", "implies")
                     else to_text(a))
        i += 1
    return " and ".join(parts)
