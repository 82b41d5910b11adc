"""The ``simcred`` command line: thin commands that parse, call one library function, render.

Exit codes: 0 done, 1 negative verdict, 2 bad input or usage (one red line, no traceback),
3 undecided. One module per command group; each registers its commands on the shared app.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

import typer

from simcred.cli import compare, contracts, convert, paper, reprocess, simulate  # noqa: F401
from simcred.cli._app import app, error_line, plain_help

plain_help(app)  # after every command group is registered

__all__ = ["app", "entry", "run"]


def run(argv: Sequence[str] | None = None) -> int:
    """Run the CLI and return its exit code; usage errors, too, are one line on stderr."""
    args = list(sys.argv[1:] if argv is None else argv) or ["--help"]
    try:
        code = app(args=args, prog_name="simcred", standalone_mode=False)
    except typer.TyperException as exc:
        error_line(exc.format_message())
        return exc.exit_code
    except typer.Abort:
        error_line("aborted")
        return 1
    return code if isinstance(code, int) else 0


def entry() -> None:
    """Console-script entry point."""
    sys.exit(run())


if __name__ == "__main__":  # pragma: no cover
    entry()
