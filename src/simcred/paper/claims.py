"""A paper's qualitative claim, checked on our numbers: value against bound, passed or not."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from pathlib import Path

from simcred._json import dumps, envelope


@dataclass(frozen=True, slots=True)
class Claim:
    """``passed`` is ``value <op> bound``; ``note`` says how the value was measured."""

    id: str
    claim: str
    value: float | None
    bound: float | None
    passed: bool
    note: str = ""


def at_least(id: str, claim: str, value: float, bound: float, note: str = "") -> Claim:
    return Claim(id, claim, value, bound, bool(value >= bound), note)


def below(id: str, claim: str, value: float, bound: float, note: str = "") -> Claim:
    return Claim(id, claim, value, bound, bool(value < bound), note)


def write_claims(claims: list[Claim], path: Path, provenance: dict) -> Path:
    body = {"provenance": provenance, "claims": [asdict(c) for c in claims]}
    path.write_text(dumps(envelope("claims", body)))
    return path

