"""Well-formedness (issue 15, item 1): port scope, no vacuity, explicit trivial contracts,
duplicate keys, viewpoints combined by conjunction, bool variables usable."""

from __future__ import annotations

import copy
from pathlib import Path

import pytest
import yaml

from simcred.cli import run
from simcred.contracts.algebra import Contract, Status, equivalent, refines
from simcred.contracts.configure import configure
from simcred.contracts.expr import Bool
from simcred.contracts.library import Library, LibraryError

FIGURE2 = Path(__file__).resolve().parents[2] / "examples" / "contracts" / "figure2.yaml"
BASE = yaml.safe_load(FIGURE2.read_text())

# The false certificate of issue 15: a camera model "guarantees" the dynamics model's error.
CAMERA = {
    "variables": {"obj.range": {"unit": "m"}, "ego.v": {"unit": "m/s"},
                  "cam.error": {"unit": "m"}, "dyn.lat_error": {"unit": "m"}},
    "components": {"camera": {"inputs": ["obj.range"], "outputs": ["cam.error"]},
                   "dynamics": {"inputs": ["ego.v"], "outputs": ["dyn.lat_error"]}},
    "architecture": ["camera", "dynamics"],
    "models": {
        "cam": {"implements": "camera", "cost": 1, "contract": {
            "assumption": "obj.range <= 100",
            "guarantee": "cam.error <= 0.5 and dyn.lat_error <= 0.01"}},
        "dyn_cheap": {"implements": "dynamics", "cost": 1, "contract": {
            "assumption": "ego.v <= 40", "guarantee": "dyn.lat_error <= 0.1"}}},
    "test_cases": {"tc": {"assumption": "obj.range <= 80 and ego.v <= 30",
                          "guarantee": "dyn.lat_error <= 0.01"}},
}


def spec(**changes):
    out = copy.deepcopy(BASE)
    for path, value in changes.items():
        *head, last = path.split("__")
        node = out
        for key in head:
            node = node[key]
        node[last] = value
    return out


def test_the_false_certificate_no_longer_configures(tmp_path, capsys):
    with pytest.raises(LibraryError, match=r"models\.cam\.contract\.guarantee: 'dyn\.lat_error' "
                                           r"is not a port of component 'camera'"):
        Library.from_dict(CAMERA)
    path = tmp_path / "camera.yaml"
    path.write_text(yaml.safe_dump(CAMERA))
    assert run(["contracts", "configure", str(path), "--test-case", "tc"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "camera.yaml" in err and "dyn.lat_error" in err


def test_without_the_foreign_clause_the_test_case_has_no_valid_setup():
    fixed = copy.deepcopy(CAMERA)
    fixed["models"]["cam"]["contract"]["guarantee"] = "cam.error <= 0.5"
    result = configure(Library.from_dict(fixed), "tc")
    assert result.status is Status.FAILS  # 0.1 does not certify 0.01: no false certificate


@pytest.mark.parametrize(("changes", "fragment"), [
    ({"models__M2a__contract__assumption": "0 <= q <= 60 and err <= 1"},
     "models.M2a.contract.assumption: 'err' is not a port"),  # an assumption on an output
    ({"models__M1__contract__guarantee": "0 <= q <= 50 and err <= 1"},
     "models.M1.contract.guarantee: 'err' is not a port of component 'I1'"),
    ({"test_cases__C_tc__assumption": "10 <= v <= 30 and q <= 5"},
     "test_cases.C_tc.assumption: 'q' is not allowed"),  # the architecture drives q
])
def test_port_scope_violations_name_model_clause_and_variable(changes, fragment):
    with pytest.raises(LibraryError) as info:
        Library.from_dict(spec(**changes))
    assert fragment in str(info.value) and "clause '" in str(info.value)


@pytest.mark.parametrize("assumption", ["q > 5 and q < 5", "q * q < 0", "false",
                                        "abs(q) < 0", "q >= 1 and q <= 0.5"])
def test_an_unsatisfiable_model_assumption_is_an_error(assumption):
    with pytest.raises(LibraryError, match="unsatisfiable, so the contract would hold vacuously"):
        Library.from_dict(spec(models__M2a__contract__assumption=assumption))


def test_an_unsatisfiable_test_case_is_an_error_not_a_cheap_pass():
    with pytest.raises(LibraryError, match=r"test_cases\.C_tc\.assumption.*unsatisfiable"):
        Library.from_dict(spec(test_cases__C_tc__assumption="v > 30 and v < 10"))


def test_a_model_needs_a_contract_or_an_explicit_trivial_one():
    missing = spec()
    del missing["models"]["M1"]["contract"]
    with pytest.raises(LibraryError, match=r"models\.M1\.contract"):
        Library.from_dict(missing)
    trivial = spec(models__M1__contract="trivial")
    lib = Library.from_dict(trivial)
    assert lib.model_contracts["M1"] == Contract(Bool(True), Bool(True), "M1")


def test_duplicate_keys_are_errors_with_the_line(tmp_path):
    text = FIGURE2.read_text().replace("  M2b:\n", "  M2a:\n")
    path = tmp_path / "dup.yaml"
    path.write_text(text)
    line = text.splitlines().index("  M2a:", text.splitlines().index("  M2a:") + 1) + 1
    with pytest.raises(LibraryError, match=rf"line {line}, column 3: duplicate key 'M2a'"):
        Library.read(path)


def test_viewpoints_are_combined_by_conjunction():
    views = [{"viewpoint": "speed", "assumption": "0 <= q <= 60", "guarantee": "err <= 0.1"},
             {"viewpoint": "range", "assumption": "0 <= q <= 20", "guarantee": "err <= 0.05"}]
    lib = Library.from_dict(spec(models__M2a__contract=views))
    combined = lib.model_contracts["M2a"]
    a = Contract.from_strings(views[0]["assumption"], views[0]["guarantee"])
    b = Contract.from_strings(views[1]["assumption"], views[1]["guarantee"])
    assert equivalent(combined, a.conjoin(b)).holds
    assert refines(combined, a).holds and refines(combined, b).holds  # it refines each view


def test_bool_variables_can_be_declared_and_used():
    s = spec(models__M2a__contract__assumption="0 <= q <= 60 and not degraded")
    s["variables"]["degraded"] = {"type": "bool"}
    s["components"]["I2"]["inputs"] = ["q", "degraded"]
    s["test_cases"]["C_tc"]["assumption"] = "10 <= v <= 30 and not degraded"
    lib = Library.from_dict(s)
    result = configure(lib, "C_tc")
    assert result.status is Status.HOLDS and result.setup == {"I1": "M1", "I2": "M2a"}
    s["test_cases"]["C_tc"]["assumption"] = "10 <= v <= 30"  # degraded may now be true
    assert configure(Library.from_dict(s), "C_tc").status is Status.FAILS


def test_contracts_check_reports_test_cases_and_exit_codes(tmp_path, capsys):
    assert run(["contracts", "check", str(FIGURE2), "--json"]) == 0
    import json

    document = json.loads(capsys.readouterr().out)
    assert [c["test_case"] for c in document["test_cases"]] == ["C_tc"]
    inconsistent = spec(models__M2a__contract__guarantee="err <= 0.1 and q <= 3")
    path = tmp_path / "lib.yaml"
    path.write_text(yaml.safe_dump(inconsistent))
    assert run(["contracts", "check", str(path)]) == 1
    out = capsys.readouterr().out
    assert "M2a (I2): consistent FAILS" in out and "no value of the other variables" in out


def test_contracts_check_exits_3_when_undecided(monkeypatch, capsys):
    from simcred.contracts import algebra

    monkeypatch.setattr(algebra, "consistent", lambda *a, **k: algebra.Verdict(
        Status.UNKNOWN, reason="timeout"))
    assert run(["contracts", "check", str(FIGURE2)]) == 3
    assert "consistent unknown (timeout)" in capsys.readouterr().out
