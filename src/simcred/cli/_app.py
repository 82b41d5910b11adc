"""The typer app, its consoles and what every command group shares (options, errors, progress).

Exit codes: 0 done, 1 negative verdict, 2 bad input or usage (one red line, no traceback),
3 undecided.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Callable, Iterable, Iterator, Sequence
from functools import wraps
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.markup import escape
from rich.progress import track
from rich.table import Table
from rich.text import Text

from simcred._version import __version__
from simcred.engine import Progress
from simcred.errors import SimcredError

app = typer.Typer(
    name="simcred",
    help="Can I trust this simulation for this test case?",
    pretty_exceptions_show_locals=False,
    add_completion=False,
)
# soft_wrap: a line longer than the terminal (a file path in "wrote ...") is never broken
# into two, so it can be copied; tables still fit the width.
out_console = Console(soft_wrap=True)
err_console = Console(stderr=True, soft_wrap=True)
EXIT_BAD_INPUT = 2


class State:
    quiet = False
    debug = False
    nested = False  # a command run inside another: Ctrl-C goes to the outer one, which reports


def _print_version(value: bool) -> None:
    if value:
        out_console.print(f"simcred {__version__}", markup=False, highlight=False)
        raise typer.Exit(0)


@app.callback()
def main(
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress or tables.")] = False,
    debug: Annotated[bool, typer.Option("--debug", help="Tracebacks for input errors.")] = False,
    version: Annotated[bool, typer.Option("--version", help="Print the version and exit.",
                                          is_eager=True, callback=_print_version)] = False,
) -> None:
    """simcred: validity of simulation models for testing automated driving."""
    State.quiet, State.debug = quiet, debug


def plain_help(root: typer.Typer) -> None:
    """Help texts are plain text, not rich markup: ``[m]`` or ``rGT[sb]`` must not vanish.

    Applied to the app and every command group registered on it (cli/__init__ calls it after
    importing all groups).
    """
    root.rich_markup_mode = None
    for group in root.registered_groups:
        if group.typer_instance is not None:
            plain_help(group.typer_instance)


def say(text: str) -> None:
    """One line of plain text on stdout (paths and names may hold brackets: not markup)."""
    out_console.print(text, markup=False, highlight=False, soft_wrap=True)


def plain_table(title: str, columns: Sequence[str], rows: Iterable[Sequence[str | Text]]
                ) -> Table:
    """A rich table whose cells are text, not markup (``rGT[sb]`` stays ``rGT[sb]``);
    pass a :class:`rich.text.Text` for a styled cell."""
    table = Table(title=Text(title))
    for column in columns:
        table.add_column(Text(column), overflow="fold")
    for row in rows:
        table.add_row(*(cell if isinstance(cell, Text) else Text(cell) for cell in row))
    return table


def error_line(message: str) -> None:
    """One red ``error:`` line on stderr; the message is escaped (brackets are text)."""
    err_console.print(f"[red]error:[/red] {escape(message)}", highlight=False, soft_wrap=True)


EXIT_INTERRUPTED = 130  # 128 + SIGINT, as shells report it


def one_line_errors(command: Callable) -> Callable:
    """Turn a SimcredError into one red line on stderr and exit code 2, and Ctrl-C into one
    line saying what was kept and exit code 130."""

    @wraps(command)
    def wrapper(*args, **kwargs):
        try:
            return command(*args, **kwargs)
        except SimcredError as exc:
            if State.debug:
                raise
            error_line(str(exc))
            raise typer.Exit(EXIT_BAD_INPUT) from None
        except KeyboardInterrupt as exc:
            from simcred.cli._writing import Interrupted

            if State.nested:
                raise
            error_line(str(exc) if isinstance(exc, Interrupted)
                       else "interrupted (Ctrl-C); no output was completed")
            raise typer.Exit(EXIT_INTERRUPTED) from None

    return wrapper


def progress(description: str) -> Progress | None:
    """Progress on stderr without --quiet: a rich bar on a terminal, else a plain log of one
    line per step (``description: 3/40``; at most about 100 lines), never on stdout."""
    if State.quiet:
        return None
    if not sys.stderr.isatty():
        return lambda items, total: _logged(items, total, description)
    return lambda items, total: track(items, total=total, description=escape(description),
                                      console=err_console, transient=True)


def _logged(items: Iterable, total: int, description: str) -> Iterator:
    every = max(1, total // 100)
    for done, item in enumerate(items, 1):
        yield item
        if done % every == 0 or done == total:
            _log(f"{description}: {done}/{total}")


def _log(line: str) -> None:
    """One plain line on stderr, flushed (a log file or pipe sees it at once)."""
    sys.stderr.write(line + "\n")
    sys.stderr.flush()



Seed = Annotated[int | None, typer.Option(min=0, help="Seed (default: fresh entropy, stored in the "
                                               "result).")]
Workers = Annotated[int | None, typer.Option(help="Run on a local Dask cluster of N worker "
                                                   "processes (default: in-process).")]
Scheduler = Annotated[str | None, typer.Option(help="Run on the Dask scheduler at this address "
                                                    "(e.g. tcp://host:8786).")]
Json = Annotated[bool, typer.Option("--json", help="Print the result JSON to stdout.")]


def _steps(description: str) -> Callable[[str], None] | None:
    """Prints each pipeline step on stderr without --quiet (dim on a terminal, else plain)."""
    if State.quiet:
        return None
    if not sys.stderr.isatty():
        return lambda step: _log(f"{description}: {step}")
    return lambda step: err_console.print(f"[dim]{escape(f'{description}: {step}')}[/dim]")



def _emit(document: dict, as_json: bool, summary: str) -> None:
    if as_json:
        sys.stdout.write(json.dumps(document, indent=1, ensure_ascii=False) + "\n")
    elif not State.quiet:
        out_console.print(summary, highlight=False)




ResimVehicle = Annotated[str, typer.Option(help="EGO vehicle model of the resimulation: ks or st.")]


def check_output(out: Path, *inputs: Path, kind: str = "directory",
                 overwrite: bool = False) -> Path:
    """Refuse an ``--out`` that is, contains or lies inside an input, has the wrong kind, or
    exists non-empty without ``overwrite`` (for a command that writes one file atomically
    itself; the others use :func:`writing`)."""
    from simcred.outputs import check_out

    check_out(out, inputs, overwrite=overwrite, kind=kind)
    return out
