"""Paths handed to pyarrow, and what simcred reads from: regular files and folders only."""

from __future__ import annotations

import os
import stat
from pathlib import Path

from simcred.errors import TraceSetError

_SPECIAL = {stat.S_IFIFO: "a FIFO (named pipe)", stat.S_IFCHR: "a character device",
            stat.S_IFBLK: "a block device", stat.S_IFSOCK: "a socket"}


def local(path: str | Path) -> str:
    """``path`` as an absolute local path: pyarrow reads a relative name with a colon in it
    (``run:1.parquet``, ``javascript:x.parquet``) as a URI and fails with an unrelated error."""
    return os.path.abspath(path)


def special_kind(path: str | Path) -> str | None:
    """What ``path`` is if it exists and is neither a regular file nor a folder (a FIFO, a
    device, a socket: reading one may never end or never stop), else None."""
    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError):  # missing, unreadable, a name the system refuses
        return None
    return _SPECIAL.get(stat.S_IFMT(mode))


def check_regular(path: str | Path) -> None:
    """One line if ``path`` is a FIFO, a device or a socket (simcred reads only regular files
    and folders, so a special file cannot hang or flood it)."""
    kind = special_kind(path)
    if kind is not None:
        raise TraceSetError(f"{path} is {kind}, not a regular file: simcred reads only regular "
                            "files and folders")
