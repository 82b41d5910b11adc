"""The user's loop (docs/validate.md): measurements → per-cell comparisons → learned domains →
contracts → configuration → monitors → one verdict for the test case.

Verdict of a candidate for the test case (its operating conditions, ``test_case.conditions``),
from its cells that meet the test case (:mod:`simcred.validate.domain`):

* ``valid`` — every such cell is valid (each deviation shown below its tolerance) and its learned
  contract refines the test case's (z3 proof). Wrongly valid with probability at most ``α``;
* ``not valid`` — some such cell is not valid (a deviation shown above its tolerance at the
  family level ``α/K``). Wrongly not valid with probability at most ``α``;
* ``inconclusive`` — otherwise: a cell whose data place the deviation on neither side, a cell
  without enough data, or conditions beyond the grid; the reasons say which and what the data
  could detect.

The overall verdict is ``valid`` when configuration finds a candidate (the cheapest whose contract
refines the test case), ``not valid`` when every candidate is not valid, else ``inconclusive``.
Exit codes 0 / 1 / 3. Candidates are ranked by their largest deviation relative to the tolerance
over the test case's cells, with a simultaneous interval (:mod:`simcred.validate.ranking`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import yaml

import simcred._display as _display
from simcred.compare.observed import SensorModel
from simcred.contracts.algebra import Contract, Status, Verdict, valid
from simcred.contracts.configure import Configuration, configure, setup_refines
from simcred.contracts.expr import Bool, negate, to_text
from simcred.contracts.library import Library
from simcred.contracts.monitor import MonitorReport, monitor
from simcred.errors import SimcredError
from simcred.regions.tables import domains_frame
from simcred.traces import TraceSet
from simcred.validate.cells import Grid, Segments, grid_of, segments
from simcred.validate.domain import (
    CellResult,
    CellRule,
    CellStatus,
    Domain,
    cell_rule,
    cell_settings,
    learn_domain,
)
from simcred.validate.learned import COMPONENT, TEST_CASE, built_contracts, library_dict
from simcred.validate.observed import (
    Observation,
    observation_level,
    read_sensor,
    with_sensor_alone,
)
from simcred.validate.plan import (
    PairedInput,
    Plan,
    cell_rows,
    needed_text,
    pilot,
    plan,
    power_per_cell,
)
from simcred.validate.ranking import Ranked, rank
from simcred.validate.spec import RunsSpec, ValidationFileError, ValidationSpec
from simcred.validate.tolerance import Resolution, placeholder, resolve

VALID, NOT_VALID, INCONCLUSIVE = "valid", "not valid", "inconclusive"
EXIT_CODES = {VALID: 0, NOT_VALID: 1, INCONCLUSIVE: 3}
MAX_VIOLATIONS = 50  # per monitor in verdict.json; the count says how many there are


@dataclass(frozen=True, slots=True, eq=False)
class Inputs:
    """The read trace sets; ``replays``: candidates a simulator command made by replaying the
    reference run by run (paired with it automatically); ``sensor``: the sensor model of an
    observed reference (:mod:`simcred.validate.observed`)."""

    reference: TraceSet
    candidates: dict[str, TraceSet]
    monitored: tuple[TraceSet, ...]
    replays: frozenset[str] = frozenset()
    sensor: SensorModel | None = None


@dataclass(frozen=True, slots=True, eq=False)
class CandidateVerdict:
    candidate: str
    verdict: str
    reasons: tuple[str, ...]
    relevant_cells: tuple[int, ...]
    proof: Verdict | None  # the z3 refinement of the test case, typed until written

    def to_dict(self) -> dict[str, Any]:
        return {"candidate": self.candidate, "verdict": self.verdict, "reasons":
                list(self.reasons), "test_case_cells": list(self.relevant_cells),
                "refinement": None if self.proof is None else _proof(self.proof)}


@dataclass(frozen=True, slots=True, eq=False)
class Validation:
    """Everything the loop found; ``verdict`` and ``exit_code`` answer the user's question."""

    spec: ValidationSpec
    grid: Grid
    domains: dict[str, Domain]
    candidates: dict[str, CandidateVerdict]
    verdict: str
    summary: str
    library: dict[str, Any]
    configuration: Configuration | None  # written by :func:`configuration_dict`
    uncovered: dict[str, list[str]]
    monitors: dict[str, MonitorReport]
    ranking: tuple[Ranked, ...] = ()
    plan: Plan | None = None
    tolerance_resolution: tuple[Resolution, ...] = ()
    observation: Observation | None = None

    @property
    def exit_code(self) -> int:
        return EXIT_CODES[self.verdict]

    def to_pandas(self):
        """Every candidate's cells as a ``pandas.DataFrame`` (:func:`simcred.regions.tables.
        domains_frame`: status, reason, data per side, deviation bounds per feature)."""
        return domains_frame(self.domains.values())

    def _repr_html_(self) -> str:
        """Notebook display: a summary table and a figure (:mod:`simcred.report.notebook`)."""
        return _display.html(self)

    def library_yaml(self) -> str:
        return yaml.safe_dump(self.library, sort_keys=False, allow_unicode=True, width=100)


def read_inputs(spec: ValidationSpec, base: Path,
                simulated: dict[str, RunsSpec] | None = None) -> Inputs:
    """Read every trace set; ``simulated`` gives the runs of candidates made by a simulator
    command (an absolute path per candidate name)."""
    simulated = simulated or {}
    missing = [n for n, c in spec.candidates.items() if c.runs is None and n not in simulated]
    if missing:
        raise ValidationFileError(f"candidates.{missing[0]}.simulate: the simulator command has "
                                  "not been run (simcred validate runs it, or "
                                  "simcred.validate.simulate_candidates)")
    return Inputs(_read(spec.reference, base),
                  {n: _read(c.runs or simulated[n], base) for n, c in spec.candidates.items()},
                  tuple(_read(m, base) for m in spec.monitor),
                  frozenset(n for n, c in spec.candidates.items() if c.simulate is not None),
                  read_sensor(spec, base))


def _read(runs: RunsSpec, base: Path) -> TraceSet:
    path = Path(runs.path)
    return TraceSet.read(path if path.is_absolute() else base / path, **runs.options)


def check_test_case(spec: ValidationSpec, source: str) -> None:
    """The test case's conditions parse over the condition variables (else a one-line error
    naming ``test_case.conditions``)."""
    try:
        Library.from_dict(library_dict(spec, {}), source=source)
    except SimcredError as exc:
        message = str(exc).split(": test_cases.test_case: ", 1)[-1]
        raise ValidationFileError(f"{source}: test_case.conditions: {message}") from None


def validate(spec: ValidationSpec, inputs: Inputs, *, source: str = "<memory>",
             planned: bool = False) -> Validation:
    """Run the loop (module docs) on validated inputs; ``planned``: also the data plan
    (:mod:`simcred.validate.plan`)."""
    check_test_case(placeholder(spec), source)
    _check_signals(spec, inputs)
    grid = grid_of(spec.conditions)
    units = inputs.reference.units
    empty = Library.from_dict(library_dict(placeholder(spec), {}, units), source="test case")
    relevant = _relevant_cells(grid, empty.test_case(TEST_CASE), empty)
    observation, seen = _observed(spec, inputs)
    reference = segments(seen.reference, grid, spec.segments.min_length)
    spec, resolution = resolve(spec, reference, relevant)
    rules = {n: cell_rule(spec, len(relevant), n in inputs.replays) for n in inputs.candidates}
    domains = {n: learn_domain(spec, grid, reference, runs, n, rules[n])
               for n, runs in seen.candidates.items()}
    data = library_dict(spec, domains, units)
    library = Library.from_dict(data, source="learned contracts", built=built_contracts(
        spec, domains, empty.test_case(TEST_CASE).assumption))
    target = library.test_case(TEST_CASE)
    beyond_text = _beyond_grid(grid, target, library)
    verdicts = {n: _candidate_verdict(spec, n, d, relevant, library, target, beyond_text)
                for n, d in domains.items()}
    configuration = _configuration(library)
    uncovered = {n: _uncovered(d, relevant, beyond_text) for n, d in domains.items()}
    monitors = _monitors(library, inputs)
    verdict, summary = _overall(spec, verdicts, configuration, planned)
    halves = pilot(spec, reference, relevant)
    needs = plan(spec, grid, halves, relevant, domains,
                 _paired(spec, grid, reference, seen, rules)) if planned else None
    ranking = rank(domains, relevant, spec, tuple(halves.comparisons.values()))
    if observation is not None:
        observation = with_sensor_alone(observation, spec, grid, relevant)
    return Validation(spec, grid, domains, verdicts, verdict, summary, data, configuration,
                      uncovered, monitors, ranking, needs, resolution, observation)


def _observed(spec: ValidationSpec, inputs: Inputs) -> tuple[Observation | None, Inputs]:
    """For an observed reference, the observation level and the inputs as compared there
    (candidates pushed through the sensor, every run cropped); else None and ``inputs``."""
    if spec.reference.observed is None:
        return None, inputs
    sensor = inputs.sensor
    if sensor is None and isinstance(spec.reference.observed.sensor, dict):
        sensor = read_sensor(spec, Path())  # declared inline: nothing to read from disk
    if sensor is None:
        raise ValidationFileError("reference.observed.sensor: the sensor model file was not "
                                  "read (read_inputs reads it, or give Inputs.sensor)")
    observation = observation_level(spec, sensor, inputs.reference, inputs.candidates)
    return observation, replace(inputs, reference=observation.reference,
                                candidates=observation.candidates)


def _paired(spec: ValidationSpec, grid: Grid, reference: Segments, inputs: Inputs,
            rules: dict[str, CellRule]) -> dict[str, PairedInput]:
    """The candidates whose runs pair with the reference's, for the plan."""
    settings = cell_settings(spec)
    return {n: PairedInput(rules[n], reference, settings.segments(inputs.candidates[n], grid))
            for n in inputs.candidates if rules[n].pair_by is not None}


def _check_signals(spec: ValidationSpec, inputs: Inputs) -> None:
    needed = [*spec.conditions, *spec.features]
    for traces, key in ((inputs.reference, "reference"),
                        *((t, f"candidates.{n}") for n, t in inputs.candidates.items())):
        for name in needed:
            if name not in traces.signals:
                raise ValidationFileError(f"{traces.source}: no signal '{name}' ({key}; signals "
                                          f"are: {', '.join(traces.signals)})")


def _relevant_cells(grid: Grid, target: Contract, library: Library) -> tuple[int, ...]:
    """Cells whose interior meets the test case's conditions: a test case that ends at an edge
    (``v <= 20``) does not reach the cell beyond it, as the learned contracts' closed cells say.
    Only a test case that meets no cell's interior (``v == 20``) counts the closed cells it
    touches."""
    for interior in (True, False):
        out = []
        for cell in range(grid.n_cells):
            box = grid.box(cell, interior=interior)
            disjoint = valid([box], negate(target.assumption), types=library.types)
            if disjoint.status is not Status.HOLDS:
                out.append(cell)
        if out:
            return tuple(out)
    return ()


def _configuration(library: Library) -> Configuration | None:
    """Configuration on the learned contracts (none without a learned model)."""
    return configure(library, TEST_CASE) if library.spec.models else None


def configuration_dict(found: Configuration | None) -> dict[str, Any] | None:
    """verdict.json's configuration, without solver models: z3's counterexamples depend on the
    solver's history in the process, which would break byte-identical verdicts (the reason is
    ours; the candidates' reasons say what is not covered)."""
    if found is None:
        return None
    reason = "" if found.status is Status.HOLDS else (
        "no candidate's learned contract refines the test case (see the candidates' reasons)"
        if found.status is Status.FAILS else "undecided (solver limit)")
    return {"status": found.status.value, "setup": found.setup, "cost": found.cost,
            "proof": None if found.proof is None else _proof(found.proof), "method": found.method,
            "reason": reason}


def _proof(verdict) -> dict[str, Any]:
    """The refinement verdict without the solver's clauses and model (which clauses a
    counterexample violates, or which premises an unsat core names, depends on z3's history
    within the process)."""
    return {"verdict": verdict.status.value, "reason": verdict.reason}


def _beyond_grid(grid: Grid, target: Contract, library: Library) -> str:
    """'' if the test case's conditions lie inside the grid, else what reaches beyond it."""
    box = grid.box()
    inside = valid([target.assumption], box, types=library.types)
    if inside.status is Status.HOLDS:
        return ""
    return f"the test case's conditions reach beyond the grid ({to_text(box)})"


def _uncovered(domain: Domain, relevant: tuple[int, ...], beyond: str) -> list[str]:
    """What of the test case the candidate's learned domain does not cover, cell by cell."""
    out = [f"{domain.cells[c].label}: {domain.cells[c].status.value}" for c in relevant
           if domain.cells[c].status is not CellStatus.VALID]
    return out + ([beyond] if beyond else [])


def _candidate_verdict(spec: ValidationSpec, name: str, domain: Domain, relevant: tuple[int, ...],
                       library: Library, target: Contract, beyond: str) -> CandidateVerdict:
    cells = [domain.cells[c] for c in relevant]
    bad = [c for c in cells if c.status is CellStatus.NOT_VALID]
    proof = None
    if name in library.spec.models:
        proof = setup_refines(library, {COMPONENT: name}, target)
    if bad:
        return CandidateVerdict(name, NOT_VALID, tuple(f"not valid in {c.label}: {c.reason}"
                                                       for c in bad), relevant, proof)
    if proof is not None and proof.holds:
        return CandidateVerdict(name, VALID, (f"valid in all {len(cells)} cells of the test "
                                              "case; its learned contract refines the test "
                                              "case (z3)",), relevant, proof)
    power = power_per_cell(len(relevant))
    reasons = [_undecided(name, c, spec, power) for c in cells if c.status is not CellStatus.VALID]
    if beyond:
        reasons.append(beyond)
    if not cells:
        reasons.append("no cell of the grid meets the test case's conditions")
    return CandidateVerdict(name, INCONCLUSIVE, tuple(reasons), relevant, proof)


def _undecided(name: str, cell: CellResult, spec: ValidationSpec, power: float) -> str:
    """An undecided cell's reason, with the data that would decide it when it was compared."""
    need = needed_text(cell_rows(name, cell, spec, power)) \
        if cell.status is CellStatus.INCONCLUSIVE else ""
    return f"{cell.status.value} in {cell.label}: {cell.reason}" + (f"; {need}" if need else "")


def _monitors(library: Library, inputs: Inputs) -> dict[str, MonitorReport]:
    """Each learned domain (assumption only: runs carry no deviation) over the candidate's own
    runs and over every monitored set."""
    out = {}
    for name in library.spec.models:
        domain = Contract(library.model_contracts[name].assumption, Bool(True), name)
        out[f"{name} on its own runs"] = monitor(inputs.candidates[name], {name: domain})
        for i, traces in enumerate(inputs.monitored):
            out[f"{name} on monitor[{i}]"] = monitor(traces, {name: domain})
    return out


def _overall(spec: ValidationSpec, verdicts: dict[str, CandidateVerdict],
             configuration: Configuration | None, planned: bool) -> tuple[str, str]:
    question = f"'{spec.test_case.conditions}'"
    if configuration is not None and configuration.status is Status.HOLDS:
        chosen = configuration.setup[COMPONENT]
        return VALID, (f"VALID: {chosen} is valid for the test case {question} (the cheapest "
                       "candidate whose learned contract refines the test case)")
    if all(v.verdict == NOT_VALID for v in verdicts.values()):
        names = ", ".join(verdicts)
        return NOT_VALID, f"NOT VALID: no candidate ({names}) is valid for {question}"
    open_ = ", ".join(n for n, v in verdicts.items() if v.verdict == INCONCLUSIVE)
    where = ("the plan says how much data would decide" if planned else
             "`simcred validate --plan` says how much data would decide")
    return INCONCLUSIVE, (f"INCONCLUSIVE: the data do not decide for {question} ({open_}: "
                          "deviations not placed on either side of the tolerance, cells "
                          f"without enough data or outside the grid); {where}")
