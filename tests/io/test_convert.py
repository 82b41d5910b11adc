"""simcred.io.read/write façade and `simcred convert`: dispatch, provenance, never overwriting."""

from __future__ import annotations

import json

import pytest

from simcred.cli import run
from simcred.io import FORMATS, detect, read, write
from simcred.traces import TraceSet

TRACES = TraceSet.from_runs(
    [{"t": [0.0, 0.1, 0.2], "ego.x": [0, 1, 2.5], "ego.v": [10, 10, 10.5], "lead.x": [20, 21, 22]},
     {"t": [0.0, 0.1], "ego.x": [3, 4], "ego.v": [9, 9.5], "lead.x": [30, 31]}],
    run_ids=["r1", "r2"], metadata={"model": "test"})


def test_detection_by_suffix_and_options(tmp_path):
    d = TRACES.write(tmp_path / "dir")
    assert detect(d).name == "csv-dir"
    p = TRACES.write(tmp_path / "set.parquet")
    assert detect(p).name == "parquet"
    assert detect(p, options={"run_column": "run"}).name == "long"
    assert detect(tmp_path / "new.csv", for_writing=True).name == "long"
    assert detect(tmp_path / "new.mcap", for_writing=True).name == "osi"
    assert detect(tmp_path / "new.d", for_writing=True).name == "csv-dir"
    assert {f.name for f in FORMATS.values() if f.writable} == {"csv-dir", "parquet", "long",
                                                                 "osi"}


@pytest.mark.parametrize("target", ["dir", "set.parquet", "long.csv", "long.parquet"])
def test_every_tabular_format_round_trips_through_the_facade(tmp_path, target):
    options = {"object_column": "obj"} if target.startswith("long") else {}
    path = write(TRACES, tmp_path / target, **options)
    back = TraceSet.read(path, **({"run_column": "run", **options} if options else {}))
    assert back.run_ids == TRACES.run_ids
    assert back.features(TRACES.signals).tolist() == TRACES.values.tolist()
    assert back.time.tolist() == TRACES.time.tolist()


def test_unknown_format_and_suffix(tmp_path):
    (tmp_path / "x.txt").write_text("t,x\n")
    with pytest.raises(ValueError, match="not a trace set"):
        read(tmp_path / "x.txt")
    with pytest.raises(ValueError, match="unknown format 'excel'"):
        read(tmp_path / "x.txt", format="excel")
    with pytest.raises(ValueError, match="can be read but not written"):
        write(TRACES, tmp_path / "x.xml")


def test_convert_cli_writes_output_with_provenance(tmp_path, capsys):
    src = write(TRACES, tmp_path / "in.csv", object_column="obj")
    out = tmp_path / "out.parquet"
    code = run(["convert", str(src), str(out), "--run-column", "run", "--object-column", "obj",
                "--format", "parquet", "--json"])
    assert code == 0
    report = json.loads(capsys.readouterr().out)
    assert report["kind"] == "conversion" and report["source_format"] == "long"
    assert report["target_format"] == "parquet" and report["runs"] == 2 and report["rows"] == 5
    assert report["source_sha256"].startswith("sha256:")
    back = read(out)
    assert back.features(TRACES.signals).tolist() == TRACES.values.tolist()
    provenance = back.metadata["converted_from"]
    assert provenance["sha256"] == report["source_sha256"]
    assert provenance["options"] == {"run_column": "run", "object_column": "obj"}


@pytest.mark.parametrize(("args", "expected"), [
    (["IN", "IN"], "overwrite the input"),
    (["IN", "EXISTING"], "--overwrite"),
    (["IN", "out.parquet", "--layout", "scenario"], "applies neither"),
    (["IN", "out.parquet", "--format", "sumo-fcd"], "can be read but not written"),
    (["missing.csv", "out.parquet"], "no such file"),
    (["IN", "out.parquet", "--missing", "maybe"], "missing must be one of"),
])
def test_convert_errors_are_one_line_exit_2(tmp_path, capsys, args, expected):
    src = TRACES.write(tmp_path / "in.parquet")
    existing = TRACES.write(tmp_path / "existing.parquet")
    before = src.read_bytes()
    names = {"IN": str(src), "EXISTING": str(existing)}
    argv = ["convert", *[names.get(a, str(tmp_path / a) if a.endswith((".csv", ".parquet"))
                                   else a) for a in args]]
    assert run(argv) == 2
    err = capsys.readouterr().err.strip()
    assert expected in err and len(err.splitlines()) == 1
    assert src.read_bytes() == before


def test_convert_refuses_a_directory_output_inside_the_input(tmp_path, capsys):
    src = TRACES.write(tmp_path / "dir")
    assert run(["convert", str(src), str(src / "nested")]) == 2
    assert "overwrite the input" in capsys.readouterr().err
    assert run(["convert", str(src / "r1.csv"), str(src.parent)]) == 2


def test_reader_options_do_not_change_the_output_format(tmp_path):
    # --objects-as is the reader's: a .parquet output stays the native Parquet format
    same_fields = TraceSet.from_runs([{"t": [0, 1], "ego.x": [0, 1], "lead.x": [5, 7]}],
                                     run_ids=["r1"])
    src = write(same_fields, tmp_path / "in.csv", object_column="obj")
    out = tmp_path / "out.parquet"
    assert run(["--quiet", "convert", str(src), str(out), "--object-column", "obj",
                "--run-column", "run", "--objects-as", "runs"]) == 0
    back = read(out)
    assert back.run_ids == ("r1.ego", "r1.lead") and back.signals == ("x",)
    assert back.column("x").tolist() == [0, 1, 5, 7]
    assert detect(out, for_writing=True, options={"objects_as": "runs"}).name == "parquet"


def test_convert_real_commonroad_to_long_csv_and_back(tmp_path):
    from pathlib import Path

    scenario = Path(__file__).parent.parent / "data" / "commonroad-ngsim" / "USA_US101-3_3_T-1.xml"
    out = tmp_path / "us101.csv"
    assert run(["--quiet", "convert", str(scenario), str(out)]) == 0
    back = read(out, run_column="run")
    original = read(scenario)
    assert back.run_ids == original.run_ids
    assert back.values.tobytes() == original.values.tobytes()
    assert back.time.tobytes() == original.time.tobytes()
