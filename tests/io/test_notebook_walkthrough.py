"""docs/notebooks.md runs as written: its `>>>` lines are a doctest with the outputs shown."""

from __future__ import annotations

import doctest
from pathlib import Path

DOC = Path(__file__).resolve().parents[2] / "docs" / "notebooks.md"


def test_the_notebook_walkthrough_runs_as_written():
    failed, attempted = doctest.testfile(str(DOC), module_relative=False, report=True,
                                         optionflags=doctest.ELLIPSIS)
    assert attempted > 15
    assert failed == 0
