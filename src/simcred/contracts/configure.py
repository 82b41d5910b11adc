"""Configuration of the cheapest sufficiently valid simulation setup (paper 003, sec. V-B, V-C).

A setup picks one model per component of the architecture; it is sufficiently valid for a test
case when the composition of the models' contracts refines the test case's contract.

Search (our design), first path that applies, named in the result's ``method``: in the interval
fragment (boxes), exact interval propagation with branch-and-bound (:mod:`.search`); with box
guarantees on an acyclic architecture and any assumptions (non-convex domains, sums over
inputs), 0-1 optimisation (:mod:`.optimise`, a MILP over the model choices); otherwise
counterexample-guided: the cheapest selection that
passes every constraint learned so far is proposed (exact branch-and-bound over the selections,
:mod:`.selection`) and checked exactly with z3; if it fails, the counterexample is an operating
point p, and at p every model's assumption and guarantee evaluate to constants, so "the
composition refines the test case at p" becomes a propositional constraint on the selection,
which excludes every selection that fails at p — not only the one checked. Each learned
constraint is necessary for validity, so the first selection that passes is the cheapest valid
one (optimality: the proposal is the exact optimum over all selections passing the learned
constraints). No enumeration of the product of candidates is needed. Every path's answer is
re-proven by the z3 refinement check and the realisability check (:mod:`.realisable`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from fractions import Fraction

import numpy as np

from simcred.contracts.algebra import (
    DEFAULT_TIMEOUT_MS,
    Contract,
    Status,
    Verdict,
    compose_all,
    valid,
)
from simcred.contracts.evaluate import evaluate
from simcred.contracts.explain import Rejection, cheaper_setups
from simcred.contracts.expr import conjoin, conjuncts, to_text, variables
from simcred.contracts.library import Library, LibraryError
from simcred.contracts.optimise import optimise
from simcred.contracts.realisable import Realisability, setup_realisability
from simcred.contracts.search import branch_and_bound, interval_problem
from simcred.contracts.selection import Constraints, cheapest


@dataclass(frozen=True, slots=True)
class Configuration:
    """Outcome: the chosen models (component → model), their total cost, the refinement proof,
    and the points that ruled out cheaper setups."""

    test_case: str
    status: Status
    setup: dict[str, str] | None
    cost: float | None
    proof: Verdict | None
    iterations: int
    counterexamples: list[dict] = field(default_factory=list)  # exact values (Fraction)
    reason: str = ""
    method: str = ""
    path: str = ""  # which search answered: PATHS
    cheaper: list[Rejection] = field(default_factory=list)  # why cheaper setups fail

    def to_dict(self) -> dict:
        return {"test_case": self.test_case, "status": self.status.value, "setup": self.setup,
                "cost": self.cost, "proof": None if self.proof is None else self.proof.to_dict(),
                "iterations": self.iterations,
                "counterexamples": [{k: _plain(v) for k, v in p.items()}
                                    for p in self.counterexamples],
                "counterexamples_exact": [{k: _exact(v) for k, v in p.items()}
                                          for p in self.counterexamples],
                "reason": self.reason, "method": self.method, "path": self.path,
                "cheaper_setups": [r.to_dict() for r in self.cheaper]}


PATHS = {"intervals": "interval fast path", "optimisation": "0-1 program",
         "cegis": "counterexample-guided search (CEGIS)", "none": "none"}


def _plain(v):
    return v if isinstance(v, bool | int) else float(v)


def _exact(v):
    return v if isinstance(v, bool | int) else str(Fraction(v))


def setup_contract(library: Library, setup: dict[str, str]) -> Contract:
    return compose_all(library.model_contracts[m] for m in setup.values())


def configure(library: Library, test_case: str, *, fixed: dict[str, str] | None = None,
              timeout_ms: int = DEFAULT_TIMEOUT_MS, max_iterations: int = 1000,
              search: str = "auto", explain: int = 3) -> Configuration:
    """The cheapest setup whose composed contract refines the test case (see module docs).

    In the interval fragment the search is exact interval propagation with branch-and-bound
    (:mod:`simcred.contracts.search`), and the chosen setup is then proven with z3; otherwise
    counterexample-guided search over z3 ``Optimize``. ``search="cegis"`` forces the latter
    (for comparison). The result's ``path`` names the search that answered; ``cheaper``
    explains the ``explain`` cheapest setups cheaper than the answer (all setups' cheapest when
    none is valid), re-checked with z3, each with the clause it leaves uncovered
    (:mod:`.explain`).
    """
    if explain < 0:
        raise LibraryError(f"explain must be a count >= 0, got {explain!r}")
    result = _configure(library, test_case, fixed=fixed, timeout_ms=timeout_ms,
                        max_iterations=max_iterations, search=search)
    if result.status is Status.UNKNOWN or explain == 0 or result.path == PATHS["none"]:
        return result
    choices = _choices(library, library.components(), fixed or {})
    chosen = result.setup if result.status is Status.HOLDS else None
    return replace(result, cheaper=cheaper_setups(
        library, library.test_case(test_case), choices, chosen, limit=explain,
        timeout_ms=timeout_ms))


def _configure(library: Library, test_case: str, *, fixed, timeout_ms, max_iterations,
               search) -> Configuration:
    if search not in ("auto", "cegis", "optimise"):
        raise LibraryError(f"search must be 'auto', 'optimise' or 'cegis', got {search!r}")
    target = library.test_case(test_case)
    fixed = fixed or {}
    empty = [c for c in library.components() if not library.candidates(c) and c not in fixed]
    if empty:  # no setup exists: a verdict (fails), not a malformed library
        return Configuration(test_case, Status.FAILS, None, None, None, 0, [],
                             f"no setup refines the test case: component '{empty[0]}' has no "
                             "model (an empty library, e.g. learned contracts without a valid "
                             "candidate)", "none (no setup to search)", PATHS["none"])
    choices = _choices(library, library.components(), fixed)
    consistency: dict[str, Realisability] = {}
    excluded: list[str] = []  # why a model or a combination can give no certificate
    forbidden: list[dict[str, str]] = []
    while True:
        found = _search(library, test_case, target, choices, forbidden, search, timeout_ms,
                        max_iterations)
        if found.status is not Status.HOLDS:
            return _noting(found, excluded)
        check = setup_realisability(library, found.setup, target, timeout_ms=timeout_ms,
                                    cache=consistency)
        if check.holds:
            return replace(_noting(found, excluded), method=found.method + (
                "; its guarantees can all hold for every environment the test case allows "
                "(realisability checked with z3)"))
        if check.verdict.status is Status.UNKNOWN:
            return Configuration(test_case, Status.UNKNOWN, found.setup, None, check.verdict,
                                 found.iterations, found.counterexamples,
                                 f"the solver could not decide whether the guarantees of "
                                 f"{', '.join(found.setup.values())} can all hold: "
                                 f"{check.verdict.reason}", found.method, found.path)
        excluded.append(f"{' with '.join(check.models)} — {check.text()}")
        owner = {m: library.spec.models[m].implements for m in check.models}
        if len(check.models) > 1:
            forbidden.append({owner[m]: m for m in check.models})
            continue
        (model, component), = owner.items()
        choices[component] = [m for m in choices[component] if m != model]
        if not choices[component]:
            return Configuration(test_case, Status.FAILS, None, None, check.verdict,
                                 found.iterations, [], "no certificate: every model of "
                                 f"component '{component}' has a guarantee that cannot hold "
                                 f"({'; '.join(excluded)})", found.method, found.path)


def _search(library, test_case, target, choices, forbidden, search, timeout_ms, max_iterations):
    """The cheapest setup whose composition refines the test case, among ``choices`` and
    without a ``forbidden`` combination (only the counterexample-guided path knows those)."""
    problem = interval_problem(library, target, choices) \
        if search == "auto" and not forbidden else None
    if problem is not None:
        result = _by_intervals(library, test_case, target, choices, problem, timeout_ms)
        if result is not None:
            return replace(result, path=PATHS["intervals"])
    if search in ("auto", "optimise"):
        result = _by_optimisation(library, test_case, target, choices, forbidden, timeout_ms)
        if result is not None:
            return replace(result, path=PATHS["optimisation"])
    return replace(_by_cegis(library, test_case, target, choices, timeout_ms, max_iterations,
                             forbidden), path=PATHS["cegis"])


def _by_optimisation(library, test_case, target, choices, forbidden, timeout_ms):
    """0-1 optimisation in the box-guarantee fragment (:mod:`.optimise`); None outside it or
    if z3 does not confirm the optimum (then CEGIS)."""
    found = optimise(library, target, choices, forbidden)
    if found is None:
        return None
    setups = int(np.prod([len(m) for m in choices.values()], dtype=object))
    method = (f"0-1 optimisation over the model choices (MILP, HiGHS; box guarantees: "
              f"{found.constraints} containment constraints, {found.checks} containments "
              f"decided while encoding, {setups:,} setups)")
    if found.setup is None:
        return Configuration(test_case, Status.FAILS, None, None, None, 1, [],
                             "no setup refines the test case (decided exactly over all "
                             f"{setups:,} setups: no choice puts every model's input box "
                             "inside its assumption and the outputs inside the test case's "
                             "guarantee)", method)
    proof = setup_refines(library, found.setup, target, timeout_ms=timeout_ms)
    if proof.status is not Status.HOLDS:  # cannot happen (module docs of optimise); be safe
        return None
    return Configuration(test_case, Status.HOLDS, found.setup, found.cost, proof, 1, [], "",
                         method + "; optimal by the solver, proven with z3")


def _noting(result: Configuration, excluded: list[str]) -> Configuration:
    """``result`` with the models (or combinations) left out because their guarantees
    contradict, in its reason."""
    if not excluded:
        return result
    note = "left out, their guarantees contradict (no certificate): " + "; ".join(excluded)
    return replace(result, reason=f"{result.reason}; {note}" if result.reason else note)


def _by_intervals(library, test_case, target, choices, problem, timeout_ms):
    """Exact search in the interval fragment; None if z3 does not confirm (then CEGIS)."""
    found = branch_and_bound(problem)
    setups = int(np.prod([len(m) for m in choices.values()], dtype=object))
    method = (f"interval propagation, branch-and-bound ({found.nodes} partial setups expanded "
              f"of {setups:,} setups)")
    if found.setup is None:
        cheapest = {c: models[0] for c, models in choices.items()}
        example = setup_refines(library, cheapest, target, timeout_ms=timeout_ms)
        points, why = [], ""
        if example.status is Status.FAILS:
            points = [dict(example.counterexample)]
            why = (f"; e.g. the cheapest setup ({', '.join(cheapest.values())}) fails at "
                   f"{_point_text(example.counterexample)}: "
                   f"{', '.join(example.clauses) or 'an assumption of a model'}")
        return Configuration(test_case, Status.FAILS, None, None, example, found.nodes, points,
                             f"no setup refines the test case (decided exactly over all "
                             f"{setups:,} setups by interval propagation){why}", method)
    proof = setup_refines(library, found.setup, target, timeout_ms=timeout_ms)
    if proof.status is not Status.HOLDS:  # cannot happen (module docs of search); be safe
        return None
    return Configuration(test_case, Status.HOLDS, found.setup, found.cost, proof, found.nodes,
                         [], "", method + "; optimal by the bound, proven with z3")


def _point_text(point) -> str:
    from simcred.contracts.intervals import decimal

    return ", ".join(f"{k} = {v if isinstance(v, bool) else decimal(v)}"
                     for k, v in point.items())


def _by_cegis(library, test_case, target, choices, timeout_ms, max_iterations, forbidden=()):
    """Counterexample-guided search (module docs) for contracts outside the interval fragment:
    propose the cheapest selection passing every learned point (:mod:`.selection`), check it
    with z3, learn its counterexample point."""
    learned = Constraints(list(choices), {c: list(m) for c, m in choices.items()})
    costs = {m: Fraction(library.spec.models[m].cost) for ms in choices.values() for m in ms}
    points: list[dict] = []
    method = "CEGIS: branch-and-bound proposals, z3 checks"
    for iteration in range(1, max_iterations + 1):
        setup = cheapest(learned, costs, forbidden)
        if setup is None:
            return Configuration(test_case, Status.FAILS, None, None, None, iteration, points,
                                 "no setup refines the test case: every candidate fails at one "
                                 "of the counterexample points", method)
        proof = setup_refines(library, setup, target, timeout_ms=timeout_ms)
        if proof.status is Status.HOLDS:
            cost = float(sum(costs[m] for m in setup.values()))
            return Configuration(test_case, Status.HOLDS, setup, cost, proof, iteration, points,
                                 "", method)
        if proof.status is Status.UNKNOWN:
            return Configuration(test_case, Status.UNKNOWN, setup, None, proof, iteration, points,
                                 f"the solver could not decide {setup}: {proof.reason}", method)
        points.append(dict(proof.counterexample))
        learned.add(*_tables_at(library, target, choices, proof.counterexample))
    return Configuration(test_case, Status.UNKNOWN, None, None, None, max_iterations, points,
                         "iteration limit reached", method)


def _tables_at(library, target: Contract, choices, point):
    """At the operating point ``point``: each candidate's assumption and saturated guarantee,
    and the test case's (constants there)."""
    columns = {k: np.array([v], dtype=object) for k, v in point.items()}
    for name in library.spec.variables:
        columns.setdefault(name, np.array([Fraction(0)], dtype=object))

    def holds(expr) -> bool:
        return bool(np.asarray(evaluate(expr, columns)).reshape(-1)[0])

    contracts = library.model_contracts
    a = {c: [holds(contracts[m].assumption) for m in ms] for c, ms in choices.items()}
    g = {c: [holds(contracts[m].saturated_guarantee) for m in ms] for c, ms in choices.items()}
    return a, g, holds(target.assumption), holds(target.saturated_guarantee)


def setup_refines(library: Library, setup: dict[str, str], target: Contract, *,
                  timeout_ms: int = DEFAULT_TIMEOUT_MS) -> Verdict:
    """``compose(models of setup) ≼ target`` as one flat validity query.

    With G_s = ∧ G_i' and A_s = ∧ A_i ∨ ¬G_s, the two refinement conditions A_tc → A_s and
    G_s → (A_tc → G_tc) are together equivalent to  A_tc ∧ G_1' ∧ … ∧ G_n' → (∧ A_i) ∧ G_tc:
    the same verdict as :func:`refines` on the composition, but with the models' guarantees as
    separate premises (a small unsat core naming the models' clauses that prove it).
    """
    contracts = [library.model_contracts[m] for m in setup.values()]
    premises = [target.assumption, *(c.saturated_guarantee for c in contracts)]
    claim = conjoin(*(c.assumption for c in contracts), target.guarantee)
    return valid(premises, claim, types=library.types, timeout_ms=timeout_ms)


def _choices(library: Library, components, fixed) -> dict[str, list[str]]:
    choices = {}
    for c in components:
        models = library.candidates(c)
        if c in fixed:
            if fixed[c] not in models:
                raise LibraryError(f"{library.source}: '{fixed[c]}' is not a model of component "
                                   f"'{c}' (models: {', '.join(models)})")
            models = [fixed[c]]
        if not models:
            raise LibraryError(f"{library.source}: component '{c}' has no model")
        choices[c] = models
    return choices


def missing_model_requirement(library: Library, test_case: str, given: dict[str, str]
                              ) -> Contract:
    """What the models not in ``given`` must satisfy together: the quotient C_tc / C_given
    (paper 003 sec. V-B)."""
    target = library.test_case(test_case)
    for component, model in given.items():
        if library.spec.models.get(model) is None or \
                library.spec.models[model].implements != component:
            raise LibraryError(f"{library.source}: '{model}' is not a model of component "
                               f"'{component}'")
    residual = setup_contract(library, given)
    return target.quotient(residual)


def missing_ports(library: Library, given: dict[str, str]) -> set[str]:
    """Variables of the ports of the components not in ``given`` (what a missing model sees)."""
    components = library.spec.architecture or list(library.spec.components)
    return {p.variable for c in components if c not in given for p in library.ports(c)}


def uncovered_assumptions(library: Library, test_case: str, given: dict[str, str],
                          *, timeout_ms: int = DEFAULT_TIMEOUT_MS) -> list[dict]:
    """The clauses of the given models' assumptions that the test case and the given models'
    guarantees do not ensure, each with its ``kind``:

    * ``"dead end"`` — the clause speaks only of variables no missing model drives, and no
      given guarantee it rests on involves a missing model's output: at ``at`` (a point the
      test case allows) it fails whatever the missing models do, so no missing model can help
      (the quotient's guarantee is ``false`` there);
    * ``"requirement"`` — the clause constrains an output of a missing component: a
      requirement on the missing model(s), which the quotient already contains (not a dead
      end);
    * ``"depends"`` — the clause speaks of given models' outputs, and a given guarantee
      involves a missing model's output: whether a missing model can ensure it depends on what
      that model guarantees (the quotient says exactly what is needed).

    With every component given, a clause is listed only if the setup does not ensure it."""
    target = library.test_case(test_case)
    missing = set().union(*(library.controlled(c) for c in library.components()
                            if c not in given))
    guarantees = [library.model_contracts[m].saturated_guarantee for m in given.values()]
    through_missing = any(variables(g) & missing for g in guarantees)
    out = []
    for model in given.values():
        for clause in conjuncts(library.model_contracts[model].assumption):
            verdict = valid([target.assumption, *guarantees], clause, types=library.types,
                            timeout_ms=timeout_ms)
            if verdict.status is not Status.FAILS:
                continue
            names = variables(clause)
            direct = bool(names & missing)
            dead = not direct and not (through_missing and names - library.environment())
            kind = "requirement" if direct else "dead end" if dead else "depends"
            out.append({"model": model, "clause": to_text(clause), "kind": kind,
                        "at": {k: v for k, v in verdict.counterexample.items()
                               if k in names} if dead else {}})
    return out
