"""Environment faults are errors, not defects: a full or read-only disk, a missing permission, a
name too long, too little memory, special files and undecodable names. Every case: one line
naming the path, exit code 74 (2 for a name or a special file, which are bad input), never 70,
nothing partial left (no ``OUT.partial``, no new ``OUT``) and an earlier output unchanged
(issue 29). Each case should take well under 10 s; that is measured (``pytest --durations=0``,
docs/reliability.md), not asserted: a subprocess gets 60 s, so only a hang fails."""

from __future__ import annotations

import errno
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import pytest

import simcred
from simcred.cli import run as run_cli
from simcred.cli._environment import EXIT_ENVIRONMENT
from simcred.outputs import partial_path

EXAMPLE = ["-q", "example", "--runs", "3", "--steps", "5"]
SRC = str(Path(simcred.__file__).resolve().parents[1])
#: Per case, the seconds of its slowest simcred command (the one that meets the fault, or the
#: one preparing an input): reported at the end of the module (``-s``), never asserted.
SECONDS: dict[str, float] = {}
CURRENT = {"case": "?"}


@pytest.fixture(autouse=True)
def _case(request):
    CURRENT["case"] = request.node.name


@pytest.fixture(autouse=True, scope="module")
def _report_durations():
    yield
    if SECONDS:
        cases = sorted(SECONDS.items(), key=lambda item: item[1])
        print(f"\nfault cases: {len(cases)}, slowest simcred command per case: median "
              f"{statistics.median(SECONDS.values()):.2f} s, maximum {cases[-1][1]:.2f} s "
              f"({cases[-1][0]}); over 10 s: {[n for n, t in cases if t > 10] or 'none'}")


def _timed(command, *args, **kwargs):
    started = time.perf_counter()
    try:
        return command(*args, **kwargs)
    finally:
        name = CURRENT["case"]
        SECONDS[name] = max(SECONDS.get(name, 0.0), time.perf_counter() - started)


def run(argv: list[str]) -> int:
    """:func:`simcred.cli.run` in this process, timed for the report."""
    return _timed(run_cli, argv)


def simcred_cli(*args: str, limit_mb: int | None = None,
                timeout: float = 60) -> subprocess.CompletedProcess:
    """``simcred ARGS`` in a fresh interpreter (optionally under ``ulimit -v``); a hang (60 s,
    generous on a loaded machine: the duration is measured, not asserted) is a failure."""
    prelude = "" if limit_mb is None else (
        f"import resource; resource.setrlimit(resource.RLIMIT_AS, ({limit_mb << 20},) * 2); ")
    code = prelude + "import sys; from simcred.cli import run; sys.exit(run(sys.argv[1:]))"
    env = {**os.environ, "PYTHONPATH": SRC, "OPENBLAS_NUM_THREADS": "1"}
    return _timed(subprocess.run, [sys.executable, "-c", code, *args], capture_output=True,
                  timeout=timeout, env=env)


def tree(root: Path) -> dict[str, bytes]:
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file()}


def listing(root: Path) -> list[str]:
    """Every path under ``root`` (files, folders, special files), by relative name: equal
    before and after a refused command when it left nothing behind (no OUT, no OUT.partial)."""
    return sorted(p.relative_to(root).as_posix() for p in root.rglob("*"))


def one_line(done: subprocess.CompletedProcess, code: int) -> str:
    """The one stderr line of a command that ended with ``code`` (never 70)."""
    err = done.stderr.decode().strip()
    assert done.returncode == code, err
    assert len(err.splitlines()) == 1 and "internal error" not in err, err
    return err


FAULTS = [errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EPERM, errno.EFBIG,
          errno.EIO]


@pytest.mark.parametrize("code", FAULTS, ids=[errno.errorcode[c] for c in FAULTS])
@pytest.mark.parametrize("form", ["--no-parquet", "--parquet"], ids=["csv-dirs", "parquet"])
def test_a_writer_fault_is_one_line_exit_74_and_leaves_the_old_output(code, form, tmp_path,
                                                                     monkeypatch, capsys):
    """The system refuses a write: the old output stays, nothing partial is left."""
    out = tmp_path / "out"
    assert run([*EXAMPLE, form, "--out", str(out)]) == 0
    before = tree(tmp_path)
    import pyarrow.csv as pacsv
    import pyarrow.parquet as pq

    def refusing(table, where, *args, **kwargs):  # the CSV and Parquet writers' last step
        raise OSError(code, os.strerror(code), str(where))

    monkeypatch.setattr(pacsv, "write_csv", refusing)
    monkeypatch.setattr(pq, "write_table", refusing)
    capsys.readouterr()
    assert run([*EXAMPLE, form, "--seed", "9", "--out", str(out), "--overwrite"]) == \
        EXIT_ENVIRONMENT
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(partial_path(out)) in err, err
    assert "internal error" not in err
    assert tree(tmp_path) == before and not partial_path(out).exists()


def test_a_name_too_long_is_one_line_exit_74(tmp_path, capsys):
    out = tmp_path / ("x" * 300)
    assert run([*EXAMPLE, "--out", str(out)]) == EXIT_ENVIRONMENT
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "too long" in err and "x" * 300 in err
    assert list(tmp_path.iterdir()) == []


def test_out_of_memory_under_ulimit_is_one_line_exit_74(tmp_path):
    """90,000 runs of 1,000 steps need more than 1.5 GB of address space."""
    done = simcred_cli("-q", "example", "--runs", "90000", "--steps", "1000", "--out",
                       str(tmp_path / "big.parquet"), limit_mb=1500)
    assert "out of memory" in one_line(done, EXIT_ENVIRONMENT)
    assert list(tmp_path.iterdir()) == []


@pytest.fixture
def fifo(tmp_path) -> Path:
    path = tmp_path / "runs.csv"
    os.mkfifo(path)
    return path


def _set(tmp_path: Path) -> Path:
    out = tmp_path / "b.parquet"
    assert run(["-q", "simulate", "simplecar", "--runs", "4", "--duration", "8", "--out",
                str(out)]) == 0
    return out


@pytest.mark.parametrize("command", [
    lambda s, b, o: ["compare", s, b, "-f", "y", "--out", o],
    lambda s, b, o: ["convert", s, o + ".parquet"],
    lambda s, b, o: ["validate", s, "--out", o],
    lambda s, b, o: ["contracts", "check", s],
    lambda s, b, o: ["vary", s, "--out", o],
    lambda s, b, o: ["reprocess", s, "--out", o],
    lambda s, b, o: ["monitor", s, b],
], ids=["compare", "convert", "validate", "contracts", "vary", "reprocess", "monitor"])
@pytest.mark.parametrize("special", ["fifo", "/dev/zero", "/dev/null"])
def test_special_files_are_refused_in_one_line(command, special, tmp_path, request):
    source = str(request.getfixturevalue("fifo")) if special == "fifo" else special
    other = str(_set(tmp_path))
    before = listing(tmp_path)
    err = one_line(simcred_cli(*command(source, other, str(tmp_path / "out"))), 2)
    assert "not a regular file" in err and source in err
    assert listing(tmp_path) == before


def test_a_fifo_named_inside_a_validation_file_is_refused(fifo, tmp_path, capsys):
    from tests.validate.conftest import write_universe

    folder = tmp_path / "project"
    folder.mkdir()
    path = write_universe(folder, runs=10, steps=20, reference={"path": str(fifo)})
    before = listing(tmp_path)
    assert "FIFO" in one_line(simcred_cli("validate", str(path), "--out",
                                          str(tmp_path / "out")), 2)
    assert listing(tmp_path) == before


def test_an_undecodable_argument_is_refused_in_one_line(tmp_path, capsys):
    name = os.fsdecode(b"out-\xff")
    assert run([*EXAMPLE, "--out", str(tmp_path / name)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "not valid UTF-8" in err
    assert list(tmp_path.iterdir()) == []


def test_an_undecodable_run_name_is_refused_or_carried(tmp_path, capsys):
    """A CSV run file whose name is not UTF-8: one line, exit 2, in every writer."""
    runs = tmp_path / "runs"
    runs.mkdir()
    (runs / os.fsdecode(b"run_\xff.csv")).write_text("t,x\n0,1\n1,2\n")
    (runs / "run_b.csv").write_text("t,x\n0,1\n1,3\n")
    before = listing(tmp_path)
    for target in ("c.parquet", "c.csv", "cdir"):
        code = run(["-q", "convert", str(runs), str(tmp_path / target)])
        err = capsys.readouterr().err.strip()
        assert code == 2 and len(err.splitlines()) == 1 and "UTF-8" in err, err
        assert listing(tmp_path) == before


@pytest.mark.parametrize("option", [["--baseline", "100000000000"],
                                    ["--bootstrap", "100000000000"],
                                    ["--history", "100000000000"],
                                    ["--resample", "1e-7"],
                                    ["--permutations", "100000000000"]])
def test_work_that_grows_with_an_option_is_bounded_before_it_starts(option, tmp_path):
    b = str(_set(tmp_path))
    before = listing(tmp_path)
    out = str(tmp_path / "out")
    assert "limit" in one_line(simcred_cli("compare", b, b, "-f", "y", "--bins", "3", *option,
                                           "--out", out), 2)
    assert listing(tmp_path) == before


def test_a_fifo_traceset_json_inside_a_csv_directory_is_refused(tmp_path):
    runs = tmp_path / "runs"
    runs.mkdir()
    (runs / "run_0.csv").write_text("t,x\n0,1\n1,2\n")
    os.mkfifo(runs / "traceset.json")
    before = listing(tmp_path)
    err = one_line(simcred_cli("convert", str(runs), str(tmp_path / "out.parquet")), 2)
    assert "traceset.json: not a regular file" in err
    assert listing(tmp_path) == before


@pytest.fixture
def small_disk(tmp_path):
    """A 1 MB tmpfs (needs the right to mount; skipped without it)."""
    folder = tmp_path / "small"
    folder.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(folder)],
                             capture_output=True)
    if mounted.returncode != 0:
        pytest.skip("cannot mount a tmpfs here")
    try:
        yield folder
    finally:
        subprocess.run(["umount", str(folder)], check=True)


def test_a_real_full_disk_keeps_the_old_output_and_says_what_was_kept(small_disk, capsys):
    out = small_disk / "out"
    assert run([*EXAMPLE, "--parquet", "--out", str(out)]) == 0
    before = tree(small_disk)
    for args in ([*EXAMPLE[:2], "--runs", "300", "--steps", "100", "--parquet", "--out",
                  str(out), "--overwrite"],
                 [*EXAMPLE[:2], "--runs", "300", "--steps", "100", "--out", str(out),
                  "--overwrite"]):
        capsys.readouterr()
        assert run(args) == EXIT_ENVIRONMENT
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and f"{out}: no space left" in err, err
        assert tree(small_disk) == before and not partial_path(out).exists()
    # a resumable command keeps its finished chunks and says so
    target = small_disk / "t.parquet"
    assert run(["-q", "simulate", "tjunction", "--runs", "50", "--out", str(target)]) == \
        EXIT_ENVIRONMENT
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "kept in" in err and "--resume" in err, err
    assert not target.exists() and partial_path(target).is_dir()


def test_a_read_only_file_system_is_one_line_exit_74(small_disk, capsys):
    subprocess.run(["mount", "-o", "remount,ro", str(small_disk)], check=True)
    assert run([*EXAMPLE, "--out", str(small_disk / "out")]) == EXIT_ENVIRONMENT
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "read-only" in err and str(small_disk) in err, err
    assert list(small_disk.iterdir()) == []
