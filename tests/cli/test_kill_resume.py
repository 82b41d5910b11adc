"""Kill tests of the resumable commands: each killed with SIGKILL once 0, 1, 2, half, all but
one and all of its chunks are checkpointed (the last while the output is being written), then
run again with ``--resume``: the same bytes as an uninterrupted run every time, and no output
that looks complete meanwhile (issue 29; ``paper 000``: tests/paper/test_kill_resume.py)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest

import simcred
from simcred.examples import lane_change_sets
from simcred.outputs import partial_path

SRC = str(Path(simcred.__file__).resolve().parents[1])


def _sets(root: Path) -> list[str]:
    """Four small trace sets for ``matrix`` (six pairs)."""
    paths = []
    for seed in range(2):
        a, b = lane_change_sets(runs=20, steps=15, seed=seed)
        paths += [str(a.write(root / f"a{seed}")), str(b.write(root / f"b{seed}.parquet"))]
    return paths


#: command -> (arguments before --out given the inputs' folder, chunks it checkpoints)
COMMANDS: dict[str, tuple[Callable[[Path], list[str]], int]] = {
    "simulate tjunction (Parquet)": (lambda root: [
        "simulate", "tjunction", "--runs", "24", "--chunk-size", "3", "--seed", "5"], 8),
    "simulate simplecar (CSV directory)": (lambda root: [
        "simulate", "simplecar", "--runs", "12", "--chunk-size", "2", "--duration", "400",
        "--dt", "0.5", "--seed", "5"], 6),
    "matrix": (lambda root: [
        "matrix", *_sets(root), "-f", "y", "--bins", "3", "--permutations", "199", "--seed",
        "2"], 6),
}
SUFFIX = {"simulate tjunction (Parquet)": ".parquet"}


def _kill_points(total: int) -> list[int]:
    return sorted({0, 1, 2, total // 2, total - 1, total})


CASES = [(name, k) for name, (_, total) in COMMANDS.items() for k in _kill_points(total)]


def _environment() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": SRC, "OMP_NUM_THREADS": "1",
            "OPENBLAS_NUM_THREADS": "1"}


def _command(args: list[str], out: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "simcred.cli", "-q", *args, "--out", str(out), *extra]


def _chunks(out: Path) -> int:
    folder = partial_path(out) / "checkpoints"
    return len(list(folder.glob("map*"))) if folder.is_dir() else 0


def _kill_after(command: list[str], out: Path, chunks: int) -> int:
    """Start ``command`` and SIGKILL it once ``chunks`` chunks are checkpointed."""
    process = subprocess.Popen(command, env=_environment(), stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 120
    while process.poll() is None and time.monotonic() < deadline:
        if _chunks(out) >= chunks and (chunks or partial_path(out).is_dir()):
            process.send_signal(signal.SIGKILL)
            break
        time.sleep(0.005)
    return process.wait()


def _files(root: Path) -> dict[str, bytes]:
    if root.is_file():
        return {"": root.read_bytes()}
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file()}


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory) -> dict[str, tuple[list[str], dict[str, bytes]]]:
    """Per command: its arguments and the files of an uninterrupted run."""
    done = {}
    for name, (make, _) in COMMANDS.items():
        root = tmp_path_factory.mktemp("inputs")
        args = make(root)
        out = root / f"whole{SUFFIX.get(name, '')}"
        subprocess.run(_command(args, out), env=_environment(), check=True, timeout=300)
        done[name] = args, _files(out)
    return done


@pytest.mark.slow
@pytest.mark.parametrize(("name", "chunks"), CASES, ids=[f"{n}-{k}" for n, k in CASES])
def test_killed_and_resumed_is_byte_identical(name, chunks, uninterrupted, tmp_path):
    args, expected = uninterrupted[name]
    out = tmp_path / f"out{SUFFIX.get(name, '')}"
    code = _kill_after(_command(args, out), out, chunks)
    total = COMMANDS[name][1]
    assert code == -signal.SIGKILL or chunks == total, code  # the kill interrupted it
    if code == -signal.SIGKILL:
        assert not out.exists()  # killed: nothing that looks complete
        assert _chunks(out) >= chunks  # finished chunks are never lost
        subprocess.run(_command(args, out, "--resume"), env=_environment(), check=True,
                       timeout=300)
    assert _files(out) == expected
    assert not partial_path(out).exists()


def test_every_command_is_killed_at_six_points_at_least():
    assert all(len(_kill_points(total)) >= 6 for _, total in COMMANDS.values())
