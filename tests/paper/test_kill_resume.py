"""The kill test: ``simcred paper 000`` at a reduced size, killed with SIGKILL at 5 random
(seeded) moments and resumed each time with ``--resume``, writes the same bytes as an
uninterrupted run; while it is interrupted no output that looks complete exists."""

from __future__ import annotations

import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from killing import chunks as _chunks
from killing import environment, files, finished_despite_kill
from simcred.outputs import partial_path

KILLS = 5
RUNS = "2"  # runs per trace set: the smallest paper 000 (the default is hundreds)


def _command(out: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "simcred.cli", "-q", "paper", "000", "--runs", RUNS,
            "--seed", "3", "--out", str(out), *extra]


@pytest.mark.slow
def test_paper_000_killed_five_times_and_resumed_is_byte_identical(tmp_path):
    env = environment()
    started = time.monotonic()
    subprocess.run(_command(tmp_path / "whole"), env=env, check=True, timeout=600)
    duration = time.monotonic() - started  # only to spread the kills over a run, not asserted
    expected = files(tmp_path / "whole")
    assert "claims.json" in expected and any(name.endswith(".png") for name in expected)

    out = tmp_path / "out"
    rng = np.random.default_rng(16)
    kept, codes = [], []
    for attempt in range(KILLS):
        extra = ("--resume",) if attempt else ()
        process = subprocess.Popen(_command(out, *extra), env=env, stdout=subprocess.DEVNULL,
                                   stderr=subprocess.PIPE)
        try:
            process.wait(timeout=float(rng.uniform(0.15, 0.6)) * duration)
        except subprocess.TimeoutExpired:
            process.send_signal(signal.SIGKILL)
            process.wait()
        codes.append(process.returncode)
        process.stderr.close()
        if finished_despite_kill(out, expected):  # it had renamed its output when the kill came
            break
        kept.append(_chunks(out))
    print(f"exit codes {codes}, finished chunks kept after each {kept}")  # shown with -s
    # the kills interrupted the job (the last attempt may have finished before its kill)
    assert codes.count(-signal.SIGKILL) >= min(3, len(codes) - 1), codes
    assert kept == sorted(kept) and (not kept or kept[-1] > 0), kept  # chunks never lost
    if not out.exists():
        subprocess.run(_command(out, "--resume"), env=env, check=True, timeout=600)
    assert files(out) == expected
    assert not partial_path(out).exists()
