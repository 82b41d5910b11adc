"""Commands of seed 000: compare, matrix, example."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated

import typer
from rich.table import Table

from simcred.cli._app import (
    Json,
    Scheduler,
    Seed,
    State,
    Workers,
    app,
    one_line_errors,
    out_console,
    progress,
)
from simcred.compare import compare as compare_sets
from simcred.compare import matrix as matrix_of_sets
from simcred.compare.kernels import Kernel
from simcred.compare.mmd import Estimator, Test
from simcred.errors import OptionError


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
Continue = Annotated[bool, typer.Option("--continue-on-start-difference",
                                        help="Test transitions even if the start "
                                             "distributions differ.")]
StopEarly = Annotated[bool, typer.Option(
    "--stop-early/--all-permutations",
    help="Permutation test: stop once rejection is impossible (same verdicts; p-values above "
         "alpha are then sequential estimates), or always draw all permutations.")]


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


