"""Configuration as a 0-1 optimisation problem (issue 28, item 2): box guarantees, any assumptions.

Applies when the architecture is acyclic, every model's guarantee is a non-empty box over its
component's outputs, and the test case's assumption is a box over the environment — the
assumptions may be anything z3 decides (unions of intervals: non-convex validity domains; sums
over several inputs, such as an AD function's error budget over every sensor's error).

**Exactness** (the argument of :mod:`simcred.contracts.search`, which does not need the
assumptions to be boxes): give every variable a box — environment variables the test case's box,
outputs the guarantee box of the chosen model driving them. A setup is valid iff every chosen
model's input box lies within its assumption and the box of the test case's guarantee variables
within that guarantee: if so, every feasible point lies in the boxes; if not, a point of the box
outside the assumption (other variables inside their non-empty boxes) is feasible and violates it.
The guarantees being non-empty boxes over outputs, every such setup is realisable too.

**Encoding.** One 0-1 variable per (component, model), exactly one per component, total cost
minimised — a mixed-integer linear program with integer data (costs, weights and bounds scaled
exactly by their common denominators), solved by HiGHS (``scipy.optimize.milp``, relative gap
0). z3 ``Optimize`` (weighted MaxSAT or a pseudo-Boolean objective) found no answer within 120 s
on the fan-in of 20 sensors × 6 models, a knapsack that an LP-based solver closes at once. The
chosen setup is then proven valid by the z3 refinement check (:mod:`.configure`). Each
containment "the input box lies within A" becomes:

* when A is a conjunction of non-strict linear inequalities Σ a_v·v ≤ b: the supremum of the
  left side over the box is Σ_v sup(a_v·v), and sup(a_v·v) is a constant for an environment
  variable and Σ_j [model j chosen]·sup_j for a driven one — one linear row, enforced when
  the model is chosen (big-M) (no enumeration: the fan-in of 20 sensors into one budget is one
  constraint over 120 Booleans);
* otherwise, for every combination of the models driving its inputs (at most
  ``MAX_COMBINATIONS``), z3 decides the containment once, and each failing combination becomes a
  row forbidding it together with the model.

Not applicable (None) otherwise; configuration then falls back to the counterexample-guided
search.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from simcred.contracts.algebra import Status, valid
from simcred.contracts.expr import Arith, Compare, Expr, Num, Var, conjoin, conjuncts, variables
from simcred.contracts.intervals import REAL_LINE, Interval
from simcred.contracts.parse import parse
from simcred.contracts.search import _topological, box

MAX_COMBINATIONS = 4096


@dataclass(frozen=True, slots=True)
class Optimum:
    setup: dict[str, str] | None  # None: no setup is valid
    cost: float | None
    constraints: int  # containment constraints and clauses given to the solver
    checks: int  # containments decided by z3 while encoding


def optimise(library, target, choices: dict[str, list[str]], forbidden=()) -> Optimum | None:
    """The cheapest valid setup by 0-1 optimisation (module docs), or None outside the
    fragment. ``forbidden``: combinations (component → model) that may not be chosen together."""
    types = library.types
    inputs = {c: tuple(sorted(library.uncontrolled(c))) for c in choices}
    outputs = {c: tuple(sorted(library.controlled(c))) for c in choices}
    if _topological(choices, inputs, outputs) is None:
        return None
    environment = box(target.assumption, types)
    if environment is None or set(environment) - library.environment():
        return None
    guarantee: dict[str, dict[str, Interval]] = {}
    for ms in choices.values():
        for m in ms:
            g = box(library.model_contracts[m].guarantee, types)
            c = library.spec.models[m].implements
            if g is None or set(g) - set(outputs[c]) or any(i.empty for i in g.values()):
                return None
            guarantee[m] = g
    driver = {v: c for c in choices for v in outputs[c]}
    index = {(c, m): i for i, (c, m) in enumerate((c, m) for c, ms in choices.items()
                                                  for m in ms)}
    rows: list[tuple[dict[int, int], int]] = []  # Σ coefficient·x <= bound, integers
    for combination in forbidden:
        picked = [index[c, m] for c, m in combination.items() if (c, m) in index]
        rows.append(({i: 1 for i in picked}, len(picked) - 1))
    counts = {"constraints": 0, "checks": 0}
    context = (choices, guarantee, environment, driver, index, types)
    consumers = [(index[c, m], library.model_contracts[m].assumption, inputs[c])
                 for c, ms in choices.items() for m in ms]
    consumers.append((None, target.guarantee, tuple(sorted(variables(target.guarantee)))))
    for chosen, assumption, variables_ in consumers:
        found = _containment(assumption, variables_, context, counts)
        if found is None:
            return None
        rows += [_enforced(row, chosen) for row in found]
    costs = {k: Fraction(library.spec.models[k[1]].cost) for k in index}
    setup = _solve(choices, index, rows, costs)
    if setup is None:
        return Optimum(None, None, counts["constraints"], counts["checks"])
    return Optimum(setup, float(sum(costs[c, m] for c, m in setup.items())),
                   counts["constraints"], counts["checks"])


def _enforced(row, chosen):
    """``row`` (Σ a·x <= b) required only when the pick ``chosen`` is 1 (big-M with the
    largest value the left side can take), or always (``chosen`` None)."""
    coefficients, bound = row
    if chosen is None:
        return row
    big = max(0, sum(a for a in coefficients.values() if a > 0) - bound)
    out = dict(coefficients)
    out[chosen] = out.get(chosen, 0) + big
    return out, bound + big


def _solve(choices, index, rows, costs) -> dict[str, str] | None:
    """The least-cost 0-1 point of the rows, one pick per component (HiGHS MILP via scipy,
    relative gap 0; integer data), or None if there is none."""
    from scipy.optimize import Bounds, LinearConstraint, milp
    from scipy.sparse import lil_matrix

    n = len(index)
    scale = math.lcm(*(f.denominator for f in costs.values()))
    c = np.zeros(n)
    for key, i in index.items():
        c[i] = float(costs[key] * scale)
    constraints = []
    one = lil_matrix((len(choices), n))
    for r, (comp, ms) in enumerate(choices.items()):
        for m in ms:
            one[r, index[comp, m]] = 1
    constraints.append(LinearConstraint(one.tocsr(), 1, 1))
    if rows:
        matrix = lil_matrix((len(rows), n))
        upper = np.empty(len(rows))
        for r, (coefficients, bound) in enumerate(rows):
            for i, a in coefficients.items():
                matrix[r, i] = a
            upper[r] = bound
        constraints.append(LinearConstraint(matrix.tocsr(), -np.inf, upper))
    result = milp(c, constraints=constraints, integrality=np.ones(n), bounds=Bounds(0, 1),
                  options={"mip_rel_gap": 0})
    if result.status != 0 or result.x is None:
        return None
    chosen = {key for key, i in index.items() if result.x[i] > 0.5}
    return {comp: next(m for m in ms if (comp, m) in chosen) for comp, ms in choices.items()}


def _containment(assumption: Expr, variables_, context, counts):
    """Integer rows (Σ a·x <= b over the picks) that say "the input box lies within
    ``assumption``" (module docs), or None if neither encoding applies."""
    choices, guarantee, environment, driver, index, types = context
    linear = _linear_inequalities(assumption)
    if linear is not None:
        rows = []
        for coefficients, bound in linear:
            total, terms = Fraction(0), []
            for v, a in coefficients.items():
                if v in driver:
                    c = driver[v]
                    for m in choices[c]:
                        top = _sup(a, guarantee[m].get(v, REAL_LINE))
                        if top is None:  # unbounded: this pick violates the inequality
                            rows.append(({index[c, m]: 1}, 0))
                        else:
                            terms.append((index[c, m], top))
                else:
                    top = _sup(a, environment.get(v, REAL_LINE))
                    if top is None:
                        return [({}, -1)]  # never
                    total += top
            rows.append(_at_most(terms, bound - total))
            counts["constraints"] += 1
        return rows
    drivers = sorted({driver[v] for v in variables_ if v in driver})
    if math.prod(len(choices[c]) for c in drivers) > MAX_COMBINATIONS:
        return None
    rows = []
    for combination in itertools.product(*(choices[c] for c in drivers)):
        boxes = {v: environment.get(v, REAL_LINE) for v in variables_ if v not in driver}
        for c, m in zip(drivers, combination, strict=True):
            boxes.update({v: guarantee[m].get(v, REAL_LINE) for v in variables_
                          if driver.get(v) == c})
        counts["checks"] += 1
        inside = _within_union(boxes, assumption, types)
        if inside is None:
            verdict = valid([_box_expr(boxes)], assumption, types=types, timeout_ms=10_000)
            if verdict.status is Status.UNKNOWN:
                return None
            inside = verdict.holds
        if not inside:  # not all of these picks together
            picks = [index[c, m] for c, m in zip(drivers, combination, strict=True)]
            rows.append(({i: 1 for i in picks}, len(picks) - 1))
            counts["constraints"] += 1
    return rows


def _at_most(terms: list, bound: Fraction) -> tuple[dict[int, int], int]:
    """Σ x_i·w_i <= bound in integers: every weight and the bound scaled by their common
    denominator (exact), the bound rounded down (the left side is an integer)."""
    scale = math.lcm(bound.denominator, *(w.denominator for _, w in terms))
    row: dict[int, int] = {}
    for i, w in terms:
        row[i] = row.get(i, 0) + int(w * scale)
    return row, math.floor(bound * scale)


def _within_union(boxes: dict[str, Interval], assumption: Expr, types) -> bool | None:
    """Exactly, without z3: is a one-variable box within an assumption that is a union of
    intervals of that variable (``0 <= x <= 4 or 6 <= x <= 9``)? None if not of that form."""
    from simcred.contracts.expr import Logic

    parts = assumption.args if isinstance(assumption, Logic) and assumption.op == "or" \
        else (assumption,)
    pieces = [box(part, types) for part in parts]
    names = {n for b in pieces if b is not None for n in b}
    if any(b is None for b in pieces) or len(names) != 1:
        return None
    (name,) = names
    inner = boxes.get(name, REAL_LINE)
    if inner.empty:
        return True
    merged: list[Interval] = []
    for piece in sorted((b[name] for b in pieces if not b[name].empty),
                        key=lambda i: (i.lo is not None, i.lo or 0, i.lo_open)):
        last = merged[-1] if merged else None
        if last is not None and (last.hi is None or piece.lo is None or piece.lo < last.hi
                                 or (piece.lo == last.hi
                                     and not (last.hi_open and piece.lo_open))):
            hi, closed = (None, True) if last.hi is None or piece.hi is None else \
                max((last.hi, not last.hi_open), (piece.hi, not piece.hi_open))
            merged[-1] = Interval(last.lo, hi, last.lo_open, not closed)
        else:
            merged.append(piece)
    return any(inner.within(m) for m in merged)


def _box_expr(boxes: dict[str, Interval]) -> Expr:
    return conjoin(*(parse(i.text(v)) for v, i in boxes.items() if i != REAL_LINE))


def _sup(a: Fraction, interval: Interval) -> Fraction | None:
    """sup of a·x over the interval (None: +∞)."""
    end = interval.hi if a > 0 else interval.lo
    if a == 0:
        return Fraction(0)
    return None if end is None else a * end


def _linear_inequalities(e: Expr) -> list[tuple[dict[str, Fraction], Fraction]] | None:
    """``e`` as Σ a_v·v <= b clauses (non-strict ``<=``/``>=``), or None."""
    out = []
    for clause in conjuncts(e):
        if not isinstance(clause, Compare) or clause.op not in ("<=", ">="):
            return None
        left, right = _affine(clause.left), _affine(clause.right)
        if left is None or right is None:
            return None
        if clause.op == ">=":
            left, right = right, left
        coefficients = dict(left[0])
        for v, a in right[0].items():
            coefficients[v] = coefficients.get(v, Fraction(0)) - a
        out.append(({v: a for v, a in coefficients.items() if a}, right[1] - left[1]))
    return out


def _affine(e: Expr):
    """(coefficients, constant) of an affine term, or None."""
    if isinstance(e, Num):
        return {}, e.value
    if isinstance(e, Var) and not e.boolean:
        return {e.name: Fraction(1)}, Fraction(0)
    if not isinstance(e, Arith):
        return None
    parts = [_affine(a) for a in e.args]
    if any(p is None for p in parts):
        return None
    if e.op == "neg":
        return {v: -a for v, a in parts[0][0].items()}, -parts[0][1]
    if e.op in ("+", "-"):
        sign = 1 if e.op == "+" else -1
        (ca, ka), (cb, kb) = parts
        merged = dict(ca)
        for v, a in cb.items():
            merged[v] = merged.get(v, Fraction(0)) + sign * a
        return merged, ka + sign * kb
    if e.op == "*":
        (ca, ka), (cb, kb) = parts
        if ca and cb:
            return None
        (coefficients, k), factor = ((ca, ka), kb) if not cb else ((cb, kb), ka)
        return {v: a * factor for v, a in coefficients.items()}, k * factor
    if e.op == "/" and not parts[1][0] and parts[1][1] != 0:
        d = parts[1][1]
        return {v: a / d for v, a in parts[0][0].items()}, parts[0][1] / d
    return None
