"""Fixtures shared by the whole suite."""

from __future__ import annotations

import subprocess

import pytest

from browser import ROOT, find_chromium


@pytest.fixture(scope="session")
def chromium() -> str:
    """Chromium on PATH, installed once by scripts/ensure_chromium.sh if needed; else FAIL."""
    found = find_chromium()
    if found is None:
        script = ROOT / "scripts" / "ensure_chromium.sh"
        done = subprocess.run(["bash", str(script)], capture_output=True, text=True,
                              timeout=900, check=False)
        found = find_chromium()
        if found is None:
            pytest.fail("the HTML report's browser test needs Chromium: scripts/ensure_chromium.sh "
                        f"could not install it (exit {done.returncode}): "
                        f"{done.stderr.strip()[-500:]}", pytrace=False)
    return found
