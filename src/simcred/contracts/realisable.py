"""Can what a certificate rests on happen? (issue 28, item 1)

A refinement proof ``A_tc ∧ G_1' ∧ … ∧ G_n' → (∧ A_i) ∧ G_tc`` holds vacuously when its premises
contradict each other: a guarantee ``false``, an empty box, a guarantee that restricts the
model's own input (``v <= 5``: no model can make its input obey), or two models in a feedback loop
whose guarantees contradict (``x == y + 1`` and ``y == x``). Such a "certificate" proves anything.
So a certificate also needs the premises to be *realisable*:

* **consistency of each model** — its saturated guarantee is receptive to its component's
  inputs: for every input value some output value satisfies ``A → G`` (paper 003 sec. III;
  Benveniste et al. 2018, consistency) — at least for the inputs its setup can feed it;
* **realisability of each feedback loop** — for every input from outside the loop, values of
  the loop's outputs exist that satisfy all its guarantees at once (``x == y + 1`` and
  ``y == x`` have none: each model is consistent, the pair is not).

Both are checked one unit at a time in topological order (a unit: a component, or a feedback
loop as a whole): each unit must respond to every value the test case and the units before it
can produce (:func:`setup_realisability`). This is exact for the setup — a model inconsistent
only at inputs its setup never feeds it still gives a certificate — and a model consistent on
its own passes without a query. When a check fails, the contradicting clauses are named: at the
failing point, an unsat core over the unit's guarantee clauses.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from simcred.contracts.algebra import (
    DEFAULT_TIMEOUT_MS,
    Contract,
    Status,
    Verdict,
    receptive,
)
from simcred.contracts.expr import Bool, Expr, conjoin, conjuncts, implies, to_text, variables


@dataclass(frozen=True, slots=True)
class Realisability:
    """``verdict`` holds when the premises can all be met; when it fails, ``models`` are the
    models whose clauses contradict (the contradiction needs all of them) and
    ``verdict.clauses`` name those clauses as ``model: clause``; ``verdict.counterexample`` is
    the input or environment point where no completion exists."""

    verdict: Verdict
    models: tuple[str, ...] = ()

    @property
    def holds(self) -> bool:
        return self.verdict.holds

    def text(self) -> str:
        """One line: who contradicts whom, where."""
        from simcred.contracts.intervals import decimal

        point = ", ".join(f"{k} = {v if isinstance(v, bool) else decimal(v)}"
                          for k, v in (self.verdict.counterexample or {}).items())
        clauses = "; ".join(f"'{c}'" for c in self.verdict.clauses) or "(no clause named)"
        where = f" at {point}" if point else ""
        return f"the guarantees {clauses} contradict each other (cannot all hold{where})"


def model_consistency(library, model: str, *, timeout_ms: int = DEFAULT_TIMEOUT_MS
                      ) -> Realisability:
    """Is the model's saturated guarantee receptive to its component's inputs?"""
    contract = library.model_contracts[model]
    inputs = library.uncontrolled(library.spec.models[model].implements)
    return _receptive({model: contract}, Bool(True), inputs, library.types, timeout_ms)


def setup_realisability(library, setup: Mapping[str, str], target: Contract | None = None, *,
                        timeout_ms: int = DEFAULT_TIMEOUT_MS,
                        cache: dict[str, Realisability] | None = None) -> Realisability:
    """Can every chosen model respond to whatever the part of the setup before it produces?

    The components are taken in topological order of their feedback loops (a loop is one unit,
    a component outside loops a unit of its own). For each unit U, with P the test case's
    assumption (if ``target``) and the saturated guarantees of every unit before U:
    ``∀ (variables of P and U's inputs): P → ∃ U's outputs: ∧ G_i' (i in U)``. A model that
    is consistent on its own (receptive to all its inputs, cached in ``cache``) passes without
    the query. When a unit fails, ``models`` are its models named in the contradiction and the
    models of the components upstream of it (their guarantees made the failing point
    reachable): every setup with all of them fails the same way."""
    cache = {} if cache is None else cache
    components = list(setup)
    units, upstream = _units(library, components)
    before: list[str] = []
    for unit in units:
        models = [setup[c] for c in unit]
        if len(unit) == 1:
            if models[0] not in cache:
                cache[models[0]] = model_consistency(library, models[0], timeout_ms=timeout_ms)
            if cache[models[0]].holds:
                before += models
                continue
        premise = conjoin(*([target.assumption] if target is not None else []),
                          *(library.model_contracts[m].saturated_guarantee for m in before))
        outputs = set().union(*(library.controlled(c) for c in unit))
        contracts = {m: library.model_contracts[m] for m in models}
        body = conjoin(*(c.saturated_guarantee for c in contracts.values()))
        free = (variables(premise) | variables(body)) - outputs
        found = _receptive(contracts, premise, free, library.types, timeout_ms)
        if not found.holds:
            cone = [setup[c] for c in components if c in upstream[unit[0]]]
            return Realisability(found.verdict, (*found.models, *cone)) \
                if found.verdict.status is Status.FAILS else found
        before += models
    return Realisability(Verdict(Status.HOLDS))


def loops(library, components: Iterable[str]) -> list[list[str]]:
    """The feedback loops among ``components``: strongly connected sets of more than one
    component (an edge from the component driving a variable to each one reading it)."""
    return [u for u in _units(library, components)[0] if len(u) > 1]


def _units(library, components: Iterable[str]):
    """Strongly connected sets of ``components`` in topological order, and for each component
    the components upstream of it (outside its own set)."""
    components = list(components)
    edges = {c: [d for d in components if d != c
                 and library.controlled(c) & library.uncontrolled(d)] for c in components}
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    out: list[list[str]] = []

    def connect(c: str) -> None:  # Tarjan; architectures are small, recursion is fine
        index[c] = low[c] = len(index)
        stack.append(c)
        for d in edges[c]:
            if d not in index:
                connect(d)
                low[c] = min(low[c], low[d])
            elif d in stack:
                low[c] = min(low[c], index[d])
        if low[c] == index[c]:
            group = []
            while True:
                d = stack.pop()
                group.append(d)
                if d == c:
                    break
            out.append(sorted(group, key=components.index))

    for c in components:
        if c not in index:
            connect(c)
    out.reverse()  # Tarjan finds sinks first
    upstream: dict[str, set[str]] = {}
    for unit in out:
        feeding = {c for c in components for d in unit if d in edges[c] and c not in unit}
        cone = set().union(feeding, *(upstream[c] for c in feeding))
        upstream.update(dict.fromkeys(unit, cone))
    return out, upstream


def _receptive(contracts: Mapping[str, Contract], premise: Expr, free: Iterable[str],
               types, timeout_ms: int) -> Realisability:
    """``∀ free: premise → ∃ rest: ∧ saturated guarantees``; on failure, the contradicting
    clauses at the point found (``models``: those whose clauses are named)."""
    body = conjoin(*(c.saturated_guarantee for c in contracts.values()))
    assertion = body if premise == Bool(True) else implies(premise, body)
    verdict = receptive(assertion, free, types=types, timeout_ms=timeout_ms)
    if verdict.status is not Status.FAILS:
        return Realisability(verdict)
    point = dict(verdict.counterexample or {})
    labelled = [(model, to_text(clause), implies(c.assumption, clause)
                 if c.assumption != Bool(True) else clause)
                for model, c in contracts.items() for clause in conjuncts(c.guarantee)]
    core = sorted(_core(labelled, [premise], point, types, timeout_ms), key=labelled.index)
    models = tuple(dict.fromkeys(m for m, _, _ in core)) or tuple(contracts)
    clauses = tuple(f"{m}: {text}" for m, text, _ in core)
    return Realisability(Verdict(Status.FAILS, point, clauses,
                                 "the guarantees contradict each other (no certificate)"),
                         models)


def _core(labelled, premises, point, types, timeout_ms):
    """The labelled clauses in an unsat core of ``premises ∧ labelled`` with ``point`` fixed."""
    import z3

    from simcred.contracts.smt import to_z3, z3_variables

    names = set(point).union(*(variables(e) for _, _, e in labelled),
                             *(variables(p) for p in premises))
    env = z3_variables(names, types)
    solver = z3.Solver()
    solver.set("timeout", int(timeout_ms))
    for name, value in point.items():
        solver.add(env[name] == (value if isinstance(value, bool)
                                 else z3.RealVal(f"{value.numerator}/{value.denominator}")
                                 if hasattr(value, "numerator") else value))
    for premise in premises:
        solver.add(to_z3(premise, env))
    tags = {}
    for i, item in enumerate(labelled):
        tag = z3.Bool(f"__clause_{i}")
        tags[str(tag)] = item
        solver.assert_and_track(to_z3(item[2], env), tag)
    if solver.check() != z3.unsat:
        return []
    return [tags[str(t)] for t in solver.unsat_core() if str(t) in tags]
