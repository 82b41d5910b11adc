"""Commands of paper 003: contracts check|refines|configure|quotient, monitor."""

from __future__ import annotations

import sys
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated

import typer
from rich.markup import escape
from rich.table import Table

from simcred.cli._app import (
    Json,
    State,
    _emit,
    app,
    check_output,
    one_line_errors,
    out_console,
)
from simcred.cli._writing import Overwrite
from simcred.errors import OptionError

contracts_app = typer.Typer(help="Contracts of simulation models (Braun et al.): check, refine, "
                                 "configure, quotient.")
app.add_typer(contracts_app, name="contracts")
LibraryPath = Annotated[Path, typer.Argument(metavar="LIB.yaml", help="Contract library (YAML).")]
Timeout = Annotated[int, typer.Option(min=1, max=3_600_000,
                                      help="Solver time limit per query [ms]; beyond it the "
                                           "answer is 'unknown' (exit 3).")]
EXIT_CODES = {"holds": 0, "fails": 1, "unknown": 3}



def _value(v) -> str:
    """A counterexample value as a short decimal (the exact rational is in the JSON)."""
    from simcred.contracts.expr import decimal_text

    if isinstance(v, bool):
        return str(v).lower()
    return decimal_text(v) or f"{float(v):.6g}"


def _point(point) -> str:
    return ", ".join(f"{k} = {_value(v)}" for k, v in point.items())


def _verdict_summary(verdict) -> str:
    """Markup-safe text of a verdict: status, reason, counterexample, clauses."""
    color = {"holds": "green", "fails": "red", "unknown": "yellow"}[verdict.status.value]
    lines = [f"[{color}]{verdict.status.value}[/{color}]" + (f" — {escape(verdict.reason)}"
                                                              if verdict.reason else "")]
    if verdict.counterexample:
        lines.append("counterexample: " + escape(_point(verdict.counterexample)))
    label = {"holds": "proof uses", "fails": "violated"}.get(verdict.status.value, "clause")
    lines += [f"  {label}: {escape(c)}" for c in verdict.clauses]
    return "\n".join(lines)


@contextmanager
def _about(library: Path):
    """Errors raised without a file (a temporal clause reaching z3) name the library."""
    from simcred.contracts.expr import ExpressionError

    try:
        yield
    except ExpressionError as exc:
        message = str(exc)
        raise ExpressionError(message if message.startswith(str(library))
                              else f"{library}: {message}") from None


def _worst(statuses) -> int:
    """Exit code of several verdicts: 1 if any fails, else 3 if any is unknown, else 0."""
    statuses = set(statuses)
    return 1 if "fails" in statuses else 3 if "unknown" in statuses else 0


def _receptivity(name: str, label: str, verdict, ports: str) -> str:
    """Why a receptivity check failed, in words."""
    if verdict.status.value == "holds":
        return f"{name}: {label} holds"
    if verdict.status.value == "unknown":
        return f"{name}: {label} unknown ({verdict.reason})"
    return (f"{name}: {label} FAILS — at {_point(verdict.counterexample)} no value of the other "
            f"variables satisfies '{verdict.clauses[0] if verdict.clauses else ''}' (it "
            f"constrains {ports})")


@contracts_app.command("check")
@one_line_errors
def contracts_check(library: LibraryPath, timeout_ms: Timeout = 10_000,
                    as_json: Json = False) -> None:
    """Names, units, composability, port scope, non-vacuity; compatibility and consistency of
    every model contract and every test case. Exit 0 ok, 1 a check fails, 3 undecided."""
    from simcred.contracts.algebra import compatible, consistent
    from simcred.contracts.expr import is_temporal
    from simcred.contracts.library import Library

    lib = Library.read(library)
    options = {"types": lib.types, "timeout_ms": timeout_ms}
    rows, lines = [], []
    for name, contract in lib.model_contracts.items():
        component = lib.spec.models[name].implements
        if is_temporal(contract.assumption) or is_temporal(contract.guarantee):
            lines.append(f"{name} ({component}): temporal, checked on runs by monitors only")
            continue
        compat = compatible(contract, lib.controlled(component), **options)
        consist = consistent(contract, lib.uncontrolled(component), **options)
        rows.append({"model": name, "component": component, "compatible": compat.to_dict(),
                     "consistent": consist.to_dict()})
        lines += [_receptivity(f"{name} ({component})", "compatible", compat,
                               "the component's outputs"),
                  _receptivity(f"{name} ({component})", "consistent", consist,
                               "the component's inputs")]
    rows_loops, loop_lines = _feedback_loops(lib, options)
    lines += loop_lines
    environment = lib.environment()
    cases = []
    for name, contract in lib.test_case_contracts.items():
        if is_temporal(contract.assumption) or is_temporal(contract.guarantee):
            lines.append(f"test case {name}: temporal, checked on runs by monitors only")
            continue
        consist = consistent(contract, environment, **options)
        cases.append({"test_case": name, "assumption_satisfiable": True,
                      "consistent": consist.to_dict()})
        lines.append(_receptivity(f"test case {name}", "consistent", consist,
                                  "the environment"))
    statuses = [r[k]["verdict"] for r in rows for k in ("compatible", "consistent")]
    statuses += [c["consistent"]["verdict"] for c in cases]
    statuses += [r["realisable"]["verdict"] for r in rows_loops]
    _emit({"library": str(library), "syntax": "ok", "units": "ok", "composability": "ok",
           "port_scope": "ok", "models": rows, "feedback_loops": rows_loops,
           "test_cases": cases}, as_json,
          escape(f"{library}: syntax, units, composability, port scope and non-vacuity ok\n"
                 + "\n".join(lines)))
    raise typer.Exit(_worst(statuses))


LOOP_COMBINATIONS = 256  # model combinations of one feedback loop checked by `check`


def _feedback_loops(lib, options) -> tuple[list[dict], list[str]]:
    """Every combination of models of each feedback loop: can their guarantees all hold for
    every input from outside the loop? (Each model's consistency does not imply it.)"""
    import itertools
    import math

    from simcred.contracts.expr import is_temporal
    from simcred.contracts.realisable import loops, setup_realisability

    rows, lines = [], []
    for group in loops(lib, lib.components()):
        candidates = [[m for m in lib.candidates(c)
                       if not any(map(is_temporal, (lib.model_contracts[m].assumption,
                                                    lib.model_contracts[m].guarantee)))]
                      for c in group]
        count = math.prod(len(c) for c in candidates)
        label = f"feedback loop {' → '.join(group)}"
        if count > LOOP_COMBINATIONS:
            lines.append(f"{label}: {count} model combinations, not checked (more than "
                         f"{LOOP_COMBINATIONS}; configure checks the setup it chooses)")
            continue
        for models in itertools.product(*candidates):
            check = setup_realisability(lib, dict(zip(group, models, strict=True)),
                                        timeout_ms=options["timeout_ms"])
            rows.append({"components": group, "models": list(models),
                         "realisable": check.verdict.to_dict()})
            head = f"{label} with {', '.join(models)}"
            status = check.verdict.status.value
            lines.append(f"{head}: realisable holds" if status == "holds" else
                         f"{head}: realisable unknown ({check.verdict.reason})"
                         if status == "unknown" else f"{head}: realisable FAILS — {check.text()}")
    return rows, lines


@contracts_app.command("refines")
@one_line_errors
def contracts_refines(
    library: LibraryPath,
    refining: Annotated[str, typer.Option(help="The refining contract C2: a name, or models "
                                               "M1,M2,... (their composition).")],
    refined: Annotated[str, typer.Option(help="The refined contract C1 (a name).")],
    timeout_ms: Timeout = 10_000,
    as_json: Json = False,
) -> None:
    """Does C2 refine C1 (C2 ≼ C1)? A proof whose premises contradict (a guarantee that cannot
    hold, a contradicting feedback loop) is no certificate. Exit 0 holds, 1 fails, 3 unknown."""
    from simcred.contracts.algebra import refines
    from simcred.contracts.library import Library

    lib = Library.read(library)
    names = [n.strip() for n in refining.split(",")]
    with _about(library):
        c2, c1 = _composition(lib, names), lib.contract(refined)
        verdict = refines(c2, c1, types=lib.types, timeout_ms=timeout_ms)
        if verdict.holds:
            verdict = _realisable(lib, names, c2, c1, refined, timeout_ms) or verdict
    _emit(verdict.to_dict(), as_json,
          f"{escape(refining)} ≼ {escape(refined)}: {_verdict_summary(verdict)}")
    raise typer.Exit(EXIT_CODES[verdict.status.value])


def _composition(lib, names: list[str]):
    """One contract by name, or the flat composition of several models (of distinct
    components)."""
    from simcred.contracts.configure import setup_contract

    if len(names) == 1:
        return lib.contract(names[0])
    return setup_contract(lib, _setup_of(lib, names, "--refining"))


def _setup_of(lib, names: list[str], option: str) -> dict[str, str]:
    """component → model for model names; each a model, one per component."""
    setup: dict[str, str] = {}
    for name in names:
        spec = lib.spec.models.get(name)
        if spec is None:
            raise OptionError(f"{option}: '{name}' is not a model (a composition is of models: "
                              f"{', '.join(lib.spec.models)})")
        if spec.implements in setup:
            raise OptionError(f"{option}: '{setup[spec.implements]}' and '{name}' are both "
                              f"models of component '{spec.implements}' (one model each)")
        setup[spec.implements] = name
    return setup


def _realisable(lib, names, refining, refined, refined_name, timeout_ms):
    """None if the refinement's premises can hold, else the verdict that says why not (no
    certificate): for models, each model consistent and their loops realisable for the
    environment a test case allows; for other contracts, A1 ∧ G2' satisfiable."""
    from simcred.contracts.algebra import Status, Verdict, valid
    from simcred.contracts.expr import Bool
    from simcred.contracts.realisable import setup_realisability

    if all(n in lib.spec.models for n in names):
        target = lib.test_case_contracts.get(refined_name)
        check = setup_realisability(lib, _setup_of(lib, names, "--refining"), target,
                                    timeout_ms=timeout_ms)
        if check.verdict.status is Status.HOLDS:
            return None
        if check.verdict.status is Status.UNKNOWN:
            return Verdict(Status.UNKNOWN, reason="refinement holds, but whether its premises "
                           f"can hold is undecided: {check.verdict.reason}")
        return Verdict(Status.FAILS, check.verdict.counterexample, check.verdict.clauses,
                       f"no certificate: the refinement holds only vacuously, {check.text()}")
    empty = valid([refined.assumption, refining.saturated_guarantee], Bool(False),
                  types=lib.types, timeout_ms=timeout_ms)
    if empty.status is Status.HOLDS:
        return Verdict(Status.FAILS, None, empty.clauses, "no certificate: the refinement holds "
                       "only vacuously, the refined assumption and the refining guarantee "
                       "contradict each other")
    return None


@contracts_app.command("configure")
@one_line_errors
def contracts_configure(
    library: LibraryPath,
    test_case: Annotated[str, typer.Option(help="The test case to configure a setup for.")],
    timeout_ms: Timeout = 10_000,
    explain: Annotated[int, typer.Option(min=0, max=100, help="How many of the cheapest setups "
                                         "below the answer to re-check and explain (the "
                                         "clause each leaves uncovered); 0: none.")] = 3,
    as_json: Json = False,
) -> None:
    """The cheapest setup whose composition refines the test case contract, with the proof,
    the path that answered and why the cheapest cheaper setups fail."""
    from simcred.contracts.configure import configure
    from simcred.contracts.library import Library

    lib = Library.read(library)
    with _about(library):
        result = configure(lib, test_case, timeout_ms=timeout_ms, explain=explain)
    if result.setup and result.status.value == "holds":
        setup = ", ".join(f"{c} = {m}" for c, m in result.setup.items())
        summary = (f"[green]{escape(test_case)}: cheapest valid setup[/green] {escape(setup)} "
                   f"(cost {result.cost:g}; {escape(result.method)})\n"
                   + _verdict_summary(result.proof))
    else:
        summary = (f"[red]{escape(test_case)}: {result.status.value}[/red] — "
                   f"{escape(result.reason)}")
    if result.path:
        summary += f"\nanswered by: {escape(result.path)}"
    if result.counterexamples:
        summary += "\npoints that ruled out cheaper setups:\n" + "\n".join(
            f"  {escape(_point(p))}" for p in result.counterexamples[:10])
    summary += "".join(f"\n{escape(line)}" for line in _cheaper_lines(result))
    _emit(result.to_dict(), as_json, summary)
    raise typer.Exit(EXIT_CODES[result.status.value])


def _cheaper_lines(result) -> list[str]:
    """Why the cheapest setups below the answer fail (:mod:`simcred.contracts.explain`): the
    models that differ from the answer, the cost, the first failing clause and its values."""
    if not result.cheaper:
        return []
    head = ("cheaper setups, and why each fails (re-checked with z3):" if result.setup
            and result.status.value == "holds" else
            "the cheapest setups, and why each fails (re-checked with z3):")
    lines = [head]
    for r in result.cheaper:
        if result.setup and result.status.value == "holds":
            changed = [f"{c} = {m} (instead of {result.setup[c]})"
                       for c, m in r.setup.items() if result.setup.get(c) != m]
        else:
            changed = [f"{c} = {m}" for c, m in r.setup.items()]
        what = ", ".join(changed)
        if r.kind in ("model assumption", "test case guarantee"):
            owner, clause = r.clauses[0]
            names = _names(clause)
            where = _point({k: v for k, v in r.point.items() if k in names})
            why = (f"{owner} assumes '{clause}', but the test case and the setup's "
                   f"guarantees allow {where}" if owner != "test case" else
                   f"the test case's guarantee '{clause}' fails at {where}, which the test "
                   "case and the setup's guarantees allow")
            more = len(r.clauses) - 1
            why += f" (and {more} more clause(s) there)" if more > 0 else ""
        else:
            why = r.reason or r.kind
        lines.append(f"  {what}; cost {float(r.cost):g}: {why}")
    return lines


def _names(clause: str) -> set[str]:
    from simcred.contracts.expr import variables
    from simcred.contracts.parse import parse

    return set(variables(parse(clause)))


@contracts_app.command("quotient")
@one_line_errors
def contracts_quotient(
    library: LibraryPath,
    test_case: Annotated[str, typer.Option(help="The test case.")],
    given: Annotated[list[str], typer.Option(help="COMPONENT=MODEL already chosen (repeat).")],
    as_json: Json = False,
) -> None:
    """The requirement on the missing model(s): C_tc / (composition of the given models)."""
    from simcred.contracts.library import Library
    from simcred.contracts.requirement import requirement

    pairs: dict[str, str] = {}
    for item in given:
        component, sep, model = item.partition("=")
        if not sep or not component or not model:
            raise OptionError(f"--given must be COMPONENT=MODEL, got {item!r}")
        pairs[component.strip()] = model.strip()
    lib = Library.read(library)
    found = requirement(lib, test_case, pairs)
    summary = (f"requirement for the missing model(s):\n  assume:    {found.assumption}"
               f"\n  guarantee: {found.guarantee}\n  ({found.method})")
    summary += "".join(f"\n{line}" for line in _uncovered_lines(found.uncovered))
    _emit(found.to_dict(), as_json, escape(summary))


def _uncovered_lines(uncovered: list[dict]) -> list[str]:
    """One line per given model and kind of uncovered assumption (see
    :func:`simcred.contracts.configure.uncovered_assumptions`)."""
    lines = []
    for item in uncovered:
        if item["kind"] == "dead end":
            lines.append(f"no missing model can help: {item['model']} assumes "
                         f"'{item['clause']}', but the test case allows {_point(item['at'])}")
    groups: dict[tuple[str, str], list[str]] = {}
    ensured: dict[str, list[str]] = {}  # "depends" clauses proven to follow from the requirement
    for item in uncovered:
        if item["kind"] == "depends" and item.get("ensured"):
            ensured.setdefault(item["model"], []).append(item["clause"])
        elif item["kind"] != "dead end":
            groups.setdefault((item["model"], item["kind"]), []).append(item["clause"])
    for (model, kind), clauses in groups.items():
        text = " and ".join(clauses)
        lines.append(f"the missing model(s) must ensure '{text}' ({model} assumes it; part of "
                     "the requirement above)" if kind == "requirement" else
                     f"{model} assumes '{text}': whether a missing model can ensure it depends "
                     "on what that model guarantees (see the requirement above)")
    if ensured:
        names = list(dict.fromkeys(n for clauses in ensured.values()
                                   for n in sorted(_names(" and ".join(clauses)))))
        lines.append(f"the assumptions of {', '.join(ensured)} (on {', '.join(names)}) hold "
                     "whenever the missing model(s) meet the requirement above (proven with z3)")
    return lines


@app.command("monitor")
@one_line_errors
def monitor_runs(
    library: LibraryPath,
    runs: Annotated[Path, typer.Argument(help="Recorded runs: a CSV directory or a Parquet file; "
                                              "signals named as the library's variables.")],
    setup: Annotated[str | None, typer.Option(help="COMPONENT=MODEL,... to monitor.")] = None,
    test_case: Annotated[str | None, typer.Option(help="Configure the cheapest valid setup for "
                                                       "this test case and monitor it.")] = None,
    out: Annotated[Path | None, typer.Option(help="Write the report JSON to this file.")] = None,
    overwrite: Overwrite = False,
    as_json: Json = False,
) -> None:
    """Check recorded runs against the validity domains of a setup's models (exit 1 on a
    violation)."""
    from simcred.contracts.configure import configure
    from simcred.contracts.library import Library
    from simcred.contracts.monitor import monitor
    from simcred.traces import TraceSet

    if out is not None:  # before any work: the report may not replace an input
        check_output(out, library, runs, kind="file", overwrite=overwrite)
    lib = Library.read(library)
    if (setup is None) == (test_case is None):
        raise OptionError("give either --setup COMPONENT=MODEL,... or --test-case NAME")
    if test_case is not None:
        result = configure(lib, test_case)
        if result.setup is None:
            raise OptionError(f"test case '{test_case}' has no valid setup: {result.reason}")
        models = list(result.setup.values())
    else:
        models = _setup_models(lib, setup)
    contracts = {m: lib.contract(m) for m in models}
    report = monitor(TraceSet.read(runs), contracts, unobserved=lib.unobserved)
    if out is not None:
        from simcred.outputs import write_atomic

        write_atomic(out, report.to_json())
    if as_json:
        sys.stdout.write(report.to_json())
    elif not State.quiet:
        table = Table(title=escape(f"{runs}: {report.samples} samples, {report.clauses} "
                                   f"clauses, {len(report.violations)} violation(s)"))
        for column in ("model", "kind", "clause", "run", "steps", "t [s]", "margin"):
            table.add_column(column)
        for v in report.violations:
            table.add_row(*map(escape, (v.contract, v.kind, v.clause, v.run)),
                          f"{v.first_step}–{v.last_step}", f"{v.t_start:g}–{v.t_end:g}",
                          f"{v.margin:.4g}")
        out_console.print(table)
        for clause in report.not_monitored:
            out_console.print(escape(f"not monitored (a variable no run carries): {clause}"))
    raise typer.Exit(0 if report.passed else 1)


def _setup_models(lib, setup: str) -> list[str]:
    """The models of ``--setup COMPONENT=MODEL,...``; each must implement its component, one
    model per component."""
    models, chosen = [], {}
    for item in setup.split(","):
        component, sep, model = (part.strip() for part in item.partition("="))
        if not sep or not component or not model:
            raise OptionError(f"--setup: expected COMPONENT=MODEL, got {item.strip()!r}")
        spec = lib.spec.models.get(model)
        if spec is None or spec.implements != component:
            known = ", ".join(lib.candidates(component)) if component in lib.spec.components \
                else f"no component '{component}'"
            raise OptionError(f"--setup: '{model}' is not a model of component '{component}' "
                              f"(models: {known})")
        if component in chosen:
            raise OptionError(f"--setup: component '{component}' has two models ('"
                              f"{chosen[component]}' and '{model}'); a setup has one each")
        chosen[component] = model
        models.append(model)
    return models
