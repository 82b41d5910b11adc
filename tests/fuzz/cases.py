"""Bad and extreme inputs for every command: each case is (id, argv builder).

A builder gets a scratch directory and a dict of valid inputs and returns the argv. Every case
must end in exit code 2 with one line on stderr naming the culprit, within a few seconds.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from simcred.outputs import MARKER, MARKER_TEXT

Builder = Callable[[Path, dict], list[str]]


# --- trace-set corruptions: each writes a broken trace set and returns its path -------------------

def _csv_dir(root: Path, files: dict[str, bytes]) -> Path:
    directory = root / "corrupt_runs"
    directory.mkdir()
    for name, data in files.items():
        (directory / name).write_bytes(data)
    return directory


GOOD_RUN = b"t,x,y\n0,0,0\n0.1,1,0.5\n0.2,2,0.7\n0.3,3,0.9\n"


def _parquet(root: Path, table: pa.Table, name: str = "corrupt_set.parquet") -> Path:
    path = root / name
    pq.write_table(table, path)
    return path


def _runs_table(run_type: pa.DataType | None, runs: list) -> pa.Table:
    n = len(runs)
    return pa.table({"run": pa.array(runs, type=run_type), "t": np.arange(n) * 0.1,
                     "x": np.arange(n, dtype=float)})


TRACE_SETS: dict[str, Callable[[Path], Path]] = {
    "missing path": lambda r: r / "corrupt_missing",
    "empty directory": lambda r: _csv_dir(r, {}),
    "empty csv file": lambda r: _csv_dir(r, {"run_0.csv": b""}),
    "header only": lambda r: _csv_dir(r, {"run_0.csv": b"t,x\n"}),
    "non-utf8 header": lambda r: _csv_dir(r, {"run_0.csv": b"t,\xff\xfe\n0,1\n0.1,2\n"}),
    "non-utf8 cell": lambda r: _csv_dir(r, {"run_0.csv": b"t,x\n0,\xff\n0.1,2\n"}),
    "no t column": lambda r: _csv_dir(r, {"run_0.csv": b"a,x\n0,1\n0.1,2\n"}),
    "duplicate columns": lambda r: _csv_dir(r, {"run_0.csv": b"t,x,x\n0,1,2\n0.1,2,3\n"}),
    "non-numeric cell": lambda r: _csv_dir(r, {"run_0.csv": b"t,x\n0,1\n0.1,abc\n"}),
    "nan cell": lambda r: _csv_dir(r, {"run_0.csv": b"t,x\n0,1\n0.1,nan\n"}),
    "inf cell": lambda r: _csv_dir(r, {"run_0.csv": b"t,x\n0,1\n0.1,inf\n"}),
    "huge literal": lambda r: _csv_dir(r, {"run_0.csv": b"t,x\n0,1\n0.1," + b"9" * 5000
                                           + b"\n"}),
    "non-increasing t": lambda r: _csv_dir(r, {"run_0.csv": b"t,x\n0,1\n0,2\n"}),
    "decreasing t": lambda r: _csv_dir(r, {"run_0.csv": b"t,x\n1,1\n0,2\n"}),
    "ragged row": lambda r: _csv_dir(r, {"run_0.csv": b"t,x\n0,1,5\n0.1,2\n"}),
    "short row": lambda r: _csv_dir(r, {"run_0.csv": b"t,x,y\n0,1\n0.1,2,3\n"}),
    "runs with different signals": lambda r: _csv_dir(
        r, {"run_0.csv": GOOD_RUN, "run_1.csv": b"t,x\n0,1\n0.1,2\n"}),
    "100k columns": lambda r: _csv_dir(
        r, {"run_0.csv": ("t," + ",".join(f"c{i}" for i in range(100_000)) + "\n0,"
                          + ",".join("1" for _ in range(100_000)) + "\n").encode()}),
    "same run in two suffix cases": lambda r: _csv_dir(
        r, {"run_0.csv": GOOD_RUN, "run_1.csv": GOOD_RUN, "run_1.CSV": GOOD_RUN}),
    "fifo as run": lambda r: _fifo_dir(r),
    "binary garbage csv": lambda r: _csv_dir(r, {"run_0.csv": bytes(range(256)) * 4}),
    "metadata nested deep": lambda r: _with_metadata(r, "[" * 100_000 + "]" * 100_000),
    "metadata not json": lambda r: _with_metadata(r, "{not json"),
    "not a parquet file": lambda r: _text(r / "corrupt_x.parquet", "t,x\n0,1\n"),
    "parquet without run column": lambda r: _parquet(
        r, pa.table({"t": [0.0, 0.1], "x": [1.0, 2.0]})),
    "parquet run of list type": lambda r: _parquet(
        r, pa.table({"run": pa.array([[1], [1]]), "t": [0.0, 0.1], "x": [1.0, 2.0]})),
    "parquet run of binary type": lambda r: _parquet(r, _runs_table(pa.binary(), [b"a", b"a"])),
    "parquet string signal": lambda r: _parquet(
        r, pa.table({"run": ["a", "a"], "t": [0.0, 0.1], "x": ["1", "2"]})),
    "parquet null in signal": lambda r: _parquet(
        r, pa.table({"run": ["a", "a"], "t": [0.0, 0.1], "x": pa.array([1.0, None])})),
    "parquet non-increasing t": lambda r: _parquet(
        r, pa.table({"run": ["a", "a"], "t": [0.1, 0.0], "x": [1.0, 2.0]})),
    "parquet empty": lambda r: _parquet(
        r, pa.table({"run": pa.array([], pa.string()), "t": pa.array([], pa.float64())})),
}


def _text(path: Path, text: str) -> Path:
    path.write_text(text)
    return path


def _fifo_dir(root: Path) -> Path:
    directory = _csv_dir(root, {"run_1.csv": GOOD_RUN})
    os.mkfifo(directory / "run_0.csv")
    return directory


def _with_metadata(root: Path, text: str) -> Path:
    directory = _csv_dir(root, {"run_0.csv": GOOD_RUN, "run_1.csv": GOOD_RUN})
    (directory / "traceset.json").write_text(text)
    return directory


# --- option values that must be refused -----------------------------------------------------------

BAD_COUNTS = ["0", "-1", "nan", "abc", "", "1e400", "9223372036854775808", "1000000000000"]
BAD_FLOATS = ["nan", "inf", "-inf", "abc", "", "1e400", "-1"]
BAD_PROBABILITIES = ["0", "1", "-0.5", "1.5", "nan", "1e-320", "abc"]


def _compare(valid: dict, *extra: str) -> list[str]:
    return ["compare", str(valid["a"]), str(valid["b"]), *extra]


def _cases() -> list[tuple[str, Builder]]:
    cases: list[tuple[str, Builder]] = []
    add = cases.append
    for name, make in TRACE_SETS.items():
        add((f"compare A={name}", lambda r, v, m=make: _compare({**v, "a": m(r)})))
        add((f"compare B={name}", lambda r, v, m=make: _compare({**v, "b": m(r)})))
        add((f"matrix {name}", lambda r, v, m=make: ["matrix", str(v["a"]), str(m(r))]))
        add((f"monitor runs={name}", lambda r, v, m=make: [
            "monitor", str(v["library"]), str(m(r)), "--setup", v["setup"]]))
    for value in BAD_COUNTS:
        add((f"compare --bins {value}", lambda r, v, x=value: _compare(v, "--bins", x)))
        add((f"compare --permutations {value}",
             lambda r, v, x=value: _compare(v, "--test", "permutation", "--permutations", x)))
        add((f"example --runs {value}", lambda r, v, x=value: [
            "example", "--out", str(r / "ex"), "--runs", x]))
        add((f"example --steps {value}", lambda r, v, x=value: [
            "example", "--out", str(r / "ex"), "--steps", x]))
        add((f"simulate simplecar --runs {value}", lambda r, v, x=value: [
            "simulate", "simplecar", "--out", str(r / "s"), "--runs", x]))
        add((f"simulate simplecar --chunk-size {value}", lambda r, v, x=value: [
            "simulate", "simplecar", "--out", str(r / "s"), "--runs", "3", "--chunk-size", x]))
        add((f"simulate tjunction --runs {value}", lambda r, v, x=value: [
            "simulate", "tjunction", "--out", str(r / "s"), "--runs", x]))
        add((f"paper 000 --runs {value}", lambda r, v, x=value: [
            "paper", "000", "--out", str(r / "p"), "--runs", x]))
        add((f"paper 002 --variations {value}", lambda r, v, x=value: [
            "paper", "002", "--out", str(r / "p"), "--variations", x]))
        add((f"vary -n {value}", lambda r, v, x=value: [
            "vary", str(v["description"]), "--out", str(r / "v"), "-n", x]))
        add((f"matrix --workers {value}", lambda r, v, x=value: [
            "matrix", str(v["a"]), str(v["b"]), "--workers", x]))
    for value in BAD_PROBABILITIES:
        add((f"compare --alpha {value}", lambda r, v, x=value: _compare(v, "--alpha", x)))
    for value in BAD_FLOATS:
        for option in ("--lambda", "--dt", "--duration"):
            add((f"simulate simplecar {option} {value}", lambda r, v, o=option, x=value: [
                "simulate", "simplecar", "--out", str(r / "s"), "--runs", "3", o, x]))
        add((f"example --duration-scale {value}", lambda r, v, x=value: [
            "example", "--out", str(r / "ex"), "--duration-scale", x]))
        add((f"reprocess --threshold {value}", lambda r, v, x=value: [
            "reprocess", str(v["measurement"]), "--out", str(r / "rp"), "--threshold", x]))
    for option, value in [("--features", "nope"), ("--features", ""), ("--features", "x,x"),
                          ("--kernel", "cubic"), ("--test", "magic"), ("--estimator", "x"),
                          ("--bins", "1"), ("--bins", "3,3,3"), ("--seed", "-1"),
                          ("--seed", "1e400")]:
        add((f"compare {option} {value!r}", lambda r, v, o=option, x=value: _compare(v, o, x)))
    for args in (["--scheduler", "tcp://127.0.0.1:1"], ["--scheduler", "not an address"],
                 ["--scheduler", "tcp://[::1"], ["--names", "one"], ["--names", "a,a"]):
        add((f"matrix {' '.join(args)}", lambda r, v, a=args: [
            "matrix", str(v["a"]), str(v["b"]), *a]))
    add(("matrix one set", lambda r, v: ["matrix", str(v["a"])]))
    add(("simulate tjunction --category bad", lambda r, v: [
        "simulate", "tjunction", "--out", str(r / "s"), "--category", "bad"]))
    add(("simulate cutin --ego-model bad", lambda r, v: [
        "simulate", "cutin", "--out", str(r / "c"), "--ego-model", "bad"]))
    add(("reprocess --vehicle bad", lambda r, v: [
        "reprocess", str(v["measurement"]), "--out", str(r / "rp"), "--vehicle", "bad"]))
    add(("vary --vehicle bad", lambda r, v: [
        "vary", str(v["description"]), "--out", str(r / "v"), "--vehicle", "bad"]))
    cases += _output_cases() + _file_cases() + _newer_command_cases()
    return cases


def _newer_command_cases() -> list[tuple[str, Builder]]:
    """study, validate, convert, data and contracts: options and files."""
    cases: list[tuple[str, Builder]] = []
    study = ["study", "car-following"]
    for option, value in [("--bands", "10-5"), ("--bands", "a-b"), ("--bands", ""),
                          ("--features", "nope"), ("--bins", "1"), ("--bins", "1000000000000"),
                          ("--sample-step", "0"), ("--sample-step", "nan"), ("--test", "magic"),
                          ("--alpha", "2"), ("--permutations", "0"), ("--baseline", "-1"),
                          ("--one-sided", "x"), ("--models", "NoSuchModel"),
                          ("--max-episodes", "0"), ("--min-runs", "0"),
                          ("--tolerance", "v=-1"), ("--tolerance", "x"), ("--inputs", "a"),
                          ("--bands", "0-10,20-30")]:
        cases.append((f"study {option} {value!r}", lambda r, v, o=option, x=value: [
            *study, "--out", str(r / "st"), o, x]))
    cases.append(("study --source corrupt", lambda r, v: [
        *study, "--out", str(r / "st"), "--source", str(_text(r / "corrupt_acc.csv", "x\n"))]))
    for label, text in [("not yaml", "a: [1"), ("empty", ""), ("list", "- 1\n- 2\n"),
                        ("unknown key", "name: x\nnonsense: 1\n"),
                        ("duplicate key", "name: x\nname: y\n"),
                        ("deep", "a: " + "[" * 10_000 + "]" * 10_000 + "\n"),
                        ("not utf8", None)]:
        cases.append((f"validate {label}", lambda r, v, t=text: [
            "validate", str(_validation(r, t)), "--out", str(r / "val")]))
    for label, args in [("missing input", ["corrupt_missing.parquet"]),
                        ("unknown format", [None, "--format", "nope"]),
                        ("unknown option", [None, "--run-column", "x"]),
                        ("same file", [None, "SAME"])]:
        cases.append((f"convert {label}", lambda r, v, a=args: _convert(r, v, a)))
    cases.append(("data path unknown", lambda r, v: ["data", "path", "corrupt_nothing"]))
    for command in (["contracts", "check"], ["contracts", "configure", "--test-case", "C_tc"]):
        cases.append((f"{' '.join(command)} missing library", lambda r, v, c=command: [
            *c[:2], str(r / "corrupt_lib.yaml"), *c[2:]]))
        cases.append((f"{' '.join(command)} non-utf8 library", lambda r, v, c=command: [
            *c[:2], str(_bytes(r / "corrupt_lib.yaml", b"variables: \xff\n")), *c[2:]]))
    return cases


def _bytes(path: Path, data: bytes) -> Path:
    path.write_bytes(data)
    return path


def _validation(root: Path, text: str | None) -> Path:
    path = root / "corrupt_validation.yaml"
    if text is None:
        path.write_bytes(b"name: \xff\xfe\n")
    else:
        path.write_text(text)
    return path


def _convert(root: Path, valid: dict, args: list) -> list[str]:
    source = str(valid["b"])
    out = str(root / "converted.parquet")
    resolved = [source if a is None else (source if a == "SAME" else a) for a in args]
    if args[0] is None and len(args) > 1 and args[1] == "SAME":
        return ["convert", source, source]
    if args[0] is None:
        return ["convert", source, out, *resolved[1:]]
    return ["convert", str(root / resolved[0]), out]


def _output_cases() -> list[tuple[str, Builder]]:
    """--out that is an input, inside an input, an existing file, or under a file."""
    def existing_file(r: Path) -> Path:
        return _text(r / "a_file", "keep me")

    return [
        ("compare --out is an input", lambda r, v: _compare(v, "--out", str(v["a"]))),
        ("compare --out inside an input", lambda r, v: _compare(v, "--out", str(v["a"] / "x"))),
        ("compare --out an existing file", lambda r, v: _compare(v, "--out",
                                                                  str(existing_file(r)))),
        ("compare --out under a file", lambda r, v: _compare(
            v, "--out", str(existing_file(r) / "sub"))),
        ("monitor --out is an input run", lambda r, v: [
            "monitor", str(v["library"]), str(v["runs"]), "--setup", v["setup"], "--out",
            str(v["runs"] / "run_0.csv")]),
        ("report --out is its input", lambda r, v: [
            "report", str(v["paper"]), "--out", str(v["paper"] / "claims.json")]),
        ("simulate --out an existing file", lambda r, v: [
            "simulate", "simplecar", "--runs", "3", "--out", str(existing_file(r))]),
        ("example --out under a file", lambda r, v: [
            "example", "--out", str(existing_file(r) / "sub")]),
        ("reprocess --out is the measurement", lambda r, v: [
            "reprocess", str(v["measurement"]), "--out", str(v["measurement"])]),
        ("vary --out contains the description", lambda r, v: [
            "vary", str(v["description"]), "--out", str(v["description"].parent)]),
        ("example --out exists, not empty, no --overwrite", lambda r, v: [
            "example", "--out", str(existing_file(r).parent)]),
        ("simulate --out a directory where a .parquet file goes", lambda r, v: [
            "simulate", "simplecar", "--runs", "3", "--out", str(_dir(r / "x.parquet"))]),
        ("simulate: a leftover OUT.partial, neither --resume nor --overwrite", lambda r, v: [
            "simulate", "simplecar", "--runs", "3", "--out", str(_leftover(r) / "sc")]),
        ("simulate --resume of a partial made with other options", lambda r, v: [
            "simulate", "simplecar", "--runs", "3", "--resume", "--out",
            str(_leftover(r, manifest="{}") / "sc")]),
        ("matrix --resume without --out", lambda r, v: [
            "matrix", str(v["a"]), str(v["b"]), "--resume"]),
        ("report --out an existing file, no --overwrite", lambda r, v: [
            "report", str(v["paper"]), "--out", str(existing_file(r))]),
    ]


def _dir(path: Path) -> Path:
    path.mkdir(parents=True)
    (path / "keep.txt").write_text("keep me")
    return path


def _leftover(root: Path, manifest: str | None = None) -> Path:
    """``root/sc.partial``: what an interrupted run left (with a checkpoint manifest)."""
    checkpoints = root / "sc.partial" / "checkpoints"
    checkpoints.mkdir(parents=True)
    (root / "sc.partial" / MARKER).write_bytes(MARKER_TEXT)  # simcred's, not a user's folder
    if manifest is not None:
        (checkpoints / "job.json").write_text(manifest)
    return root


def _deep_json(r: Path) -> Path:
    return _text(r / "deep.json", "[" * 100_000 + "]" * 100_000)


def _file_cases() -> list[tuple[str, Builder]]:
    """Broken measurement directories, descriptions, A9 files and report directories."""
    def measurement_without(r: Path, v: dict, name: str) -> Path:
        import shutil

        copy = r / "m"
        shutil.copytree(v["measurement"], copy)
        (copy / name).unlink()
        return copy

    def a9(r: Path, v: dict, edit: Callable[[str], str]) -> Path:
        return _text(r / "a9.csv", edit(v["a9"].read_text()))

    def lat95(text: str) -> str:
        lines = text.splitlines()
        header = lines[0].split(",")
        row = lines[2].split(",")
        row[header.index("lat")] = "95"
        return "\n".join([lines[0], lines[1], ",".join(row), *lines[3:]]) + "\n"

    cases: list[tuple[str, Builder]] = []
    for name in ("sd.parquet", "measurement.json"):  # without gt.parquet: SD-only, valid
        cases.append((f"reprocess measurement without {name}", lambda r, v, n=name: [
            "reprocess", str(measurement_without(r, v, n)), "--out", str(r / "rp")]))
    for label, edit in [("lat 95", lat95), ("empty", lambda t: ""),
                        ("header only", lambda t: t.splitlines()[0] + "\n"),
                        ("speed text", lambda t: t.replace(",", ",x", 1)),
                        ("binary", lambda t: "\x00\x01" * 100)]:
        cases.append((f"reprocess A9 {label}", lambda r, v, e=edit: [
            "reprocess", str(a9(r, v, e)), "--out", str(r / "rp")]))
    for label, text in [("not json", "{"), ("empty object", "{}"), ("list", "[1,2]"),
                        ("deep", None)]:
        cases.append((f"vary description {label}", lambda r, v, t=text: [
            "vary", str(_deep_json(r) if t is None else _text(r / "d.json", t)), "--out",
            str(r / "v")]))
    for label, text in [("not json", "{"), ("deep", None), ("wrong kind", json.dumps({"a": 1}))]:
        cases.append((f"report claims {label}", lambda r, v, t=text: [
            "report", str(_report_dir(r, t))]))
    cases.append(("report missing directory", lambda r, v: ["report", str(r / "nothing")]))
    return cases


def _report_dir(root: Path, text: str | None) -> Path:
    directory = root / "paper"
    directory.mkdir()
    (directory / "claims.json").write_text("[" * 100_000 + "]" * 100_000 if text is None else text)
    return directory


CASES = _cases()
