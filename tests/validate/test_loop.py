"""The loop end to end on the synthetic universe: verdicts and exit codes, learned contracts that
`contracts check` accepts, configuration against brute force, monitors at the right steps,
byte-identical reruns, the grid against a literal implementation."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from simcred.cli import run
from simcred.contracts.configure import setup_refines
from simcred.contracts.library import Library
from simcred.traces import TraceSet
from simcred.validate import read_inputs, read_validation, validate
from simcred.validate.cells import OUTSIDE, Grid, segments
from simcred.validate.domain import CellStatus
from simcred.validate.learned import COMPONENT, TEST_CASE, built_contracts, number

from .conftest import write_universe

TWO = {"sim": {"runs": {"path": "sim.parquet"}, "cost": 1},
       "twin": {"runs": {"path": "twin.parquet"}, "cost": 5}}


def _run(path, out, *extra):
    code = run(["-q", "validate", str(path), "--out", str(out), "--no-report", *extra])
    return code, json.loads((out / "verdict.json").read_text())


def test_not_valid_above_the_switch(tmp_path):
    code, verdict = _run(write_universe(tmp_path), tmp_path / "out")
    assert code == 1 and verdict["verdict"] == "not valid"
    cells = verdict["domains"]["sim"]["cells"]
    assert [c["status"] for c in cells] == ["valid"] * 3 + ["not valid"] * 2
    # 10 <= v <= 25 ends at the edge 25: the cell 25-30 is not part of it (issue 22)
    assert verdict["candidates"]["sim"]["test_case_cells"] == [1, 2, 3]


def test_valid_below_the_switch_and_cheapest_by_brute_force(tmp_path, capsys):
    path = write_universe(tmp_path, test_case={"conditions": "5 <= v < 20",
                                               "tolerance": {"x": 1.0}}, candidates=TWO)
    code, verdict = _run(path, tmp_path / "out")
    assert code == 0 and verdict["verdict"] == "valid"
    assert verdict["configuration"]["setup"] == {COMPONENT: "sim"}
    library = Library.read(tmp_path / "out" / "contracts.yaml")
    target = library.test_case(TEST_CASE)
    costs = {m: library.spec.models[m].cost for m in library.spec.models
             if setup_refines(library, {COMPONENT: m}, target).holds}
    assert set(costs) == {"sim", "twin"}
    assert verdict["configuration"]["cost"] == min(costs.values())
    assert run(["contracts", "check", str(tmp_path / "out" / "contracts.yaml")]) == 0
    # over the whole test case 10..25 only the twin is valid, though it costs more
    path = write_universe(tmp_path, candidates=TWO)
    code, verdict = _run(path, tmp_path / "out2")
    assert code == 0 and verdict["configuration"]["setup"] == {COMPONENT: "twin"}
    assert verdict["candidates"]["sim"]["verdict"] == "not valid"


def test_inconclusive_when_data_is_short_or_the_grid_ends(tmp_path):
    path = write_universe(tmp_path, test_case={"conditions": "5 <= v < 20",
                                               "tolerance": {"x": 1.0}},
                          min_data={"runs": 10_000, "samples": 200})
    code, verdict = _run(path, tmp_path / "a")
    assert code == 3 and verdict["verdict"] == "inconclusive"
    assert {c["status"] for c in verdict["domains"]["sim"]["cells"]} == {"unknown"}
    assert verdict["configuration"] is None
    path = write_universe(tmp_path, test_case={"conditions": "0 <= v < 20",
                                               "tolerance": {"x": 1.0}})
    code, verdict = _run(path, tmp_path / "b")
    assert code == 3
    assert any("beyond the grid" in r for r in verdict["candidates"]["sim"]["reasons"])
    assert verdict["uncovered"]["sim"] == [
        "the test case's conditions reach beyond the grid (5 <= v and v <= 30)"]


def test_monitor_flags_the_steps_that_leave_the_domain(tmp_path):
    t = np.arange(100) * 0.1
    v = np.linspace(12.0, 24.0, 100)
    TraceSet.from_runs([{"t": t, "v": v, "x": np.zeros(100)}], run_ids=["ramp"]).write(
        tmp_path / "ramp.parquet")
    path = write_universe(tmp_path, monitor=[{"path": "ramp.parquet"}])
    _, verdict = _run(path, tmp_path / "out")
    report = verdict["monitors"]["sim on monitor[0]"]
    assert report["violations"] == 1
    outside = np.flatnonzero(v > 20.0)  # the learned domain is 5 <= v <= 20
    found = report["first_violations"][0]
    assert (found["first_step"], found["last_step"]) == (outside[0], outside[-1])
    assert found["margin"] == pytest.approx(-(v.max() - 20.0))


def test_same_inputs_and_seed_give_identical_bytes(tmp_path):
    path = write_universe(tmp_path)
    assert run(["-q", "validate", str(path), "--out", str(tmp_path / "a")]) == 1
    (tmp_path / "other").mkdir()
    other = write_universe(tmp_path / "other", candidates=TWO)  # other solver queries between
    assert run(["-q", "validate", str(other), "--out", str(tmp_path / "o"), "--no-report"]) == 0
    assert run(["-q", "validate", str(path), "--out", str(tmp_path / "b")]) == 1
    for name in ("verdict.json", "contracts.yaml", "report.html"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes()
    document = yaml.safe_load(path.read_text())
    document["comparison"]["seed"] = 8
    path.write_text(yaml.safe_dump(document))
    run(["-q", "validate", str(path), "--out", str(tmp_path / "c"), "--no-report"])
    assert (tmp_path / "c" / "verdict.json").read_bytes() != \
        (tmp_path / "a" / "verdict.json").read_bytes()


def test_library_api_matches_cli(tmp_path):
    spec, base = read_validation(write_universe(tmp_path))
    result = validate(spec, read_inputs(spec, base))
    assert result.verdict == "not valid" and result.exit_code == 1
    domain = result.domains["sim"]
    for cell in domain.with_status(CellStatus.VALID):  # each valid cell guarantees its bound
        guarantee = result.library["models"]["sim"]["contract"]["guarantee"]
        assert f"deviation.x <= {number(cell.bounds[0].upper)}" in guarantee
    assert yaml.safe_load(result.library_yaml()) == result.library
    _the_file_says_what_was_built(result)


def _the_file_says_what_was_built(result):
    """The learned contracts are built as ASTs; contracts.yaml's text of them parses back to
    the very same trees (issue 27: printed at the edge, never parsed back by the loop)."""
    from_file = Library.from_dict(result.library, source="contracts.yaml")
    target = from_file.test_case(TEST_CASE)
    built = built_contracts(result.spec, result.domains, target.assumption)
    assert built.pop(f"test_cases.{TEST_CASE}") == target
    assert built and {k.split(".")[1] for k in built} == set(from_file.model_contracts)
    for key, contract in built.items():
        assert from_file.model_contracts[key.split(".")[1]] == contract


@settings(max_examples=60, deadline=None)
@given(st.lists(st.sampled_from([4.0, 5.0, 7.5, 10.0, 12.0, 20.0, 29.9, 30.0, 31.0]),
                min_size=2, max_size=40),
       st.lists(st.floats(-1, 3), min_size=2, max_size=40))
def test_cells_and_segments_match_a_literal_implementation(vs, gs):
    n = min(len(vs), len(gs))
    grid = Grid(("v", "g"), ((5.0, 10.0, 20.0, 30.0), (0.0, 1.0, 2.0)), ("m/s", "m"))
    traces = TraceSet.from_runs([{"t": np.arange(n), "v": vs[:n], "g": gs[:n]}])

    def literal(value, edges):
        for i in range(len(edges) - 1):
            last = i == len(edges) - 2
            if edges[i] <= value < edges[i + 1] or (last and value == edges[i + 1]):
                return i
        return None

    expected = []
    for v, g in zip(vs[:n], gs[:n], strict=True):
        i, j = literal(v, grid.edges[0]), literal(g, grid.edges[1])
        expected.append(OUTSIDE if i is None or j is None else i * 2 + j)
    assert grid.cells_of(traces).tolist() == expected
    cut = segments(traces, grid, 2)
    rows = sum(ts.n_rows for ts in cut.by_cell.values())
    runs_of_two = sum(1 for k, grp in _groups(expected) if k != OUTSIDE and grp >= 2)
    assert sum(ts.n_runs for ts in cut.by_cell.values()) == runs_of_two
    assert rows == sum(grp for k, grp in _groups(expected) if k != OUTSIDE and grp >= 2)


def _groups(values):
    out, k = [], 0
    while k < len(values):
        j = k
        while j < len(values) and values[j] == values[k]:
            j += 1
        out.append((values[k], j - k))
        k = j
    return out


def test_each_cell_is_the_comparison_of_its_segments(tmp_path):
    """Oracle: compare() called directly on the reference's and the candidate's segments of a
    cell, grouped by the run each segment was cut from, with the cell's seed, gives the cell's
    p-value and bounds; the status is the literal rule on those bounds (K = 3 cells)."""
    from simcred.compare import compare
    from simcred.validate.cells import grid_of
    from simcred.validate.domain import cell_seed

    spec, base = read_validation(write_universe(tmp_path))
    inputs = read_inputs(spec, base)
    result = validate(spec, inputs)
    grid = grid_of(spec.conditions)
    ref = segments(inputs.reference, grid, spec.segments.min_length)
    cand = segments(inputs.candidates["sim"], grid, spec.segments.min_length)
    for cell in result.domains["sim"].cells:
        direct = compare(ref.by_cell[cell.cell], cand.by_cell[cell.cell], features=["x"], bins=4,
                         alpha=0.05, permutations=99, bootstrap=500, test="response",
                         group_by="source_run", margin={"x": 1.0},
                         seed=cell_seed(7, "sim", cell.cell))
        effect = direct.response.effect.features[0]
        lower, upper = effect.bounds(0.05 / 3)[0], effect.bounds(0.05)[1]
        assert cell.pvalue == direct.chain.pvalue
        assert (cell.bounds[0].lower, cell.bounds[0].upper) == (lower, upper)
        expected = "not valid" if lower > 1.0 else "valid" if upper < 1.0 else "inconclusive"
        assert cell.status.value == expected


def test_provenance_names_the_inputs(tmp_path):
    import hashlib

    path = write_universe(tmp_path)
    code, verdict = _run(path, tmp_path / "out", "--date", "2026-11-23")
    provenance = verdict["provenance"]
    assert provenance["date"] == "2026-11-23"
    assert provenance["validation_file"]["sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
    assert provenance["inputs"]["reference"]["digest"] == \
        TraceSet.read(tmp_path / "ref.parquet").digest()
    assert provenance["seed"] == 7 and provenance["options"]["comparison"]["seed"] == 7
    _, undated = _run(path, tmp_path / "undated")
    assert undated["provenance"]["date"] is None


def _with_run_constant(traces: TraceSet, name: str, seed: int) -> TraceSet:
    """``traces`` plus a signal that is constant within each run (an exogenous condition)."""
    rng = np.random.default_rng(seed)
    per_run = rng.uniform(0.0, 2.0, size=traces.n_runs)
    column = np.repeat(per_run, traces.lengths)
    return TraceSet((*traces.signals, name), traces.time,
                    np.column_stack([traces.values, column]), traces.offsets, traces.run_ids,
                    source=traces.source)


def test_two_condition_variables(tmp_path):
    from simcred.report.validate import write_validation_report
    from simcred.validate.loop import Inputs
    from simcred.validate.synthetic import universe
    from simcred.validate.verdict import verdict_document

    path = write_universe(tmp_path, conditions={"v": {"unit": "m/s", "edges": [5, 20, 30]},
                                                "g": {"unit": "m", "edges": [0, 1, 2]}})
    spec, _ = read_validation(path)
    reference = _with_run_constant(universe(160, 150, seed=1), "g", 11)
    candidate = _with_run_constant(universe(160, 150, seed=2, effect=0.3, v_switch=20,
                                            name="sim"), "g", 12)
    inputs = Inputs(reference, {"sim": candidate}, ())
    result = validate(spec, inputs)
    status = {c.index: c.status.value for c in result.domains["sim"].cells}
    assert status == {(0, 0): "valid", (0, 1): "valid", (1, 0): "not valid",
                      (1, 1): "not valid"}
    assumption = result.library["models"]["sim"]["contract"]["assumption"]
    assert assumption == "(5 <= v <= 20 and 0 <= g <= 1) or (5 <= v <= 20 and 1 <= g <= 2)"
    _the_file_says_what_was_built(result)
    out = tmp_path / "out"
    out.mkdir()
    html = write_validation_report(result, verdict_document(result, inputs), out).read_text()
    assert html.count("data:image/png;base64,") == 1 + 1 + 4  # ranking, domain, state maps


def test_the_size_decides_not_the_p_value(tmp_path):
    """Issue 22: VALID meant "no difference found", NOT VALID "a difference found". Now the size
    of the deviation decides: with a tolerance far above the AR change's deviation every cell
    is valid, whatever its difference or deviation p-value; with one far below, cells whose
    bounds straddle it are inconclusive, never valid. (Here the difference test does not even
    reject above 20 m/s: the AR change shifts the response up for x > 0 and down for x < 0,
    which its pooled statistic averages away — the deviation, an RMS over states, does not;
    docs/validate.md.)"""
    path = write_universe(tmp_path, test_case={"conditions": "10 <= v <= 25",
                                               "tolerance": {"x": 20.0}})
    code, verdict = _run(path, tmp_path / "wide")
    cells = verdict["domains"]["sim"]["cells"]
    assert [c["status"] for c in cells] == ["valid"] * 5 and code == 0
    # a shown deviation (the deviation's own test rejects the same law) in a valid cell
    assert min(c["deviation"][0]["deviation_pvalue"] for c in cells) <= 0.05
    path = write_universe(tmp_path, test_case={"conditions": "10 <= v <= 25",
                                               "tolerance": {"x": 0.3}})
    code, verdict = _run(path, tmp_path / "narrow")
    cells = verdict["domains"]["sim"]["cells"]
    for c in cells:
        bound = c["deviation"][0]
        assert c["status"] != "valid" or bound["upper"] < 0.3
        if bound["lower"] <= 0.3 <= bound["upper"]:
            assert c["status"] == "inconclusive"
    assert [c["status"] for c in cells[3:]] == ["not valid"] * 2
    assert max(c["difference_pvalue"] for c in cells[3:]) > 0.05  # not valid, not "different"
    assert code == 1


def test_the_bound_is_per_cell(tmp_path):
    """Issue 22: one global bound (the largest of any valid cell) decided the test case, so a
    cell outside it could make it fail. The guarantee is one bound per valid cell, and a test
    case is judged on its own cells only."""
    path = write_universe(tmp_path, test_case={"conditions": "10 <= v < 15",
                                               "tolerance": {"x": 0.55}})
    code, verdict = _run(path, tmp_path / "out")
    upper = {c["label"]: c["deviation"][0]["upper"] for c in verdict["domains"]["sim"]["cells"]}
    assert upper["10 ≤ v < 15"] < 0.55 < upper["15 ≤ v < 20"]  # this universe, seed 1/2/7
    assert code == 0 and verdict["verdict"] == "valid"
    guarantee = yaml.safe_load((tmp_path / "out" / "contracts.yaml").read_text())[
        "models"]["sim"]["contract"]["guarantee"]
    assert f"(10 <= v <= 15 implies deviation.x <= {number(upper['10 ≤ v < 15'])})" in guarantee
    assert "15 <= v <= 20" not in guarantee  # not shown within 0.55: not in the domain
    path = write_universe(tmp_path, test_case={"conditions": "12 <= v <= 18",
                                               "tolerance": {"x": 0.55}})
    code, verdict = _run(path, tmp_path / "out2")
    assert code == 3 and verdict["candidates"]["sim"]["verdict"] == "inconclusive"
    assert verdict["candidates"]["sim"]["reasons"][0].startswith("inconclusive in 15 ≤ v < 20")


def test_a_test_case_ending_at_an_edge_does_not_pull_in_the_next_cell(tmp_path):
    """Issue 22: ``v <= 20`` met the cell 20-25 at the single point 20, which made the test case
    NOT VALID although the learned contract (5 <= v <= 20) covers it."""
    path = write_universe(tmp_path, test_case={"conditions": "10 <= v <= 20",
                                               "tolerance": {"x": 1.0}})
    code, verdict = _run(path, tmp_path / "out")
    assert verdict["candidates"]["sim"]["test_case_cells"] == [1, 2]
    assert code == 0 and verdict["verdict"] == "valid"
    assert verdict["candidates"]["sim"]["refinement"]["verdict"] == "holds"
    # starting at the edge: only the cells above it
    path = write_universe(tmp_path, test_case={"conditions": "20 <= v <= 25",
                                               "tolerance": {"x": 1.0}})
    code, verdict = _run(path, tmp_path / "out2")
    assert verdict["candidates"]["sim"]["test_case_cells"] == [3]
    assert code == 1
    # a test case on the edge itself meets the two closed cells that share it
    path = write_universe(tmp_path, test_case={"conditions": "v == 20",
                                               "tolerance": {"x": 1.0}})
    _, verdict = _run(path, tmp_path / "out3")
    assert verdict["candidates"]["sim"]["test_case_cells"] == [2, 3]


def test_learned_contracts_work_with_monitor(tmp_path, capsys):
    """Issue 22: ``simcred monitor`` refused the learned contracts.yaml (no run carries the
    ``distance`` signal). The library marks the deviations ``observed: false``; the monitor
    checks the domains and names the guarantee clauses it cannot check."""
    _, verdict = _run(write_universe(tmp_path), tmp_path / "out")
    capsys.readouterr()
    library = tmp_path / "out" / "contracts.yaml"
    code = run(["monitor", str(library), str(tmp_path / "sim.parquet"), "--setup",
                "simulation=sim", "--json"])
    report = json.loads(capsys.readouterr().out)
    assert code == 1 and report["violations"]  # the candidate's runs leave 5 <= v <= 20
    assert {v["kind"] for v in report["violations"]} == {"assumption"}
    upper = [number(c["deviation"][0]["upper"]) for c in verdict["domains"]["sim"]["cells"][:3]]
    assert report["not_monitored"] == [
        f"sim: {lo} <= v and v <= {hi} implies deviation.x <= {u}"
        for lo, hi, u in zip((5, 10, 15), (10, 15, 20), upper, strict=True)]
    assert run(["-q", "monitor", str(library), str(tmp_path / "sim.parquet"),
                "--test-case", "test_case"]) == 2  # no valid setup to monitor: named, exit 2


def test_an_empty_learned_library_is_a_verdict(tmp_path, capsys):
    """Issue 22: ``contracts configure`` exited 2 (bad input) on learned contracts without a
    valid candidate; no setup is a verdict: fails, exit 1, with the reason."""
    path = write_universe(tmp_path, min_data={"runs": 10_000, "samples": 200})
    code, _ = _run(path, tmp_path / "out")
    assert code == 3
    library = str(tmp_path / "out" / "contracts.yaml")
    assert yaml.safe_load((tmp_path / "out" / "contracts.yaml").read_text())["models"] == {}
    assert run(["contracts", "check", library]) == 0
    capsys.readouterr()
    assert run(["contracts", "configure", library, "--test-case", "test_case", "--json"]) == 1
    result = json.loads(capsys.readouterr().out)
    assert result["status"] == "fails" and result["setup"] is None
    assert "component 'simulation' has no model" in result["reason"]


def test_ranking_orders_by_deviation_with_intervals(tmp_path):
    """Issue 22: candidates ranked by their largest deviation relative to the tolerance with a
    simultaneous interval, beside two halves of the reference (the floor)."""
    _, verdict = _run(write_universe(tmp_path, candidates=TWO), tmp_path / "out")
    ranking = verdict["ranking"]
    assert [r["candidate"] for r in ranking] == ["twin", "reference halves", "sim"] or \
        [r["candidate"] for r in ranking] == ["reference halves", "twin", "sim"]
    for r in ranking:
        low, high = r["interval"]
        assert low <= r["score"] <= high and r["test_case_cells"] == 3
    sim = ranking[-1]
    assert sim["interval"][0] > 1  # beyond the tolerance, shown
    cells = verdict["domains"]["sim"]["cells"][1:4]
    assert sim["score"] == max(c["deviation"][0]["estimate"] for c in cells) / 1.0


def test_relative_tolerance_is_resolved_from_the_reference_halves(tmp_path):
    """Issue 22: a tolerance relative to the reference's own spread: f times the median
    deviation between 5 random halves of the reference's runs over the test case's cells,
    written with its splits and then used as an absolute tolerance."""
    import numpy as np

    path = write_universe(tmp_path, test_case={"conditions": "10 <= v <= 25",
                                               "tolerance": {"x": {"relative": 3.0}}})
    spec, base = read_validation(path)
    result = validate(spec, read_inputs(spec, base))
    (found,) = result.tolerance_resolution
    assert found.spread == np.median(found.estimates) and len(found.estimates) == 5
    assert found.tolerance == 3.0 * found.spread == result.spec.test_case.tolerance["x"]
    absolute = write_universe(tmp_path / "abs" if (tmp_path / "abs").mkdir() is None else None,
                              test_case={"conditions": "10 <= v <= 25",
                                         "tolerance": {"x": found.tolerance}})
    spec2, base2 = read_validation(absolute)
    again = validate(spec2, read_inputs(spec2, base2))
    assert [c.status for c in again.domains["sim"].cells] == \
        [c.status for c in result.domains["sim"].cells]
    code, verdict = _run(path, tmp_path / "out")
    assert verdict["tolerance_resolution"][0]["units"] == "run"
    path = write_universe(tmp_path, test_case={"conditions": "10 <= v <= 25",
                                               "tolerance": {"x": {"relative": 1.0}}},
                          min_data={"runs": 2, "samples": 10}, runs=2, steps=40)
    assert run(["-q", "validate", str(path), "--out", str(tmp_path / "few")]) == 2


def test_an_inconclusive_cell_says_what_data_would_decide_it(tmp_path):
    """Issue 22: INCONCLUSIVE comes with the data that would be needed — per undecided cell the
    normal rule's units per side at the candidate's estimate (the plan's number)."""
    from simcred.validate import read_inputs, read_validation, validate
    from simcred.validate.plan import cell_rows

    path = write_universe(tmp_path, test_case={"conditions": "5 <= v < 20",
                                               "tolerance": {"x": 0.5}})
    spec, base = read_validation(path)
    result = validate(spec, read_inputs(spec, base))
    power = 0.8 ** (1 / 3)
    undecided = [c for c in result.domains["sim"].cells if c.status.value == "inconclusive"]
    assert undecided, "the design should leave a cell undecided at tolerance 0.5"
    reasons = result.candidates["sim"].reasons
    for cell in undecided:
        rows = cell_rows("sim", cell, spec, power)
        needed = max(r.needed for r in rows)
        line = next(r for r in reasons if r.startswith(f"inconclusive in {cell.label}"))
        assert f"about {needed} units per side would show it within tolerance" in line
    assert "--plan" in result.summary


@pytest.mark.parametrize("lower, upper, pvalue, status", [
    (0.05, 0.6, 0.5, "inconclusive"),   # bounds straddle the tolerance
    (0.05, 0.09, 0.5, "valid"),         # upper bound below it
    (0.2, 0.4, 0.01, "not valid"),      # lower bound above it, permutation test rejects at α/K
    (0.2, 0.4, 0.02, "inconclusive"),   # lower bound above it, but p > α/K = 0.05 / 3
])
def test_the_cell_decision_rule(lower, upper, pvalue, status):
    """Valid: every upper 1 − α bound below the tolerance; not valid: a lower 1 − α/K bound
    above it AND the deviation's permutation p-value at most α/K; else inconclusive."""
    from simcred.regions.engine import CellRule, FeatureBounds, _decide

    bounds = (FeatureBounds("x", "1/s", 0.1, (lower + upper) / 2, lower, upper, lower, upper,
                            0.1, pvalue),)
    found, reason = _decide(bounds, CellRule(0.05, 3, None, "source_run"))
    assert found.value == status, reason
    if status == "inconclusive" and lower > 0.1:
        assert "does not reject the same law at 0.0167 (p = 0.02)" in reason


def test_a_floor_at_the_tolerance_says_more_units_are_needed():
    """When the upper bound's power floor reaches the tolerance, no draw of these data could make
    the cell valid; the reason says so. Below it, the plain "straddle" reason."""
    from simcred.regions.engine import CellRule, FeatureBounds, _decide

    rule = CellRule(0.05, 3, None, "source_run")
    for floor, said in ((0.12, True), (0.08, False)):
        bounds = (FeatureBounds("x", "1/s", 0.1, 0.07, 0.05, 0.6, 0.05, 0.6, 0.1, 0.5, floor),)
        found, reason = _decide(bounds, rule)
        assert found.value == "inconclusive"
        assert ("power floor 0.12 (more units needed)" in reason) is said, reason
        assert "straddle the tolerance 0.1" in reason


def test_each_cell_reports_the_floor_its_upper_bound_is_held_at(tmp_path):
    """Every judged cell's ``floor`` is √ of its comparison's power floor at α, the upper bound is
    never below it, and the domain's JSON carries it."""
    import math

    path = write_universe(tmp_path, test_case={"conditions": "5 <= v < 20",
                                               "tolerance": {"x": 0.5}})
    spec, base = read_validation(path)
    result = validate(spec, read_inputs(spec, base))
    judged = [c for c in result.domains["sim"].cells if c.comparison is not None]
    assert judged
    for cell in judged:
        effects = {f.feature: f for f in cell.comparison.response.effect.features}
        alpha = cell.comparison.options.alpha
        for b in cell.bounds:
            expected = math.sqrt(effects[b.feature].power_floor(alpha))
            assert b.floor == pytest.approx(expected, rel=1e-12, abs=1e-15)
            assert b.upper >= b.floor
        assert all("upper_floor" in d for d in cell.to_dict()["deviation"])
