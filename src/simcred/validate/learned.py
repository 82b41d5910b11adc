"""Learned validity domains as contracts: a contracts library the ``contracts`` commands accept.

One component ``simulation`` reads the operating-condition variables and drives the validity
metric ``distance`` (the calibrated distance of the comparison, dimensionless). Each candidate
with at least one valid cell becomes a model of it (seed 003: the model's contract is its validity
domain)::

    assumption = cell_1 or cell_2 or ...                  (the valid cells, closed intervals)
    guarantee  = (cell_1 implies distance <= d_1) and ... (the distance measured in each cell)

The guarantee is per cell, so a refinement check against a test case sees only the distances of
the cells its conditions reach (a global bound would let a cell outside the test case decide it).
Adjacent cells with the same distance share one clause; when every valid cell has the same
distance the guarantee is simply ``distance <= d``. Cells are closed boxes here: at an edge two
adjacent cells meet, and a test case ending at an edge (``v <= 20``) is covered by the cell on
its side (the loop counts a cell for a test case only where the cell's interior meets it).
The test case assumes its operating conditions and requires ``distance <= max_distance``.
Candidates without a valid cell have an empty domain; an empty assumption is vacuous (the library
refuses it), so they are left out of the library and named in the verdict.
"""

from __future__ import annotations

from fractions import Fraction
from typing import Any

from simcred.contracts.expr import decimal_text
from simcred.validate.domain import CellStatus, Domain
from simcred.validate.spec import ValidationSpec

COMPONENT = "simulation"
METRIC = "distance"
TEST_CASE = "test_case"


def library_dict(spec: ValidationSpec, domains: dict[str, Domain]) -> dict[str, Any]:
    """The contracts library (as YAML-ready data) of the learned domains (module docs)."""
    variables = {name: {"type": "real", "unit": c.unit} for name, c in spec.conditions.items()}
    # no run carries the distance: monitors check the domains and name the guarantee unchecked
    variables[METRIC] = {"type": "real", "unit": "dimensionless", "observed": False}
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
    return {
        "variables": variables,
        "components": {COMPONENT: {"inputs": list(spec.conditions), "outputs": [METRIC]}},
        "models": models,
        "architecture": [COMPONENT],
        "test_cases": {TEST_CASE: {"assumption": spec.test_case.conditions,
                                   "guarantee": f"{METRIC} <= "
                                                f"{number(spec.test_case.max_distance)}"}},
    }


def domain_parts(domain: Domain) -> list[str]:
    """The valid cells as closed boxes; with one condition variable, runs of adjacent valid
    cells are merged into one interval (the same set, shorter text)."""
    valid = [c.cell for c in domain.with_status(CellStatus.VALID)]
    return _boxes(domain, [[c] for c in valid] if len(domain.grid.variables) > 1
                  else _runs(valid, lambda a, b: True))


def guarantee(domain: Domain) -> str:
    """The per-cell guarantee (module docs): ``distance <= d`` if every valid cell measured the
    same ``d``, else one implication per run of adjacent valid cells with the same distance."""
    valid = domain.with_status(CellStatus.VALID)
    distance = {c.cell: c.distance for c in valid}
    if len(set(distance.values())) == 1:
        return f"{METRIC} <= {number(valid[0].distance)}"
    cells = [c.cell for c in valid]
    runs = ([[c] for c in cells] if len(domain.grid.variables) > 1
            else _runs(cells, lambda a, b: distance[a] == distance[b]))
    return " and ".join(f"({box} implies {METRIC} <= {number(distance[run[0]])})"
                        for box, run in zip(_boxes(domain, runs), runs, strict=True))


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
