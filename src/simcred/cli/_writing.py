"""How a command writes its ``--out``: atomically, never over an input, replaced only with
``--overwrite``, resumable with ``--resume`` (docs/reliability.md)."""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import typer

from simcred.cli._app import State, _log
from simcred.engine import Engine
from simcred.errors import SimcredError
from simcred.outputs import real

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
    except (OSError, MemoryError) as exc:  # reported by the CLI (exit 74) with this note
        if holder and holder[0].kept():
            exc.add_note(f"{_chunks(holder[0].kept())} kept in {partial}: --resume continues "
                         "once the cause is fixed")
        raise
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
    each input (names, sizes and modification times of its files). Paths are resolved, so the
    same files typed relative or absolute, or through a link, name the same job."""
    try:  # typer vendors click: its context stack is its own
        from typer._click.globals import get_current_context
    except ImportError:  # pragma: no cover (a typer that uses click itself)
        from click import get_current_context

    context = get_current_context(silent=True)
    ignored = {"out", "resume", "overwrite", "workers", "scheduler", "as_json"}
    params = {} if context is None else {k: _resolved(v) for k, v in context.params.items()
                                         if k not in ignored}
    return json.dumps({"command": None if context is None else context.command_path,
                       "options": params, "inputs": [_fingerprint(p) for p in inputs]},
                      sort_keys=True, default=str, ensure_ascii=False)


def _resolved(value: object) -> object:
    if isinstance(value, Path):
        return str(real(value))
    if isinstance(value, list | tuple):
        return [_resolved(v) for v in value]
    return value


def _fingerprint(path: Path) -> list:
    root = real(path)
    files = sorted(p for p in root.rglob("*") if p.is_file()) if root.is_dir() else [root]
    found = []
    for file in files:
        stat = file.stat() if file.exists() else None
        found.append([str(file), None if stat is None else [stat.st_size, stat.st_mtime_ns]])
    return found
