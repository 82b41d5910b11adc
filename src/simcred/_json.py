"""Deterministic JSON for results: fixed key order, floats in shortest round-trip form."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

import simcred
from simcred.errors import SimcredError

SCHEMA_VERSION = 1


def plain(value: Any) -> Any:
    """Convert numpy scalars/arrays, tuples and enums to JSON-native values, recursively."""
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return plain(value.tolist())
    if isinstance(value, np.integer):
        return int(value)
    if isinstance(value, np.floating):
        return float(value)
    if isinstance(value, np.bool_):
        return bool(value)
    if isinstance(value, float) and not np.isfinite(value):
        return None
    return value


def envelope(kind: str, body: dict[str, Any]) -> dict[str, Any]:
    """Every result document starts with its schema version, kind and simcred version."""
    return {"schema_version": SCHEMA_VERSION, "kind": kind, "simcred_version": simcred.__version__,
            **body}


def dumps(document: dict[str, Any]) -> str:
    return json.dumps(plain(document), indent=1, allow_nan=False) + "\n"


def loads(text: str | bytes, where: str, error: type[SimcredError] = SimcredError) -> Any:
    """Parse JSON text from a user's file; any defect is a one-line error naming ``where``.

    Covers malformed JSON, non-UTF-8 bytes, nesting too deep for the parser and integers with
    more digits than Python converts.
    """
    try:
        return json.loads(text)
    except RecursionError:
        raise error(f"{where}: JSON nested too deeply") from None
    except ValueError as exc:  # JSONDecodeError, UnicodeDecodeError, int digit limit
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise error(f"{where}: not valid JSON ({reason})") from None


def read_json(path: Path, error: type[SimcredError] = SimcredError) -> Any:
    """Read and parse a JSON file (see :func:`loads`); unreadable files are one-line errors."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise error(f"{path}: cannot read ({exc.strerror or exc})") from None
    return loads(data, str(path), error)
