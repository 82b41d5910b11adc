"""Contract library (YAML), configuration (optimal, proven) and quotient; bad input."""

import itertools
import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from simcred.cli import run
from simcred.contracts.algebra import Status, refines
from simcred.contracts.configure import configure, missing_model_requirement, setup_contract
from simcred.contracts.library import Library
from simcred.errors import SimcredError

FIGURE2 = Path(__file__).resolve().parents[2] / "examples" / "contracts" / "figure2.yaml"


def test_figure2_picks_the_cheapest_valid_setup_with_a_proof():
    lib = Library.read(FIGURE2)
    result = configure(lib, "C_tc")
    assert result.status is Status.HOLDS
    assert result.setup == {"I1": "M1", "I2": "M2a"}  # M2b is cheaper but valid only to q <= 20
    assert result.cost == 6
    assert refines(setup_contract(lib, result.setup), lib.test_case("C_tc")).holds
    assert not refines(setup_contract(lib, {"I1": "M1", "I2": "M2b"}), lib.test_case("C_tc")).holds


def test_figure2_quotient_composes_with_m1_to_refine_the_test_case():
    lib = Library.read(FIGURE2)
    requirement = missing_model_requirement(lib, "C_tc", {"I1": "M1"})
    assert refines(lib.model_contracts["M1"].compose(requirement), lib.test_case("C_tc")).holds
    assert refines(lib.model_contracts["M2a"], requirement).holds
    assert not refines(lib.model_contracts["M2b"], requirement).holds


def random_library(rng, components=3, per_component=3):
    """A chain I0 -> I1 -> ... of interval contracts with random ranges and costs."""
    variables = {f"x{i}": {"type": "real", "unit": "m"} for i in range(components + 1)}
    spec = {"variables": variables, "components": {}, "models": {},
            "architecture": [f"I{i}" for i in range(components)]}
    for i in range(components):
        spec["components"][f"I{i}"] = {"inputs": [f"x{i}"], "outputs": [f"x{i + 1}"]}
        for j in range(per_component):
            lo, hi = sorted(rng.integers(0, 12, size=2))
            out = int(rng.integers(4, 14))
            spec["models"][f"M{i}{j}"] = {
                "implements": f"I{i}", "cost": int(rng.integers(1, 10)),
                "contract": {"assumption": f"{lo} <= x{i} <= {hi + 2}",
                             "guarantee": f"0 <= x{i + 1} <= {out}"}}
    spec["test_cases"] = {"tc": {"assumption": "2 <= x0 <= 5",
                                 "guarantee": f"x{components} <= {int(rng.integers(5, 14))}"}}
    return Library.from_dict(spec)


@pytest.mark.parametrize("seed", range(12))
def test_configuration_is_optimal_against_brute_force(seed):
    lib = random_library(np.random.default_rng(seed))
    result = configure(lib, "tc")
    components = lib.spec.architecture
    valid_costs = []
    for models in itertools.product(*(lib.candidates(c) for c in components)):
        setup = dict(zip(components, models, strict=True))
        if refines(setup_contract(lib, setup), lib.test_case("tc")).holds:
            valid_costs.append(sum(lib.spec.models[m].cost for m in models))
    if not valid_costs:
        assert result.status is Status.FAILS
    else:
        assert result.status is Status.HOLDS and result.cost == min(valid_costs)


def write(tmp_path, spec) -> Path:
    path = tmp_path / "lib.yaml"
    path.write_text(yaml.safe_dump(spec) if isinstance(spec, dict) else spec)
    return path


def base_spec():
    return yaml.safe_load(FIGURE2.read_text())


@pytest.mark.parametrize(
    ("mutate", "expected"),
    [
        (lambda s: s["models"]["M1"]["contract"].update(assumption="0 <= w <= 4"),
         "undeclared variable 'w'"),
        (lambda s: s["components"]["I2"].update(inputs=[{"q": "km"}]), "unit mismatch"),
        (lambda s: s["components"]["I2"].update(inputs=["v"], outputs=["err", "q"]),
         "driven by two outputs"),
        (lambda s: s["models"]["M2a"]["contract"].update(guarantee="err <= "),
         "models.M2a.contract"),
        (lambda s: s["models"]["M1"].update(implements="I9"), "unknown component 'I9'"),
        (lambda s: s["variables"]["v"].update(unit="blorbs per glorp"), "not a physical unit"),
        (lambda s: s["models"]["M1"].update(colour="red"), "models.M1.colour"),
        (lambda s: s["models"]["M1"].update(cost=-1), "models.M1.cost"),
    ],
)
def test_bad_libraries_are_one_line_errors(mutate, expected, tmp_path, capsys):
    spec = base_spec()
    mutate(spec)
    path = write(tmp_path, spec)
    with pytest.raises(SimcredError) as info:
        Library.read(path)
    assert expected in str(info.value) and "\n" not in str(info.value)
    assert run(["contracts", "check", str(path)]) == 2
    err = capsys.readouterr().err
    assert expected in err and err.count("\n") == 1


def test_malformed_yaml_names_line_and_column(tmp_path, capsys):
    path = write(tmp_path, "variables:\n  v: {type: real\nmodels: [\n")
    assert run(["contracts", "check", str(path)]) == 2
    err = capsys.readouterr().err
    assert "lib.yaml" in err and "line" in err and err.count("\n") == 1


def test_cli_refines_json_and_exit_codes(capsys):
    assert run(["contracts", "refines", str(FIGURE2), "--refining", "M2b", "--refined", "M2a",
                "--json"]) == 1
    doc = json.loads(capsys.readouterr().out)
    assert doc["verdict"] == "fails" and 20 < doc["counterexample"]["q"] <= 60
    assert run(["contracts", "refines", str(FIGURE2), "--refining", "M2a", "--refined",
                "M2b"]) == 0


def test_cli_configure_and_quotient(capsys):
    assert run(["contracts", "configure", str(FIGURE2), "--test-case", "C_tc", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["setup"] == {"I1": "M1", "I2": "M2a"}
    assert run(["contracts", "quotient", str(FIGURE2), "--test-case", "C_tc", "--given",
                "I1=M1", "--json"]) == 0
    assert "err" in json.loads(capsys.readouterr().out)["guarantee"]
    assert run(["contracts", "quotient", str(FIGURE2), "--test-case", "C_tc", "--given",
                "I1"]) == 2


def test_projected_quotient_is_the_requirement_over_the_missing_ports():
    from simcred.contracts.configure import missing_ports
    from simcred.contracts.evaluate import evaluate
    from simcred.contracts.expr import variables
    from simcred.contracts.project import project

    lib = Library.read(FIGURE2)
    quotient = missing_model_requirement(lib, "C_tc", {"I1": "M1"})
    projected = project(quotient, missing_ports(lib, {"I1": "M1"}), types=lib.types)
    assert projected is not None
    assert variables(projected.assumption) | variables(projected.guarantee) <= {"q", "err"}
    assert refines(projected, quotient).holds  # sufficient for the quotient
    assert refines(lib.model_contracts["M1"].compose(projected), lib.test_case("C_tc")).holds
    assert refines(lib.model_contracts["M2a"], projected).holds
    assert not refines(lib.model_contracts["M2b"], projected).holds
    # closed form: assume 0 <= q <= 50, guarantee err <= 0.2 there
    grid = {"q": np.array([-1.0, 0, 25, 50, 51]), "err": np.array([0.0, 0.2, 0.21, 0.3, 9])}
    assert evaluate(projected.assumption, grid).tolist() == [False, True, True, True, False]
    q, e = np.meshgrid(np.linspace(0, 50, 11), np.linspace(0, 0.4, 9))
    holds = evaluate(projected.saturated_guarantee, {"q": q, "err": e})
    assert np.array_equal(holds, e <= 0.2)
