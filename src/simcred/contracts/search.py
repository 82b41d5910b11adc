"""Configuration by exact interval propagation and branch-and-bound (the interval fragment).

Applies when the architecture is acyclic, every model's assumption is a box over its component's
inputs and its guarantee a non-empty box over its outputs, and the test case's assumption is a
box over the environment and its guarantee a box (:mod:`simcred.contracts.intervals`).

**Exactness.** A setup refines the test case iff, for every point p with A_tc(p) and
A_i(p) → G_i(p) for all its models, all A_i(p) and G_tc(p) hold (the flat form of
:func:`simcred.contracts.configure.setup_refines`). Walk the components in topological order and
give every variable a box: environment variables the test case's box, outputs the guarantee box
of the model that drives them. Then the setup is valid **iff** every model's input box lies
within its assumption and every box lies within the test case's guarantee:

* if so, by induction along the order every feasible p lies in the boxes, so each A_i(p) holds,
  hence G_i(p), and G_tc(p) holds;
* if not, take the first model whose input box leaves its assumption (or a box leaving G_tc):
  choose that input's value outside it and all other variables inside their boxes, choosing the
  outputs of downstream models inside their (non-empty) guarantee boxes. This point is feasible
  and violates A_i (or G_tc): the setup is not valid.

**Optimality.** Depth-first branch-and-bound over the topological order, cheapest model first,
with the admissible bound "cost so far + the cheapest model of every remaining component"; a
state (level, boxes of the variables later components read) reached before at no higher cost is
not expanded again, since the remaining choices depend on nothing else. Every setup is thus
either visited or excluded by a bound that no cheaper valid setup can beat: the first-best setup
found is a cheapest valid one (ties broken by the candidate order: cost, then name).
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction

from simcred.contracts.intervals import REAL_LINE, Interval
from simcred.contracts.intervals import box as _box
from simcred.contracts.readable import tidy


def box(expr, types):
    """The box of ``expr`` or of its tidied form (an equivalent one: ``tidy`` merges the
    viewpoints' ``(c and a) or (c and b)`` and unions of intervals), else None."""
    found = _box(expr, types)
    return found if found is not None else _box(tidy(expr), types)


@dataclass(frozen=True, slots=True)
class Candidate:
    model: str
    cost: Fraction  # exact: sums of float costs compare without rounding
    assumption: dict[str, Interval]
    guarantee: dict[str, Interval]


@dataclass(frozen=True, slots=True)
class IntervalProblem:
    order: tuple[str, ...]  # components, topologically sorted
    inputs: dict[str, tuple[str, ...]]
    outputs: dict[str, tuple[str, ...]]
    candidates: dict[str, tuple[Candidate, ...]]
    environment: dict[str, Interval]
    goal: dict[str, Interval]


@dataclass(frozen=True, slots=True)
class SearchResult:
    setup: dict[str, str] | None
    cost: float | None
    nodes: int  # partial setups expanded


def interval_problem(library, target, choices: dict[str, list[str]]) -> IntervalProblem | None:
    """The configuration problem in the interval fragment, or None if it is not in it."""
    types = library.types
    inputs = {c: tuple(sorted(library.uncontrolled(c))) for c in choices}
    outputs = {c: tuple(sorted(library.controlled(c))) for c in choices}
    order = _topological(choices, inputs, outputs)
    environment, goal = box(target.assumption, types), box(target.guarantee, types)
    if order is None or environment is None or goal is None:
        return None
    if set(environment) - library.environment():
        return None
    candidates = {}
    for c, models in choices.items():
        row = []
        for m in models:
            contract = library.model_contracts[m]
            a, g = box(contract.assumption, types), box(contract.guarantee, types)
            if a is None or g is None or set(a) - set(inputs[c]) or set(g) - set(outputs[c]) \
                    or any(i.empty for i in g.values()):
                return None
            row.append(Candidate(m, Fraction(library.spec.models[m].cost), a, g))
        candidates[c] = tuple(row)
    return IntervalProblem(order, inputs, outputs, candidates, environment, goal)


def _topological(choices, inputs, outputs) -> tuple[str, ...] | None:
    driver = {v: c for c in choices for v in outputs[c]}
    order, state = [], dict.fromkeys(choices, 0)  # 0 new, 1 on the path, 2 done

    def visit(c) -> bool:
        if state[c] == 1:
            return False  # a cycle
        if state[c] == 2:
            return True
        state[c] = 1
        if not all(visit(driver[v]) for v in inputs[c] if v in driver):
            return False
        state[c] = 2
        order.append(c)
        return True

    return tuple(order) if all(visit(c) for c in choices) else None


def branch_and_bound(problem: IntervalProblem) -> SearchResult:
    """The cheapest valid setup (see module docs for the proof), or None if there is none."""
    order, n = problem.order, len(problem.order)
    boxes = {v: problem.environment.get(v, REAL_LINE) for c in order for v in problem.inputs[c]}
    if not all(boxes[v].within(problem.goal[v]) for v in problem.goal if v in boxes
               and not any(v in problem.outputs[c] for c in order)):
        return SearchResult(None, None, 0)
    min_rest = [Fraction(0)] * (n + 1)
    for k in range(n - 1, -1, -1):
        min_rest[k] = min_rest[k + 1] + min(c.cost for c in problem.candidates[order[k]])
    live = [tuple(sorted({v for c in order[k:] for v in problem.inputs[c]})) for k in range(n)]
    best: dict = {"cost": float("inf"), "setup": None}
    seen: dict = {}
    nodes = 0

    def expand(k: int, cost: Fraction, chosen: list[str]) -> None:
        nonlocal nodes
        if cost + min_rest[k] >= best["cost"]:
            return
        if k == n:
            best["cost"], best["setup"] = cost, list(chosen)
            return
        key = (k, tuple(boxes[v] for v in live[k]))
        if seen.get(key, float("inf")) <= cost:
            return
        seen[key] = cost
        nodes += 1
        component = order[k]
        for candidate in problem.candidates[component]:
            if not all(boxes[v].within(candidate.assumption.get(v, REAL_LINE))
                       for v in problem.inputs[component]):
                continue
            produced = {v: candidate.guarantee.get(v, REAL_LINE)
                        for v in problem.outputs[component]}
            if not all(i.within(problem.goal[v]) for v, i in produced.items()
                       if v in problem.goal):
                continue
            saved = {v: boxes.get(v) for v in produced}
            boxes.update(produced)
            chosen.append(candidate.model)
            expand(k + 1, cost + candidate.cost, chosen)
            chosen.pop()
            for v, old in saved.items():
                if old is None:
                    boxes.pop(v, None)
                else:
                    boxes[v] = old

    expand(0, Fraction(0), [])
    if best["setup"] is None:
        return SearchResult(None, None, nodes)
    return SearchResult(dict(zip(order, best["setup"], strict=True)), float(best["cost"]), nodes)
