"""Commands of seed 003: contracts check|refines|configure|quotient, monitor."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from simcred.cli._app import (
    Json,
    State,
    _emit,
    app,
    one_line_errors,
    out_console,
)
from simcred.errors import OptionError

contracts_app = typer.Typer(help="Contracts of simulation models (Braun et al.): check, refine, "
                                 "configure, quotient.")
app.add_typer(contracts_app, name="contracts")
LibraryPath = Annotated[Path, typer.Argument(metavar="LIB.yaml", help="Contract library (YAML).")]
Timeout = Annotated[int, typer.Option(help="Solver time limit per query [ms]; beyond it the "
                                           "answer is 'unknown' (exit 3).")]
EXIT_CODES = {"holds": 0, "fails": 1, "unknown": 3}



def _verdict_summary(verdict) -> str:
    color = {"holds": "green", "fails": "red", "unknown": "yellow"}[verdict.status.value]
    lines = [f"[{color}]{verdict.status.value}[/{color}]" + (f" — {verdict.reason}"
                                                              if verdict.reason else "")]
    if verdict.counterexample:
        lines.append("counterexample: " + ", ".join(f"{k} = {float(v):g}" for k, v in
                                                   verdict.counterexample.items()))
    lines += [f"  clause: {c}" for c in verdict.clauses]
    return "\n".join(lines)


@contracts_app.command("check")
@one_line_errors
def contracts_check(library: LibraryPath, timeout_ms: Timeout = 10_000,
                    as_json: Json = False) -> None:
    """Syntax, units, composability; compatibility and consistency of every model contract."""
    from simcred.contracts.algebra import compatible, consistent
    from simcred.contracts.library import Library

    lib = Library.read(library)
    rows = []
    for name, contract in lib.model_contracts.items():
        component = lib.spec.models[name].implements
        rows.append({"model": name, "component": component,
                     "compatible": compatible(contract, lib.controlled(component),
                                              types=lib.types, timeout_ms=timeout_ms).to_dict(),
                     "consistent": consistent(contract, lib.uncontrolled(component),
                                              types=lib.types, timeout_ms=timeout_ms).to_dict()})
    ok = all(r[k]["verdict"] == "holds" for r in rows for k in ("compatible", "consistent"))
    summary = "\n".join(f"{r['model']} ({r['component']}): compatible "
                         f"{r['compatible']['verdict']}, consistent {r['consistent']['verdict']}"
                         for r in rows)
    _emit({"library": str(library), "syntax": "ok", "units": "ok", "composability": "ok",
           "models": rows}, as_json, f"{library}: syntax, units and composability ok\n{summary}")
    if not ok:
        raise typer.Exit(1)


@contracts_app.command("refines")
@one_line_errors
def contracts_refines(
    library: LibraryPath,
    refining: Annotated[str, typer.Option(help="The refining contract C2 (a name).")],
    refined: Annotated[str, typer.Option(help="The refined contract C1 (a name).")],
    timeout_ms: Timeout = 10_000,
    as_json: Json = False,
) -> None:
    """Does C2 refine C1 (C2 ≼ C1)? Exit 0 holds, 1 fails, 3 unknown."""
    from simcred.contracts.algebra import refines
    from simcred.contracts.library import Library

    lib = Library.read(library)
    verdict = refines(lib.contract(refining), lib.contract(refined), types=lib.types,
                      timeout_ms=timeout_ms)
    _emit(verdict.to_dict(), as_json, f"{refining} ≼ {refined}: {_verdict_summary(verdict)}")
    raise typer.Exit(EXIT_CODES[verdict.status.value])


@contracts_app.command("configure")
@one_line_errors
def contracts_configure(
    library: LibraryPath,
    test_case: Annotated[str, typer.Option(help="The test case to configure a setup for.")],
    timeout_ms: Timeout = 10_000,
    as_json: Json = False,
) -> None:
    """The cheapest setup whose composition refines the test case contract, with the proof."""
    from simcred.contracts.configure import configure
    from simcred.contracts.library import Library

    result = configure(Library.read(library), test_case, timeout_ms=timeout_ms)
    if result.setup and result.status.value == "holds":
        setup = ", ".join(f"{c} = {m}" for c, m in result.setup.items())
        summary = (f"[green]{test_case}: cheapest valid setup[/green] {setup} (cost "
                   f"{result.cost:g}; {result.iterations} candidate(s) checked)\n"
                   + _verdict_summary(result.proof))
    else:
        summary = f"[red]{test_case}: {result.status.value}[/red] — {result.reason}"
    _emit(result.to_dict(), as_json, summary)
    raise typer.Exit(EXIT_CODES[result.status.value])


@contracts_app.command("quotient")
@one_line_errors
def contracts_quotient(
    library: LibraryPath,
    test_case: Annotated[str, typer.Option(help="The test case.")],
    given: Annotated[list[str], typer.Option(help="COMPONENT=MODEL already chosen (repeat).")],
    as_json: Json = False,
) -> None:
    """The requirement on the missing model(s): C_tc / (composition of the given models)."""
    from simcred.contracts.configure import missing_model_requirement, missing_ports
    from simcred.contracts.expr import to_text
    from simcred.contracts.library import Library
    from simcred.contracts.project import project

    pairs = {}
    for item in given:
        component, sep, model = item.partition("=")
        if not sep or not component or not model:
            raise OptionError(f"--given must be COMPONENT=MODEL, got {item!r}")
        pairs[component.strip()] = model.strip()
    lib = Library.read(library)
    requirement = missing_model_requirement(lib, test_case, pairs)
    projected = project(requirement, missing_ports(lib, pairs), types=lib.types)
    if projected is not None:
        requirement = projected
    document = {"test_case": test_case, "given": pairs,
                "projected_onto_ports": projected is not None,
                "assumption": to_text(requirement.assumption),
                "guarantee": to_text(requirement.guarantee)}
    _emit(document, as_json, f"requirement for the missing model(s):\n  assume:    "
          f"{document['assumption']}\n  guarantee: {document['guarantee']}")


@app.command("monitor")
@one_line_errors
def monitor_runs(
    library: LibraryPath,
    runs: Annotated[Path, typer.Argument(help="Recorded runs: a CSV directory or a Parquet file; "
                                              "signals named as the library's variables.")],
    setup: Annotated[str | None, typer.Option(help="COMPONENT=MODEL,... to monitor.")] = None,
    test_case: Annotated[str | None, typer.Option(help="Configure the cheapest valid setup for "
                                                       "this test case and monitor it.")] = None,
    out: Annotated[Path | None, typer.Option(help="Write the report JSON here.")] = None,
    as_json: Json = False,
) -> None:
    """Check recorded runs against the validity domains of a setup's models (exit 1 on a
    violation)."""
    from simcred.contracts.configure import configure
    from simcred.contracts.library import Library
    from simcred.contracts.monitor import monitor
    from simcred.traces import TraceSet

    lib = Library.read(library)
    if (setup is None) == (test_case is None):
        raise OptionError("give either --setup COMPONENT=MODEL,... or --test-case NAME")
    if test_case is not None:
        result = configure(lib, test_case)
        if result.setup is None:
            raise OptionError(f"test case '{test_case}' has no valid setup: {result.reason}")
        models = list(result.setup.values())
    else:
        models = [item.partition("=")[2].strip() or item.strip() for item in setup.split(",")]
    contracts = {m: lib.contract(m) for m in models}
    report = monitor(TraceSet.read(runs), contracts)
    if out is not None:
        out.write_text(report.to_json())
    if as_json:
        sys.stdout.write(report.to_json())
    elif not State.quiet:
        table = Table(title=f"{runs}: {report.samples} samples, {report.clauses} clauses, "
                            f"{len(report.violations)} violation(s)")
        for column in ("model", "kind", "clause", "run", "steps", "t [s]", "margin"):
            table.add_column(column)
        for v in report.violations:
            table.add_row(v.contract, v.kind, v.clause, v.run, f"{v.first_step}–{v.last_step}",
                          f"{v.t_start:g}–{v.t_end:g}", f"{v.margin:.4g}")
        out_console.print(table)
    raise typer.Exit(0 if report.passed else 1)


