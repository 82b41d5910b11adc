"""Outputs that never destroy inputs: atomic directories and files, resumable partial results.

Every command writes into a *partial* sibling of its output (``OUT.partial``) and renames it into
place only when everything was written, so an output that exists is complete. ``--out`` may never
be, contain or lie inside an input. An existing non-empty output is replaced only when the caller
says so (``--overwrite``), never merged. A command that can resume keeps the partial directory when
it is interrupted; :class:`Checkpoint` stores finished pieces there atomically.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path

from simcred.errors import OptionError

PARTIAL_SUFFIX = ".partial"
CHECKPOINTS = "checkpoints"


def partial_path(out: Path) -> Path:
    """Where the output is assembled before it is renamed into place."""
    return out.with_name(out.name + PARTIAL_SUFFIX)


def check_out(out: Path, inputs: Sequence[Path] = (), *, overwrite: bool = False,
              kind: str = "directory") -> None:
    """Refuse an output that is, contains or lies inside an input, or that would be clobbered.

    Raises :class:`~simcred.errors.OptionError` naming the path and the way out.
    """
    target = Path(os.path.abspath(out))
    for item in inputs:
        source = Path(os.path.abspath(item))
        if target == source or source.is_relative_to(target) or target.is_relative_to(source):
            raise OptionError(f"--out {out} would overwrite the input {item}: choose another "
                              "output path")
    if target.exists() or target.is_symlink():
        if kind == "directory" and not target.is_dir():
            raise OptionError(f"--out {out} exists and is not a directory")
        if kind == "file" and target.is_dir():
            raise OptionError(f"--out {out} is a directory, expected a file")
        if not overwrite and (target.is_file() or any(target.iterdir())):
            raise OptionError(f"--out {out} exists and is not empty: choose another path or "
                              "pass --overwrite to replace it")
    for parent in target.parents:
        if parent.exists():
            if not parent.is_dir():
                raise OptionError(f"--out {out}: {parent} is not a directory")
            break


@contextmanager
def output_dir(out: Path, inputs: Sequence[Path] = (), *, overwrite: bool = False,
               resume: bool = False, keep_partial: bool = False) -> Iterator[Path]:
    """Yield the partial directory to write into; on success it becomes ``out`` atomically.

    Parameters
    ----------
    out : Path
        The output directory.
    inputs : sequence of Path, default: ()
        Files and directories the command reads; ``out`` may not be, contain or be inside one.
    overwrite : bool, default: False
        Replace an existing non-empty ``out`` (never merge into it).
    resume : bool, default: False
        Continue in the partial directory a previous, interrupted run left behind.
    keep_partial : bool, default: False
        Keep the partial directory when the body fails or is interrupted (commands that can
        resume); otherwise it is removed, so nothing half-written remains.
    """
    check_out(out, inputs, overwrite=overwrite)
    partial = partial_path(out)
    if partial.exists() and not resume:
        if not overwrite:
            raise OptionError(f"{partial} holds the output of an interrupted run: continue it "
                              "with --resume or start over with --overwrite")
        shutil.rmtree(partial)
    partial.mkdir(parents=True, exist_ok=True)
    try:
        yield partial
    except BaseException:
        if not keep_partial:
            shutil.rmtree(partial, ignore_errors=True)
        raise
    shutil.rmtree(partial / CHECKPOINTS, ignore_errors=True)
    _replace_dir(partial, out)


def _replace_dir(partial: Path, out: Path) -> None:
    if out.exists():
        trash = Path(tempfile.mkdtemp(prefix=f".{out.name}.old-", dir=out.parent))
        os.replace(out, trash / out.name)
        os.replace(partial, out)
        shutil.rmtree(trash, ignore_errors=True)
    else:
        os.replace(partial, out)


def write_atomic(path: Path, data: bytes | str) -> Path:
    """Write a file so that it exists either complete or not at all (temp file + rename)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    payload = data.encode("utf-8") if isinstance(data, str) else data
    handle, temp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(handle, "wb") as stream:
            stream.write(payload)
        os.replace(temp, path)
    except BaseException:
        Path(temp).unlink(missing_ok=True)
        raise
    return path


class Checkpoint:
    """Finished pieces of a long job, stored in its partial directory, one file per key.

    A piece is written atomically, so after an interruption every stored piece is complete and a
    resumed job recomputes only what is missing.
    """

    def __init__(self, directory: Path) -> None:
        self.directory = directory / CHECKPOINTS
        self.directory.mkdir(parents=True, exist_ok=True)

    def _file(self, key: str) -> Path:
        if not key or "/" in key or key.startswith("."):
            raise ValueError(f"checkpoint key must be a plain file name, got {key!r}")
        return self.directory / key

    def __contains__(self, key: str) -> bool:
        return self._file(key).is_file()

    def save(self, key: str, data: bytes) -> None:
        write_atomic(self._file(key), data)

    def load(self, key: str) -> bytes:
        return self._file(key).read_bytes()

    def keys(self) -> list[str]:
        return sorted(p.name for p in self.directory.iterdir() if not p.name.startswith("."))
