"""Deterministic JSON for results: fixed key order, floats in shortest round-trip form."""

from __future__ import annotations

import dataclasses
import hashlib
import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from simcred._version import __version__
from simcred.errors import SimcredError

SCHEMA_VERSION = 1


def plain(value: Any) -> Any:
    """Convert numpy scalars/arrays, tuples and enums to JSON-native values, recursively."""
    if isinstance(value, Mapping):
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


def envelope(kind: str, body: Mapping[str, Any], *, inputs: Mapping[str, str] | None = None,
             options: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """A result document: the envelope, then ``body``.

    Every JSON file simcred writes starts with ``schema_version``, ``kind`` (what the document
    is, e.g. ``"reprocess"``) and ``simcred_version``; then, when given, ``inputs`` (name →
    content hash, e.g. :meth:`simcred.traces.TraceSet.digest` or :func:`file_digest`) and
    ``options`` (everything that produced it, the seed included). Stable API: every package
    writes its files through it.

    >>> list(envelope("x", {"value": 1}, inputs={"a": "sha256:00"}))
    ['schema_version', 'kind', 'simcred_version', 'inputs', 'value']
    """
    head: dict[str, Any] = {"schema_version": SCHEMA_VERSION, "kind": kind,
                            "simcred_version": __version__}
    if inputs is not None:
        head["inputs"] = dict(inputs)
    if options is not None:
        head["options"] = dict(options)
    clash = set(head) & set(body)
    if clash:
        raise ValueError(f"envelope keys in the body of a {kind!r} document: {sorted(clash)}")
    return {**head, **body}


def file_sha256(path: str | Path) -> str:
    """The hex SHA-256 of a file's bytes."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def file_digest(path: str | Path) -> str:
    """``sha256:<hex>`` of a file's bytes (an input's content hash for :func:`envelope`)."""
    return "sha256:" + file_sha256(path)


def dumps(document: Mapping[str, Any]) -> str:
    """Deterministic JSON text: keys in insertion order, floats round-trip, no NaN."""
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
    """Read and parse a JSON file (see :func:`loads`); unreadable files, and special files (a
    FIFO or a device, which could block or never end), are one-line errors."""
    if path.exists() and not path.is_file():
        raise error(f"{path}: not a regular file")
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise error(f"{path}: cannot read ({exc.strerror or exc})") from None
    return loads(data, str(path), error)


def json_key(name: str | None) -> dict[str, str | None]:
    """Field metadata for :func:`fields_dict`: the field's key in the JSON (``None``: the field
    is left out, e.g. an array the document does not dump).

    >>> from dataclasses import dataclass, field
    >>> @dataclass
    ... class Row:
    ...     units: int = field(metadata=json_key("units_per_side"))
    ...     bands: tuple = (1, 2)
    >>> fields_dict(Row(3))
    {'units_per_side': 3, 'bands': [1, 2]}
    """
    return {"json": name}


def fields_dict(record: Any) -> dict[str, Any]:
    """A dataclass record as JSON-ready data, the convention for a record whose document is its
    fields: each field in declaration order under its name (or its :func:`json_key`), tuples
    as lists. A document with a deliberate layout of its own (nested groups, derived keys)
    keeps a hand-written ``to_dict``."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(record):
        key = f.metadata.get("json", f.name)
        if key is not None:
            value = getattr(record, f.name)
            out[key] = list(value) if isinstance(value, tuple) else value
    return out


class JsonResult:
    """The result convention: a frozen dataclass gives :meth:`to_dict` (plain data); this mixin
    gives :meth:`to_json`, the deterministic text of that dict (:func:`dumps`)."""

    __slots__ = ()

    def to_dict(self) -> dict[str, Any]:  # pragma: no cover - every result defines it
        raise NotImplementedError

    def to_json(self) -> str:
        """:meth:`to_dict` as deterministic JSON text."""
        return dumps(self.to_dict())
