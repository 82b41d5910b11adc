"""Paper 003 on the cut-in (the paper 003 part of `simcred paper all`): configuration, quotient,
monitors; and the combined claims of `paper all`."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from simcred.paper import validity_contracts
from simcred.reprocess.pipeline import ReprocessConfig, reprocess
from simcred.sim.experiments import cutin
from simcred.traces import TraceSet, concat


@pytest.fixture(scope="module")
def resimulations():
    result = reprocess(cutin.simulate(0, cutin.CutInConfig(duration=8.0)),
                       ReprocessConfig())  # rGT[sb] brakes hard: outside KS
    return concat(list(result.resimulations.values()))


@pytest.fixture(scope="module")
def findings(resimulations, tmp_path_factory):
    out = tmp_path_factory.mktemp("paper003")
    found, claims = validity_contracts.run_contracts(out, {"resimulations": resimulations})
    assert json.loads((out / "findings.json").read_text()) == json.loads(
        json.dumps(found, allow_nan=False))
    return found, {c.id: c for c in claims}


def test_the_cutin_configures_to_st_with_the_scenario_based_sensor(findings):
    found, claims = findings
    assert found["configuration"]["setup"] == {
        "dynamics": "ST", "sensor": "scenario_sensor", "ad_function": "ad_v1"}
    assert claims["cutin_configurable"].passed and claims["configuration_is_cheapest"].passed


def test_quotient_without_st_accepts_only_st(findings):
    found, claims = findings
    assert not found["quotient"]["configurable_without"]
    assert found["quotient"]["accepts"] == {"SimpleCar": False, "KS": False, "ST": True}
    assert claims["quotient_characterises_missing_model"].passed


def test_monitors_find_the_braking_outside_ks_domain(findings, resimulations):
    found, claims = findings
    ks = [v for v in found["monitors"][0]["violations"] if v["contract"] == "KS"]
    assert ks and all(v["clause"] == "abs(ego.a_long) <= 4" for v in ks)
    signals = validity_contracts.monitored_signals(resimulations)
    # oracle: the samples where |dv/dt| > 4 are exactly those inside KS's violation segments
    flagged = np.zeros(signals.n_rows, dtype=bool)
    for v in ks:
        run = signals.run_ids.index(v["run"])
        t = signals.run(run)["t"]
        rows = signals.offsets[run] + np.flatnonzero((t >= v["t_start"]) & (t <= v["t_end"]))
        flagged[rows] = True
    np.testing.assert_array_equal(flagged, np.abs(signals.column("ego.a_long")) > 4 + 1e-6)
    assert claims["monitor_finds_ks_outside_its_domain"].passed


def test_monitored_signals_are_derived_from_the_run():
    t = np.linspace(0.0, 2.0, 201)
    run = {"t": t, "ego.x": 20 * t, "ego.y": 0 * t, "ego.v": 20 - 3 * t, "ego.heading": 0.1 * t,
           "to.x": 30 + 20 * t, "to.y": 0 * t + 4, "to.v": 0 * t + 20, "to.heading": 0 * t}
    signals = validity_contracts.monitored_signals(TraceSet.from_runs([run])).run(0)
    np.testing.assert_allclose(signals["ego.a_long"], -3.0, atol=1e-9)
    np.testing.assert_allclose(signals["ego.a_lat"], 0.1 * (20 - 3 * t), atol=1e-9)
    np.testing.assert_allclose(signals["obj.range"], np.hypot(30.0, 4.0), atol=1e-9)


def test_the_library_ships_with_the_package_and_the_example_is_that_file():
    """`simcred paper 003|all` from a wheel: the library is package data, not a repository file
    (tests/test_wheel_install.py runs it from a real non-editable install)."""
    package = Path(validity_contracts.__file__).resolve().parents[1]
    assert validity_contracts.LIBRARY.is_file()
    library = validity_contracts.LIBRARY
    assert package in library.parents, library  # not examples/ beside src/
    example = package.parents[1] / "examples" / "contracts" / "vehicle.yaml"
    assert example.resolve() == library.resolve()  # one file, linked: nothing can drift
