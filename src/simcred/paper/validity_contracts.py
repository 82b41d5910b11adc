"""Paper 003 (Braun et al.) on simcred's own cut-in: configure the cheapest valid simulation setup
for the test case, derive what a missing dynamics model must satisfy when ST is removed, and
monitor the resimulated runs and the variations of paper 002 against the validity domains.

The library is ``vehicle.yaml`` (SimpleCar/KS/ST, ideal vs scenario-based sensor, the AD
function; test case ``cutin``), shipped as ``simcred.data``'s ``contracts/vehicle.yaml`` (the
repository's ``examples/contracts/vehicle.yaml`` links to it). Monitored signals are derived
from each run: ``ego.v``, ``ego.a_long`` = dv/dt, ``ego.a_lat`` = v · dθ/dt and ``obj.range``
(centre distance to the TO); only the models' *assumptions* (their validity domains) are
monitored, because a resimulation alone has no reality to measure the error metrics
(``dyn.error``, ...) against.
"""

from __future__ import annotations

from itertools import product
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from simcred._json import dumps
from simcred.contracts.algebra import Contract, refines
from simcred.contracts.configure import (
    configure,
    missing_model_requirement,
    missing_ports,
    setup_refines,
)
from simcred.contracts.expr import Bool, to_text
from simcred.contracts.library import Library
from simcred.contracts.monitor import MonitorReport, monitor
from simcred.contracts.project import project
from simcred.data import path as data_path
from simcred.paper.claims import Claim
from simcred.traces import TIME, TraceSet

LIBRARY = data_path("contracts/vehicle.yaml")
TEST_CASE = "cutin"
REMOVED = "ST"
MONITORED_MODELS = ("KS", "ST", "scenario_sensor")
TOLERANCE = 1e-6  # accelerations are differentiated: the AD function's 9 m/s² limit sits on ST's


def monitored_signals(traces: TraceSet, ego: str = "ego", to: str = "to") -> TraceSet:
    """The library's operating-condition variables of every run."""
    runs = []
    for i in range(traces.n_runs):
        run = traces.run(i)
        t, v = run[TIME], run[f"{ego}.v"]
        heading = np.unwrap(run[f"{ego}.heading"])
        runs.append({TIME: t, "ego.v": v, "ego.a_long": np.gradient(v, t),
                     "ego.a_lat": v * np.gradient(heading, t),
                     "obj.range": np.hypot(run[f"{to}.x"] - run[f"{ego}.x"],
                                           run[f"{to}.y"] - run[f"{ego}.y"])})
    return TraceSet.from_runs(runs, run_ids=traces.run_ids, source=traces.source)


def validity_domains(library: Library, models: tuple[str, ...]) -> dict[str, Contract]:
    """The assumptions of ``models`` and of the test case, as contracts with guarantee true."""
    domains = {m: Contract(library.contract(m).assumption, Bool(True), m) for m in models}
    domains[f"test case {TEST_CASE}"] = Contract(library.test_case(TEST_CASE).assumption,
                                                 Bool(True), TEST_CASE)
    return domains


def _cheapest_by_brute_force(library: Library) -> float:
    components = library.spec.architecture or list(library.spec.components)
    choices = [[m for m, spec in library.spec.models.items() if spec.implements == c]
               for c in components]
    target = library.test_case(TEST_CASE)
    costs = [sum(library.spec.models[m].cost for m in setup) for setup in product(*choices)
             if setup_refines(library, dict(zip(components, setup, strict=True)), target).holds]
    return min(costs) if costs else float("inf")


def _without(library_path: Path, model: str) -> Library:
    spec = yaml.safe_load(library_path.read_text())
    del spec["models"][model]
    return Library.from_dict(spec, source=f"{library_path} without {model}")


def _quotient(library_path: Path, library: Library, setup: dict[str, str]) -> dict[str, Any]:
    reduced = _without(library_path, REMOVED)
    without = configure(reduced, TEST_CASE)
    component = library.spec.models[REMOVED].implements
    given = {c: m for c, m in setup.items() if c != component}
    requirement = missing_model_requirement(library, TEST_CASE, given)
    projected = project(requirement, missing_ports(library, given), types=library.types)
    shown = projected if projected is not None else requirement
    candidates = [m for m, spec in library.spec.models.items() if spec.implements == component]
    return {"removed": REMOVED, "test_case": TEST_CASE,
            "configurable_without": without.status.value == "holds",
            "without_reason": without.reason, "given": given,
            "requirement": f"assume    {to_text(shown.assumption)}\n"
                           f"guarantee {to_text(shown.guarantee)}",
            "accepts": {m: refines(library.contract(m), requirement).holds
                        for m in candidates}}


def _monitor_entry(name: str, report: MonitorReport) -> dict[str, Any]:
    return {"name": name, "runs": report.runs, "samples": report.samples,
            "passed": report.passed,
            "violations": [{"contract": v.contract, "kind": v.kind, "clause": v.clause,
                            "run": v.run, "t_start": v.t_start, "t_end": v.t_end,
                            "margin": v.margin} for v in report.violations]}


def run_contracts(out: Path, monitored: dict[str, TraceSet], library_path: Path = LIBRARY
                  ) -> tuple[dict[str, Any], list[Claim]]:
    """Configuration, quotient and monitors; writes ``findings.json`` into ``out``."""
    out.mkdir(parents=True, exist_ok=True)
    library = Library.read(library_path)
    configuration = configure(library, TEST_CASE)
    setup = configuration.setup or {}
    cheapest = _cheapest_by_brute_force(library)
    quotient = _quotient(library_path, library, setup) if setup else {}
    domains = validity_domains(library, MONITORED_MODELS)
    reports = {name: monitor(monitored_signals(traces), domains, tolerance=TOLERANCE)
               for name, traces in monitored.items()}
    findings = {
        "library": str(library_path.name),
        "configuration": {"test_case": TEST_CASE, "setup": setup, "cost": configuration.cost,
                          "verdict": configuration.status.value,
                          "checked_setups": configuration.iterations,
                          "explanation": configuration.reason or "the composition of the "
                          "setup's contracts refines the test case's contract (z3 proof)"},
        "quotient": quotient,
        "monitors": [_monitor_entry(name, r) for name, r in reports.items()],
    }
    (out / "findings.json").write_text(dumps(findings))
    return findings, _claims(findings, configuration, cheapest, reports, setup)


def _claims(findings, configuration, cheapest, reports, setup) -> list[Claim]:
    q = findings["quotient"]
    configured = configuration.status.value == "holds"
    claims = [
        Claim("cutin_configurable", "the cut-in test case has a valid setup, with a proof",
              configuration.cost, None, configured,
              ", ".join(f"{c} = {m}" for c, m in setup.items()) or configuration.reason),
        Claim("configuration_is_cheapest",
              "the configured setup is the cheapest one whose composition refines the test "
              "case (brute force over all setups)", configuration.cost, cheapest,
              configured and configuration.cost == cheapest,
              f"configured {configuration.cost}, brute-force minimum {cheapest}"),
    ]
    if q:
        accepts = q["accepts"]
        claims.append(Claim(
            "quotient_characterises_missing_model",
            f"without {REMOVED} the test case is not configurable, and the quotient accepts "
            f"{REMOVED}'s contract but not the weaker models'", None, None,
            bool(not q["configurable_without"] and accepts.get(REMOVED)
                 and not any(ok for m, ok in accepts.items() if m != REMOVED)),
            "accepts: " + ", ".join(f"{m} {'yes' if ok else 'no'}"
                                    for m, ok in accepts.items())))
    ks = [v for r in reports.values() for v in r.violations if v.contract == "KS"]
    claims.append(Claim(
        "monitor_finds_ks_outside_its_domain",
        "the monitors find where the resimulations' default model KS leaves its validity domain "
        "(which is why the configuration chose ST)", float(len(ks)), 1.0, bool(ks),
        f"{len(ks)} KS violation segment(s), clauses: "
        + ", ".join(sorted({v.clause for v in ks}))))
    for name, report in reports.items():
        chosen = [v for v in report.violations if v.contract in setup.values()]
        claims.append(Claim(
            f"monitor_{name}_inside_configured_domains",
            f"the {name} stay inside the validity domains of the configured setup's models",
            float(len(chosen)), 0.0, not chosen,
            f"{len(report.violations)} violation segment(s) over all monitored domains "
            f"(configured setup: {len(chosen)})"))
    return claims

