"""Kills inside the last steps of writing an output (issue 29).

A file output: a job killed between renaming it into place (``OUT.partial/<name>`` -> ``OUT``)
and removing ``OUT.partial`` leaves a complete ``OUT`` beside a stale ``OUT.partial``. The next
run, plain, ``--resume`` or ``--overwrite``, recognises it (simcred's marker, and a record of the
very file now at ``OUT``) and removes it; a partial output that is not provably done is never
removed so (simcred.outputs._drop_moved).

A directory output replacing an older one (``--overwrite``): the old ``OUT`` is moved aside
(``.OUT.simcred-replaced``), then ``OUT.partial`` renamed to ``OUT``. Killed between the two, the
next run puts the old output back as it was; killed after them, it removes the old one
(simcred.outputs._recover_replaced).

The states are made deterministically: a step of the writer is replaced by a "kill" (an
exception no handler catches)."""

from __future__ import annotations

import os
import shutil
import types
from pathlib import Path

import pytest

import simcred.outputs as outputs
from simcred.cli import run
from simcred.outputs import MARKER, MOVED, partial_path, replaced_path

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


# -- a directory output replaced with --overwrite -------------------------------------------------

EXAMPLE = ["-q", "example", "--runs", "3", "--steps", "5"]


def tree(root: Path) -> dict[str, bytes]:
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file()}


class _KillingOs:
    """``os`` for simcred.outputs, except that renaming ``OUT.partial`` to ``OUT`` dies."""

    def __init__(self, out: Path) -> None:
        self.partial = partial_path(out)

    def __getattr__(self, name):
        return getattr(os, name)

    def replace(self, source, target):
        if Path(source) == self.partial:
            raise Killed
        return os.replace(source, target)


@pytest.fixture
def replaced(tmp_path) -> tuple[Path, dict[str, bytes]]:
    """``out``, written by ``example --seed 1``, and its files."""
    out = tmp_path / "out"
    assert run([*EXAMPLE, "--seed", "1", "--out", str(out)]) == 0
    return out, tree(out)


def _overwrite_killed(out: Path, patch_name: str, patched, monkeypatch) -> None:
    with monkeypatch.context() as patch:
        patch.setattr(outputs, patch_name, patched)
        with pytest.raises(Killed):
            run([*EXAMPLE, "--seed", "2", "--out", str(out), "--overwrite"])


def test_killed_between_the_renames_the_old_output_comes_back(replaced, monkeypatch, capsys):
    out, old = replaced
    _overwrite_killed(out, "os", _KillingOs(out), monkeypatch)
    assert not out.exists() and tree(replaced_path(out)) == old  # the state of the kill
    assert partial_path(out).is_dir()
    capsys.readouterr()
    assert run([*EXAMPLE, "--seed", "2", "--out", str(out)]) == 2  # plain: OUT is back
    assert "--overwrite" in capsys.readouterr().err
    assert tree(out) == old and not replaced_path(out).exists()
    assert run([*EXAMPLE, "--seed", "2", "--out", str(out), "--overwrite"]) == 0
    assert tree(out) != old and not partial_path(out).exists()
    assert not replaced_path(out).exists()


def test_killed_after_the_renames_the_old_output_is_removed(replaced, monkeypatch):
    out, _ = replaced
    assert run([*EXAMPLE, "--seed", "2", "--out", str(out.with_name("new"))]) == 0
    new = tree(out.with_name("new"))

    def rmtree(path, *args, **kwargs):
        if Path(path) == replaced_path(out):
            raise Killed
        return shutil.rmtree(path, *args, **kwargs)

    _overwrite_killed(out, "shutil", types.SimpleNamespace(rmtree=rmtree), monkeypatch)
    assert tree(out) == new and replaced_path(out).is_dir()  # the state of the kill
    assert run([*EXAMPLE, "--seed", "2", "--out", str(out)]) == 2
    assert tree(out) == new and not replaced_path(out).exists()
    assert not partial_path(out).exists()


def test_a_foreign_folder_at_the_replaced_name_is_left_alone(replaced):
    out, old = replaced
    foreign = replaced_path(out)
    foreign.mkdir()
    (foreign / "mine.txt").write_text("a user's file")
    assert run([*EXAMPLE, "--seed", "2", "--out", str(out)]) == 2
    assert (foreign / "mine.txt").read_text() == "a user's file" and tree(out) == old
