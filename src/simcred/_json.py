"""Deterministic JSON for results: fixed key order, floats in shortest round-trip form."""

from __future__ import annotations

import json
from typing import Any

import numpy as np

from simcred._version import __version__

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
    return {"schema_version": SCHEMA_VERSION, "kind": kind, "simcred_version": __version__,
            **body}


def dumps(document: dict[str, Any]) -> str:
    return json.dumps(plain(document), indent=1, allow_nan=False) + "\n"
