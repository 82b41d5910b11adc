"""Kill test of ``simcred simulate tjunction`` to one Parquet file: SIGKILL after 0, 1, 2, 4, 6
and 8 of 8 finished chunks (the last while the file is being written), then ``--resume``: the
same bytes as an uninterrupted run each time, and no output that looks complete meanwhile."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import simcred
from simcred.outputs import partial_path

SRC = str(Path(simcred.__file__).resolve().parents[1])
KILL_AFTER = [0, 1, 2, 4, 6, 8]  # finished chunks of 8


def _command(out: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "simcred.cli", "-q", "simulate", "tjunction", "--runs", "24",
            "--chunk-size", "3", "--seed", "5", "--out", str(out), *extra]


def _environment() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": SRC, "OMP_NUM_THREADS": "1",
            "OPENBLAS_NUM_THREADS": "1"}


def _chunks(out: Path) -> int:
    folder = partial_path(out) / "checkpoints"
    return len(list(folder.glob("map*"))) if folder.is_dir() else 0


def _kill_after(out: Path, chunks: int) -> int:
    """Start the command and SIGKILL it once ``chunks`` chunks are checkpointed."""
    process = subprocess.Popen(_command(out), env=_environment(), stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 120
    while process.poll() is None and time.monotonic() < deadline:
        if _chunks(out) >= chunks and (chunks or partial_path(out).is_dir()):
            process.send_signal(signal.SIGKILL)
            break
        time.sleep(0.01)
    return process.wait()


@pytest.mark.slow
@pytest.mark.parametrize("chunks", KILL_AFTER)
def test_tjunction_parquet_killed_and_resumed_is_byte_identical(chunks, tmp_path):
    env = _environment()
    subprocess.run(_command(tmp_path / "whole.parquet"), env=env, check=True, timeout=300)
    expected = (tmp_path / "whole.parquet").read_bytes()
    out = tmp_path / "out.parquet"
    code = _kill_after(out, chunks)
    assert code == -signal.SIGKILL or chunks == KILL_AFTER[-1], code  # the kill interrupted it
    if code == -signal.SIGKILL:
        assert not out.exists()  # killed: nothing that looks complete
        assert _chunks(out) >= chunks  # finished chunks are never lost
    subprocess.run(_command(out, "--resume"), env=env, check=True, timeout=300)
    assert out.read_bytes() == expected
    assert not partial_path(out).exists()
