"""``simcred validate VALIDATION.yaml --out DIR``: one verdict for the user's test case."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from simcred._json import dumps
from simcred.cli._app import State, app, one_line_errors, out_console
from simcred.errors import SimcredError
from simcred.report.validate import write_validation_report
from simcred.validate import read_inputs, read_validation, validate
from simcred.validate.spec import RunsSpec, ValidationSpec
from simcred.validate.verdict import verdict_document

OUTPUTS = ("verdict.json", "contracts.yaml", "report.html")


@app.command("validate")
@one_line_errors
def validate_command(
    validation: Annotated[Path, typer.Argument(help="The validation file (YAML).")],
    out: Annotated[Path, typer.Option("--out", "-o", help="Folder for verdict.json, "
                                      "contracts.yaml (the learned contracts) and report.html.")],
    date: Annotated[str | None, typer.Option(help="Date to record in the provenance (none by "
                                             "default, so reruns are byte-identical).")] = None,
    no_report: Annotated[bool, typer.Option("--no-report", help="Skip the HTML report.")] = False,
) -> None:
    """Learn each candidate's validity domain, configure and monitor on it, and decide whether a
    candidate is valid for the test case. Exit 0 valid, 1 not valid, 3 inconclusive, 2 bad
    input."""
    spec, base = read_validation(validation)
    _check_out(out, validation, spec, base)
    inputs = read_inputs(spec, base, simulate_candidates(spec, base, out))
    result = validate(spec, inputs, source=str(validation))
    document = verdict_document(result, inputs, validation_file=validation, date=date)
    out.mkdir(parents=True, exist_ok=True)
    (out / "verdict.json").write_text(dumps(document), encoding="utf-8")
    (out / "contracts.yaml").write_text(result.library_yaml(), encoding="utf-8")
    if not no_report:
        write_validation_report(result, document, out)
    if not State.quiet:
        out_console.print(result.summary, highlight=False, soft_wrap=True)
        for verdict in result.candidates.values():
            out_console.print(f"  {verdict.candidate}: {verdict.verdict}", highlight=False)
            for reason in verdict.reasons:
                out_console.print(f"    - {reason}", highlight=False, soft_wrap=True)
        out_console.print(f"wrote {out / 'verdict.json'}", highlight=False, soft_wrap=True)
    raise typer.Exit(result.exit_code)


def simulate_candidates(spec: ValidationSpec, base: Path, out: Path) -> dict[str, RunsSpec]:
    """Run each candidate's simulator command (in-process, ``simcred simulate ...``) into
    ``out/runs/<candidate>/``; the runs it wrote, per candidate."""
    made = {}
    for name, candidate in spec.candidates.items():
        if candidate.simulate is None:
            continue
        folder = (out / "runs" / name).resolve()
        folder.mkdir(parents=True, exist_ok=True)
        args = [a.replace("{base}", str(base)).replace("{out}", str(folder))
                for a in candidate.simulate.command]
        from simcred.cli import run

        quiet, debug = State.quiet, State.debug
        try:
            code = run(["--quiet", *args])
        finally:
            State.quiet, State.debug = quiet, debug
        if code != 0:
            raise SimcredError(f"candidates.{name}.simulate: 'simcred {' '.join(args)}' exited "
                               f"with {code}")
        made[name] = RunsSpec(path=str(folder / candidate.simulate.output),
                              options=candidate.simulate.options)
    return made


def _check_out(out: Path, validation: Path, spec: ValidationSpec, base: Path) -> None:
    """Outputs never overwrite inputs."""
    if out.exists() and not out.is_dir():
        raise SimcredError(f"{out}: --out must be a folder")
    runs = [c.runs for c in spec.candidates.values() if c.runs is not None]
    inputs = {validation.resolve(), *((base / r.path).resolve() for r in
                                      [spec.reference, *runs, *spec.monitor])}
    for name in OUTPUTS:
        if (out / name).resolve() in inputs:
            raise SimcredError(f"{out / name}: is an input of the validation; choose another "
                               "--out")
