"""The repository's text cites only documents it has: every ``NAME.md`` that README.md, docs/,
src/, tests/, scripts/ or examples/ mention is a file of the repository (no DESIGN.md)."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CITED = re.compile(r"[A-Za-z0-9_./-]*[A-Za-z0-9_-]\.md\b")


def _texts() -> list[Path]:
    found = [ROOT / "README.md"]
    for folder in ("docs", "src", "tests", "scripts", "examples"):
        found += [p for p in (ROOT / folder).rglob("*") if p.suffix in (".md", ".py", ".sh")
                  and "__pycache__" not in p.parts and p.is_file()]
    return [p for p in found if p != Path(__file__).resolve()]  # this file names examples


def _exists(name: str, citing: Path, documents: list[Path]) -> bool:
    name = name.lstrip("./")
    if any((base / name).is_file() for base in (ROOT, ROOT / "docs", citing.parent)):
        return True
    return any(p.as_posix().endswith("/" + name) for p in documents)


def test_every_cited_document_exists():
    documents = [p for p in ROOT.rglob("*.md") if ".git" not in p.parts
                 and ".venv" not in p.parts]
    missing = sorted({f"{path.relative_to(ROOT)}: {name}" for path in _texts()
                      for name in CITED.findall(path.read_text(errors="replace"))
                      if not _exists(name, path, documents)})
    assert not missing, "cited documents that are not in the repository:\n" + "\n".join(missing)
