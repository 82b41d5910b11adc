"""Learned validity domains as contracts: a contracts library the ``contracts`` commands accept.

One component ``simulation`` reads the operating-condition variables and drives one validity
metric per feature with a tolerance, ``deviation.<feature>`` (the response deviation of
:mod:`simcred.compare.effect`, in the feature's unit per second). Each candidate with at least
one valid cell becomes a model of it (seed 003: the model's contract is its validity domain)::

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
"""

from __future__ import annotations

import zlib
from fractions import Fraction
from typing import Any

from simcred.compare.effect import rate_unit
from simcred.contracts.expr import decimal_text
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
    for name, domain in domains.items():
        valid = domain.with_status(CellStatus.VALID)
        if not valid:
            continue
        parts = domain_parts(domain)
        assumption = " or ".join(f"({c})" for c in parts) if len(parts) > 1 else parts[0]
        models[name] = {
            "implements": COMPONENT,
            "cost": spec.candidates[name].cost,
            "contract": {"assumption": assumption, "guarantee": guarantee(domain)},
            "description": f"learned: {len(valid)} valid cells of {domain.grid.n_cells}",
        }
    required = " and ".join(f"{metric(f)} <= {number(d)}"
                            for f, d in spec.test_case.tolerance.items())
    return {
        "variables": variables,
        "components": {COMPONENT: {"inputs": list(spec.conditions),
                                   "outputs": [metric(f) for f in spec.test_case.tolerance]}},
        "models": models,
        "architecture": [COMPONENT],
        "test_cases": {TEST_CASE: {"assumption": spec.test_case.conditions,
                                   "guarantee": required}},
    }


def domain_parts(domain: Domain) -> list[str]:
    """The valid cells as closed boxes; with one condition variable, runs of adjacent valid
    cells are merged into one interval (the same set, shorter text)."""
    valid = [c.cell for c in domain.with_status(CellStatus.VALID)]
    return _boxes(domain, [[c] for c in valid] if len(domain.grid.variables) > 1
                  else _runs(valid, lambda a, b: True))


def guarantee(domain: Domain) -> str:
    """The per-cell guarantee (module docs): the bounds alone if every valid cell showed the
    same, else one implication per run of adjacent valid cells with the same bounds."""
    valid = domain.with_status(CellStatus.VALID)
    bounds = {c.cell: _bound_text(c) for c in valid}
    if len(set(bounds.values())) == 1:
        return bounds[valid[0].cell]
    cells = [c.cell for c in valid]
    runs = ([[c] for c in cells] if len(domain.grid.variables) > 1
            else _runs(cells, lambda a, b: bounds[a] == bounds[b]))
    return " and ".join(f"({box} implies {_grouped(bounds[run[0]])})"
                        for box, run in zip(_boxes(domain, runs), runs, strict=True))


def _bound_text(cell: CellResult) -> str:
    return " and ".join(f"{metric(b.feature)} <= {number(b.upper)}" for b in cell.bounds)


def _grouped(text: str) -> str:
    return f"({text})" if " and " in text else text


def _runs(cells: list[int], same) -> list[list[int]]:
    """Runs of adjacent cells (one condition variable) for which ``same`` holds pairwise."""
    runs: list[list[int]] = []
    for c in cells:
        if runs and runs[-1][-1] == c - 1 and same(runs[-1][-1], c):
            runs[-1].append(c)
        else:
            runs.append([c])
    return runs


def _boxes(domain: Domain, runs: list[list[int]]) -> list[str]:
    """Each run of cells as one closed box (a run has one cell when there are several
    condition variables)."""
    grid = domain.grid
    if len(grid.variables) > 1:
        return [grid.assertion(r[0]) for r in runs]
    edges, name = grid.edges[0], grid.variables[0]
    return [f"{number(edges[r[0]])} <= {name} <= {number(edges[r[-1] + 1])}" for r in runs]


def number(value: float) -> str:
    """A float as the exact decimal of its shortest repr."""
    return decimal_text(Fraction(repr(float(value))))
