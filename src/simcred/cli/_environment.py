"""Faults of the environment, not of simcred or of the input: a full or read-only disk, a
missing permission, a name too long, too little memory. One line naming the path and what to do,
exit code 74 (``EX_IOERR`` of sysexits.h); and the checks on the command line that keep such
faults away: every argument valid UTF-8, no argument naming a FIFO, a device or a socket."""

from __future__ import annotations

import errno
from collections.abc import Sequence

from simcred.errors import OptionError
from simcred.io._paths import special_kind

EXIT_ENVIRONMENT = 74  # EX_IOERR: the system refused (disk, permissions, memory)

_ADVICE = {
    errno.ENOSPC: "no space left on the device: free some space or write elsewhere",
    errno.EDQUOT: "disk quota exceeded: free some space or write elsewhere",
    errno.EROFS: "the file system is read-only: write elsewhere",
    errno.EACCES: "permission denied: check the permissions of the path and its folder",
    errno.EPERM: "operation not permitted: check the permissions of the path and its folder",
    errno.ENAMETOOLONG: "the name is too long for the file system: choose a shorter path",
    errno.EFBIG: "the file is too large for the file system: write elsewhere",
    errno.EMFILE: "too many open files: raise the limit (ulimit -n)",
    errno.ENFILE: "too many open files in the system: retry later",
    errno.ELOOP: "too many levels of symbolic links: name the real path",
    errno.EIO: "input/output error: check the disk",
}


def environment_fault(exc: BaseException) -> str | None:
    """The one line for an environment fault (an ``OSError`` or a ``MemoryError``), else None.

    A command that fails so has removed its partial output, as on any other error; a resumable
    one keeps its finished chunks and says so (a note on the exception).
    """
    kept = "; ".join(getattr(exc, "__notes__", ()))  # what a resumable command kept
    if isinstance(exc, MemoryError):
        line = ("out of memory: use smaller inputs or options (runs, permutations, bins, "
                "resample period), or a machine with more memory")
    elif isinstance(exc, OSError):
        names = [str(n) for n in (exc.filename, exc.filename2) if n is not None]
        where = " -> ".join(names) if names else "a file"
        line = f"{where}: {_ADVICE.get(exc.errno, exc.strerror or type(exc).__name__)}"
    else:
        return None
    return line + (f" ({kept})" if kept else "")


def undecodable_name(exc: BaseException) -> str | None:
    """The one line for a name that is not valid UTF-8 reaching a writer (a file or run name
    read from a folder listing), else None."""
    if isinstance(exc, UnicodeEncodeError) and exc.reason == "surrogates not allowed":
        bad = exc.object[max(0, exc.start - 20):exc.end + 20]
        shown = bad.encode("utf-8", "surrogateescape").decode("utf-8", "backslashreplace")
        return (f"a file or run name is not valid UTF-8 (…{shown}…): rename it; simcred writes "
                "names as UTF-8 text")
    return None


def check_arguments(args: Sequence[str]) -> None:
    """One line for an argument that is not valid UTF-8 or names a special file, before any
    command runs (an option's value may follow ``=``)."""
    for index, arg in enumerate(args, 1):
        try:
            arg.encode("utf-8")
        except UnicodeEncodeError as exc:
            shown = arg.encode("utf-8", "surrogateescape").decode("utf-8", "backslashreplace")
            raise OptionError(f"argument {index} ({shown}) is not valid UTF-8 (byte "
                              f"{exc.start}): rename the file; simcred writes names as UTF-8 "
                              "text") from None
        for value in {arg, arg.partition("=")[2]} - {""}:
            kind = special_kind(value)
            if kind is not None:
                raise OptionError(f"{value} is {kind}, not a regular file: simcred reads and "
                                  "writes only regular files and folders")
