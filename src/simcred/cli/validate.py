"""``simcred validate VALIDATION.yaml --out DIR``: one verdict for the user's test case."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from simcred._json import dumps
from simcred.cli._app import (
    State,
    app,
    one_line_errors,
    out_console,
)
from simcred.cli._writing import Overwrite, Resume, writing
from simcred.report.validate import write_validation_report
from simcred.validate import read_inputs, read_validation, validate
from simcred.validate.simulate import simulate_candidates
from simcred.validate.spec import ValidationSpec
from simcred.validate.verdict import verdict_document


@app.command("validate")
@one_line_errors
def validate_command(
    validation: Annotated[Path, typer.Argument(help="The validation file (YAML).")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Folder for verdict.json, "
                                      "contracts.yaml (the learned contracts) and report.html.")],
    date: Annotated[str | None, typer.Option(help="Date to record in the provenance (none by "
                                             "default, so reruns are byte-identical).")] = None,
    no_report: Annotated[bool, typer.Option("--no-report", help="Skip the HTML report.")] = False,
    planned: Annotated[bool, typer.Option("--plan", help="Also plan the data: units per side "
                                          "and cell that would show equivalence with 80 % "
                                          "power, from a pilot of the reference, checked by "
                                          "simulation (verdict.json 'plan').")] = False,
    overwrite: Overwrite = False,
    resume: Resume = False,
) -> None:
    """Learn each candidate's validity domain, configure and monitor on it, and decide whether a
    candidate is valid for the test case. Exit 0 valid, 1 not valid, 3 inconclusive, 2 bad
    input. Candidates' simulations are checkpointed: --resume reuses those that finished."""
    spec, base = read_validation(validation)
    with writing(out, *_inputs(validation, spec, base), overwrite=overwrite,
                 resume=resume) as target:
        inputs = read_inputs(spec, base, simulate_candidates(spec, base, target.path,
                                                               target.checkpoint))
        result = validate(spec, inputs, source=str(validation), planned=planned)
        document = verdict_document(result, inputs, validation_file=validation, date=date)
        (target.path / "verdict.json").write_text(dumps(document), encoding="utf-8")
        (target.path / "contracts.yaml").write_text(result.library_yaml(), encoding="utf-8")
        if not no_report:
            write_validation_report(result, document, target.path)
    if not State.quiet:
        out_console.print(result.summary, highlight=False, soft_wrap=True)
        for verdict in result.candidates.values():
            out_console.print(f"  {verdict.candidate}: {verdict.verdict}", highlight=False)
            for reason in verdict.reasons:
                out_console.print(f"    - {reason}", highlight=False, soft_wrap=True)
        if result.observation is not None:
            _print_observation(document["observation"])
        if result.plan is not None:
            _print_plan(result.plan)
        out_console.print(f"wrote {out / 'verdict.json'}", highlight=False, soft_wrap=True)
    raise typer.Exit(result.exit_code)


def _print_observation(observation: dict) -> None:
    sensor = observation["sensor"]
    out_console.print(f"reference observed ({observation['route']}): the candidates pushed "
                      f"through the {sensor['kind']} sensor model ({sensor['source']}"
                      + (f", {sensor['draws']} parameter draws" if sensor["draws"] else "")
                      + f"), {observation['cropped_samples']} samples cropped per run",
                      highlight=False, soft_wrap=True)
    for name, cells in observation["sensor_alone"].items():
        for cell in cells:
            shown = ", ".join(f"{d['feature']} {d['estimate']:.3g} {d['unit']}"
                              for d in cell["deviation"]) or cell["reason"]
            out_console.print(f"  the sensor alone, {name}, {cell['label']}: {shown}",
                              highlight=False, soft_wrap=True)


def _print_plan(plan) -> None:
    out_console.print(f"plan: units per side and cell for {100 * plan.power:.0f} % power over "
                      f"the test case ({100 * plan.cell_power:.1f} % per cell)", highlight=False)
    for row in plan.rows:
        need = "not reachable at its estimate" if row.needed is None \
            else f"{row.needed} at its estimate"
        out_console.print(f"  {row.source}, {row.label}, {row.feature}: {row.units} now, "
                          f"estimate {row.estimate:.3g} ± {row.se:.2g} vs {row.tolerance:g}: "
                          f"{row.if_perfect} if as good as the reference, {need}",
                          highlight=False, soft_wrap=True)
    if plan.sizes:
        sizes = ", ".join(str(n) for n in plan.sizes.values())
        out_console.print(f"  a candidate as good as the reference, at {sizes} units per side "
                          f"in the {len(plan.sizes)} cells: shown valid in "
                          f"{100 * plan.simulated_power:.0f} % of {plan.simulations} "
                          "simulations", highlight=False)
    if plan.note:
        out_console.print(f"  {plan.note}", highlight=False, soft_wrap=True)
    for name, searched in plan.candidates.items():
        if searched.sizes:
            sizes = ", ".join(str(n) for n in searched.sizes.values())
            out_console.print(f"  {name} as good as the reference, its own pairs resampled: "
                              f"{sizes} pairs in the {len(searched.sizes)} cells, shown valid "
                              f"in {100 * searched.simulated_power:.0f} % of "
                              f"{searched.simulations} simulations", highlight=False)
        if searched.note:
            out_console.print(f"  {name}: {searched.note}", highlight=False, soft_wrap=True)


def _inputs(validation: Path, spec: ValidationSpec, base: Path) -> list[Path]:
    """Every file the validation reads: --out may not be, contain or lie inside one."""
    runs = [c.runs for c in spec.candidates.values() if c.runs is not None]
    observed = spec.reference.observed
    sensor = [base / observed.sensor] if observed and isinstance(observed.sensor, str) else []
    return [validation, *(base / r.path for r in [spec.reference, *runs, *spec.monitor]),
            *sensor]
