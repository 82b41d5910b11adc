"""The ``simcred`` command line: thin commands that parse, call one library function, render.

Exit codes: 0 done, 1 negative verdict, 2 bad input or usage (one red line, no traceback),
3 undecided.
"""

from __future__ import annotations

import sys
from collections.abc import Callable, Sequence
from functools import wraps
from pathlib import Path
from typing import Annotated, TypeVar

import typer
from rich.console import Console
from rich.progress import track
from rich.table import Table

from simcred import __version__
from simcred.compare import compare as compare_sets
from simcred.compare import matrix as matrix_of_sets
from simcred.compare.kernels import Kernel
from simcred.compare.mmd import Estimator, Test
from simcred.engine import Progress
from simcred.errors import OptionError, SimcredError

app = typer.Typer(
    name="simcred",
    help="Can I trust this simulation for this test case?",
    pretty_exceptions_show_locals=False,
    add_completion=False,
)
out_console = Console()
err_console = Console(stderr=True)
EXIT_BAD_INPUT = 2
T = TypeVar("T")


class State:
    quiet = False
    debug = False


@app.callback()
def main(
    quiet: Annotated[bool, typer.Option("--quiet", "-q", help="No progress or tables.")] = False,
    debug: Annotated[bool, typer.Option("--debug", help="Tracebacks for input errors.")] = False,
    version: Annotated[bool, typer.Option("--version", help="Print the version and exit.",
                                          is_eager=True)] = False,
) -> None:
    """simcred: validity of simulation models for testing automated driving."""
    if version:
        out_console.print(f"simcred {__version__}")
        raise typer.Exit(0)
    State.quiet, State.debug = quiet, debug


def one_line_errors(command: Callable) -> Callable:
    """Turn a SimcredError into one red line on stderr and exit code 2."""

    @wraps(command)
    def wrapper(*args, **kwargs):
        try:
            return command(*args, **kwargs)
        except SimcredError as exc:
            if State.debug:
                raise
            err_console.print(f"[red]error:[/red] {exc}", highlight=False, soft_wrap=True)
            raise typer.Exit(EXIT_BAD_INPUT) from None

    return wrapper


def progress(description: str) -> Progress | None:
    """A rich progress bar on stderr, only on a terminal and without --quiet."""
    if State.quiet or not sys.stderr.isatty():
        return None
    return lambda items, total: track(items, total=total, description=description,
                                      console=err_console, transient=True)


def _split(text: str | None) -> list[str] | None:
    return None if text is None else [part.strip() for part in text.split(",")]


def _bins(text: str) -> int | list[int]:
    try:
        values = [int(part) for part in text.split(",")]
    except ValueError:
        raise OptionError(f"--bins must be an integer or a comma-separated list, got {text!r}"
                          ) from None
    return values[0] if len(values) == 1 else values


Features = Annotated[str | None, typer.Option(
    "--features", "-f", help="Comma-separated signals spanning the state space "
    "(default: all signals, which both sets must share).")]
Bins = Annotated[str, typer.Option(help="Equal-frequency bins per feature (≥ 2), or one per "
                                        "feature: 10,8.")]
KernelOpt = Annotated[Kernel, typer.Option(help="MMD kernel.")]
EstimatorOpt = Annotated[Estimator, typer.Option(help="MMD estimator: the paper's biased "
                                                      "MMD_b or the unbiased MMD²_u.")]
TestOpt = Annotated[Test, typer.Option(help="The paper's bound test or a permutation test.")]
Alpha = Annotated[float, typer.Option(help="Level of each test, in (0, 1).")]
Permutations = Annotated[int, typer.Option(help="Resamples of the permutation test.")]
Seed = Annotated[int | None, typer.Option(help="Seed (default: fresh entropy, stored in the "
                                               "result).")]
Continue = Annotated[bool, typer.Option("--continue-on-start-difference",
                                        help="Test transitions even if the start "
                                             "distributions differ.")]
StopEarly = Annotated[bool, typer.Option(
    "--stop-early/--all-permutations",
    help="Permutation test: stop once rejection is impossible (same verdicts; p-values above "
         "alpha are then sequential estimates), or always draw all permutations.")]
Workers = Annotated[int | None, typer.Option(help="Run on a local Dask cluster of N worker "
                                                   "processes (default: in-process).")]
Scheduler = Annotated[str | None, typer.Option(help="Run on the Dask scheduler at this address "
                                                    "(e.g. tcp://host:8786).")]
Json = Annotated[bool, typer.Option("--json", help="Print the result JSON to stdout.")]


def _options(features, bins, kernel, estimator, test, alpha, permutations, seed,
             continue_on_start_difference, stop_early) -> dict:
    return dict(features=_split(features), bins=_bins(bins), kernel=kernel.value,
                estimator=estimator.value, test=test.value, alpha=alpha,
                permutations=permutations, seed=seed,
                continue_on_start_difference=continue_on_start_difference,
                stop_early=stop_early)


@app.command()
@one_line_errors
def compare(
    a: Annotated[Path, typer.Argument(metavar="A", help="Trace set A: a CSV directory or a "
                                                        "Parquet file.")],
    b: Annotated[Path, typer.Argument(metavar="B", help="Trace set B: a CSV directory or a "
                                                        "Parquet file.")],
    features: Features = None,
    bins: Bins = "10",
    kernel: KernelOpt = Kernel.GAUSSIAN,
    estimator: EstimatorOpt = Estimator.BIASED,
    test: TestOpt = Test.BOUND,
    alpha: Alpha = 0.01,
    permutations: Permutations = 999,
    seed: Seed = None,
    continue_on_start_difference: Continue = False,
    stop_early: StopEarly = True,
    out: Annotated[Path | None, typer.Option(help="Directory for comparison.json and "
                                                  "state_map.png.")] = None,
    as_json: Json = False,
) -> None:
    """Compare two trace sets: the fraction of distinguishable transitions (Neurohr et al.)."""
    result = compare_sets(a, b, progress=progress("testing states"),
                          **_options(features, bins, kernel, estimator, test, alpha,
                                     permutations, seed, continue_on_start_difference,
                                     stop_early))
    if out is not None:
        from simcred.report.figures import state_map

        out.mkdir(parents=True, exist_ok=True)
        (out / "comparison.json").write_text(result.to_json())
        state_map(result, out / "state_map.png")
    if as_json:
        sys.stdout.write(result.to_json())
    elif not State.quiet:
        _print_comparison(result, out)


def _print_comparison(result, out: Path | None) -> None:
    table = Table(title=f"{result.inputs[0].source}  vs  {result.inputs[1].source}")
    table.add_column("quantity")
    table.add_column("value", justify="right")
    start = result.start
    verdict = "differ" if start.rejected else "equal (H0 kept)"
    table.add_row("start distributions", f"{verdict}, MMD {start.statistic:.4g}")
    table.add_row("states |S|", str(result.n_states))
    table.add_row("tested / rejected / untestable",
                  f"{len(result.states)} / {len(result.rejected_states)} / "
                  f"{len(result.untestable)}")
    distance = "stopped (start distributions differ)" if result.stopped \
        else f"{100 * result.distance:.2f} %"
    table.add_row("distance", distance)
    out_console.print(table)
    if out is not None:
        out_console.print(f"wrote {out / 'comparison.json'} and {out / 'state_map.png'}")


@app.command()
@one_line_errors
def matrix(
    sets: Annotated[list[Path], typer.Argument(metavar="SETS...", help="Two or more trace "
                                                                      "sets.")],
    names: Annotated[str | None, typer.Option(help="Comma-separated labels (default: file "
                                                   "names).")] = None,
    features: Features = None,
    bins: Bins = "10",
    kernel: KernelOpt = Kernel.GAUSSIAN,
    estimator: EstimatorOpt = Estimator.BIASED,
    test: TestOpt = Test.BOUND,
    alpha: Alpha = 0.01,
    permutations: Permutations = 999,
    seed: Seed = None,
    continue_on_start_difference: Continue = False,
    stop_early: StopEarly = True,
    workers: Workers = None,
    scheduler: Scheduler = None,
    out: Annotated[Path | None, typer.Option(help="Directory for matrix.json, matrix.csv and "
                                                  "matrix.png.")] = None,
    as_json: Json = False,
) -> None:
    """Distance matrix of N trace sets (as Table 3 of Neurohr et al.)."""
    result = matrix_of_sets(sets, names=_split(names), workers=workers, scheduler=scheduler,
                            progress=progress("comparing pairs"),
                            **_options(features, bins, kernel, estimator, test, alpha,
                                       permutations, seed, continue_on_start_difference,
                                     stop_early))
    if out is not None:
        from simcred.report.figures import distance_heatmap

        out.mkdir(parents=True, exist_ok=True)
        (out / "matrix.json").write_text(result.to_json())
        (out / "matrix.csv").write_text(result.to_csv())
        distance_heatmap(result, out / "matrix.png")
    if as_json:
        sys.stdout.write(result.to_json())
    elif not State.quiet:
        table = Table(title="distance [%] (distinguishable transitions)")
        table.add_column("")
        for name in result.names:
            table.add_column(name, justify="right")
        for name, row in zip(result.names, result.distances, strict=True):
            table.add_row(name, *("start≠" if v != v else f"{100 * v:.2f}" for v in row))
        out_console.print(table)
        if out is not None:
            out_console.print(f"wrote {out}/matrix.json, matrix.csv and matrix.png")


@app.command()
@one_line_errors
def example(
    out: Annotated[Path, typer.Option(help="Directory to write baseline/ and variant/ into.")],
    runs: Annotated[int, typer.Option(help="Runs per set.")] = 300,
    steps: Annotated[int, typer.Option(help="Steps per run.")] = 100,
    seed: Annotated[int, typer.Option(help="Seed.")] = 0,
    duration_scale: Annotated[float, typer.Option(help="Lane-change duration of the variant "
                                                       "relative to the baseline.")] = 0.8,
    parquet: Annotated[bool, typer.Option(help="Write Parquet files instead of CSV "
                                               "directories.")] = False,
) -> None:
    """Write the built-in example trace sets (seeded lane changes: baseline and variant)."""
    from simcred.examples import lane_change_sets

    if runs < 1 or steps < 2:
        raise OptionError(f"need runs ≥ 1 and steps ≥ 2, got runs={runs}, steps={steps}")
    suffix = ".parquet" if parquet else ""
    for traces, name in zip(lane_change_sets(runs, steps, seed=seed,
                                             duration_scale=duration_scale),
                            ("baseline", "variant"), strict=True):
        path = traces.write(out / f"{name}{suffix}")
        if not State.quiet:
            out_console.print(f"wrote {path} ({traces.n_runs} runs)")


simulate_app = typer.Typer(help="Simulate seeded campaigns of runs into trace sets.")
app.add_typer(simulate_app, name="simulate")
Runs = Annotated[int, typer.Option(help="Number of runs.")]
CampaignSeed = Annotated[int, typer.Option(help="Campaign seed: run i uses the stream "
                                                "SeedSequence(seed, spawn_key=(i,)).")]
TraceOut = Annotated[Path, typer.Option(help="Trace set to write: a directory (CSV, one file per "
                                             "run) or a .parquet file.")]
ChunkSize = Annotated[int, typer.Option(help="Runs per task.")]


def _simulate(experiment, params: dict, runs: int, seed: int, out: Path, chunk_size: int,
              workers: int | None, scheduler: str | None) -> None:
    from simcred.sim.campaign import Campaign

    campaign = Campaign(experiment, runs, seed, params, chunk_size)
    traces = campaign.run(workers=workers, scheduler=scheduler,
                          progress=progress("simulating chunks"))
    path = traces.write(out)
    if not State.quiet:
        out_console.print(f"wrote {path}: {traces.n_runs} runs, {traces.n_rows} rows, "
                          f"signals {', '.join(traces.signals)}")


@simulate_app.command("simplecar")
@one_line_errors
def simulate_simplecar(
    out: TraceOut,
    lam: Annotated[float, typer.Option("--lambda", help="Logical scenario λ: τ ~ U[λ-0.01, λ].")
                   ] = 1.0,
    runs: Runs = 1000,
    seed: CampaignSeed = 0,
    dt: Annotated[float, typer.Option(help="Sample period [s].")] = 2.0,
    duration: Annotated[float, typer.Option(help="Simulated time per run [s].")] = 40.0,
    chunk_size: ChunkSize = 250,
    workers: Workers = None,
    scheduler: Scheduler = None,
) -> None:
    """SimpleCar runs of the λ sweep (Neurohr et al. sec. VI-A, eq. 8)."""
    from simcred.sim.experiments import simplecar_sweep

    if not (dt > 0 and duration > 0):
        raise OptionError(f"dt and duration must be positive, got dt={dt}, duration={duration}")
    _simulate(simplecar_sweep.simulate, {"lam": lam, "dt": dt, "duration": duration}, runs,
              seed, out, chunk_size, workers, scheduler)


@simulate_app.command("tjunction")
@one_line_errors
def simulate_tjunction(
    out: TraceOut,
    category: Annotated[str, typer.Option(help="no-occlusion, occlusion or random.")
                        ] = "no-occlusion",
    runs: Runs = 1000,
    seed: CampaignSeed = 0,
    chunk_size: ChunkSize = 250,
    workers: Workers = None,
    scheduler: Scheduler = None,
) -> None:
    """T-junction runs with static occlusion (Neurohr et al. sec. VI-B)."""
    from simcred.sim.experiments import tjunction

    if category not in tjunction.CATEGORIES:
        raise OptionError(f"category must be one of {', '.join(tjunction.CATEGORIES)}; "
                          f"got {category!r}")
    _simulate(tjunction.simulate, {"category": category}, runs, seed, out, chunk_size,
              workers, scheduler)


@simulate_app.command("cutin")
@one_line_errors
def simulate_cutin(
    out: Annotated[Path, typer.Option(help="Measurement directory to write (gt.parquet, "
                                           "sd.parquet, measurement.json).")],
    seed: Annotated[int, typer.Option(help="Seed of the sensor and DGPS noise.")] = 0,
    ego_model: Annotated[str, typer.Option(help="EGO vehicle model of 'reality': st or ks.")
                         ] = "st",
) -> None:
    """Cut-in and brake, the manufactured universe of Wagner, Groh et al. (GT and SD)."""
    from simcred.sim.experiments import cutin

    measurement = cutin.simulate(seed, cutin.CutInConfig(ego_model=ego_model))
    measurement.write(out)
    if not State.quiet:
        out_console.print(f"wrote {out}: GT and SD, {measurement.sd.n_rows} samples each")


contracts_app = typer.Typer(help="Contracts of simulation models (Braun et al.): check, refine, "
                                 "configure, quotient.")
app.add_typer(contracts_app, name="contracts")
LibraryPath = Annotated[Path, typer.Argument(metavar="LIB.yaml", help="Contract library (YAML).")]
Timeout = Annotated[int, typer.Option(help="Solver time limit per query [ms]; beyond it the "
                                           "answer is 'unknown' (exit 3).")]
EXIT_CODES = {"holds": 0, "fails": 1, "unknown": 3}


def _emit(document: dict, as_json: bool, summary: str) -> None:
    import json

    if as_json:
        sys.stdout.write(json.dumps(document, indent=1, ensure_ascii=False) + "\n")
    elif not State.quiet:
        out_console.print(summary, highlight=False)


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


paper_app = typer.Typer(help="Regenerate the papers' experiments and check their claims.")
app.add_typer(paper_app, name="paper")


@paper_app.command("000")
@one_line_errors
def paper_000(
    out: Annotated[Path, typer.Option(help="Directory for figures, tables and claims.json.")],
    runs: Annotated[int | None, typer.Option(help="Runs per trace set (default: the "
                                                  "documented full size).")] = None,
    seed: Annotated[int, typer.Option(help="Seed of every campaign and test.")] = 0,
    workers: Workers = None,
    scheduler: Scheduler = None,
) -> None:
    """Neurohr et al. sec. VI: SimpleCar λ sweep (Figs. 5-7) and T-junction (Table 3)."""
    from simcred.engine import engine
    from simcred.paper import seed000
    from simcred.paper.claims import claims_table

    if runs is not None and runs < 2:
        raise OptionError(f"runs must be at least 2, got {runs}")
    with engine(workers, scheduler) as runner:
        claims = seed000.run_all(out, runs=runs, seed=seed, runner=runner,
                                 progress_for=progress)
    if not State.quiet:
        out_console.print(claims_table(claims, "seed 000: the paper's claims"))
        out_console.print(f"wrote figures, tables and claims.json to {out}")


@paper_app.command("002")
@one_line_errors
def paper_002(
    out: Annotated[Path, typer.Option(help="Directory for the measurement, the reprocessing "
                                           "results, figures and claims.json.")],
    seed: Annotated[int, typer.Option(help="Seed of the manufactured universe (the variations "
                                           "use seed + 1).")] = 0,
    variations: Annotated[int, typer.Option(help="Variations of the cut-in (sec. V).")] = 300,
    workers: Workers = None,
    scheduler: Scheduler = None,
) -> None:
    """Wagner, Groh et al.: reprocessing the cut-in (Figs. 3-8, eqs. 2-7) and its claims."""
    from simcred.engine import engine
    from simcred.paper import seed002
    from simcred.paper.claims import claims_table

    if variations < 20:
        raise OptionError(f"variations must be at least 20 (for the 5th/95th percentiles), "
                          f"got {variations}")
    with engine(workers, scheduler) as runner:
        claims = seed002.run_all(out, seed=seed, variations=variations, runner=runner,
                                 progress=_steps("paper 002"), progress_for=progress).claims
    if not State.quiet:
        out_console.print(claims_table(claims, "seed 002: the paper's claims"))
        out_console.print(f"wrote measurement, results, figures and claims.json to {out}")


ResimVehicle = Annotated[str, typer.Option(help="EGO vehicle model of the resimulation: ks or st.")]


@paper_app.command("all")
@one_line_errors
def paper_all(
    out: Annotated[Path, typer.Option(help="Directory for every seed's results and the "
                                           "combined claims.json.")],
    runs: Annotated[int | None, typer.Option(help="Seed 000: runs per trace set (default: the "
                                                  "documented full size).")] = None,
    variations: Annotated[int, typer.Option(help="Seed 002: variations of the cut-in.")] = 300,
    seed: Annotated[int, typer.Option(help="Seed of every experiment.")] = 0,
    workers: Workers = None,
    scheduler: Scheduler = None,
) -> None:
    """All three seeds: paper 000, paper 002, and seed 003's contracts on the cut-in."""
    from simcred.engine import engine
    from simcred.paper.all import AllOptions, run_all
    from simcred.paper.claims import claims_table

    if runs is not None and runs < 2:
        raise OptionError(f"runs must be at least 2, got {runs}")
    if variations < 20:
        raise OptionError(f"variations must be at least 20, got {variations}")
    with engine(workers, scheduler) as runner:
        claims = run_all(out, AllOptions(runs=runs, variations=variations, seed=seed),
                         runner=runner, progress=_steps("paper 002"), progress_for=progress)
    if not State.quiet:
        for key, found in claims.items():
            out_console.print(claims_table(found, f"seed {key}: claims"))
        total = sum(len(c) for c in claims.values())
        held = sum(c.passed for found in claims.values() for c in found)
        out_console.print(f"{held} of {total} claims hold; wrote {out / 'claims.json'}")


@app.command()
@one_line_errors
def reprocess(
    measurement: Annotated[Path, typer.Argument(help="A measurement directory (simcred simulate "
                                                     "cutin) or an A9 sensor-data CSV file.")],
    out: Annotated[Path, typer.Option(help="Directory for the results.")],
    vehicle: ResimVehicle = "ks",
    object_id: Annotated[int | None, typer.Option(
        "--object", help="A9 CSV: the object to reprocess (default: the lane changer).")] = None,
    seed: Annotated[int, typer.Option(help="Seed of the resimulations' sensor noise.")] = 0,
    threshold: Annotated[float, typer.Option(help="Position RMSE [m] at which the fit stops "
                                                  "adding sections.")] = 0.02,
    scenario_based: Annotated[bool, typer.Option(
        help="Also resimulate with the scenario-based sensor model (needs GT).")] = True,
) -> None:
    """Reprocess a drive: fit, resimulate, refit, assess; errors per step (Wagner, Groh et al.)."""
    from simcred.reprocess import output
    from simcred.reprocess.inputs import read_measurement
    from simcred.reprocess.pipeline import ReprocessConfig
    from simcred.reprocess.pipeline import reprocess as run_pipeline
    from simcred.sim.experiments.cutin import vehicle_model

    vehicle_model(vehicle)  # validates the name before any work
    config = ReprocessConfig(vehicle=vehicle, seed=seed, threshold=threshold,
                             scenario_based=scenario_based)
    result = run_pipeline(read_measurement(measurement, object_id), config,
                          _steps("reprocessing"))
    output.write(result, out)
    if not State.quiet:
        _print_reactions(result)
        out_console.print(f"wrote errors.json, reaction.json, descriptions, scenario.xosc and "
                          f"figures to {out}")


@app.command()
@one_line_errors
def vary(
    description: Annotated[Path, typer.Argument(help="Scenario description JSON (e.g. "
                                                     "descriptions/fit_GT.json of reprocess).")],
    out: Annotated[Path, typer.Option(help="Directory for variations, runs and figures.")],
    n: Annotated[int, typer.Option("-n", "--n", help="Variations to generate.")] = 300,
    seed: Annotated[int, typer.Option(help="Seed: variation i uses SeedSequence(seed, "
                                           "spawn_key=(i,)).")] = 1,
    vehicle: ResimVehicle = "ks",
    workers: Workers = None,
    scheduler: Scheduler = None,
) -> None:
    """Local variations of the TO's cut-in (Wagner, Groh et al. sec. V): vary, resimulate, risk."""
    from simcred.engine import engine
    from simcred.reprocess.vary import VaryConfig, run_campaign, write_campaign
    from simcred.scenario.description import ScenarioDescription
    from simcred.sim.experiments.cutin import vehicle_model

    if n < 1:
        raise OptionError(f"n must be at least 1, got {n}")
    vehicle_model(vehicle)
    original = ScenarioDescription.read(description)
    with engine(workers, scheduler) as runner:
        campaign = run_campaign(original, VaryConfig(n=n, seed=seed, vehicle=vehicle),
                                runner=runner, progress_for=progress)
    write_campaign(campaign, out)
    if not State.quiet:
        _print_campaign(campaign.summary())
        out_console.print(f"wrote variations.json, variation_set.json, runs.parquet and "
                          f"figures/fig8_variations.png to {out}")


def _print_campaign(summary: dict) -> None:
    table = Table(title="variation campaign")
    table.add_column("what")
    table.add_column("value")
    p = summary["max_risk_percentiles"]
    rows = [("generated / kept / rejected",
             f"{summary['generated']} / {summary['kept']} / {summary['rejected']}"),
            ("rejected because", ", ".join(f"{k}: {v}" for k, v in summary["rejections"].items())
             or "—"),
            ("manoeuvres", ", ".join(f"{k}: {v}" for k, v in summary["manoeuvres"].items())),
            ("same category", f"{summary['same_category']:.1%}"),
            ("max risk p5 / p50 / p95", f"{p['p5']:.3g} / {p['p50']:.3g} / {p['p95']:.3g}"),
            ("unvaried (rGT) max risk", f"{summary['reference']['max_risk']:.3g} "
                                        f"(percentile {summary['reference_risk_percentile']:.0f})"),
            ("outside the validity range", str(len(summary["validity"]["outside"])))]
    for row in rows:
        table.add_row(*row)
    out_console.print(table)


def _steps(description: str) -> Callable[[str], None] | None:
    """Prints each pipeline step on stderr (on a terminal, without --quiet)."""
    if State.quiet or not sys.stderr.isatty():
        return None
    return lambda step: err_console.print(f"[dim]{description}: {step}[/dim]")


def _print_reactions(result) -> None:
    table = Table(title="EGO reaction per representation")
    for column in ("trace", "manoeuvre", "reaction time [s]", "max risk"):
        table.add_column(column)
    for name, r in result.reactions.items():
        time = "—" if r.time != r.time else f"{r.time:.2f}"
        table.add_row(name, r.manoeuvre, time, f"{result.risk[name]['risk'].max():.3g}")
    out_console.print(table)


@app.command()
@one_line_errors
def report(
    directory: Annotated[Path, typer.Argument(metavar="DIR", help="Output directory of simcred "
                                                                  "paper all.")],
    out: Annotated[Path | None, typer.Option(help="HTML file to write (default: "
                                                  "DIR/index.html).")] = None,
) -> None:
    """Write a self-contained HTML report of the papers' claims, figures and provenance."""
    from simcred.report.html import write_report

    path = write_report(directory, out=out)
    if not State.quiet:
        out_console.print(str(path), markup=False, highlight=False, soft_wrap=True)


def run(argv: Sequence[str] | None = None) -> int:
    """Run the CLI and return its exit code; usage errors, too, are one line on stderr."""
    args = list(sys.argv[1:] if argv is None else argv) or ["--help"]
    try:
        code = app(args=args, prog_name="simcred", standalone_mode=False)
    except typer.TyperException as exc:
        err_console.print(f"[red]error:[/red] {exc.format_message()}", highlight=False,
                          soft_wrap=True)
        return exc.exit_code
    except typer.Abort:
        err_console.print("aborted")
        return 1
    return code if isinstance(code, int) else 0


def entry() -> None:
    """Console-script entry point."""
    sys.exit(run())


if __name__ == "__main__":  # pragma: no cover
    entry()
