"""Shared code of the kill tests (issue 29): start a ``simcred`` command in a child process,
SIGKILL it at a chosen moment, rerun it with ``--resume``, and compare the final output with an
uninterrupted run byte for byte (tests/cli/test_kill_resume.py, tests/paper/test_kill_resume.py).

A kill can land after the job has already renamed ``OUT.partial`` to ``OUT`` (it finished between
the last poll and the signal): then the output must be complete, which is what the helpers
accept, rather than demanding an interruption that did not happen.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import simcred
from simcred.outputs import CHECKPOINTS, MANIFEST, partial_path

SRC = str(Path(simcred.__file__).resolve().parents[1])
#: Checkpoint keys that are not finished chunks (a value kept for a resumed run, e.g. a seed).
VALUE_PREFIX = "value-"


def environment() -> dict[str, str]:
    return {**os.environ, "PYTHONPATH": SRC, "OMP_NUM_THREADS": "1",
            "OPENBLAS_NUM_THREADS": "1"}


def command(args: list[str], out: Path, *extra: str) -> list[str]:
    return [sys.executable, "-m", "simcred.cli", "-q", *args, "--out", str(out), *extra]


def files(root: Path) -> dict[str, bytes]:
    """Every file under ``root`` (or ``root`` itself when it is a file) by relative name."""
    if root.is_file():
        return {"": root.read_bytes()}
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*"))
            if p.is_file()}


def chunks(out: Path) -> int:
    """Finished chunks checkpointed in ``OUT.partial`` (engine tasks ``map*``, a validation's
    ``simulated-*``; not the job manifest, kept values or a file being written)."""
    folder = partial_path(out) / CHECKPOINTS
    try:
        names = [p.name for p in folder.iterdir()]
    except OSError:
        return 0
    return sum(not n.startswith((".", VALUE_PREFIX)) and n != MANIFEST for n in names)


def kill_points(total: int) -> list[int]:
    """Kill once 0, 1, 2, half, all but one and all of ``total`` chunks are checkpointed."""
    return sorted({0, 1, 2, total // 2, total - 1, total})


def run_whole(args: list[str], out: Path, codes: tuple[int, ...] = (0,),
              timeout: float = 300) -> tuple[int, dict[str, bytes]]:
    """An uninterrupted run: its exit code (one of ``codes``) and its files."""
    done = subprocess.run(command(args, out), env=environment(), timeout=timeout,
                          stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    assert done.returncode in codes, (done.returncode, done.stderr[-2000:])
    return done.returncode, files(out)


def kill_after(argv: list[str], out: Path, count: int, timeout: float = 120
               ) -> tuple[int, bool]:
    """Start ``argv`` and SIGKILL it once ``count`` chunks are checkpointed (with 0: as soon as
    ``OUT.partial`` exists): its exit code (negative: the signal) and whether the kill was sent
    (False: it ended before the kill point was seen)."""
    process = subprocess.Popen(argv, env=environment(), stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL)
    deadline, sent = time.monotonic() + timeout, False
    while process.poll() is None and time.monotonic() < deadline:
        if chunks(out) >= count and (count or partial_path(out).is_dir()):
            process.send_signal(signal.SIGKILL)
            sent = True
            break
        time.sleep(0.005)
    if process.poll() is None and not sent:  # never reached the kill point in time
        process.kill()
    return process.wait(), sent


def differing(got: dict[str, bytes], want: dict[str, bytes]) -> list[str]:
    """The files missing from, extra in or different in ``got`` against ``want``."""
    return sorted(n for n in got.keys() | want.keys() if got.get(n) != want.get(n))


def finished_despite_kill(out: Path, expected: dict[str, bytes]) -> bool:
    """True when the job had renamed its output before the kill came: then it is complete."""
    if not out.exists():
        return False
    got = files(out)
    assert got == expected, differing(got, expected)  # what looks complete is complete
    return True


def kill_and_resume(args: list[str], out: Path, count: int, total: int,
                    expected: tuple[int, dict[str, bytes]], timeout: float = 300) -> int:
    """Kill ``simcred ARGS --out OUT`` once ``count`` of its ``total`` chunks are checkpointed,
    resume it, and check the result against ``expected`` (exit code, files) of an
    uninterrupted run. Returns the exit code of the killed process."""
    code, want = expected
    killed, sent = kill_after(command(args, out), out, count)
    assert sent or (count == total and killed == code), (count, killed)  # the point was seen
    if finished_despite_kill(out, want):  # the kill came after the job finished
        print(f"kill point {count}/{total}: finished before the kill (exit {killed})")
        return killed
    assert killed == -signal.SIGKILL, killed  # interrupted, and nothing looks complete
    assert chunks(out) >= count  # finished chunks are never lost
    print(f"kill point {count}/{total}: killed with {chunks(out)} chunks kept")  # with -s
    done = subprocess.run(command(args, out, "--resume"), env=environment(), timeout=timeout,
                          stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    assert done.returncode == code, (done.returncode, done.stderr[-2000:])
    got = files(out)
    assert got == want, differing(got, want)
    assert not partial_path(out).exists()
    return killed
