"""The CLI: results on disk, byte-identical JSON, and one-line errors with exit code 2."""

import json

import numpy as np
import pytest

from simcred.cli import run
from simcred.examples import lane_change_sets
from simcred.traces import TraceSet


@pytest.fixture(scope="module")
def sets(tmp_path_factory):
    root = tmp_path_factory.mktemp("sets")
    a, b = lane_change_sets(runs=80, steps=40, seed=3)
    return a.write(root / "a"), b.write(root / "b.parquet")


def test_compare_writes_json_and_map(sets, tmp_path, capsys):
    a, b = sets
    code = run(["--quiet", "compare", str(a), str(b), "--features", "y,heading", "--bins", "6",
                "--test", "permutation", "--permutations", "99", "--seed", "4",
                "--out", str(tmp_path)])
    assert code == 0
    doc = json.loads((tmp_path / "comparison.json").read_text())
    for key in ("schema_version", "options", "edges", "n_states", "start", "states",
                "untestable", "distance"):
        assert key in doc
    assert set(doc["start"]) >= {"m", "n", "statistic", "threshold", "pvalue", "rejected"}
    assert doc["n_states"] == np.prod([len(e) + 1 for e in doc["edges"]])
    rejected = sum(s["rejected"] for s in doc["states"])
    assert doc["distance"] == rejected / doc["n_states"]
    assert (tmp_path / "state_map.png").stat().st_size > 10_000


def test_same_seed_gives_byte_identical_json(sets, tmp_path, capsys):
    a, b = sets
    outputs = []
    for name in ("one", "two"):
        args = ["--quiet", "compare", str(a), str(b), "-f", "y,heading", "--test",
                "permutation", "--permutations", "49", "--seed", "11", "--out",
                str(tmp_path / name)]
        assert run(args) == 0
        outputs.append((tmp_path / name / "comparison.json").read_bytes())
    assert outputs[0] == outputs[1]
    assert run(["compare", str(a), str(b), "-f", "y,heading", "--test", "permutation",
                "--permutations", "49", "--seed", "11", "--json"]) == 0
    assert capsys.readouterr().out.encode() == outputs[0]


def test_matrix_writes_table_and_heatmap(sets, tmp_path):
    a, b = sets
    assert run(["--quiet", "matrix", str(a), str(b), str(a), "--names", "a,b,a2", "-f", "y",
                "--bins", "5", "--out", str(tmp_path)]) == 0
    doc = json.loads((tmp_path / "matrix.json").read_text())
    d = np.array(doc["distances"], dtype=float)
    assert d.shape == (3, 3) and np.allclose(d, d.T) and d[0, 2] == 0
    assert (tmp_path / "matrix.csv").read_text().splitlines()[0] == ",a,b,a2"
    assert (tmp_path / "matrix.png").exists()


def _write_csv(directory, name, text):
    directory.mkdir(exist_ok=True)
    (directory / name).write_text(text)
    return directory


BAD_CSV = {
    "nan": ("t,x,y\n0,1,2\n1,nan,2\n", "column 'x', row 2"),
    "inf": ("t,x,y\n0,1,2\n1,2,inf\n", "column 'y', row 2"),
    "time": ("t,x,y\n0,1,2\n0,1,2\n", "not strictly increasing"),
    "no_time": ("x,y\n0,1\n1,2\n", "no column 't'"),
    "short": ("t,x,y\n0,1,2\n", "1 step"),
    "ragged": ("t,x,y\n0,1,2\n1,2\n", "unreadable CSV"),
    "text": ("t,x,y\n0,1,a\n1,2,b\n", "not numeric"),
}


@pytest.mark.parametrize("case", sorted(BAD_CSV))
def test_bad_csv_is_one_line_exit_2(case, sets, tmp_path, capsys):
    text, expected = BAD_CSV[case]
    bad = _write_csv(tmp_path / "bad", "run_1.csv", text)
    code = run(["compare", str(sets[0]), str(bad), "-f", "x,y"])
    err = capsys.readouterr().err
    assert code == 2
    assert expected in err and "run_1.csv" in err
    assert err.count("\n") == 1 and "Traceback" not in err


@pytest.mark.parametrize(
    ("args", "expected"),
    [
        (["-f", "x,nope"], "unknown signal 'nope'"),
        (["--bins", "1"], "--bins must be at least 2"),
        (["--alpha", "0"], "--alpha must be in [1e-15, 1)"),
        (["--alpha", "1.5"], "--alpha must be in [1e-15, 1)"),
        (["--permutations", "0", "--test", "permutation"], "--permutations must be at least 1"),
        (["--kernel", "cosine"], "--kernel"),
        (["--bins", "ten"], "--bins must be an integer"),
    ],
)
def test_bad_options_are_one_line_exit_2(args, expected, sets, capsys):
    code = run(["compare", str(sets[0]), str(sets[1]), *args])
    err = capsys.readouterr().err
    assert code == 2
    assert expected in err
    assert err.count("\n") == 1


def test_different_signal_names_need_features(sets, tmp_path, capsys):
    other = TraceSet.from_runs([{"t": [0, 1], "x": [0, 1], "z": [1, 2]}]).write(tmp_path / "o")
    assert run(["compare", str(sets[0]), str(other)]) == 2
    assert "different signal names" in capsys.readouterr().err
    assert run(["compare", str(sets[0]), str(other), "-f", "x,y"]) == 2
    assert "unknown signal 'y'" in capsys.readouterr().err


def test_empty_and_unreadable_sets(sets, tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    assert run(["compare", str(sets[0]), str(tmp_path / "empty")]) == 2
    assert "empty" in capsys.readouterr().err
    (tmp_path / "junk.parquet").write_bytes(b"not parquet at all")
    assert run(["compare", str(sets[0]), str(tmp_path / "junk.parquet")]) == 2
    assert "unreadable Parquet" in capsys.readouterr().err
    assert run(["compare", str(sets[0]), str(tmp_path / "missing")]) == 2
    assert "no such file" in capsys.readouterr().err


def test_example_command_writes_both_sets(tmp_path):
    assert run(["--quiet", "example", "--out", str(tmp_path), "--runs", "5", "--steps", "7"]) == 0
    assert TraceSet.read(tmp_path / "baseline").n_runs == 5
    assert TraceSet.read(tmp_path / "variant").n_rows == 35
