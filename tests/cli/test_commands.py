"""Every command of the typer app, found by walking it: --help, bad input, --json, brackets.

Generic over the app, so command groups added later are checked too: ``--help`` exits 0 and
shows every option's help text unchanged (rich markup must not eat ``[m]`` or ``rGT[sb]``); an
unknown option and a missing input file each give exit code 2 and one line on stderr, no
traceback (with ``--json`` too, and then nothing on stdout).
"""

from __future__ import annotations

import re

import pytest
import typer

from helpers import leaf_commands
from simcred import __version__
from simcred.cli import app, run

COMMANDS = leaf_commands(typer.main.get_command(app))
IDS = [" ".join(path) for path, _ in COMMANDS]


def _flat(text: str) -> str:
    """Whitespace collapsed, and words the terminal wrapped at a hyphen joined again."""
    return re.sub(r"(\w)- (\w)", r"\1-\2", re.sub(r"\s+", " ", text))


def _one_line(err: str) -> str:
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert "Traceback" not in err
    return lines[0]


def _is(param, kind: str) -> bool:
    return param.param_type_name == kind


def _bad_input_args(command, tmp_path) -> list[str] | None:
    """Arguments naming a missing input file (with brackets in its name), or None when the
    command takes no input argument."""
    missing = str(tmp_path / "no such [dir]" / "input")
    arguments = [p for p in command.params if _is(p, "argument")]
    if not arguments:
        return None
    args = [missing] * sum(max(1, p.nargs) for p in arguments)
    for param in command.params:
        if _is(param, "option") and param.required:
            args += [param.opts[0], str(tmp_path / "out")]
    return args


def test_the_app_has_commands():
    assert {"compare", "reprocess", "vary", "simulate cutin", "paper 002", "report"} <= set(IDS)


@pytest.mark.parametrize(("path", "command"), COMMANDS, ids=IDS)
def test_help_shows_every_help_text_unchanged(path, command, capsys):
    assert run([*path, "--help"]) == 0
    shown = _flat(capsys.readouterr().out)
    for param in command.params:
        text = getattr(param, "help", None)
        if text:
            assert _flat(text) in shown, f"{param.name}: {text!r} not in help"
    assert "\\[" not in shown  # help is plain text: a rich escape would show as a backslash


@pytest.mark.parametrize(("path", "command"), COMMANDS, ids=IDS)
def test_an_unknown_option_is_one_line_exit_2(path, command, capsys):
    assert run([*path, "--no-such-option"]) == 2
    captured = capsys.readouterr()
    assert "--no-such-option" in _one_line(captured.err)


@pytest.mark.parametrize(("path", "command"), COMMANDS, ids=IDS)
def test_a_missing_input_is_one_line_exit_2(path, command, tmp_path, capsys):
    args = _bad_input_args(command, tmp_path)
    if args is None:
        pytest.skip("no input argument")
    assert run(["--quiet", *path, *args]) == 2
    line = _one_line(capsys.readouterr().err)
    required = [p for p in command.params if _is(p, "option") and p.required]
    if all(p.bare_type() == "Path" for p in required):  # else a filler value may fail first
        assert "no such [dir]" in line  # the culprit is named, brackets and all


@pytest.mark.parametrize(("path", "command"),
                         [(p, c) for p, c in COMMANDS if any("--json" in getattr(o, "opts", ())
                                                             for o in c.params)],
                         ids=[i for i, (_, c) in zip(IDS, COMMANDS, strict=True)
                              if any("--json" in getattr(o, "opts", ()) for o in c.params)])
def test_json_commands_keep_stdout_clean_on_bad_input(path, command, tmp_path, capsys):
    args = _bad_input_args(command, tmp_path)
    if args is None:
        pytest.skip("no input argument")
    assert run([*path, *args, "--json"]) == 2
    captured = capsys.readouterr()
    _one_line(captured.err)
    assert captured.out == ""


def test_version(capsys):
    assert run(["--version"]) == 0
    assert capsys.readouterr().out.strip() == f"simcred {__version__}"


def test_error_messages_keep_brackets(capsys):
    from simcred.cli._app import one_line_errors
    from simcred.errors import OptionError

    @one_line_errors
    def failing():
        raise OptionError("threshold [m] of rGT[sb] must be positive")

    with pytest.raises(typer.Exit) as exit_info:
        failing()
    assert exit_info.value.exit_code == 2
    assert "threshold [m] of rGT[sb] must be positive" in capsys.readouterr().err


def test_tables_keep_brackets(capsys):
    from simcred.cli._app import out_console, plain_table

    out_console.print(plain_table("reactions [s]", ("trace", "time [s]"), [("rGT[sb]", "3.78")]))
    shown = capsys.readouterr().out
    assert "rGT[sb]" in shown and "time [s]" in shown and "reactions [s]" in shown


def test_reprocess_json_is_the_summary_file(tmp_path, capsys):
    from simcred.sim.experiments import cutin

    cutin.simulate(0).write(tmp_path / "m")
    assert run(["reprocess", str(tmp_path / "m"), "--out", str(tmp_path / "r"),
                "--no-scenario-based", "--json"]) == 0
    printed = capsys.readouterr().out
    assert printed == (tmp_path / "r" / "reprocess.json").read_text()
    assert '"kind": "reprocess"' in printed and '"inputs"' in printed
