"""The simulator registry: the one place ``simcred simulate`` and ``validate`` run simulators
from (issue 27); the command line and the registry agree, and a library run writes what the
command writes."""

from __future__ import annotations

import pytest
import typer

from simcred.cli import run
from simcred.cli._app import app
from simcred.errors import OptionError
from simcred.sim import registry
from simcred.sim.registry import SIMULATORS

#: Options of the commands that are the CLI's, not the simulator's.
CLI_ONLY = {"out", "overwrite", "resume"}


def _command(name: str):
    return typer.main.get_command(app).commands["simulate"].commands[name]


def test_every_simulate_command_is_a_simulator():
    assert set(typer.main.get_command(app).commands["simulate"].commands) == set(SIMULATORS)


@pytest.mark.parametrize("name", sorted(SIMULATORS))
def test_the_command_offers_the_simulators_parameters(name):
    """Same names, options and defaults: validate reads a command line as the CLI does."""
    simulator = SIMULATORS[name]
    params = {p.name: p for p in _command(name).params if p.name not in CLI_ONLY}
    assert set(params) == {p.name for p in simulator.all_params}
    for param in simulator.all_params:
        cli = params[param.name]
        assert (cli.param_type_name == "argument") == param.positional, param.name
        if not param.positional:
            assert param.option in cli.opts, (param.option, cli.opts)
            assert cli.default == param.default, param.name


@pytest.mark.parametrize(("args", "needle"), [
    (["--runs"], "--runs needs a value"),
    (["--runs", "two"], "--runs: cannot read 'two' as int"),
    (["--nope", "1"], "no option --nope"),
    (["extra"], "unexpected argument 'extra'"),
])
def test_a_command_line_it_cannot_read_is_one_line(args, needle):
    with pytest.raises(OptionError, match=needle):
        SIMULATORS["simplecar"].parse(args)


def test_unknown_simulator_and_missing_argument(tmp_path):
    with pytest.raises(OptionError, match="no simulator 'nope'"):
        registry.run(["simulate", "nope"], tmp_path / "x")
    with pytest.raises(OptionError, match="missing argument TRACES"):
        SIMULATORS["sumo-following"].parse(["--models", "IDM"])
    with pytest.raises(OptionError, match="--lambda must be"):  # the checks: before writing
        registry.run(["simulate", "simplecar", "--lambda", "0"], tmp_path / "y")
    assert not (tmp_path / "y").exists()


def test_a_library_run_writes_what_the_command_writes(tmp_path):
    args = ["simulate", "simplecar", "--runs", "3", "--duration", "6", "--dt", "2", "--seed",
            "4", "--chunk-size", "2"]
    assert run(["-q", *args, "--out", str(tmp_path / "cli")]) == 0
    summary = registry.run(args, tmp_path / "lib")
    assert summary.startswith("3 runs, 12 rows")
    files = sorted(p.relative_to(tmp_path / "cli") for p in (tmp_path / "cli").rglob("*"))
    assert files == sorted(p.relative_to(tmp_path / "lib") for p in (tmp_path / "lib").rglob("*"))
    for name in files:
        if (tmp_path / "cli" / name).is_file():
            assert (tmp_path / "cli" / name).read_bytes() == (tmp_path / "lib" / name).read_bytes()
