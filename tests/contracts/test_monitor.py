"""Monitors find exactly the out-of-domain steps of a run (variable and time step)."""

import json
from pathlib import Path

import numpy as np
import pytest

from simcred.cli import run
from simcred.contracts.algebra import Contract
from simcred.contracts.monitor import monitor
from simcred.errors import SimcredError
from simcred.traces import TraceSet

FIGURE2 = Path(__file__).resolve().parents[2] / "examples" / "contracts" / "figure2.yaml"


def runs_with_excursions(rng, n_runs=5, steps=200):
    """Runs inside M1/M2a's domains, with a known excursion planted in run 3."""
    out = []
    for _ in range(n_runs):
        v = rng.uniform(10, 30, steps)
        out.append({"t": np.arange(steps) * 0.05, "v": v, "q": v * 1.5, "err": rng.uniform(0, 0.09,
                                                                                          steps)})
    out[3]["v"][50:54] = 45.0        # outside M1's validity domain (v <= 40), steps 50..53
    out[3]["err"][120] = 0.4          # M2a's guarantee violated at step 120 (q inside its domain)
    return TraceSet.from_runs(out, run_ids=[f"r{i}" for i in range(n_runs)])


def test_monitor_finds_the_planted_violations_exactly():
    traces = runs_with_excursions(np.random.default_rng(0))
    lib_contracts = {"M1": Contract.from_strings("0 <= v <= 40", "0 <= q <= 50"),
                     "M2a": Contract.from_strings("0 <= q <= 60", "err <= 0.1")}
    report = monitor(traces, lib_contracts)
    found = {(v.contract, v.kind, v.clause, v.run, v.first_step, v.last_step)
             for v in report.violations}
    assert ("M1", "assumption", "v <= 40", "r3", 50, 53) in found
    assert ("M2a", "guarantee", "err <= 0.1", "r3", 120, 120) in found
    # at v = 45, q = 67.5 leaves M1's guarantee and M2a's domain: reported, but only there
    assert all(v.run == "r3" and 50 <= v.first_step <= v.last_step <= 120
               for v in report.violations)
    err = next(v for v in report.violations if v.clause == "err <= 0.1")
    assert err.margin == pytest.approx(-0.3) and err.t_start == pytest.approx(6.0)


def test_monitor_agrees_with_a_literal_loop():
    rng = np.random.default_rng(4)
    traces = TraceSet.from_runs([{"t": np.arange(30.0), "a": rng.normal(size=30),
                                  "b": rng.normal(size=30)} for _ in range(4)])
    contract = Contract.from_strings("abs(a) <= 1.5", "a + b < 1 or b > 2")
    report = monitor(traces, {"C": contract})
    flagged = {(v.run, s) for v in report.violations if v.kind == "guarantee"
               for s in range(v.first_step, v.last_step + 1)}
    expected = set()
    for i in range(traces.n_runs):
        r = traces.run(i)
        for s in range(30):
            a, b = r["a"][s], r["b"][s]
            if abs(a) <= 1.5 and not (a + b < 1 or b > 2):
                expected.add((traces.run_ids[i], s))
    assert flagged == expected


def test_missing_signal_is_a_one_line_error():
    traces = TraceSet.from_runs([{"t": [0, 1], "v": [1, 2]}])
    with pytest.raises(SimcredError, match="no signal 'err'"):
        monitor(traces, {"M": Contract.from_strings("v <= 3", "err <= 1")})


def test_cli_monitor_with_a_configured_setup(tmp_path, capsys):
    path = runs_with_excursions(np.random.default_rng(1)).write(tmp_path / "runs.parquet")
    code = run(["monitor", str(FIGURE2), str(path), "--test-case", "C_tc", "--json"])
    assert code == 1
    doc = json.loads(capsys.readouterr().out)
    assert not doc["passed"]
    assert {"contract": "M1", "clause": "v <= 40", "run": "r3", "first_step": 50,
            "last_step": 53}.items() <= next(v for v in doc["violations"]
                                             if v["clause"] == "v <= 40").items()


VEHICLE = FIGURE2.parent / "vehicle.yaml"


def test_vehicle_library_configures_its_test_cases():
    from simcred.contracts.algebra import Status
    from simcred.contracts.configure import configure
    from simcred.contracts.library import Library

    lib = Library.read(VEHICLE)
    assert configure(lib, "cutin").setup == {"dynamics": "ST", "sensor": "scenario_sensor",
                                             "ad_function": "ad_v1"}
    assert configure(lib, "urban_following").setup["dynamics"] == "KS"
    for name in lib.spec.test_cases:  # every shipped test case has a valid setup
        assert configure(lib, name).status is Status.HOLDS


def test_without_st_the_cutin_needs_a_new_dynamics_model():
    import yaml

    from simcred.contracts.algebra import Status, refines
    from simcred.contracts.configure import configure, missing_model_requirement
    from simcred.contracts.library import Library

    spec = yaml.safe_load(VEHICLE.read_text())
    st = spec["models"].pop("ST")
    lib = Library.from_dict(spec)
    result = configure(lib, "cutin")
    assert result.status is Status.FAILS and result.counterexamples
    need = missing_model_requirement(lib, "cutin",
                                     {"sensor": "scenario_sensor", "ad_function": "ad_v1"})
    assert not refines(lib.model_contracts["KS"], need).holds
    st_contract = Contract.from_strings(st["contract"]["assumption"], st["contract"]["guarantee"])
    assert refines(st_contract, need).holds


def test_monitor_finds_the_out_of_domain_braking_of_a_cutin_run(tmp_path, capsys):
    steps = 100
    t = np.arange(steps) * 0.1
    a_long = np.where((t >= 4.0) & (t < 5.0), -7.5, -0.5)
    a_long[43] = -9.4  # harder than ST's validity domain (-9 m/s^2) at step 43 only
    recording = TraceSet.from_runs([{
        "t": t, "ego.v": np.linspace(27.8, 20.0, steps), "ego.a_long": a_long,
        "ego.a_lat": np.zeros(steps), "obj.range": np.linspace(60, 15, steps),
        "dyn.error": np.full(steps, 0.05), "sen.model_error": np.full(steps, 0.1),
        "ttc.error": np.full(steps, 0.02)}], run_ids=["cutin_0"])
    path = recording.write(tmp_path / "cutin.parquet")
    assert run(["monitor", str(VEHICLE), str(path), "--test-case", "cutin", "--json"]) == 1
    violations = json.loads(capsys.readouterr().out)["violations"]
    assert len(violations) == 1
    v = violations[0]
    assert (v["contract"], v["kind"], v["clause"], v["variables"]) == (
        "ST", "assumption", "(-9) <= ego.a_long", ["ego.a_long"])
    assert (v["first_step"], v["last_step"]) == (43, 43) and v["margin"] == pytest.approx(-0.4)


def test_tolerance_absorbs_rounding_on_a_domain_boundary():
    a = np.array([-8.0, -9.0 - 1e-12, -9.0, -9.5])
    traces = TraceSet.from_runs([{"t": np.arange(4.0), "a": a}])
    domain = {"ST": Contract.from_strings("-9 <= a", "true", declared={"a": "real"})}
    exact = monitor(traces, domain)
    assert [(v.first_step, v.last_step) for v in exact.violations] == [(1, 1), (3, 3)]
    tolerant = monitor(traces, domain, tolerance=1e-9)
    assert [(v.first_step, v.last_step) for v in tolerant.violations] == [(3, 3)]


def test_unobserved_variables_are_named_not_checked():
    traces = TraceSet.from_runs([{"t": [0, 1, 2], "v": [1, 2, 5]}])
    contract = Contract.from_strings("v <= 3", "err <= 1 and v >= 0")
    report = monitor(traces, {"M": contract}, unobserved=frozenset({"err"}))
    assert report.not_monitored == ("M: err <= 1",)
    assert [(v.kind, v.clause, v.first_step) for v in report.violations] == [
        ("assumption", "v <= 3", 2)]
    assert report.clauses == 2
    with pytest.raises(SimcredError, match="observed: false"):
        monitor(traces, {"M": Contract.from_strings("err <= 3", "v >= 0")},
                unobserved=frozenset({"err"}))
