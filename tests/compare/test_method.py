"""One comparison method object (issue 27, item 1): ``compare``, ``matrix``, the CLI, ``validate``
and ``study`` share :class:`simcred.compare.Method`; an option is declared once, as its field."""

from __future__ import annotations

import dataclasses
import inspect

import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from simcred.cli import app, run
from simcred.cli._method import build_method, fields_of, method_options, parameters
from simcred.compare import Method, compare, matrix
from simcred.compare.method import option
from simcred.compare.process import comparison_options
from simcred.errors import OptionError
from simcred.examples import lane_change_sets


@pytest.fixture(scope="module")
def sets():
    return lane_change_sets(runs=40, steps=30, seed=2)


@pytest.mark.parametrize("options", [
    dict(features=["y"], bins=4, test="bound", seed=0),
    dict(features="x,y", bins=[3, 4], test="permutation", permutations=49, seed=1),
    dict(features=["y"], bins=4, permutations=49, seed=2, baseline=2, chain="max"),
    dict(features=["x", "y"], bins=3, test="response", permutations=19, bootstrap=100, seed=3,
         inputs=["x"], margin={"y": 0.5}),
])
def test_a_method_gives_the_result_of_its_keywords(sets, options):
    by_keywords = compare(*sets, **options).to_json()
    assert compare(*sets, Method(**options)).to_json() == by_keywords
    assert compare(*sets, method=Method(**options)).to_json() == by_keywords


def test_keywords_replace_fields_of_a_method(sets):
    method = Method(features=["y"], bins=4, test="bound", alpha=0.05)
    result = compare(*sets, method, bins=5)
    assert result.options.bins == (5,) and result.options.alpha == 0.05
    assert method.bins == 4  # frozen: the caller's method is unchanged
    with pytest.raises(dataclasses.FrozenInstanceError):
        method.bins = 3


def test_matrix_takes_the_method(sets):
    a, b = sets
    method = Method(features=["y"], bins=4, permutations=19, seed=0)
    assert matrix([a, b], method).to_json() == matrix([a, b], features=["y"], bins=4,
                                                      permutations=19, seed=0).to_json()


@pytest.mark.parametrize(("options", "message"), [
    (dict(alpha=1.5), "alpha must be a number in"),
    (dict(kernel="cubic"), "kernel must be one of"),
    (dict(test="bound", multiplicity="fwer"), "multiplicity fwer needs the run-level test"),
    (dict(inputs=["x"]), "belong to the response test"),
    (dict(test="response", baseline=3), "no random-halves baseline"),
    (dict(features=["x", "x"]), "features repeat a name"),
    (dict(history=0), "history must be an integer"),
    (dict(seed=-1), "seed must be a non-negative integer"),
    (dict(pair_by=" ", test="response"), "pair-by must be"),
])
def test_checked_once_on_construction_with_the_messages_of_compare(sets, options, message):
    with pytest.raises(OptionError, match=message):
        Method(**options)
    with pytest.raises(OptionError, match=message):
        compare(*sets, **options)


def test_checks_that_need_the_data_stay_with_the_data(sets):
    method = Method(features=["nope"])  # no data: nothing to say yet
    with pytest.raises(Exception, match="nope"):
        comparison_options(sets, method)
    with pytest.raises(OptionError, match="method must be a simcred.compare.Method"):
        compare(*sets, {"bins": 3})


def test_every_field_is_an_option_of_the_commands_that_offer_it():
    for command in ("compare", "matrix"):
        text = CliRunner().invoke(app, [command, "--help"], env={"COLUMNS": "200"}).output
        for field in fields_of(command):
            flag = (field.metadata["flags"] or (f"--{field.name.replace('_', '-')}",))[0]
            assert flag.split("/")[0] in text, (command, field.name)


@dataclasses.dataclass(frozen=True)
class Wider(Method):
    window: int = option(3, help="Samples per smoothing window.")


def _probe(command: str) -> tuple[typer.Typer, dict]:
    """A one-command app whose command takes the option group of ``command`` over Wider."""
    seen: dict = {}
    probe = typer.Typer()

    @probe.command()
    @method_options(command, Wider)
    def probe_command(method: dict | None = None) -> None:
        seen.update(method)

    @probe.command()
    def other() -> None: ...

    return probe, seen


@pytest.mark.parametrize("command", ["compare", "matrix"])
def test_a_new_field_becomes_an_option_of_both_commands(command):
    """Single source: a field added to the method (here on a subclass) is offered by compare and
    matrix with its help, and reaches the command, without a line of CLI code."""
    names = [p.name for p in parameters(command, Wider)]
    assert names[-1] == "window" and "features" in names
    probe, seen = _probe(command)
    help_text = CliRunner().invoke(probe, ["probe-command", "--help"],
                                   env={"COLUMNS": "200"}).output
    assert "--window" in help_text and "Samples per smoothing window." in help_text
    assert CliRunner().invoke(probe, ["probe-command", "--window", "5"]).exit_code == 0
    assert seen["window"] == 5


def test_the_command_line_builds_the_method_of_the_library(sets, tmp_path, capsys):
    a, b = sets
    pa, pb = a.write(tmp_path / "a"), b.write(tmp_path / "b")
    assert run(["compare", str(pa), str(pb), "-f", "y", "--bins", "4", "--permutations", "19",
                "--seed", "4", "--baseline", "0", "--json"]) == 0
    cli = capsys.readouterr().out
    method = build_method(dict(features="y", bins="4", permutations=19, seed=4, baseline=0))
    assert cli == compare(pa, pb, method).to_json()
    signature = inspect.signature(app.registered_commands[0].callback)
    assert "method" not in signature.parameters


def test_validate_and_study_share_the_method(tmp_path):
    from simcred.study.car_following import StudyOptions
    from simcred.validate.spec import parse_validation

    spec = parse_validation({
        "test_case": {"conditions": "1 <= c <= 2", "tolerance": {"v": 0.1}},
        "reference": {"path": "r.parquet"}, "candidates": {"m": {"runs": {"path": "m.parquet"}}},
        "features": ["v", "c"], "inputs": ["c"], "conditions": {"c": {"edges": [1, 2]}},
        "comparison": {"bins": 4, "seed": 7}})
    assert spec.method == Method(test="response", features=("v", "c"), inputs=("c",), bins=4,
                                 alpha=0.05, permutations=199, bootstrap=500, seed=7)
    study = StudyOptions(seed=3).method
    assert study.test == "response" and study.seed == 3 and study.resample == 0.5
    assert np.isclose(study.alpha, 0.05)


def test_the_validation_file_speaks_the_method_s_vocabulary():
    from simcred.validate.spec import ComparisonSpec

    assert set(ComparisonSpec.model_fields) <= {f.name for f in dataclasses.fields(Method)}
