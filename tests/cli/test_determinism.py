"""Same inputs and seed ⇒ byte-identical outputs, for every command that writes files.

Each writing command runs twice (small sizes) into two fresh outputs; every file of the two,
figures and OpenSCENARIO included, must be equal byte for byte. The two passes are two separate
Python processes with different ``PYTHONHASHSEED`` (one process per pass runs every selected
command, so the start-up is paid twice, not per command): an output that depends on the order of
a set or dict of strings differs between them. A command of the app that takes ``--out`` but has
no entry here fails the coverage test, so a new command cannot skip this check.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import typer

import simcred
from helpers import leaf_commands
from simcred.cli import app, run
from simcred.traces import TraceSet

ROOT = Path(__file__).resolve().parents[2]
FIGURE2 = ROOT / "examples" / "contracts" / "figure2.yaml"
NGSIM = ROOT / "tests" / "data" / "commonroad-ngsim"

Args = Callable[[dict[str, Path], Path], list[str]]

# Command → argv builder from (the shared inputs, the output path). Sizes are small: the check
# is that nothing in a command depends on the clock, the process, hash order or the output path.
CASES: dict[str, Args] = {
    "example": lambda v, o: ["example", "--runs", "20", "--steps", "30", "--seed", "4",
                             "--out", str(o)],
    "compare": lambda v, o: ["compare", str(v["a"]), str(v["b"]), "--test", "permutation",
                             "--permutations", "99", "--seed", "1", "--out", str(o)],
    "matrix": lambda v, o: ["matrix", str(v["a"]), str(v["b"]), str(v["a"]), "--permutations",
                            "99", "--seed", "1", "--out", str(o)],
    "convert": lambda v, o: ["convert", str(v["a"]), str(o.with_suffix(".parquet"))],
    "estimate-sensor": lambda v, o: ["estimate-sensor", str(v["a"]), str(v["b"]), "-f", "x,y",
                                     "--bootstrap", "20", "--seed", "2",
                                     "--out", str(o.with_suffix(".json"))],
    "simulate simplecar": lambda v, o: ["simulate", "simplecar", "--runs", "3", "--seed", "2",
                                        "--out", str(o)],
    "simulate tjunction": lambda v, o: ["simulate", "tjunction", "--runs", "3", "--seed", "2",
                                        "--out", str(o)],
    "simulate cutin": lambda v, o: ["simulate", "cutin", "--seed", "2", "--out", str(o)],
    "simulate sumo-following": lambda v, o: ["simulate", "sumo-following", str(v["human"]),
                                             "--models", "IDM", "--seed", "2", "--out", str(o)],
    "data openacc": lambda v, o: ["data", "openacc", "--follower", "acc",
                                  "--out", str(o.with_suffix(".parquet"))],
    "reprocess": lambda v, o: ["reprocess", str(v["measurement"]), "--seed", "2",
                               "--out", str(o)],
    "vary": lambda v, o: ["vary", str(v["description"]), "-n", "4", "--seed", "2",
                          "--out", str(o)],
    "paper 000": lambda v, o: ["paper", "000", "--runs", "2", "--seed", "3", "--out", str(o)],
    "paper 002": lambda v, o: ["paper", "002", "--variations", "20", "--seed", "3",
                               "--out", str(o)],
    "monitor": lambda v, o: ["monitor", str(FIGURE2), str(v["runs"]), "--setup",
                             "I1=M1,I2=M2a", "--out", str(o.with_suffix(".json"))],
    "study car-following": lambda v, o: ["study", "car-following", "--models", "IDM",
                                         "--max-episodes", "60", "--permutations", "99",
                                         "--tolerance", "v=0.1", "--min-runs", "5", "--seed",
                                         "2",
                                         "--out", str(o)],
}
# Writes the same files as its parts, `paper 000` and `paper 002`, checked above.
COVERED_ELSEWHERE = {"paper all": "paper 000 + paper 002",
                     "validate": "tests/validate/test_loop.py (identical bytes, same seed)",
                     "report": "tests/report/test_html.py (same directory, identical HTML)"}


def _writing_commands() -> list[str]:
    return [" ".join(path) for path, command in leaf_commands(typer.main.get_command(app))
            if any("--out" in getattr(p, "opts", ()) for p in command.params)
            or " ".join(path) == "convert"]


def test_every_writing_command_is_checked():
    missing = set(_writing_commands()) - set(CASES) - set(COVERED_ELSEWHERE)
    assert not missing, f"add a determinism case for {sorted(missing)}"


@pytest.fixture(scope="module")
def inputs(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("inputs")
    v = {"a": root / "sets" / "baseline", "b": root / "sets" / "variant",
         "measurement": root / "measurement", "human": root / "human.parquet",
         "runs": root / "runs"}
    steps = [["example", "--runs", "20", "--steps", "30", "--seed", "0", "--out",
              str(root / "sets")],
             ["simulate", "cutin", "--seed", "0", "--out", str(v["measurement"])],
             ["reprocess", str(v["measurement"]), "--out", str(root / "reprocessed")],
             ["data", "openacc", "--follower", "human", "--out", str(v["human"])]]
    for argv in steps:
        assert run(["--quiet", *argv]) == 0, argv
    TraceSet.from_runs([{"t": np.arange(5) * 0.1, "v": np.full(5, 20.0), "q": np.full(5, 10.0),
                         "err": np.full(5, 0.05)}], source="r").write(v["runs"])
    v["description"] = root / "reprocessed" / "descriptions" / "fit_GT.json"
    assert v["description"].is_file(), sorted(p.name for p in v["description"].parent.iterdir())
    return v


#: Hash seeds of the two passes (different, so string hashing orders sets differently).
HASH_SEEDS = (1, 2)
#: One pass: every command of a JSON list of argvs in this process; the exit codes as JSON.
PASS = """
import json, sys
from simcred.cli import run
cases = json.loads(open(sys.argv[1]).read())
codes = {name: run(["--quiet", *argv]) for name, argv in cases.items()}
open(sys.argv[2], "w").write(json.dumps(codes))
"""


def _selected(request) -> list[str]:
    """The cases of the byte-identity test that this session runs (all, or those of ``-k``)."""
    test = test_same_inputs_and_seed_give_byte_identical_outputs.__name__
    return sorted({item.callspec.params["name"] for item in request.session.items
                   if getattr(item, "originalname", None) == test}) or sorted(CASES)


@pytest.fixture(scope="module")
def passes(inputs, request, tmp_path_factory) -> dict[str, list[tuple[int, Path]]]:
    """Both passes, as two processes with different hash seeds run side by side: per case, the
    exit code and output path of each."""
    root = tmp_path_factory.mktemp("passes")
    names = _selected(request)
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1",  # the simcred this session imports
           "PYTHONPATH": os.pathsep.join([str(Path(simcred.__file__).parents[1]),
                                          os.environ.get("PYTHONPATH", "")])}
    argvs, started = [], []
    for k, hash_seed in enumerate(HASH_SEEDS, 1):
        argvs.append({n: CASES[n](inputs, root / f"out{k}" / n.replace(" ", "-")) for n in names})
        (root / f"cases{k}.json").write_text(json.dumps(argvs[-1]))
        with (root / f"stderr{k}.txt").open("w") as stderr:
            started.append(subprocess.Popen(
                [sys.executable, "-c", PASS, str(root / f"cases{k}.json"),
                 str(root / f"codes{k}.json")],
                env={**env, "PYTHONHASHSEED": str(hash_seed)}, stderr=stderr))
    for k, process in enumerate(started, 1):
        assert process.wait(timeout=1200) == 0, \
            f"pass {k} failed: {(root / f'stderr{k}.txt').read_text()[-3000:]}"
    codes = [json.loads((root / f"codes{k}.json").read_text()) for k in (1, 2)]
    return {n: [(codes[i][n], _output(argvs[i][n])) for i in (0, 1)] for n in names}


def _files(out: Path) -> dict[str, bytes]:
    if out.is_file():
        return {"": out.read_bytes()}
    return {str(p.relative_to(out)): p.read_bytes() for p in sorted(out.rglob("*")) if p.is_file()}


def _output(argv: list[str]) -> Path:
    """The path the command wrote: ``--out``'s value, or convert's target."""
    return Path(argv[argv.index("--out") + 1]) if "--out" in argv else Path(argv[-1])


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(CASES))
def test_same_inputs_and_seed_give_byte_identical_outputs(name, passes):
    written = []
    for code, out in passes[name]:
        assert code in (0, 1), (name, out, code)  # 1 = a verdict ("differs"), not a failure
        written.append(_files(out))
    first, second = written
    assert first, f"{name} wrote nothing"
    assert first.keys() == second.keys()
    differing = [path for path in first if first[path] != second[path]]
    assert not differing, (f"{name}: {differing} differ between two identical runs "
                           f"(processes with PYTHONHASHSEED {HASH_SEEDS})")
