"""``verdict.json``: the verdict, its reasons and the provenance, byte for byte reproducible.

No wall-clock time enters the document: ``date`` is what the caller gives (an option), so the same
inputs, options and seed give the same bytes. Inputs are named by content hash (the validation
file's SHA-256, each trace set's digest), code by version and, when simcred runs from a git
checkout, its commit.
"""

from __future__ import annotations

import subprocess
from pathlib import Path
from typing import Any

from simcred._json import dumps, envelope, file_sha256
from simcred._version import versions
from simcred.validate.loop import MAX_VIOLATIONS, Inputs, Validation, configuration_dict


def verdict_document(result: Validation, inputs: Inputs, *, validation_file: Path | None = None,
                     date: str | None = None) -> dict[str, Any]:
    body = {
        "verdict": result.verdict,
        "summary": result.summary,
        "test_case": result.spec.test_case.model_dump(),
        "tolerance_resolution": [r.to_dict() for r in result.tolerance_resolution],
        "error_rates": error_rates(result),
        "ranking": [r.to_dict() for r in result.ranking],
        "plan": None if result.plan is None else result.plan.to_dict(),
        "candidates": {n: v.to_dict() for n, v in result.candidates.items()},
        "grid": {"variables": list(result.grid.variables), "units": list(result.grid.units),
                 "edges": [list(e) for e in result.grid.edges]},
        "domains": {n: d.to_dict() for n, d in result.domains.items()},
        "configuration": configuration_dict(result.configuration),
        "uncovered": result.uncovered,
        "monitors": {n: _monitor(m) for n, m in result.monitors.items()},
        "provenance": provenance(result, inputs, validation_file, date),
    }
    if result.observation is not None:  # only then: a direct validation keeps its bytes
        body = {"observation": result.observation.to_dict(), **body}
    return envelope("validation_verdict", body)


def error_rates(result: Validation) -> dict[str, Any]:
    """Which error probabilities the verdict controls, and at what level."""
    alpha = result.spec.comparison.alpha
    cells = len(next(iter(result.candidates.values())).relevant_cells)
    return {
        "alpha": alpha,
        "test_case_cells": cells,
        "false_valid": f"at most {alpha:g} per candidate: VALID needs, in every cell of the "
                       f"test case, each deviation's upper {1 - alpha:.4g} bound below its "
                       "tolerance (intersection-union test)",
        "false_not_valid": f"at most {alpha:g} per candidate within tolerance in every cell: "
                           f"NOT VALID needs, in some cell, a deviation's lower "
                           f"{1 - alpha / max(cells, 1):.4g} bound above its tolerance and its "
                           f"permutation test rejecting the same law at "
                           f"{alpha / max(cells, 1):.4g} (Bonferroni over the {cells} cells)",
        "overall": f"the chosen candidate is wrongly valid with probability at most {alpha:g} "
                   "times the number of candidates that are not within tolerance",
        "bounds": "cluster-bootstrap (basic) bounds over the design's units, upper bounds never "
                  "below the deviation the cell's permutation test detects with 50 % power (to "
                  "first order): approximate; their coverage is measured in docs/calibration.md",
    }


def verdict_json(result: Validation, inputs: Inputs, **kwargs: Any) -> str:
    return dumps(verdict_document(result, inputs, **kwargs))


def _monitor(report) -> dict[str, Any]:
    violations = [{"run": v.run, "first_step": v.first_step, "last_step": v.last_step,
                   "t_start": v.t_start, "t_end": v.t_end, "margin": v.margin}
                  for v in report.violations]
    return {"source": report.source, "runs": report.runs, "samples": report.samples,
            "passed": report.passed, "violations": len(violations),
            "runs_leaving_domain": len({v["run"] for v in violations}),
            "first_violations": violations[:MAX_VIOLATIONS]}


def provenance(result: Validation, inputs: Inputs, validation_file: Path | None,
               date: str | None) -> dict[str, Any]:
    return {
        "validation_file": None if validation_file is None else {
            "path": validation_file.name,
            "sha256": file_sha256(validation_file)},
        "inputs": {"reference": _set(inputs.reference),
                   "candidates": {n: _set(t) for n, t in inputs.candidates.items()},
                   "monitor": [_set(t) for t in inputs.monitored]},
        "options": result.spec.model_dump(mode="json"),
        "seed": result.spec.comparison.seed,
        "versions": versions("numpy", "scipy", "z3-solver"),
        "git_commit": git_commit(),
        "date": date,
    }


def _set(traces) -> dict[str, Any]:
    return {"source": Path(traces.source).name, "digest": traces.digest(),
            "runs": traces.n_runs, "rows": traces.n_rows}


def git_commit() -> str | None:
    """The commit of the checkout simcred runs from, if it is one (None otherwise)."""
    here = Path(__file__).resolve().parents[1]
    try:
        done = subprocess.run(["git", "-C", str(here), "rev-parse", "HEAD"], capture_output=True,
                              text=True, timeout=10, check=False)
    except (OSError, subprocess.SubprocessError):
        return None
    return done.stdout.strip() or None if done.returncode == 0 else None
