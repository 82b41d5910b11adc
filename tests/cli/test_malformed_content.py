"""Malformed content that used to end as "internal error" (exit 70): one line, exit 2, nothing
written (issue 29)."""

from __future__ import annotations

from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

import simcred.data
from simcred.cli import run

COMMONROAD = Path(__file__).parents[1] / "data" / "commonroad-ngsim" / "USA_Lanker-1_1_T-1.xml"


def _parquet(path: Path, columns: dict, metadata: bytes | None = None) -> Path:
    table = pa.table(columns)
    if metadata is not None:
        table = table.replace_schema_metadata({b"simcred": metadata})
    pq.write_table(table, path)
    return path


def _a9_off_the_globe(tmp_path: Path) -> Path:
    lines = simcred.data.path("a9/trajectories_file.csv").read_text().splitlines()
    first = lines[1].split(",")
    first[1] = "95"
    path = tmp_path / "a9.csv"
    path.write_text("\n".join([lines[0], ",".join(first), *lines[2:]]) + "\n")
    return path


def _commonroad_time_reversed(tmp_path: Path) -> Path:
    path = tmp_path / "scenario.xml"
    path.write_text(COMMONROAD.read_text().replace('timeStepSize="0.1"', 'timeStepSize="-0.1"'))
    return path


def _xml_unknown_encoding(tmp_path: Path) -> Path:
    path = tmp_path / "fcd.xml"
    path.write_text('<?xml version="1.0" encoding="klingon"?>\n<fcd-export></fcd-export>\n')
    return path


RUNS = {"run": ["a", "a", "b", "b"], "t": [0.0, 1.0, 0.0, 1.0]}
CASES = {
    "Parquet metadata a JSON list": (
        lambda p: ["convert", str(_parquet(p / "m.parquet", {**RUNS, "x": [1.0] * 4}, b"[1]")),
                   str(p / "out.csv")], "metadata must be a JSON object"),
    "a 300-character run id to a CSV directory": (
        lambda p: ["convert", str(_parquet(p / "r.parquet", {"run": ["r" * 300] * 2,
                                                             "t": [0.0, 1.0], "x": [1.0] * 2})),
                   str(p / "out")], "longer than a file name"),
    "a comma, quote and newline in a signal name to a CSV directory": (
        lambda p: ["convert", str(_parquet(p / "s.parquet", {**RUNS, 'x,"y\nz': [1.0] * 4})),
                   str(p / "out")], "cannot be a CSV header cell"),
    "the same to a long CSV": (
        lambda p: ["convert", str(_parquet(p / "s.parquet", {**RUNS, 'x,"y': [1.0] * 4})),
                   str(p / "out.csv")], "cannot be a CSV header cell"),
    "an XML file of an unknown encoding": (
        lambda p: ["convert", str(_xml_unknown_encoding(p)), str(p / "out.parquet")],
        "unknown encoding"),
    "CommonRoad timeStepSize < 0": (
        lambda p: ["convert", str(_commonroad_time_reversed(p)), str(p / "out.parquet")],
        "timeStepSize must be a positive"),
    "simulate --seed -1": (
        lambda p: ["simulate", "simplecar", "--runs", "2", "--seed", "-1", "--out",
                   str(p / "out")], "--seed"),
    "example --seed -1": (
        lambda p: ["example", "--runs", "2", "--seed", "-1", "--out", str(p / "out")], "--seed"),
}


@pytest.mark.parametrize("name", CASES)
def test_malformed_content_is_one_line_exit_2(name, tmp_path, capsys):
    make, expected = CASES[name]
    args = make(tmp_path)
    before = sorted(p.name for p in tmp_path.iterdir())
    assert run(["-q", *args]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and expected in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_an_a9_fix_off_the_globe_is_one_line(tmp_path):
    from simcred.errors import TraceSetError
    from simcred.io.a9 import read_a9

    with pytest.raises(TraceSetError, match=r"column 'lat', row 1: 95 is outside \[-90, 90\]"):
        read_a9(_a9_off_the_globe(tmp_path))
