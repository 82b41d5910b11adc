"""Learned validity domains as contracts: a contracts library the ``contracts`` commands accept.

One component ``simulation`` reads the operating-condition variables and drives the validity
metric ``distance`` (the calibrated distance of the comparison, dimensionless). Each candidate
with at least one valid cell becomes a model of it (seed 003: the model's contract is its validity
domain)::

    assumption = cell_1 or cell_2 or ...     (the valid cells, closed intervals)
    guarantee  = distance <= d               (the largest distance measured in those cells)

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
    variables[METRIC] = {"type": "real", "unit": "dimensionless"}
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
            "contract": {"assumption": assumption,
                         "guarantee": f"{METRIC} <= {number(domain.bound)}"},
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
    grid = domain.grid
    if len(grid.variables) > 1:
        return [grid.assertion(c) for c in valid]
    runs: list[list[int]] = []
    for c in valid:
        if runs and runs[-1][-1] == c - 1:
            runs[-1].append(c)
        else:
            runs.append([c])
    edges, name = grid.edges[0], grid.variables[0]
    return [f"{number(edges[r[0]])} <= {name} <= {number(edges[r[-1] + 1])}" for r in runs]


def number(value: float) -> str:
    """A float as the exact decimal of its shortest repr."""
    return decimal_text(Fraction(repr(float(value))))
