"""The grid's cells as contract ASTs: ``Grid.box`` is the tree its text parses to (issue 27:
validate builds the boxes as objects, never as text parsed back)."""

from __future__ import annotations

import pytest

from simcred.contracts.expr import Logic, conjuncts, to_text
from simcred.contracts.library import VariableSpec
from simcred.contracts.parse import parse
from simcred.regions.cells import Grid

GRIDS = [
    Grid(("v",), ((0.0, 10.0, 20.5, 30.0),), ("m/s",)),
    Grid(("v", "gap"), ((-2.5, 1e-05, 3.0), (0.0, 0.1, 0.30000000000000004, 40.0)),
         ("m/s", "m")),
]


@pytest.mark.parametrize("grid", GRIDS)
def test_box_is_the_tree_the_assertion_parses_to(grid):
    declared = {v: VariableSpec(type="real", unit=u)
                for v, u in zip(grid.variables, grid.units, strict=True)}
    for cell in range(grid.n_cells):
        assert grid.box(cell) == parse(grid.assertion(cell), declared=declared)
        assert grid.box(cell, interior=True) == parse(grid.interior(cell), declared=declared)
    whole = " and ".join(f"{e[0]!r} <= {v} <= {e[-1]!r}" for v, e in zip(grid.variables,
                                                                         grid.edges, strict=True))
    assert grid.box() == parse(whole, declared=declared)


def test_box_is_one_flat_conjunction():
    box = GRIDS[1].box(0)
    assert isinstance(box, Logic) and len(conjuncts(box)) == 4
    assert to_text(box).startswith("(-2.5) <= v")
