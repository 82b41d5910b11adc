"""The typer app, its consoles and what every command group shares (options, errors, progress).

Exit codes: 0 done, 1 negative verdict, 2 bad input or usage (one red line, no traceback),
3 undecided.
"""

from __future__ import annotations

import json
import sys
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
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
from simcred.engine import Engine, Progress
from simcred.errors import SimcredError

app = typer.Typer(
    name="simcred",
    help="Can I trust this simulation for this test case?",
    pretty_exceptions_show_locals=False,
    add_completion=False,
)
out_console = Console()
err_console = Console(stderr=True)
EXIT_BAD_INPUT = 2


class State:
    quiet = False
    debug = False


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



Seed = Annotated[int | None, typer.Option(help="Seed (default: fresh entropy, stored in the "
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


Overwrite = Annotated[bool, typer.Option(
    "--overwrite", help="Replace an existing non-empty --out (the old content is removed, never "
                        "merged; an input is never replaced).")]
Resume = Annotated[bool, typer.Option(
    "--resume", help="Continue an interrupted run: reuse the finished chunks kept in "
                     "OUT.partial (same command, options and inputs).")]
#: A trace-set output whose name ends so is one file (Parquet, long CSV, OSI); else a folder
#: of CSV files, one per run.
TRACE_FILE_SUFFIXES = (".parquet", ".pq", ".csv", ".osi", ".mcap")


def trace_set_kind(out: Path) -> str:
    """``"file"`` for a trace-set output named ``*.parquet|.pq|.csv|.osi|.mcap``, else
    ``"directory"`` (docs/reliability.md: what --out is)."""
    return "file" if out.suffix.lower() in TRACE_FILE_SUFFIXES else "directory"


VALUE_PREFIX = "value-"


class Interrupted(KeyboardInterrupt):
    """Ctrl-C during a command that writes: the message says what was kept."""


@dataclass
class Output:
    """Where a command writes: ``path`` (inside ``partial``) becomes ``out`` when it completes.

    ``checkpoint`` holds the finished chunks of a resumable command (None otherwise).
    """

    out: Path
    path: Path
    partial: Path
    checkpoint: object | None = None
    runner: object | None = None

    @contextmanager
    def engine(self, workers: int | None = None, scheduler: str | None = None
               ) -> Iterator[Engine]:
        """:func:`simcred.engine.engine`, whose finished tasks are checkpointed when the
        command can resume."""
        from simcred.engine import Checkpointed, engine

        with engine(workers, scheduler) as runner:
            if self.checkpoint is not None:
                runner = self.runner = Checkpointed(runner, self.checkpoint)
            yield runner

    def kept(self) -> int:
        """Finished chunks in the checkpoint."""
        if self.checkpoint is None:
            return 0
        return sum(not key.startswith(VALUE_PREFIX) for key in self.checkpoint)

    def value(self, key: str, make: Callable[[], int | str]) -> int | str:
        """``make()``, kept in the checkpoint so that a resumed run uses the same value (e.g. a
        seed drawn from fresh entropy)."""
        if self.checkpoint is None:
            return make()
        name = VALUE_PREFIX + key
        if name not in self.checkpoint:
            self.checkpoint.save(name, json.dumps(make()).encode())
        return json.loads(self.checkpoint.load(name))


@contextmanager
def writing(out: Path, *inputs: Path, kind: str = "directory", overwrite: bool = False,
            resume: bool | None = None) -> Iterator[Output]:
    """Write ``out`` atomically (``OUT.partial``, renamed at the end), then print the elapsed time.

    ``out`` may not be, contain or lie inside an input; an existing non-empty ``out`` is replaced
    only with ``overwrite``. ``resume`` is None for a command that cannot resume; otherwise its
    finished chunks are checkpointed in ``OUT.partial``, kept on Ctrl-C or failure, and reused
    with ``resume=True``. Ctrl-C raises :class:`Interrupted` saying what was kept.
    """
    from simcred.outputs import Checkpoint, output_path, partial_path

    started = time.monotonic()
    partial = partial_path(out)
    holder: list[Output] = []

    def keep(exc: BaseException) -> bool:
        return resume is not None and bool(holder) and holder[0].kept() > 0

    try:
        with output_path(out, inputs, kind=kind, overwrite=overwrite, resume=bool(resume),
                         keep_partial=keep) as path:
            checkpoint = None
            if resume is not None:
                checkpoint = Checkpoint(partial)
                checkpoint.claim(_job_manifest(inputs))
            holder.append(Output(out, path, partial, checkpoint))
            yield holder[0]
    except KeyboardInterrupt:
        raise Interrupted(_interrupted(out, holder[0] if holder else None)) from None
    except SimcredError as exc:
        if holder and holder[0].kept():
            raise SimcredError(f"{exc} ({_chunks(holder[0].kept())} kept in {partial}: "
                               "--resume continues)") from None
        raise
    if not State.quiet:
        _log(f"done in {_duration(time.monotonic() - started)}")


def _interrupted(out: Path, output: Output | None) -> str:
    kept = 0 if output is None else output.kept()
    if not kept:
        return f"interrupted (Ctrl-C): nothing kept, {out} unchanged"
    runner = output.runner
    step = "" if runner is None or not runner.total else \
        f" (current step {runner.done}/{runner.total})"
    return (f"interrupted (Ctrl-C): {_chunks(kept)} kept in {output.partial}{step}; "
            "rerun the same command with --resume to continue")


def _chunks(count: int) -> str:
    return f"{count} finished chunk{'' if count == 1 else 's'}"


def _duration(seconds: float) -> str:
    minutes, rest = divmod(seconds, 60)
    return f"{rest:.1f} s" if minutes < 1 else f"{int(minutes)} min {rest:04.1f} s"


def _job_manifest(inputs: Sequence[Path]) -> str:
    """The command, its options (but not where or how verbosely it runs) and a fingerprint of
    each input (names, sizes and modification times of its files)."""
    try:  # typer vendors click: its context stack is its own
        from typer._click.globals import get_current_context
    except ImportError:  # pragma: no cover (a typer that uses click itself)
        from click import get_current_context

    context = get_current_context(silent=True)
    ignored = {"resume", "overwrite", "workers", "scheduler", "as_json"}
    params = {} if context is None else {k: v for k, v in context.params.items()
                                         if k not in ignored}
    return json.dumps({"command": None if context is None else context.command_path,
                       "options": params, "inputs": [_fingerprint(p) for p in inputs]},
                      sort_keys=True, default=str, ensure_ascii=False)


def _fingerprint(path: Path) -> list:
    files = sorted(p for p in path.rglob("*") if p.is_file()) if path.is_dir() else [path]
    found = []
    for file in files:
        stat = file.stat() if file.exists() else None
        found.append([str(file), None if stat is None else [stat.st_size, stat.st_mtime_ns]])
    return found


def check_output(out: Path, *inputs: Path, kind: str = "directory",
                 overwrite: bool = False) -> Path:
    """Refuse an ``--out`` that is, contains or lies inside an input, has the wrong kind, or
    exists non-empty without ``overwrite`` (for a command that writes one file atomically
    itself; the others use :func:`writing`)."""
    from simcred.outputs import check_out

    check_out(out, inputs, overwrite=overwrite, kind=kind)
    return out
