"""Paths handed to pyarrow."""

from __future__ import annotations

import os
from pathlib import Path


def local(path: str | Path) -> str:
    """``path`` as an absolute local path: pyarrow reads a relative name with a colon in it
    (``run:1.parquet``, ``javascript:x.parquet``) as a URI and fails with an unrelated error."""
    return os.path.abspath(path)
