"""Why cheaper setups fail: the cheapest rejected setups and the clause each leaves uncovered.

A configuration proves its setup optimal (every path of :func:`~.configure.configure` is exact),
which says nothing a person can check about the setups it passed over. For the ``limit``
cheapest setups strictly cheaper than the chosen one (or the cheapest at all, when no setup is
valid), :func:`cheaper_setups` re-checks each with z3 — independently of the path that answered
— and names what fails:

* ``"model assumption"`` — at a point the test case allows, a model of the setup is fed a value
  outside its validity domain (the clause of its assumption that fails there);
* ``"test case guarantee"`` — the setup's guarantees do not ensure a clause of the test case's
  guarantee at that point;
* ``"contradiction"`` — the setup refines the test case only vacuously: its guarantees
  contradict each other (:mod:`.realisable`), so it gets no certificate;
* ``"unknown"`` — the solver could not decide within its time limit.

Setups are enumerated in order of total cost without listing the product of the candidates:
best-first over index vectors into each component's candidates sorted by cost, where the
children of a vector raise one coordinate at or after its last raised one (each vector is
generated once, and a child never costs less than its parent).
"""

from __future__ import annotations

import heapq
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from fractions import Fraction

import numpy as np

from simcred.contracts.algebra import DEFAULT_TIMEOUT_MS, Contract, Status
from simcred.contracts.evaluate import evaluate
from simcred.contracts.expr import Expr, conjuncts, to_text, variables


@dataclass(frozen=True, slots=True)
class Rejection:
    """A setup cheaper than the chosen one and why it gets no certificate. ``clauses``: the
    failing clauses as ``(owner, clause)``, owner a model name or ``"test case"``; ``point``:
    the counterexample (exact values) where they fail."""

    setup: dict[str, str]
    cost: Fraction
    kind: str
    clauses: tuple[tuple[str, str], ...] = ()
    point: Mapping[str, Fraction | int | bool] = field(default_factory=dict)
    reason: str = ""

    def to_dict(self) -> dict:
        def plain(v):
            return v if isinstance(v, bool | int) else float(v)

        def exact(v):
            return v if isinstance(v, bool | int) else str(Fraction(v))

        return {"setup": self.setup, "cost": float(self.cost), "kind": self.kind,
                "clauses": [{"owner": o, "clause": c} for o, c in self.clauses],
                "at": {k: plain(v) for k, v in self.point.items()},
                "at_exact": {k: exact(v) for k, v in self.point.items()},
                "reason": self.reason}


def by_cost(choices: Mapping[str, list[str]], costs: Mapping[str, Fraction]
            ) -> Iterator[tuple[Fraction, dict[str, str]]]:
    """Every setup (component → model) of ``choices``, in order of total cost (module docs)."""
    components = list(choices)
    ranked = [sorted(choices[c], key=lambda m: costs[m]) for c in components]
    if any(not r for r in ranked):
        return
    start = (0,) * len(components)

    def total(index) -> Fraction:
        return sum((costs[ranked[k][i]] for k, i in enumerate(index)), Fraction(0))

    heap = [(total(start), start, 0)]
    while heap:
        cost, index, last = heapq.heappop(heap)
        yield cost, {c: ranked[k][i] for k, (c, i) in enumerate(zip(components, index,
                                                                   strict=True))}
        for k in range(last, len(components)):
            if index[k] + 1 < len(ranked[k]):
                child = index[:k] + (index[k] + 1,) + index[k + 1:]
                heapq.heappush(heap, (total(child), child, k))


def cheaper_setups(library, target: Contract, choices: Mapping[str, list[str]],
                   chosen: Mapping[str, str] | None, *, limit: int = 3,
                   timeout_ms: int = DEFAULT_TIMEOUT_MS) -> list[Rejection]:
    """The ``limit`` cheapest setups of ``choices`` cheaper than ``chosen`` (all setups if
    ``chosen`` is None), each with why it fails (module docs)."""
    from simcred.contracts.configure import setup_refines
    from simcred.contracts.realisable import setup_realisability

    if limit <= 0:
        return []
    costs = {m: Fraction(library.spec.models[m].cost) for ms in choices.values() for m in ms}
    bound = None if chosen is None else sum((costs[m] for m in chosen.values()), Fraction(0))
    out: list[Rejection] = []
    for cost, setup in by_cost(choices, costs):
        if len(out) >= limit or (bound is not None and cost >= bound):
            break
        proof = setup_refines(library, setup, target, timeout_ms=timeout_ms)
        if proof.status is Status.UNKNOWN:
            out.append(Rejection(setup, cost, "unknown", reason=proof.reason))
        elif proof.status is Status.FAILS:
            point = dict(proof.counterexample)
            clauses = _failing(library, setup, target, point)
            kind = "model assumption" if clauses and clauses[0][0] != "test case" \
                else "test case guarantee"
            out.append(Rejection(setup, cost, kind, tuple(clauses), point))
        else:  # refines, so it was left out because its guarantees contradict
            check = setup_realisability(library, setup, target, timeout_ms=timeout_ms)
            kind = "contradiction" if check.verdict.status is Status.FAILS else "unknown"
            out.append(Rejection(setup, cost, kind,
                                 tuple(("realisability", c) for c in check.verdict.clauses),
                                 dict(check.verdict.counterexample or {}), check.text()
                                 if kind == "contradiction" else check.verdict.reason))
    return out


def _failing(library, setup, target: Contract, point) -> list[tuple[str, str]]:
    """The clauses of the setup's assumptions (owner: the model) and of the test case's
    guarantee (owner: "test case") that are false at ``point``; models' first."""
    clauses: list[tuple[str, Expr]] = [
        (m, c) for m in setup.values() for c in conjuncts(library.model_contracts[m].assumption)]
    clauses += [("test case", c) for c in conjuncts(target.guarantee)]
    return [(owner, to_text(c)) for owner, c in clauses if not _holds(c, point, library)]


def _holds(clause: Expr, point, library) -> bool:
    """``clause`` at ``point`` (exact: Fractions in object arrays); variables the point does
    not fix are irrelevant to the failing query and taken as 0."""
    columns = {name: np.array([point.get(name, Fraction(0))], dtype=object)
               for name in variables(clause)}
    if not columns:
        columns = {next(iter(library.spec.variables)): np.array([Fraction(0)], dtype=object)}
    return bool(np.asarray(evaluate(clause, columns)).reshape(-1)[0])
