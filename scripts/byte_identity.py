"""Byte identity of the comparison commands' outputs on two commits (issue 27, item 1).

Runs the demo's comparison commands (scripts/demo.sh steps 1-4 and 10, at smaller sizes, plus
the runs and response tests, ``--json`` to stdout and a few refused options), step 7's
reprocessing (files and ``--json``), the cut-in's (with GT: eqs. (4)-(7) in its analysis),
a variation campaign of the cut-in's fit(GT) (files and ``--json``), ``convert`` of a folder
and of a file, and a quotient, with the sources of each commit (``git
worktree`` of the commit, ``PYTHONPATH=<tree>/src``), and compares the SHA-256 of every output
file, stdout and stderr included.

Excluded from the hash: the elapsed time the commands print on stderr ("done in 1.3 s",
replaced by "done in T") and the run's output folder in stdout/stderr (replaced by "OUT"). Every
other file is hashed whole; one that differs only in provenance — the envelope's version keys
(``simcred_version``, ``created_by``, ``version``) or the commit a validation records
(``git_commit`` in verdict.json and its copy in report.html) — is reported as a provenance
difference, not a failure. PNG figures are hashed like every other file (same matplotlib on both
sides). The help of the comparison commands is compared too.

Usage: python scripts/byte_identity.py BEFORE_COMMIT AFTER_COMMIT [WORKDIR]
(exit 0 iff every file is identical).
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import subprocess
import sys
import tempfile
from pathlib import Path

#: The one wall-clock value the commands print (stderr): replaced before hashing.
ELAPSED = re.compile(rb"done in [^\n]*")
PROVENANCE = {"simcred_version", "created_by", "version"}
#: The commit a validation records (verdict.json ``provenance.git_commit``, and report.html).
COMMIT = re.compile(rb"(git_commit(?:&#34;|\")?\s*:\s*(?:&#34;|\"))[0-9a-f]{40}")
SIMCRED = [sys.executable, "-m", "simcred.cli"]

#: (name, arguments of simcred); ``{o}`` is the output folder of the run, ``{d}`` the data.
COMMANDS = [
    ("example", ["example", "--out", "{o}/data", "--runs", "120", "--steps", "60", "--seed", "0"]),
    ("repeat", ["--quiet", "example", "--out", "{o}/data/repeat", "--runs", "120", "--steps",
                "60", "--seed", "1", "--duration-scale", "1.0"]),
    ("bound", ["compare", "{d}/baseline", "{d}/variant", "--features", "y,heading", "--bins", "6",
               "--test", "bound", "--seed", "0", "--out", "{o}/compare-bound"]),
    ("permutation", ["compare", "{d}/baseline", "{d}/variant", "--features", "y,heading",
                     "--bins", "6", "--test", "permutation", "--seed", "0", "--permutations",
                     "199", "--out", "{o}/compare-permutation"]),
    ("runs", ["compare", "{d}/baseline", "{d}/variant", "--features", "y,heading", "--bins", "4",
              "--seed", "0", "--permutations", "99", "--baseline", "2", "--bootstrap", "2",
              "--relevance", "--chain", "max", "--history", "2", "--out", "{o}/compare-runs"]),
    ("runs-json", ["compare", "{d}/baseline", "{d}/variant", "--features", "y", "--bins", "5",
                   "--seed", "1", "--permutations", "49", "--time-bins", "2", "--json"]),
    ("response", ["compare", "{d}/baseline", "{d}/variant", "--features", "y,heading", "--bins",
                  "3", "--test", "response", "--seed", "0", "--permutations", "49",
                  "--bootstrap", "100", "--margin", "0.5", "--out", "{o}/compare-response"]),
    ("matrix", ["matrix", "{d}/baseline", "{d}/repeat/baseline", "{d}/variant", "--names",
                "baseline,repeat,variant", "--features", "y,heading", "--bins", "6", "--test",
                "permutation", "--permutations", "199", "--seed", "0", "--out", "{o}/matrix"]),
    ("matrix-runs", ["matrix", "{d}/baseline", "{d}/variant", "--features", "y", "--bins", "4",
                     "--permutations", "49", "--seed", "3", "--json"]),
    ("bad-alpha", ["compare", "{d}/baseline", "{d}/variant", "--alpha", "2"]),
    ("bad-multiplicity", ["compare", "{d}/baseline", "{d}/variant", "--test", "bound",
                          "--multiplicity", "fwer"]),
    ("bad-inputs", ["compare", "{d}/baseline", "{d}/variant", "--inputs", "y"]),
    ("bad-bins", ["matrix", "{d}/baseline", "{d}/variant", "--bins", "1"]),
    ("bad-feature", ["matrix", "{d}/baseline", "{d}/variant", "--features", "nope"]),
    ("compare-help", ["compare", "--help"]),
    ("matrix-help", ["matrix", "--help"]),
    ("estimate-sensor-help", ["estimate-sensor", "--help"]),
    ("cutin-runs", ["python", "examples/validate/cutin/make_runs.py", "--out", "{o}/cutin"]),
    ("validate-cutin", ["validate", "{o}/cutin/validation.yaml", "--out", "{o}/validate-cutin"]),
    # beyond the comparison: conversion records, reprocessing (files and --json), the quotient
    ("convert-dir", ["convert", "{d}/baseline", "{o}/baseline.parquet", "--json"]),
    ("convert-file", ["convert", "{o}/baseline.parquet", "{o}/baseline-long.csv", "--json"]),
    ("reprocess-a9", ["reprocess", "src/simcred/data/a9/trajectories_file.csv", "--out",
                      "{o}/a9", "--threshold", "0.1"]),
    ("reprocess-a9-json", ["reprocess", "src/simcred/data/a9/trajectories_file.csv", "--out",
                           "{o}/a9-json", "--threshold", "0.1", "--json"]),
    # the cut-in has GT: reprocess.json's analysis (eqs. (4)-(7), [sb]) is not empty
    ("simulate-cutin", ["--quiet", "simulate", "cutin", "--out", "{o}/cutin-measurement"]),
    ("reprocess-cutin", ["reprocess", "{o}/cutin-measurement", "--out", "{o}/reprocess-cutin"]),
    ("reprocess-ngsim", ["reprocess", "tests/data/commonroad-ngsim/USA_US101-3_3_T-1.xml",
                         "--object", "394", "--out", "{o}/ngsim-394"]),
    # the variation campaign of the cut-in's fit(GT): files, and --json printed from memory
    ("vary", ["vary", "{o}/reprocess-cutin/descriptions/fit_GT.json", "-n", "6", "--seed", "2",
              "--out", "{o}/vary"]),
    ("vary-json", ["vary", "{o}/reprocess-cutin/descriptions/fit_GT.json", "-n", "6", "--seed",
                   "2", "--out", "{o}/vary-json", "--json"]),
    ("quotient", ["contracts", "quotient", "examples/contracts/figure2.yaml", "--test-case",
                  "C_tc", "--given", "I1=M1", "--json"]),
]


def run_all(tree: Path, out: Path) -> None:
    env = {**os.environ, "PYTHONPATH": str(tree / "src"), "OPENBLAS_NUM_THREADS": "1",
           "COLUMNS": "100", "NO_COLOR": "1"}
    out.mkdir(parents=True)
    (out / "cutin").mkdir()
    (out / "cutin" / "validation.yaml").write_bytes(
        (tree / "examples/validate/cutin/validation.yaml").read_bytes())
    for name, args in COMMANDS:
        args = [a.format(o=out, d=out / "data") for a in args]
        command = [sys.executable, *args[1:]] if args[0] == "python" else [*SIMCRED, *args]
        done = subprocess.run(command, cwd=tree, env=env, capture_output=True)
        text = [t.replace(str(out).encode(), b"OUT") for t in (done.stdout, done.stderr)]
        text[1] = ELAPSED.sub(b"done in T", text[1])
        (out / f"{name}.stdout").write_bytes(text[0])
        (out / f"{name}.stderr").write_bytes(text[1] + f"\nexit {done.returncode}\n".encode())
        print(f"  {name}: exit {done.returncode}", flush=True)


def digest(path: Path) -> str:
    data = path.read_bytes()
    if path.suffix == ".stderr":  # a reused "before" folder may predate the replacement
        data = ELAPSED.sub(b"done in T", data)
    return hashlib.sha256(data).hexdigest()


def without_provenance(path: Path) -> str:
    """The digest with the commit's hash replaced (``git_commit`` in verdict.json and its copy
    in report.html) and, in JSON files, the envelope's version keys dropped."""
    data = COMMIT.sub(rb"\1COMMIT", path.read_bytes())
    if path.suffix == ".json":
        try:
            document = json.loads(data)
        except ValueError:
            document = None
        if isinstance(document, dict):
            for key in PROVENANCE:
                document.pop(key, None)
            data = json.dumps(document, sort_keys=True).encode()
    return hashlib.sha256(data).hexdigest()


def compare(before: Path, after: Path) -> int:
    names = {p.relative_to(before) for p in before.rglob("*") if p.is_file()}
    names_after = {p.relative_to(after) for p in after.rglob("*") if p.is_file()}
    failures = [f"only before: {n}" for n in sorted(names - names_after)]
    failures += [f"only after: {n}" for n in sorted(names_after - names)]
    provenance = []
    for name in sorted(names & names_after):
        if digest(before / name) == digest(after / name):
            continue
        if without_provenance(before / name) == without_provenance(after / name):
            provenance.append(str(name))
        else:
            failures.append(f"differs: {name}")
    for line in failures:
        print("DIFF", line)
    for name in provenance:
        print("PROVENANCE ONLY", name)
    print(f"{len(names & names_after)} files compared by SHA-256: {len(failures)} differ, "
          f"{len(provenance)} differ only in provenance ({', '.join(sorted(PROVENANCE))}, "
          "git_commit)")
    return 1 if failures else 0


def main(before: str, after: str, workdir: str | None = None) -> int:
    """Both commits run in the same tree and output paths (``WORKDIR/tree``, ``WORKDIR/work``),
    so paths inside outputs agree; an existing ``WORKDIR/before`` is reused."""
    root = Path(workdir or tempfile.mkdtemp(prefix="byte-identity-")).resolve()
    repo = Path(__file__).resolve().parents[1]
    for label, commit in (("before", before), ("after", after)):
        if label == "before" and (root / label).is_dir():
            print(f"{label}: reusing {root / label}")
            continue
        tree = root / "tree"
        subprocess.run(["git", "-C", str(repo), "worktree", "add", "--detach", str(tree),
                        commit], check=True, capture_output=True)
        try:
            print(f"{label}: {commit}", flush=True)
            run_all(tree, root / "work")
            (root / "work").rename(root / label)
        finally:
            subprocess.run(["git", "-C", str(repo), "worktree", "remove", "--force", str(tree)],
                           check=True)
    return compare(root / "before", root / "after")


if __name__ == "__main__":
    sys.exit(main(*sys.argv[1:4]))
