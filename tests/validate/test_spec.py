"""Bad validation files: one line naming the file and the key; CLI exit 2, no traceback."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
import yaml

from simcred.cli import run
from simcred.compare import Method
from simcred.validate.spec import (
    FILE_FIELDS,
    NOT_IN_FILE,
    ComparisonSpec,
    ValidationFileError,
    parse_validation,
    read_validation,
)

from .conftest import write_universe


def _mutated(path, change):
    document = yaml.safe_load(path.read_text())
    change(document)
    path.write_text(yaml.safe_dump(document, sort_keys=False))
    return path


CASES = [
    ("unknown top-level key", lambda d: d.update(extra=1), "extra"),
    ("unknown nested key", lambda d: d["comparison"].update(bin=3),
     "comparison.bin: unknown key (the section takes bins, alpha"),
    ("missing test case", lambda d: d.pop("test_case"), "test_case"),
    ("edges not increasing", lambda d: d["conditions"]["v"].update(edges=[5, 5, 10]),
     "conditions.v.edges"),
    ("one edge", lambda d: d["conditions"]["v"].update(edges=[5]), "conditions.v.edges"),
    ("alpha out of range", lambda d: d["comparison"].update(alpha=1.5), "comparison.alpha"),
    ("removed acceptance rule", lambda d: d.update(acceptance={"rule": "chain"}),
     "acceptance: no longer an option"),
    ("removed max_distance", lambda d: d["test_case"].update(max_distance=0.5),
     "test_case.max_distance: no longer an option"),
    ("baseline not an option", lambda d: d["comparison"].update(baseline=3),
     "comparison.baseline: not an option of the validation file"),
    ("history below 1", lambda d: d["comparison"].update(history=0),
     "comparison.history: history must be an integer >= 1"),
    ("missing tolerance", lambda d: d["test_case"].pop("tolerance"), "test_case.tolerance"),
    ("tolerance not positive", lambda d: d["test_case"].update(tolerance={"x": 0}),
     "test_case.tolerance: tolerance of 'x' must be a finite number > 0 or"),
    ("relative tolerance negative", lambda d: d["test_case"].update(
        tolerance={"x": {"relative": -1}}), "test_case.tolerance: tolerance of 'x'"),
    ("relative tolerance misspelt", lambda d: d["test_case"].update(
        tolerance={"x": {"relativ": 1}}), "test_case.tolerance: tolerance of 'x'"),
    ("tolerance of an input", lambda d: d.update(features=["x", "v"], inputs=["x"]),
     "test_case.tolerance: 'x' is not a response feature"),
    ("input not a feature", lambda d: d.update(inputs=["w"]), "inputs: 'w'"),
    ("pairs and groups", lambda d: d.update(pairs={"by": "run_id"}, groups={"by": "driver"}),
     "pairs: pairs and groups cannot be combined"),
    ("reserved condition name", lambda d: d.update(
        conditions={"deviation": {"edges": [0, 1]}}), "conditions"),
    ("min_data too small", lambda d: d.update(min_data={"runs": 1}), "min_data.runs"),
    ("no candidates", lambda d: d.update(candidates={}), "candidates"),
    ("features not a list", lambda d: d.update(features="x"), "features"),
]


@pytest.mark.parametrize(("what", "change", "key"), CASES, ids=[c[0] for c in CASES])
def test_bad_file_names_the_key(tmp_path, capsys, what, change, key):
    path = _mutated(write_universe(tmp_path, runs=10, steps=20), change)
    with pytest.raises(ValidationFileError) as info:
        read_validation(path)
    message = str(info.value)
    assert "\n" not in message
    assert message.startswith(f"{path}: {key}")
    assert run(["validate", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err and key in err


def test_bad_yaml_and_duplicate_keys(tmp_path, capsys):
    path = tmp_path / "v.yaml"
    path.write_text("test_case: {conditions: 'v < 1'}\ntest_case: {conditions: 'v < 2'}\n")
    assert run(["validate", str(path), "--out", str(tmp_path / "o")]) == 2
    assert "duplicate key 'test_case'" in capsys.readouterr().err
    path.write_text("- a list\n")
    assert run(["validate", str(path), "--out", str(tmp_path / "o")]) == 2
    assert "is a mapping" in capsys.readouterr().err


@pytest.mark.parametrize(("change", "needle"), [
    (lambda d: d["test_case"].update(conditions="10 <= speed"), "test_case.conditions"),
    (lambda d: d["test_case"].update(conditions="10 <= v <="), "test_case.conditions"),
    (lambda d: d.update(features=["x", "nope"]), "no signal 'nope'"),
    (lambda d: d["reference"].update(path="missing.parquet"), "missing.parquet"),
])
def test_bad_content_is_one_line_exit_2(tmp_path, capsys, change, needle):
    path = _mutated(write_universe(tmp_path, runs=10, steps=20), change)
    assert run(["validate", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert needle in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1 or err.count("error:") == 1


def test_outputs_never_overwrite_inputs(tmp_path, capsys):
    path = write_universe(tmp_path, runs=10, steps=20,
                          reference={"path": "verdict.json"})
    assert run(["validate", str(path), "--out", str(tmp_path)]) == 2


@pytest.mark.parametrize(("candidate", "needle"), [
    ({"runs": {"path": "sim.parquet"},
      "simulate": {"command": ["simulate", "cutin"], "output": "x.parquet"}},
     "candidates.sim: give either runs or simulate"),
    ({"cost": 1}, "candidates.sim: give either runs or simulate"),
    ({"simulate": {"command": ["paper", "all"], "output": "x.parquet"}},
     "candidates.sim.simulate.command: a simulator command starts with 'simulate'"),
])
def test_candidate_sources(tmp_path, candidate, needle):
    path = _mutated(write_universe(tmp_path, runs=10, steps=20),
                    lambda d: d.update(candidates={"sim": candidate}))
    with pytest.raises(ValidationFileError, match=needle):
        read_validation(path)


def test_failing_simulator_command_names_the_candidate(tmp_path, capsys):
    path = _mutated(write_universe(tmp_path, runs=10, steps=20), lambda d: d.update(
        candidates={"sim": {"simulate": {"command": ["simulate", "sumo-following",
                                                     "{base}/missing.parquet", "--out", "{out}"],
                                         "output": "IDM.parquet"}}}))
    assert run(["validate", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "candidates.sim.simulate" in err and "Traceback" not in err


# -- the comparison section: every field of Method, or excluded with its reason ---------------

#: A valid value of every key of the comparison section that is not the file's default.
VALUES = {"bins": [4, 5], "alpha": 0.1, "permutations": 99, "seed": 3, "history": 2,
          "time_bins": 3, "resample": 0.5, "bootstrap": 200}
DOCUMENT = {"test_case": {"conditions": "10 <= v <= 25", "tolerance": {"x": 1.0}},
            "reference": {"path": "ref.parquet"},
            "candidates": {"sim": {"runs": {"path": "sim.parquet"}}},
            "features": ["x", "v"], "inputs": ["v"],
            "conditions": {"v": {"edges": [5, 10, 20]}}}


def _with_comparison(**comparison):
    return {**DOCUMENT, "comparison": comparison}


def test_every_method_field_is_a_key_or_excluded_with_a_reason():
    fields = {f.name for f in dataclasses.fields(Method)}
    keys = set(ComparisonSpec.model_fields)
    assert keys | set(NOT_IN_FILE) == fields and not keys & set(NOT_IN_FILE)
    assert all(reason.strip() for reason in NOT_IN_FILE.values())
    assert set(VALUES) == keys  # a new key of the section needs a value here
    assert set(FILE_FIELDS) <= keys


def test_recorded_options_are_the_file_keys_and_what_it_sets():
    """verdict.json's provenance.options.comparison: the file's own keys always, a key with
    Method's default only where the file sets it otherwise (earlier verdicts keep their bytes)."""
    assert list(ComparisonSpec().model_dump()) == list(FILE_FIELDS)
    assert list(ComparisonSpec(time_bins=4).model_dump()) == [*FILE_FIELDS, "time_bins"]


@pytest.mark.parametrize("key", sorted(VALUES))
def test_every_key_reaches_the_method(key):
    spec = parse_validation(_with_comparison(**{key: VALUES[key]}), source="v.yaml")
    method, expected = spec.method, VALUES[key]
    assert getattr(method, key) == (tuple(expected) if isinstance(expected, list) else expected)
    assert spec.model_dump(mode="json")["comparison"][key] == expected  # the verdict records it
    assert method.test.value == "response" and method.inputs == ("v",)


def test_defaults_are_the_files():
    method = parse_validation(_with_comparison(), source="v.yaml").method
    assert (method.bins, method.alpha, method.permutations, method.bootstrap, method.seed,
            method.history, method.time_bins, method.resample) == (3, 0.05, 199, 500, 0, 1,
                                                                   None, None)


@pytest.mark.parametrize("key", sorted(NOT_IN_FILE))
def test_excluded_field_is_one_line_with_its_reason(key):
    with pytest.raises(ValidationFileError) as info:
        parse_validation(_with_comparison(**{key: 1}), source="v.yaml")
    assert str(info.value) == (f"v.yaml: comparison.{key}: not an option of the validation "
                               f"file: {NOT_IN_FILE[key]}")


@pytest.mark.parametrize(("key", "value", "needle"), [
    ("time_bins", 1, "time-bins must be an integer >= 2"),
    ("history", "two", "history must be an integer >= 1"),
    ("permutations", 5, "Input should be greater than or equal to 19"),
    ("nope", 1, "unknown key"),
])
def test_bad_comparison_value_is_one_line_naming_the_key(key, value, needle):
    with pytest.raises(ValidationFileError) as info:
        parse_validation(_with_comparison(**{key: value}), source="v.yaml")
    message = str(info.value)
    assert "\n" not in message and message.startswith(f"v.yaml: comparison.{key}: ")
    assert needle in message


def test_docs_name_every_key_and_every_exclusion():
    text = (Path(__file__).parents[2] / "docs" / "validate.md").read_text()
    for key in (*ComparisonSpec.model_fields, *NOT_IN_FILE):
        assert f"`{key}`" in text, key
