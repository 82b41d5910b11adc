"""Learned validity domains as contracts: a contracts library the ``contracts`` commands accept.

One component ``simulation`` reads the operating-condition variables and drives one validity
metric per feature with a tolerance, ``deviation.<feature>`` (the response deviation of
:mod:`simcred.compare.effect`, in the feature's unit per second). Each candidate with at least
one valid cell becomes a model of it (paper 003: the model's contract is its validity domain)::

    assumption = cell_1 or cell_2 or ...              (the valid cells, closed intervals)
    guarantee  = (cell_1 implies deviation.v <= u_1) and ...

``u`` is the cell's upper confidence bound of the deviation (what the data showed), so the
guarantee is per cell: a refinement check against a test case sees only the bounds of the cells
its conditions reach. Adjacent cells with the same bounds share one clause; a single clause is
written without the implication. Cells are closed boxes here: at an edge two adjacent cells meet,
and a test case ending at an edge (``v <= 20``) is covered by the cell on its side (the loop
counts a cell for a test case only where the cell's interior meets it). The test case assumes
its operating conditions and requires ``deviation.<feature> <= tolerance`` for each feature.
Candidates without a valid cell have an empty domain; an empty assumption is vacuous (the
library refuses it), so they are left out of the library and named in the verdict.

The contracts are built as ASTs (:func:`learned_contracts`, :func:`required`) and handed to
the library as they are (:meth:`~simcred.contracts.library.Library.from_dict`'s ``built``);
their text in ``contracts.yaml`` is printed from the same trees (:func:`assertion_text`), never
parsed back. Only the test case's conditions, the user's text, are parsed (once, as written).
"""

from __future__ import annotations

import zlib
from fractions import Fraction
from typing import Any

from simcred.compare.effect import rate_unit
from simcred.contracts.algebra import Contract
from simcred.contracts.expr import Compare, Expr, Logic, Num, Var, conjoin, decimal_text, implies
from simcred.contracts.library import NAME
from simcred.validate.domain import CellResult, CellStatus, Domain
from simcred.validate.spec import ValidationSpec

COMPONENT = "simulation"
TEST_CASE = "test_case"


def metric(feature: str) -> str:
    """The contract variable of one feature's response deviation: ``deviation.<feature>``, or
    ``deviation.feature_<hash>`` for a feature whose name is not a contract identifier."""
    name = f"deviation.{feature}"
    if NAME.fullmatch(name):
        return name
    return f"deviation.feature_{zlib.crc32(feature.encode()):08x}"


def library_dict(spec: ValidationSpec, domains: dict[str, Domain],
                 units: dict[str, str] | None = None) -> dict[str, Any]:
    """The contracts library (as YAML-ready data) of the learned domains (module docs);
    ``units``: each feature's unit (its deviation's unit is that per second)."""
    units = units or {}
    variables = {name: {"type": "real", "unit": c.unit} for name, c in spec.conditions.items()}
    # no run carries a deviation: monitors check the domains and name the guarantee unchecked
    for feature in spec.test_case.tolerance:
        variables[metric(feature)] = {"type": "real", "unit": rate_unit(units.get(feature)),
                                      "observed": False}
    models = {}
    for name, contract in learned_contracts(domains).items():
        domain = domains[name]
        models[name] = {
            "implements": COMPONENT,
            "cost": spec.candidates[name].cost,
            "contract": {"assumption": assertion_text(contract.assumption),
                         "guarantee": assertion_text(contract.guarantee)},
            "description": f"learned: {len(domain.with_status(CellStatus.VALID))} valid cells "
                           f"of {domain.grid.n_cells}",
        }
    return {
        "variables": variables,
        "components": {COMPONENT: {"inputs": list(spec.conditions),
                                   "outputs": [metric(f) for f in spec.test_case.tolerance]}},
        "models": models,
        "architecture": [COMPONENT],
        "test_cases": {TEST_CASE: {"assumption": spec.test_case.conditions,
                                   "guarantee": assertion_text(required(spec))}},
    }


def built_contracts(spec: ValidationSpec, domains: dict[str, Domain],
                    conditions: Expr) -> dict[str, Contract]:
    """The learned contracts and the test case (``conditions``: its conditions as parsed from
    the user's text) keyed as the library names them (``models.<name>.contract``,
    ``test_cases.test_case``), for :meth:`~simcred.contracts.library.Library.from_dict`'s
    ``built``."""
    return {**{f"models.{n}.contract": c for n, c in learned_contracts(domains).items()},
            f"test_cases.{TEST_CASE}": Contract(conditions, required(spec), TEST_CASE)}


def learned_contracts(domains: dict[str, Domain]) -> dict[str, Contract]:
    """Each candidate with a valid cell: its validity domain (module docs) as a contract."""
    out = {}
    for name, domain in domains.items():
        if domain.with_status(CellStatus.VALID):
            parts = domain_parts(domain)
            assumption = Logic("or", tuple(parts)) if len(parts) > 1 else parts[0]
            out[name] = Contract(assumption, guarantee(domain), name)
    return out


def required(spec: ValidationSpec) -> Expr:
    """The test case's guarantee: each feature's deviation within its tolerance."""
    return conjoin(*(_at_most(f, d) for f, d in spec.test_case.tolerance.items()))


def domain_parts(domain: Domain) -> list[Expr]:
    """The valid cells as closed boxes; with one condition variable, runs of adjacent valid
    cells are merged into one interval (the same set, shorter text)."""
    valid = [c.cell for c in domain.with_status(CellStatus.VALID)]
    return _boxes(domain, [[c] for c in valid] if len(domain.grid.variables) > 1
                  else _runs(valid, lambda a, b: True))


def guarantee(domain: Domain) -> Expr:
    """The per-cell guarantee (module docs): the bounds alone if every valid cell showed the
    same, else one implication per run of adjacent valid cells with the same bounds."""
    valid = domain.with_status(CellStatus.VALID)
    bounds = {c.cell: _bound(c) for c in valid}
    if len(set(bounds.values())) == 1:
        return bounds[valid[0].cell]
    cells = [c.cell for c in valid]
    runs = ([[c] for c in cells] if len(domain.grid.variables) > 1
            else _runs(cells, lambda a, b: bounds[a] == bounds[b]))
    return Logic("and", tuple(implies(box, bounds[run[0]])
                              for box, run in zip(_boxes(domain, runs), runs, strict=True)))


def _bound(cell: CellResult) -> Expr:
    return conjoin(*(_at_most(b.feature, b.upper) for b in cell.bounds))


def _at_most(feature: str, value: float) -> Expr:
    return Compare("<=", Var(metric(feature)), Num(_exact(value)))


def _runs(cells: list[int], same) -> list[list[int]]:
    """Runs of adjacent cells (one condition variable) for which ``same`` holds pairwise."""
    runs: list[list[int]] = []
    for c in cells:
        if runs and runs[-1][-1] == c - 1 and same(runs[-1][-1], c):
            runs[-1].append(c)
        else:
            runs.append([c])
    return runs


def _boxes(domain: Domain, runs: list[list[int]]) -> list[Expr]:
    """Each run of cells as one closed box (a run has one cell when there are several
    condition variables)."""
    grid = domain.grid
    if len(grid.variables) > 1:
        return [grid.box(r[0]) for r in runs]
    edges, name = grid.edges[0], grid.variables[0]
    return [conjoin(Compare("<=", Num(_exact(edges[r[0]])), Var(name)),
                    Compare("<=", Var(name), Num(_exact(edges[r[-1] + 1])))) for r in runs]


# -- the file's text of the learned assertions ----------------------------------------------------


def assertion_text(e: Expr) -> str:
    """A learned assertion as ``contracts.yaml`` writes it: boxes as chains (``10 <= v <= 15``;
    a negative edge in parentheses where a box has several variables), disjuncts and
    implications in parentheses."""
    if isinstance(e, Logic) and e.op == "or":
        return " or ".join(f"({assertion_text(a)})" for a in e.args)
    if isinstance(e, Logic) and e.op == "and" and all(_is_implication(a) for a in e.args):
        return " and ".join(f"({assertion_text(a)})" for a in e.args)
    if _is_implication(e):
        bound = assertion_text(e.args[1])
        return f"{assertion_text(e.args[0])} implies " + (
            f"({bound})" if " and " in bound else bound)
    compares = e.args if isinstance(e, Logic) and e.op == "and" else (e,)
    return " and ".join(_chains(compares))


def _is_implication(e: Expr) -> bool:
    return isinstance(e, Logic) and e.op == "implies"


def _chains(compares: tuple[Expr, ...]) -> list[str]:
    """``lo <= v``, ``v <= hi`` pairs as ``lo <= v <= hi``; a bound ``m <= u`` as it is."""
    variables = {c.right.name for c in compares if isinstance(c.left, Num)}
    text = _number if len(variables) <= 1 else _bracketed
    out, i = [], 0
    while i < len(compares):
        c = compares[i]
        if isinstance(c.left, Num):
            upper = compares[i + 1]
            out.append(f"{text(c.left)} {c.op} {c.right.name} {upper.op} {text(upper.right)}")
            i += 2
        else:
            out.append(f"{c.left.name} {c.op} {number(c.right.value)}")
            i += 1
    return out


def _number(n: Num) -> str:
    return number(n.value)


def _bracketed(n: Num) -> str:
    return number(n.value) if n.value >= 0 else f"({number(n.value)})"


def _exact(value: float) -> Fraction:
    """A float as the exact value of its shortest repr."""
    return Fraction(repr(float(value)))


def number(value: float | Fraction) -> str:
    """A float as the exact decimal of its shortest repr (a ``Fraction`` as its decimal)."""
    return decimal_text(value if isinstance(value, Fraction) else _exact(value))
