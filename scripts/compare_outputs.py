"""Compare two output trees of scripts/reprocess_baseline.sh (issue 12: byte-identical outputs).

JSON files: identical after removing the documented envelope keys (ENVELOPE below; their changes
are printed, not failed); every other file, too, must be byte-identical, except:
- Parquet files: equal tables (pyarrow ``equals``) — file metadata carries the writer's version;
- ``scenario.xosc``: byte-identical except the FileHeader's ``date`` attribute when the baseline
  still embedded the wall-clock date (issue 12 defect; fixed: the date now comes from the inputs);
- PNG figures: not compared (matplotlib metadata); listed as present/absent.

Usage: python scripts/compare_outputs.py BEFORE AFTER  (exit 0 iff everything matches)
"""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path

ENVELOPE = {"schema_version", "kind", "simcred_version", "version", "inputs", "created_by"}


def _body(path: Path) -> tuple[str, dict]:
    document = json.loads(path.read_text())
    envelope = {k: document.pop(k) for k in list(document) if k in ENVELOPE}
    return json.dumps(document, indent=1, sort_keys=False), envelope


def _same(before: Path, after: Path) -> str | None:
    if before.suffix == ".json":
        (body_a, env_a), (body_b, env_b) = _body(before), _body(after)
        if body_a != body_b:
            return "JSON body differs"
        if env_a != env_b:
            print(f"  envelope change {after}: {env_a} -> {env_b}")
        return None
    if before.suffix == ".parquet":
        import pyarrow.parquet as pq

        return None if pq.read_table(before).equals(pq.read_table(after)) else "table differs"
    if before.suffix == ".png":
        return None
    a, b = before.read_bytes(), after.read_bytes()
    if before.suffix == ".xosc":
        date = re.compile(rb' date="[^"]*"')
        a, b = date.sub(b"", a), date.sub(b"", b)
    return None if a == b else "bytes differ"


def main(before_root: str, after_root: str) -> int:
    before_root, after_root = Path(before_root), Path(after_root)
    names = {p.relative_to(before_root) for p in before_root.rglob("*") if p.is_file()}
    names_after = {p.relative_to(after_root) for p in after_root.rglob("*") if p.is_file()}
    failures = [f"missing in after: {n}" for n in sorted(names - names_after)]
    failures += [f"new in after: {n}" for n in sorted(names_after - names)]
    for name in sorted(names & names_after):
        problem = _same(before_root / name, after_root / name)
        if problem:
            failures.append(f"{name}: {problem}")
    for failure in failures:
        print("DIFF", failure)
    print(f"{len(names & names_after)} files compared, {len(failures)} differences")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:3]))
