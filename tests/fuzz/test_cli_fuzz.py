"""Every command, every bad input: exit 2, one line naming the culprit, no traceback, no hang.

The cases live in ``cases.py``. Each runs in a forked child; a case that is still running after
``LIMIT_S`` is killed and fails as a hang.
"""

from __future__ import annotations

import io
import multiprocessing
import sys
import time
import traceback
from pathlib import Path

import numpy as np
import pytest

import simcred.data
from fuzz.cases import CASES
from simcred.cli import run
from simcred.traces import TraceSet

LIMIT_S = 10
ROOT = Path(__file__).resolve().parents[2]
FIGURE2 = ROOT / "examples" / "contracts" / "figure2.yaml"


def run_isolated(argv: list[str], limit: float) -> tuple[int | None, str, str, float]:
    """Run the CLI in a forked child (a hang in C code cannot be interrupted in-process).

    Returns (exit code or None on a hang, stdout, stderr, seconds).
    """
    context = multiprocessing.get_context("fork")
    receiver, sender = context.Pipe(duplex=False)

    def child() -> None:
        sys.stdout, sys.stderr = io.StringIO(), io.StringIO()
        try:
            code = run(argv)
        except BaseException:  # what escapes run() is a traceback the user would see
            code = -1
            sys.stderr.write("Traceback (escaped run)\n" + traceback.format_exc())
        sender.send((code, sys.stdout.getvalue(), sys.stderr.getvalue()))

    start = time.perf_counter()
    process = context.Process(target=child)
    process.start()
    result = receiver.recv() if receiver.poll(limit) else None
    elapsed = time.perf_counter() - start
    process.join(1)
    if process.is_alive():
        process.kill()
        process.join()
    if result is None:
        return None, "", "", elapsed
    return (*result, elapsed)


@pytest.fixture(scope="module")
def valid(tmp_path_factory):
    """Valid inputs the cases start from (each case breaks one thing)."""
    root = tmp_path_factory.mktemp("valid")
    rng = np.random.default_rng(0)

    def walk(n):
        return [{"t": np.arange(20) * 0.1, "x": np.cumsum(rng.normal(size=20)),
                 "y": np.cumsum(rng.normal(size=20))} for _ in range(n)]

    a = TraceSet.from_runs(walk(20), source="a").write(root / "a")
    b = TraceSet.from_runs(walk(20), source="b").write(root / "b.parquet")
    runs = TraceSet.from_runs([{"t": np.arange(5) * 0.1, "v": np.full(5, 20.0),
                                "q": np.full(5, 10.0), "err": np.full(5, 0.05)}],
                              source="r").write(root / "runs")
    measurement = root / "measurement"
    assert run(["--quiet", "simulate", "cutin", "--out", str(measurement)]) == 0
    description = root / "descriptions" / "fit.json"
    description.parent.mkdir()
    description.write_text("{}")
    paper = root / "paper"
    paper.mkdir()
    (paper / "claims.json").write_text("{}")
    a9 = simcred.data.path("a9/trajectories_file.csv")
    return {"a": a, "b": b, "library": FIGURE2, "setup": "I1=M1,I2=M2a", "runs": runs,
            "measurement": measurement, "description": description, "paper": paper,
            "a9": a9}


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_bad_input_gets_one_line_and_exit_2(case, valid, tmp_path):
    name, build = case
    if "A9" in name and not valid["a9"].exists():
        pytest.skip("A9 recording not available")
    argv = build(tmp_path, valid)
    code, out, err, elapsed = run_isolated(argv, LIMIT_S)
    assert code is not None, f"hang: still running after {LIMIT_S} s"
    lines = [line for line in err.splitlines() if line.strip()]
    assert "Traceback" not in err + out, err[-800:]
    assert code == 2, f"exit {code}; stderr: {err[-300:]!r}"
    assert len(lines) == 1, f"{len(lines)} lines on stderr: {err[-500:]!r}"
    assert lines[0].startswith("error:") and len(lines[0]) > len("error: ") + 10
    if any("corrupt_" in arg for arg in argv):  # the error names the broken input, not another
        assert "corrupt_" in lines[0], lines[0]
    assert elapsed < LIMIT_S
