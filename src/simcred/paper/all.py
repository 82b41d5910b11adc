"""``simcred paper all``: the three papers one after the other into one directory, and one
``claims.json`` that collects theirs, with the provenance of the whole run.

Layout: ``paper000/``, ``paper002/`` (with ``variations/``), ``paper003/``, ``claims.json``.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from simcred._json import dumps, envelope, file_sha256
from simcred._version import versions as package_versions
from simcred.engine import Engine
from simcred.paper import markov_chains, reprocessing, validity_contracts
from simcred.paper.claims import Claim, write_claims
from simcred.traces import concat

TITLES = {
    "000": "Neurohr et al. 2023 — comparing sets of runs (Markov chains + MMD tests)",
    "002": "Wagner, Groh et al. — reprocessing a drive, scenario-based sensor model, variation",
    "003": "Braun et al. — contracts: configuration, quotient, monitors",
}
PACKAGES = ("numpy", "scipy", "pyarrow", "dask", "z3-solver", "scenariogeneration",
            "commonroad-vehicle-models", "matplotlib", "jinja2")


@dataclass(frozen=True, slots=True)
class AllOptions:
    runs: int | None = None
    variations: int = 300
    seed: int = 0


def versions() -> dict[str, str]:
    return package_versions(*PACKAGES)


def run_all(out: Path, options: AllOptions, *, runner: Engine,
            progress_for=lambda _: None) -> dict[str, list[Claim]]:
    """Run every paper into ``out`` and write the combined ``claims.json``."""
    out.mkdir(parents=True, exist_ok=True)
    claims = {"000": markov_chains.run_all(out / "paper000", runs=options.runs,
                                           seed=options.seed, runner=runner,
                                           progress_for=progress_for)}
    run002 = reprocessing.run_all(out / "paper002", seed=options.seed,
                                  variations=options.variations, runner=runner,
                                  progress_for=progress_for)
    claims["002"] = run002.claims
    monitored = {"resimulations": concat(list(run002.result.resimulations.values()),
                                         source="paper002 resimulations"),
                 "variations": run002.campaign.runs}
    _, claims["003"] = validity_contracts.run_contracts(out / "paper003", monitored)
    contracts = validity_contracts
    write_claims(claims["003"], out / "paper003" / "claims.json", {
        "library": contracts.LIBRARY.name, "test_case": contracts.TEST_CASE,
        "removed_model": contracts.REMOVED, "monitored_models": list(contracts.MONITORED_MODELS),
        "monitored_runs": {k: v.n_runs for k, v in monitored.items()},
        "monitor_tolerance": contracts.TOLERANCE})
    inputs = {
        validity_contracts.LIBRARY.name: file_sha256(validity_contracts.LIBRARY),
        "paper002/measurement/gt.parquet": file_sha256(out / "paper002/measurement/gt.parquet"),
        "paper002/measurement/sd.parquet": file_sha256(out / "paper002/measurement/sd.parquet"),
        "paper002/descriptions/fit_GT.json": file_sha256(out / "paper002/descriptions/fit_GT.json"),
    }
    _write_combined(out, options, inputs)
    return claims


def _write_combined(out: Path, options: AllOptions, inputs: dict[str, str]) -> Path:
    papers: dict[str, Any] = {}
    for key, title in TITLES.items():
        document = json.loads((out / f"paper{key}" / "claims.json").read_text())
        papers[key] = {"title": title, "provenance": document["provenance"],
                       "claims": document["claims"]}
    run = {"command": "simcred paper all",
           "options": {"runs": options.runs, "variations": options.variations,
                       "seed": options.seed},
           "versions": versions(), "inputs": inputs}
    path = out / "claims.json"
    path.write_text(dumps(envelope("claims_all", {"papers": papers, "run": run})))
    return path
