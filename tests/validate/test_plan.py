"""The data plan: the size formula against a literal computation, the pilot's rows, the search
by simulation, and what it says when a candidate cannot be shown within tolerance."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from scipy.stats import norm

from simcred.cli import run
from simcred.traces import TraceSet
from simcred.validate import read_inputs, read_validation, validate
from simcred.validate.plan import PILOT, needed_if_perfect, needed_units
from simcred.validate.synthetic import universe

from .conftest import write_universe


@pytest.mark.parametrize("units, se, tolerance, estimate", [
    (10, 0.2, 1.0, 0.0), (40, 0.05, 0.1, 0.03), (7, 1.3, 2.0, 1.5)])
def test_needed_units_is_the_equivalence_size_formula(units, se, tolerance, estimate):
    z = norm.ppf(0.95) + norm.ppf(0.8)
    literal = units * (z * se / (tolerance - estimate)) ** 2
    assert needed_units(units, se, tolerance, estimate, 0.05, 0.8) == max(2, math.ceil(literal))
    assert needed_units(units, se, tolerance, tolerance, 0.05, 0.8) is None  # at the tolerance
    assert needed_units(units, float("nan"), tolerance, estimate, 0.05, 0.8) is None
    perfect = units * ((estimate + z * se) / tolerance) ** 2
    assert needed_if_perfect(units, se, tolerance, estimate, 0.05, 0.8) == \
        max(2, math.ceil(perfect))


def test_plan_rows_and_simulated_size(tmp_path, capsys):
    spec, base = read_validation(write_universe(tmp_path))
    result = validate(spec, read_inputs(spec, base), planned=True)
    plan = result.plan
    assert plan.cell_power == pytest.approx(0.8 ** (1 / 3))  # three cells in the test case
    pilot = [r for r in plan.rows if r.source == PILOT]
    assert [r.cell for r in pilot] == [1, 2, 3]
    beyond = [r for r in plan.rows if r.source == "sim" and r.cell == 3]
    assert beyond[0].needed is None  # the deviating cell cannot be shown within tolerance
    # the search stops at the first simulated size with 80 %: at least the formula's size
    assert all(plan.sizes[r.cell] >= r.if_perfect for r in pilot)
    assert plan.simulated_power >= 0.8 and plan.simulations == 20
    again = validate(spec, read_inputs(spec, base), planned=True).plan
    assert again.to_dict() == plan.to_dict()  # seeded
    out = tmp_path / "out"
    assert run(["validate", str(tmp_path / "validation.yaml"), "--out", str(out), "--plan"]) == 1
    printed = capsys.readouterr().out
    assert "plan: units per side" in printed and "not reachable" in printed
    document = json.loads((out / "verdict.json").read_text())
    assert document["plan"]["planned_units_per_side"] == {str(c): n
                                                          for c, n in plan.sizes.items()}
    assert 'id="plan"' in (out / "report.html").read_text()


def test_paired_candidate_plan_is_searched_from_its_own_pairs(tmp_path):
    """A twin with the reference's law that replays it run by run (same run ids): its plan is
    searched by simulation from its own pairs (members swapped at random), starts at the
    normal rule's size, reaches 80 % there or above, and is seeded."""
    path = write_universe(tmp_path, runs=60, pairs={"by": "run_id"},
                          candidates={"twin": {"runs": {"path": "twin.parquet"}}})
    reference = TraceSet.read(tmp_path / "ref.parquet")
    other = universe(60, 150, seed=3)  # the same law (x does not depend on v below v_switch)
    x, v = reference.signals.index("x"), reference.signals.index("v")
    values = reference.values.copy()
    values[:, x] = other.values[:, other.signals.index("x")]
    assert np.array_equal(values[:, v], reference.values[:, v])  # the same scenarios: a replay
    TraceSet(reference.signals, reference.time, values, reference.offsets, reference.run_ids,
             reference.metadata, "twin").write(tmp_path / "twin.parquet")
    spec, base = read_validation(path)
    plan = validate(spec, read_inputs(spec, base), planned=True).plan
    searched = plan.candidates["twin"]
    rows = {r.cell: r.if_perfect for r in plan.rows if r.source == "twin"}
    assert searched.sizes and set(searched.sizes) == set(rows)
    assert all(searched.sizes[c] >= rows[c] for c in rows)
    assert searched.simulated_power >= 0.8 and searched.simulations == 20
    again = validate(spec, read_inputs(spec, base), planned=True).plan
    assert again.to_dict()["candidates"] == plan.to_dict()["candidates"]


def test_plan_row_document_keeps_its_keys_and_order():
    """PlanRow's document comes from its fields (``simcred._json.fields_dict``, issue 27) with
    the keys and order verdict.json always had."""
    from simcred.validate.plan import PlanRow

    row = PlanRow("idm", 3, "10 ≤ v < 15", 40, "v", 0.1, 0.05, 0.01, 12, None)
    assert row.to_dict() == {
        "source": "idm", "cell": 3, "label": "10 ≤ v < 15", "units_per_side": 40,
        "feature": "v", "tolerance": 0.1, "estimate": 0.05, "se": 0.01,
        "needed_if_as_good_as_reference": 12, "needed_at_estimate": None}
    assert list(row.to_dict()) == ["source", "cell", "label", "units_per_side", "feature",
                                   "tolerance", "estimate", "se",
                                   "needed_if_as_good_as_reference", "needed_at_estimate"]
