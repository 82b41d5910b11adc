"""One record of what produced an output (issue 27: four hand-written lists, validate's without
the z3 whose proofs it reports)."""

from __future__ import annotations

import platform
from importlib.metadata import version

import simcred
from simcred._version import versions


def test_versions_in_a_fixed_order_with_programs_and_python():
    found = versions("numpy", "z3-solver", "no-such-distribution-xyz", sumo="1.20.0")
    assert list(found) == ["simcred", "sumo", "numpy", "z3-solver", "no-such-distribution-xyz",
                           "python"]
    assert found["simcred"] == simcred.__version__ and found["sumo"] == "1.20.0"
    assert found["numpy"] == version("numpy") and found["z3-solver"] == version("z3-solver")
    assert found["no-such-distribution-xyz"] == "not installed"
    assert found["python"] == platform.python_version()
