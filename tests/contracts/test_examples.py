"""The example libraries load, configure and monitor as docs/contracts.md says."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from simcred.cli import run
from simcred.contracts import Library, configure, monitor, to_text
from simcred.traces import TraceSet

EXAMPLES = Path(__file__).resolve().parents[2] / "examples" / "contracts"


def test_units_and_time_example_configures_with_converted_units():
    lib = Library.read(EXAMPLES / "units_and_time.yaml")
    ks = lib.model_contracts["KS"]
    # abs(a) <= 6 m/s^2 * mu for every mu in [0.6, 1]: abs(a) <= 3.6
    assert "3.6" in to_text(ks.assumption)
    assert to_text(lib.model_contracts["ad_v1"].guarantee) == "ttc.error <= 0.1"
    result = configure(lib, "night_approach")
    assert result.status.value == "holds"
    assert result.setup == {"camera": "camera_night", "dynamics": "KS", "ad": "ad_v1"}


def test_temporal_contract_is_monitored_and_refused_by_the_algebra(tmp_path, capsys):
    lib = Library.read(EXAMPLES / "units_and_time.yaml")
    t = np.arange(0, 4, 0.5)
    a = np.array([0, -5, -5, -5, -5, 0, 0, 0], dtype=float)  # brakes hard for 2 s
    traces = TraceSet(("ego.a_long",), t, a[:, None], np.array([0, len(t)]), ("r0",))
    report = monitor(traces, {"braking_settles": lib.contract("braking_settles")})
    assert [(v.first_step, v.last_step) for v in report.violations] == [(1, 1)]
    path = EXAMPLES / "units_and_time.yaml"
    assert run(["contracts", "refines", str(path), "--refining", "braking_settles",
                "--refined", "braking_settles"]) == 2
    err = capsys.readouterr().err
    assert "units_and_time.yaml" in err and "is temporal" in err and err.count("\n") == 1
    assert run(["contracts", "check", str(path)]) == 0


def test_unit_brackets_survive_in_text_output(tmp_path, capsys):
    path = EXAMPLES / "units_and_time.yaml"
    text = path.read_text().replace('"0.5 [km/h] <= ego.v', '"0.5 [km/h] <= ego.v')
    lib_path = tmp_path / "lib[m_s].yaml"
    lib_path.write_text(text)
    assert run(["contracts", "check", str(lib_path)]) == 0
    assert "lib[m_s].yaml" in capsys.readouterr().out


def test_a_long_path_is_printed_on_one_line(tmp_path, capsys):
    """Text output never breaks a path (rich wraps at 80 columns off a terminal by default)."""
    folder = tmp_path / ("deep_" * 20)
    folder.mkdir()
    lib_path = folder / "library.yaml"
    lib_path.write_text((EXAMPLES / "units_and_time.yaml").read_text())
    assert run(["contracts", "check", str(lib_path)]) == 0
    assert str(lib_path) in capsys.readouterr().out
