"""A job killed between renaming its file output into place (``OUT.partial/<name>`` -> ``OUT``)
and removing ``OUT.partial`` leaves a complete ``OUT`` beside a stale ``OUT.partial``. The next
run, plain, ``--resume`` or ``--overwrite``, recognises it (simcred's marker, and a record of the
very file now at ``OUT``) and removes it; a partial output that is not provably done is never
removed so (issue 29; simcred.outputs._drop_moved).

The state is made deterministically: the writer's removal of ``OUT.partial`` is replaced by a
"kill" (an exception no handler catches) right after the rename."""

from __future__ import annotations

import shutil
import types
from pathlib import Path

import pytest

import simcred.outputs as outputs
from simcred.cli import run
from simcred.outputs import MARKER, MOVED, partial_path

ARGS = ["simulate", "tjunction", "--runs", "4", "--chunk-size", "2", "--seed", "1"]


class Killed(BaseException):
    """The process dying: nothing in simcred handles it."""


def _command(out: Path, *extra: str) -> list[str]:
    return ["-q", *ARGS, "--out", str(out), *extra]


def _killed_after_the_rename(out: Path, monkeypatch) -> None:
    """Run the command into ``out`` and die right after its file was renamed to ``out``."""
    def rmtree(path, *args, **kwargs):
        if Path(path) == partial_path(out):
            raise Killed
        return shutil.rmtree(path, *args, **kwargs)

    with monkeypatch.context() as patch:
        patch.setattr(outputs, "shutil", types.SimpleNamespace(rmtree=rmtree))
        with pytest.raises(Killed):
            run(_command(out))


@pytest.fixture
def stale(tmp_path, monkeypatch) -> tuple[Path, bytes]:
    """``out.parquet`` complete and its stale ``out.parquet.partial``; the bytes of an
    uninterrupted run."""
    assert run(_command(tmp_path / "whole.parquet")) == 0
    out = tmp_path / "out.parquet"
    _killed_after_the_rename(out, monkeypatch)
    partial = partial_path(out)
    assert out.is_file() and (partial / MARKER).is_file() and (partial / MOVED).is_file()
    assert not (partial / out.name).exists()
    return out, (tmp_path / "whole.parquet").read_bytes()


@pytest.mark.parametrize(("extra", "code"), [((), 2), (("--resume",), 2),
                                             (("--overwrite",), 0)])
def test_the_next_run_removes_a_stale_partial_output(stale, extra, code, capsys):
    out, expected = stale
    assert out.read_bytes() == expected  # what the killed job renamed is complete
    capsys.readouterr()
    assert run(_command(out, *extra)) == code
    err = capsys.readouterr().err.strip()
    if code:  # OUT exists: the usual one line, about OUT, not about a leftover partial output
        assert len(err.splitlines()) == 1 and "--overwrite" in err and ".partial" not in err
    assert not partial_path(out).exists()
    assert out.read_bytes() == expected


def test_a_partial_output_whose_file_is_not_at_out_is_kept(stale, capsys):
    """``OUT`` replaced since (another file there): the record does not name it, so the
    partial output is an interrupted run's, kept until --resume or --overwrite."""
    out, _ = stale
    out.unlink()
    out.write_bytes(b"another file")
    assert run(_command(out)) == 2
    assert "not empty" in capsys.readouterr().err
    assert (partial_path(out) / MOVED).is_file()


def test_a_folder_without_the_marker_is_never_removed(stale, capsys):
    out, _ = stale
    partial = partial_path(out)
    (partial / MARKER).unlink()
    (partial / "mine.txt").write_text("a user's file")
    assert run(_command(out, "--overwrite")) == 2
    assert "not written by simcred" in capsys.readouterr().err
    assert (partial / "mine.txt").read_text() == "a user's file"


def test_a_done_job_leaves_no_partial_output(tmp_path):
    out = tmp_path / "out.parquet"
    assert run(_command(out)) == 0
    assert out.is_file() and not partial_path(out).exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.parquet"]
