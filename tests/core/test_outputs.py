"""Atomic outputs: inputs are never overwritten, outputs exist complete or not at all."""

from __future__ import annotations

from pathlib import Path

import pytest

from simcred.errors import OptionError
from simcred.outputs import (
    MARKER,
    MARKER_TEXT,
    Checkpoint,
    check_out,
    output_dir,
    partial_path,
    write_atomic,
)


def listing(folder: Path) -> list[str]:
    """The files of ``folder`` besides simcred's marker."""
    names = sorted(p.name for p in folder.iterdir())
    assert MARKER in names
    return [n for n in names if n != MARKER]


@pytest.fixture()
def runs(tmp_path):
    directory = tmp_path / "runs"
    directory.mkdir()
    (directory / "run_0.csv").write_text("t,x\n0,1\n")
    return directory


@pytest.mark.parametrize("relative", ["runs", "runs/run_0.csv", "runs/sub/out", "."])
def test_out_may_not_be_contain_or_lie_inside_an_input(tmp_path, runs, relative):
    with pytest.raises(OptionError, match="would overwrite the input"):
        check_out(tmp_path / relative, [runs])
    assert (runs / "run_0.csv").read_text() == "t,x\n0,1\n"


def test_existing_nonempty_output_needs_overwrite(tmp_path):
    out = tmp_path / "out"
    with output_dir(out) as partial:
        (partial / "old.json").write_text("{}")
    with pytest.raises(OptionError, match="--overwrite"), output_dir(out):
        pass
    with output_dir(out, overwrite=True) as partial:
        (partial / "new.json").write_text("[]")
    assert listing(out) == ["new.json"]  # replaced, never merged


def test_overwrite_replaces_only_a_folder_simcred_wrote(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "old.json").write_text("{}")
    with pytest.raises(OptionError, match="not written by simcred"), \
            output_dir(out, overwrite=True):
        pass
    assert sorted(p.name for p in out.iterdir()) == ["old.json"]
    assert not partial_path(out).exists()


def test_existing_file_is_not_a_directory(tmp_path):
    (tmp_path / "f").write_text("x")
    with pytest.raises(OptionError, match="not a directory"):
        check_out(tmp_path / "f", overwrite=True)
    with pytest.raises(OptionError, match="not a directory"):
        check_out(tmp_path / "f" / "out")


def test_output_appears_only_when_complete(tmp_path):
    out = tmp_path / "a" / "b" / "out"
    with output_dir(out) as partial:
        (partial / "x.json").write_text("1")
        assert not out.exists() and partial == partial_path(out)
    assert (out / "x.json").read_text() == "1" and not partial_path(out).exists()


@pytest.mark.parametrize("error", [RuntimeError, KeyboardInterrupt])
def test_failure_leaves_nothing_unless_resumable(tmp_path, error):
    out = tmp_path / "out"
    with pytest.raises(error), output_dir(out) as partial:
        (partial / "half.json").write_text("{")
        raise error()
    assert not out.exists() and not partial_path(out).exists()
    with pytest.raises(error), output_dir(out, keep_partial=True) as partial:
        Checkpoint(partial).save("chunk_0", b"done")
        raise error()
    assert not out.exists() and (partial_path(out) / "checkpoints" / "chunk_0").exists()


def test_resume_continues_the_partial_run(tmp_path):
    out = tmp_path / "out"
    with pytest.raises(KeyboardInterrupt), output_dir(out, keep_partial=True) as partial:
        Checkpoint(partial).save("chunk_0", b"zero")
        raise KeyboardInterrupt
    with pytest.raises(OptionError, match="--resume"), output_dir(out, keep_partial=True):
        pass
    with output_dir(out, resume=True, keep_partial=True) as partial:
        checkpoint = Checkpoint(partial)
        assert "chunk_0" in checkpoint and "chunk_1" not in checkpoint
        assert checkpoint.load("chunk_0") == b"zero" and checkpoint.keys() == ["chunk_0"]
        (partial / "result.json").write_text("{}")
    assert listing(out) == ["result.json"]  # checkpoints dropped


@pytest.mark.parametrize("marker", [None, b"", MARKER_TEXT[:7], MARKER_TEXT],
                         ids=["empty", "empty marker", "half marker", "marker"])
def test_a_staging_folder_left_by_a_kill_is_removed(tmp_path, marker):
    """A kill between creating ``OUT.partial``'s staging folder and renaming it leaves that
    folder beside the output (seen in CI in a validation's candidate simulation); the next run
    removes it, and nothing that holds anything else."""
    out = tmp_path / "out"
    debris = tmp_path / ".out.partial-x1y2"
    debris.mkdir()
    if marker is not None:
        (debris / MARKER).write_bytes(marker)
    other = tmp_path / ".out.partial-keep"
    other.mkdir()
    (other / "data.csv").write_text("t\n")
    with output_dir(out) as partial:
        (partial / "f").write_text("x")
    assert sorted(p.name for p in tmp_path.iterdir()) == [".out.partial-keep", "out"]


def test_a_resumed_run_drops_temporaries_of_interrupted_writes(tmp_path):
    """A kill inside :func:`write_atomic` leaves its temporary file; a resumed run removes it
    (else the output would differ from an uninterrupted run's) and keeps everything else."""
    out = tmp_path / "out"
    with pytest.raises(KeyboardInterrupt), output_dir(out, keep_partial=True) as partial:
        Checkpoint(partial).save("chunk_0", b"zero")
        (partial / "sub").mkdir()
        for name in (".result.json.ab_3x9zq.tmp", "sub/.f.csv.12345678.tmp", "keep.tmp"):
            (partial / name).write_text("half")
        raise KeyboardInterrupt
    with output_dir(out, resume=True, keep_partial=True) as partial:
        assert Checkpoint(partial).keys() == ["chunk_0"]
    assert sorted(p.relative_to(out).as_posix() for p in out.rglob("*") if p.name != MARKER) == [
        "keep.tmp", "sub"]


def test_write_atomic_leaves_no_temporary_on_failure(tmp_path):
    path = write_atomic(tmp_path / "d" / "f.json", "abc")
    assert path.read_text() == "abc"

    with pytest.raises(TypeError):
        write_atomic(tmp_path / "d" / "g.json", 3)  # type: ignore[arg-type]
    assert sorted(p.name for p in (tmp_path / "d").iterdir()) == ["f.json"]


@pytest.mark.parametrize("key", ["", "../x", "a/b", ".hidden"])
def test_checkpoint_keys_are_plain_names(tmp_path, key):
    with pytest.raises(ValueError, match="plain file name"):
        Checkpoint(tmp_path).save(key, b"")


def test_a_partial_output_being_written_is_refused(tmp_path):
    """Two commands writing one output: the second stops with one line, the first goes on."""
    out = tmp_path / "out"
    with output_dir(out, keep_partial=True) as partial:
        (partial / "a.json").write_text("1")
        for options in ({"resume": True}, {"overwrite": True}, {}):
            with pytest.raises(OptionError, match="being written by another"), \
                    output_dir(out, **options):
                pass
        assert (partial / "a.json").read_text() == "1"
    assert (out / "a.json").read_text() == "1"


def test_overwrite_never_replaces_the_working_or_home_directory(tmp_path, monkeypatch):
    work = tmp_path / "work"
    (work / "sub").mkdir(parents=True)
    (work / "sub" / "data.csv").write_text("t,x\n")
    monkeypatch.chdir(work / "sub")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    (tmp_path / "home").mkdir()
    (tmp_path / "home" / "notes").write_text("mine")
    for out in (Path("."), work, tmp_path / "home"):
        with pytest.raises(OptionError, match="--overwrite would delete it"):
            check_out(out, overwrite=True)
    assert (work / "sub" / "data.csv").exists() and (tmp_path / "home" / "notes").exists()
