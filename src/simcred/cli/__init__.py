"""The ``simcred`` command line: thin commands that parse, call one library function, render.

Exit codes: 0 done, 1 negative verdict, 2 bad input or usage (one red line, no traceback),
3 undecided, 70 a defect of simcred, 74 an environment fault (disk, permission, memory), 130
Ctrl-C. One module per command group; each registers its commands on the shared app.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence

import typer

from simcred.cli import (  # noqa: F401  (importing registers the commands)
    compare,
    contracts,
    convert,
    data,
    paper,
    reprocess,
    simulate,
    study,
    validate,
)
from simcred.cli._app import (
    EXIT_BAD_INPUT,
    EXIT_INTERRUPTED,
    State,
    app,
    error_line,
    plain_help,
)
from simcred.cli._environment import (
    EXIT_ENVIRONMENT,
    check_arguments,
    environment_fault,
    undecodable_name,
)
from simcred.cli._writing import Interrupted
from simcred.errors import SimcredError

plain_help(app)  # after every command group is registered

__all__ = ["app", "entry", "run"]


EXIT_INTERNAL = 70  # EX_SOFTWARE: a defect of simcred, not of the input


def run(argv: Sequence[str] | None = None, *, propagate_interrupt: bool = False) -> int:
    """Run the CLI and return its exit code; every failure is one line on stderr.

    Bad input and usage: exit 2. The environment refused (disk full, read-only, permission,
    name too long, out of memory): exit 74 with one line naming the path. Ctrl-C: exit 130
    (a command that can resume keeps ``OUT.partial`` and says so), or, with
    ``propagate_interrupt`` (a command run inside another), the interruption or environment
    fault is raised to the caller, which reports it once. A defect of
    simcred itself: exit 70 with one line, the traceback only under ``--debug``.
    """
    args = list(sys.argv[1:] if argv is None else argv) or ["--help"]
    nested, State.nested = State.nested, propagate_interrupt
    try:
        check_arguments(args)
        code = app(args=args, prog_name="simcred", standalone_mode=False)
    except typer.TyperException as exc:
        error_line(exc.format_message())
        return exc.exit_code
    except (typer.Abort, KeyboardInterrupt) as exc:
        if propagate_interrupt:
            raise KeyboardInterrupt from exc
        error_line(_interruption(exc))
        return EXIT_INTERRUPTED
    except SimcredError as exc:  # raised outside a command body, e.g. in an option callback
        error_line(str(exc))
        return EXIT_BAD_INPUT
    except (OSError, MemoryError) as exc:  # the system refused: not a defect of simcred
        if State.debug or "--debug" in args or propagate_interrupt:
            raise  # a nested command leaves it to the outer one, which reports it once
        error_line(environment_fault(exc))
        return EXIT_ENVIRONMENT
    except Exception as exc:
        if State.debug or "--debug" in args:
            raise
        if undecodable_name(exc):
            error_line(undecodable_name(exc))
            return EXIT_BAD_INPUT
        error_line(f"internal error ({type(exc).__name__}: {' '.join(str(exc).split())[:300]}); "
                   "please report it; --debug shows the traceback")
        return EXIT_INTERNAL
    finally:
        State.nested = nested
    if propagate_interrupt and code == EXIT_INTERRUPTED:  # typer turns Ctrl-C into Exit(130)
        raise KeyboardInterrupt
    return code if isinstance(code, int) else 0


def _interruption(exc: BaseException) -> str:
    """What an interrupted command kept (click wraps Ctrl-C in an Abort)."""
    for cause in (exc, exc.__cause__, exc.__context__):
        if isinstance(cause, Interrupted):
            return str(cause)
    return "interrupted (Ctrl-C); no output was completed"


def entry() -> None:
    """Console-script entry point."""
    sys.exit(run())


if __name__ == "__main__":  # pragma: no cover
    entry()
