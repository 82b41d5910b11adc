"""``pip install .`` (not editable) into a fresh virtual environment, then ``simcred paper all``
and ``simcred validate`` on the shipped example: scripts/check_wheel_install.sh, run here so CI
runs it (about two minutes, most of it pip; the dependencies come from the configured index)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[1] / "scripts" / "check_wheel_install.sh"


@pytest.mark.slow
def test_a_wheel_install_runs_paper_all_and_validate(tmp_path):
    base = Path(getattr(sys, "_base_executable", sys.executable))
    done = subprocess.run(["bash", str(SCRIPT), str(tmp_path / "work")], capture_output=True,
                          text=True, timeout=900, env={**_env(), "PYTHON": str(base)})
    assert done.returncode == 0, (done.stdout + done.stderr)[-4000:]
    assert "done: the installed simcred runs paper all and validate" in done.stdout


def _env() -> dict[str, str]:
    """The environment without this session's PYTHONPATH (it would put src/ first)."""
    import os

    return {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
