"""Outputs that never destroy inputs: atomic directories and files, resumable partial results.

Every command writes into a *partial* sibling of its output (``OUT.partial``) and renames it into
place only when everything was written, so an output that exists is complete. ``--out`` may never
be, contain or lie inside an input, compared as resolved paths and by identity. An existing
non-empty output is replaced only when the caller says so (``--overwrite``), never merged, and only
if simcred wrote it (its :data:`MARKER` file); never the working or home directory or a folder
above them. A command that can resume keeps the partial directory when
it is interrupted; :class:`Checkpoint` stores finished pieces there atomically.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import tempfile
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager, suppress
from pathlib import Path

from simcred.errors import OptionError

PARTIAL_SUFFIX = ".partial"
CHECKPOINTS = "checkpoints"
MANIFEST = "job.json"
#: The file simcred puts in every directory it writes (an output, its partial directory):
#: ``--overwrite`` replaces a directory only if it holds this file, never one simcred did not make.
MARKER = ".simcred-output"
MARKER_TEXT = b"written by simcred; --overwrite may replace this folder\n"
#: Written into ``OUT.partial`` just before its file output is renamed to ``OUT``: the file's
#: identity, so that a later run recognises a partial output whose work is already at ``OUT``
#: (the job was killed between the rename and removing ``OUT.partial``) and removes it.
MOVED = ".simcred-moved"


def partial_path(out: Path) -> Path:
    """Where the output is assembled before it is renamed into place: beside the resolved
    ``out`` (so ``out`` typed relative, absolute or through a link has one partial output)."""
    target = real(out)
    if not target.name:
        raise OptionError(f"--out {out} is the root folder: choose a folder of its own")
    return target.with_name(target.name + PARTIAL_SUFFIX)


def real(path: Path) -> Path:
    """``path`` absolute, with every symbolic link and ``..`` resolved as the system would (a
    ``..`` after a link climbs from the link's target, not from the link)."""
    return Path(os.path.realpath(path))


def contains(outer: Path, inner: Path) -> bool:
    """Whether ``inner`` is ``outer`` or lies below it, compared as resolved paths and by the
    identity (device and inode) of ``outer`` and every existing folder above ``inner`` (a bind
    mount or a hard link is the same file under another name)."""
    outer, inner = real(outer), real(inner)
    if inner.is_relative_to(outer):
        return True
    try:
        identity = os.stat(outer)
    except OSError:  # does not exist: nothing lies below it
        return False
    for place in (inner, *inner.parents):
        try:
            if os.path.samestat(identity, os.stat(place)):
                return True
        except OSError:
            continue
    return False


def check_out(out: Path, inputs: Sequence[Path] = (), *, overwrite: bool = False,
              kind: str = "directory") -> None:
    """Refuse an output that is, contains or lies inside an input, or that would be clobbered.

    Paths are compared resolved (links, ``..``) and by identity (:func:`contains`). An existing
    output is never a symbolic link, the working or home directory or a folder above them, and
    ``overwrite`` replaces a directory only if simcred wrote it (:data:`MARKER`).

    Raises :class:`~simcred.errors.OptionError` naming the path and the way out.
    """
    if out.is_symlink():
        raise OptionError(f"--out {out} is a symbolic link (to {os.readlink(out)}): name the "
                          "real path, or another one")
    for item in inputs:
        if contains(out, item) or contains(item, out):
            raise OptionError(f"--out {out} would overwrite the input {item}: choose another "
                              "output path")
    target = real(out)
    if target.exists():
        _refuse_replacing_a_home(out)
        if kind == "directory" and not target.is_dir():
            raise OptionError(f"--out {out} exists and is not a directory")
        if kind == "file" and target.is_dir():
            raise OptionError(f"--out {out} is a directory, expected a file")
        if target.is_file() or any(target.iterdir()):
            if not overwrite:
                raise OptionError(f"--out {out} exists and is not empty: choose another path "
                                  "or pass --overwrite to replace it")
            if target.is_dir():
                _refuse_foreign(out, "--out")
    for parent in target.parents:
        if parent.exists():
            if not parent.is_dir():
                raise OptionError(f"--out {out}: {parent} is not a directory")
            break


def _refuse_replacing_a_home(out: Path) -> None:
    """An existing output is replaced whole: never the working directory, the home directory or
    a folder holding either."""
    places = [Path.cwd()]
    home = os.environ.get("HOME")
    if home:
        places.append(Path(home))
    for place in places:
        if contains(out, place):
            raise OptionError(f"--out {out} holds the working or home directory: --overwrite "
                              "would delete it; choose a folder of its own")


def _refuse_foreign(directory: Path, what: str) -> None:
    """One line unless ``directory`` holds simcred's :data:`MARKER` (a regular file)."""
    marker = directory / MARKER
    if marker.is_symlink() or not marker.is_file():
        raise OptionError(f"{what} {directory} was not written by simcred (no {MARKER} in it): "
                          "--overwrite replaces only simcred's outputs; move it away yourself "
                          "or choose another path")


def _make_partial(partial: Path) -> None:
    """Create ``partial`` holding its :data:`MARKER`, atomically: a kill at any moment leaves
    no partial output without its marker (which could then be neither resumed nor replaced)."""
    partial.parent.mkdir(parents=True, exist_ok=True)
    _drop_staging_debris(partial)
    staging = Path(tempfile.mkdtemp(prefix=f".{partial.name}-", dir=partial.parent))
    try:
        (staging / MARKER).write_bytes(MARKER_TEXT)
        os.rename(staging, partial)
    except BaseException:  # e.g. the disk is full: nothing is left behind
        shutil.rmtree(staging, ignore_errors=True)
        raise


def _drop_staging_debris(partial: Path) -> None:
    """Remove what an earlier :func:`_make_partial` killed before its rename left beside
    ``partial``: folders named like its staging folder that hold nothing but simcred's
    :data:`MARKER` (nothing else can be in them)."""
    for debris in partial.parent.glob(f".{partial.name}-*"):
        if debris.is_symlink() or not debris.is_dir():
            continue
        content = list(debris.iterdir())
        marker = debris / MARKER
        if content in ([], [marker]) and (not content or _is_marker(marker)):
            shutil.rmtree(debris, ignore_errors=True)


#: The name :func:`write_atomic` gives its temporary file (``tempfile.mkstemp``'s 8 characters).
_TEMPORARY = re.compile(r"\..+\.[a-z0-9_]{8}\.tmp")


def _drop_temporaries(partial: Path) -> None:
    """Remove the temporary files of :func:`write_atomic` calls that a kill interrupted in an
    inherited ``partial`` (a resumed run writes those files again; left, they would end up in
    the output)."""
    for path in partial.rglob(".*.tmp"):
        if _TEMPORARY.fullmatch(path.name) and path.is_file() and not path.is_symlink():
            path.unlink(missing_ok=True)


def _is_marker(path: Path) -> bool:
    """Whether ``path`` is a regular file holding :data:`MARKER_TEXT` or a prefix of it (a kill
    can land while it is written)."""
    return (not path.is_symlink() and path.is_file() and path.stat().st_size <= len(MARKER_TEXT)
            and MARKER_TEXT.startswith(path.read_bytes()))


@contextmanager
def output_path(out: Path, inputs: Sequence[Path] = (), *, kind: str = "directory",
                overwrite: bool = False, resume: bool = False,
                keep_partial: bool | Callable[[BaseException], bool] = False) -> Iterator[Path]:
    """Yield where to write ``out``; on success it appears at ``out`` atomically, complete.

    The output is assembled in the partial directory ``OUT.partial``: a directory output *is*
    that directory, a file output is ``OUT.partial/<name of OUT>`` (so its suffix, which may pick
    the format, is kept). On success the partial directory (or the file in it) is renamed to
    ``out``, replacing an existing ``out`` only with ``overwrite`` (never merging into it).

    Parameters
    ----------
    out : Path
        The output directory or file.
    inputs : sequence of Path, default: ()
        Files and directories the command reads; ``out`` may not be, contain or be inside one.
    kind : {"directory", "file"}, default: "directory"
        What ``out`` is; an existing path of the other kind is refused.
    overwrite : bool, default: False
        Replace an existing non-empty ``out`` (never merge into it).
    resume : bool, default: False
        Continue in the partial directory a previous, interrupted run left behind.
    keep_partial : bool or callable, default: False
        Keep the partial directory when the body fails or is interrupted (commands that can
        resume; a callable decides from the exception); otherwise it is removed, so nothing
        half-written remains.
    """
    (_drop_moved if kind == "file" else _recover_replaced)(out, inputs)
    check_out(out, inputs, overwrite=overwrite, kind=kind)
    partial, out = partial_path(out), real(out)
    if partial.is_symlink() or (partial.exists() and not partial.is_dir()):
        raise OptionError(f"{partial} is not a directory simcred made: remove it or choose "
                          "another --out")
    lock, inherited = None, partial.exists()
    if inherited:
        _refuse_foreign(partial, "the partial output")
        lock = _lock(partial)  # refuses a partial output another command is writing now
        _drop_temporaries(partial)
        if not resume:
            if not overwrite:
                _unlock(lock)
                raise OptionError(f"{partial} holds the output of an interrupted run: continue "
                                  "it with --resume or start over with --overwrite")
            lock = _unlock(lock)
            shutil.rmtree(partial)
            inherited = False
    if not inherited:
        _make_partial(partial)
    lock = lock if lock is not None else _lock(partial)
    try:
        yield partial if kind == "directory" else partial / out.name
    except BaseException as exc:
        if isinstance(exc, OSError) and exc.filename is None:  # pyarrow names no file
            exc.filename = str(out)
        # a resumed run never removes what an earlier run finished, even when it is refused
        keep = inherited or (keep_partial(exc) if callable(keep_partial) else keep_partial)
        if not keep:
            shutil.rmtree(partial, ignore_errors=True)
        raise
    else:
        if kind == "directory":
            shutil.rmtree(partial / CHECKPOINTS, ignore_errors=True)
            _replace_dir(partial, out)
        else:
            _move_file(partial, out)
    finally:
        _unlock(lock)


def _identity(path: Path) -> list[int]:
    stat = os.stat(path, follow_symlinks=False)
    return [stat.st_dev, stat.st_ino, stat.st_size, stat.st_mtime_ns]


def _move_file(partial: Path, out: Path) -> None:
    """Rename the finished ``partial/<name>`` to ``out`` and remove ``partial``, first recording
    the file's identity in ``partial`` (:data:`MOVED`): a kill between the rename and the removal
    leaves a partial output that :func:`_drop_moved` recognises as done."""
    with suppress(OSError):  # e.g. a full disk: moved all the same, unrecorded
        write_atomic(partial / MOVED, json.dumps(_identity(partial / out.name)))
    os.replace(partial / out.name, out)
    shutil.rmtree(partial, ignore_errors=True)


def _drop_moved(out: Path, inputs: Sequence[Path]) -> None:
    """Remove a stale ``OUT.partial`` whose file was already renamed to ``out``: only one that
    holds simcred's :data:`MARKER` and a :data:`MOVED` record naming the very file at ``out``
    (device, inode, size, modification time), no longer holds that file, is no input and is not
    being written by a running command."""
    try:
        partial, target = partial_path(out), real(out)
    except OptionError:
        return
    moved = partial / MOVED
    if (out.is_symlink() or partial.is_symlink() or not moved.is_file() or not target.is_file()
            or (partial / target.name).exists()
            or any(contains(partial, item) or contains(item, partial) for item in inputs)):
        return
    try:
        _refuse_foreign(partial, "the partial output")
        if json.loads(moved.read_text(encoding="utf-8")) != _identity(target):
            return
    except (OptionError, OSError, ValueError):
        return
    lock = _lock(partial)  # a command finishing it now holds it: one line, nothing removed
    try:
        shutil.rmtree(partial)
    finally:
        _unlock(lock)


def _lock(directory: Path) -> int | None:
    """An exclusive lock on ``directory`` for this process (released when it ends, even by
    SIGKILL); one line if another process holds it."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover (not POSIX: no locking)
        return None
    handle = os.open(directory, os.O_RDONLY)
    try:
        fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(handle)
        raise OptionError(f"{directory} is being written by another running command: wait for "
                          "it to finish, or choose another --out") from None
    return handle


def _unlock(handle: int | None) -> None:
    if handle is not None:
        os.close(handle)


@contextmanager
def output_dir(out: Path, inputs: Sequence[Path] = (), *, overwrite: bool = False,
               resume: bool = False, keep_partial: bool = False) -> Iterator[Path]:
    """Yield the partial directory to write into; on success it becomes ``out`` atomically
    (:func:`output_path` for a directory)."""
    with output_path(out, inputs, overwrite=overwrite, resume=resume,
                     keep_partial=keep_partial) as partial:
        yield partial


def replaced_path(out: Path) -> Path:
    """Where an existing directory output waits, hidden beside it, while its replacement is
    renamed into place (:func:`_replace_dir`)."""
    target = real(out)
    return target.with_name(f".{target.name}.simcred-replaced")


def _replace_dir(partial: Path, out: Path) -> None:
    """Rename ``partial`` to ``out``; an existing ``out`` is first moved to
    :func:`replaced_path`, removed afterwards. A kill between the steps leaves that folder,
    which the next run resolves (:func:`_recover_replaced`)."""
    if out.exists():
        old = replaced_path(out)
        os.replace(out, old)  # refused (one line) if something else is at that name
        os.replace(partial, out)
        shutil.rmtree(old, ignore_errors=True)
    else:
        os.replace(partial, out)


def _recover_replaced(out: Path, inputs: Sequence[Path]) -> None:
    """Finish a replacement of the directory ``out`` that a kill interrupted: with no ``out``
    (killed between the two renames) the previous output is put back, as it was; with ``out``
    in place (killed before the old one was removed) the old one is removed. Only a folder that
    is simcred's (its :data:`MARKER`, or empty), no input, and not while a running command
    holds ``OUT.partial``."""
    try:
        old, target, partial = replaced_path(out), real(out), partial_path(out)
    except OptionError:
        return
    if (old.is_symlink() or not old.is_dir()
            or any(contains(old, item) or contains(item, old) for item in inputs)):
        return
    try:
        _refuse_foreign(old, "the replaced output")
    except OptionError:
        if any(old.iterdir()):
            return
    lock = _lock(partial) if partial.is_dir() and not partial.is_symlink() else None
    try:
        if os.path.lexists(target):
            shutil.rmtree(old)
        else:
            os.replace(old, target)
    finally:
        _unlock(lock)


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
        if not key or "/" in key or key.startswith(".") or key == MANIFEST:
            raise ValueError(f"checkpoint key must be a plain file name, got {key!r}")
        return self.directory / key

    def __contains__(self, key: str) -> bool:
        return self._file(key).is_file()

    def save(self, key: str, data: bytes) -> None:
        write_atomic(self._file(key), data)

    def load(self, key: str) -> bytes:
        return self._file(key).read_bytes()

    def keys(self) -> list[str]:
        if not self.directory.is_dir():  # the partial output was removed
            return []
        return sorted(p.name for p in self.directory.iterdir()
                      if not p.name.startswith(".") and p.name != MANIFEST)

    def __iter__(self) -> Iterator[str]:
        return iter(self.keys())

    def claim(self, manifest: str) -> None:
        """Tie the checkpoints to the job that made them: the first call stores ``manifest``
        (the command, its options and its inputs' fingerprints); a resumed job with another
        manifest is refused, so stale pieces are never mixed into a different job."""
        path = self.directory / MANIFEST
        if path.is_file() and path.read_text(encoding="utf-8") != manifest:
            kept = len(self.keys())
            raise OptionError(f"{self.directory.parent} was started with other options or "
                              f"inputs ({path} names them); its {kept} finished piece"
                              f"{'' if kept == 1 else 's'} are kept: rerun that command with "
                              "--resume to continue, or start over with --overwrite")
        write_atomic(path, manifest)
