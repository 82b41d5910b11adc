"""Commands of paper 000: compare, matrix, example."""

from __future__ import annotations

import json
import sys
from dataclasses import replace
from enum import StrEnum
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
    check_output,
    one_line_errors,
    out_console,
    progress,
)
from simcred.cli._method import (
    CHECKS,
    build_method,
    check_alpha,
    method_options,
    parameter,
    parse_bins,
    split,
)
from simcred.cli._writing import Overwrite, Resume, writing
from simcred.compare import compare as compare_sets
from simcred.compare import matrix as matrix_of_sets
from simcred.compare.mmd import Test
from simcred.errors import OptionError
from simcred.limits import check_count, check_finite
from simcred.seeds import resolve_seed


class Side(StrEnum):
    """The recorded side of an observed comparison."""

    A = "a"
    B = "b"


#: ``--features`` as the method declares it (estimate-sensor offers it too).
Features = parameter("features").annotation


def _reader_options(items: list[str] | None) -> dict:
    """``--read KEY=VALUE`` pairs: a JSON value (number, true/false, list) where it parses, a
    comma list as a list of text, else the text itself."""
    options = {}
    for item in items or ():
        key, sep, value = item.partition("=")
        if not sep or not key.strip():
            raise OptionError(f"--read expects KEY=VALUE (a reader option), got {item!r}")
        try:
            parsed = json.loads(value)
        except ValueError:
            parsed = [p.strip() for p in value.split(",")] if "," in value else value
        options[key.strip()] = parsed
    return options


@app.command()
@one_line_errors
@method_options("compare")
def compare(
    a: Annotated[str, typer.Argument(metavar="A", help="Trace set A: a CSV directory, a "
                                                        "Parquet file, or a Parquet data set "
                                                        "(folder, glob or URI; read out of "
                                                        "core).")],
    b: Annotated[str, typer.Argument(metavar="B", help="Trace set B, as A.")],
    method: dict | None = None,  # the method options (method_options)
    read: Annotated[list[str] | None, typer.Option(
        "--read", help="A reader option KEY=VALUE for both inputs, repeatable (the format's own, "
                       "as in `simcred convert`: e.g. runs=namespace for ROS 2 bags, "
                       "runs=recordings for highD-family folders, "
                       "topics=/a/odom,/b/odom).")] = None,
    observed: Annotated[Side | None, typer.Option(
        help="The side that is a sensor's recording; the other side's ground truth is pushed "
             "through --sensor before the comparison (docs/observed.md).")] = None,
    sensor: Annotated[Path | None, typer.Option(
        help="Sensor model JSON for --observed (declared, or written by estimate-sensor).")
    ] = None,
    calibration: Annotated[str | None, typer.Option(
        help="Path b for --observed: GT,SD — ground truth and sensor recording of the same "
             "calibration runs; the observed side's hidden chain is estimated by an HMM "
             "(features and bins as given; docs/observed.md).")] = None,
    out: Annotated[Path | None, typer.Option(help="Directory for comparison.json and "
                                                  "state_map.png.")] = None,
    overwrite: Overwrite = False,
    as_json: Json = False,
) -> None:
    """Compare two trace sets: a chain verdict and the fraction of distinguishable transitions
    (Neurohr et al.)."""
    given = tuple(p if "://" in p else Path(p) for p in (a, b))  # a URI is no local Path
    a, b = Path(a), Path(b)
    for name in ("baseline", "bootstrap"):  # before any work: each repeats the whole test
        CHECKS[name](method[name])
    if (observed is None) != (sensor is None and calibration is None) \
            or (sensor is not None and calibration is not None):
        raise OptionError("--observed goes with one of --sensor (observation model) or "
                          "--calibration (path b, HMM): name the recorded side and how it is seen")
    if calibration is not None:
        _compare_hidden(a, b, observed.value, calibration, method, as_json)
        return
    if method["test"] is not Test.RESPONSE and any(
            method[name] for name in ("inputs", "pair_by", "group_by", "margin")):
        raise OptionError("--inputs, --pair-by, --group-by and --margin need --test response")
    settings = build_method(method)
    if observed is not None:
        if read:
            raise OptionError("--read does not combine with --observed yet: convert the inputs "
                              "first (simcred convert)")
        _compare_observed(a, b, observed.value, sensor, out, overwrite, as_json, settings)
        return
    sets = _read_sets(*given, _reader_options(read))
    from simcred.io.dataset import is_dataset

    steps = progress("partitions (3 passes)" if any(map(is_dataset, sets)) else "testing states")
    if out is None:
        result = compare_sets(*sets, settings, progress=steps)
    else:
        from simcred.report.figures import state_map

        with writing(out, a, b, overwrite=overwrite) as target:
            result = compare_sets(*sets, settings, progress=steps)
            (target.path / "comparison.json").write_text(result.to_json())
            state_map(result, target.path / "state_map.png")
    if as_json:
        sys.stdout.write(result.to_json())
    elif not State.quiet:
        _print_comparison(result, out)


def _read_sets(a: Path, b: Path, reader: dict) -> tuple:
    """The two inputs: paths as given (compare reads them), or read here with ``reader``."""
    if not reader:
        return a, b
    from simcred.io import read as read_set

    return read_set(a, **reader), read_set(b, **reader)


def _compare_observed(a, b, observed, sensor, out, overwrite, as_json, method) -> None:
    """``compare --observed``: the observation-model route (issue 23)."""
    from simcred.compare.observed import compare_observed

    def run():
        return compare_observed(a, b, observed=observed, sensor=sensor, sensor_effect=True,
                                progress=progress("testing states"), seed=method.seed,
                                method=method)

    if out is None:
        result = run()
    else:
        with writing(out, a, b, overwrite=overwrite) as target:
            result = run()
            (target.path / "comparison.json").write_text(json.dumps(result.to_dict(), indent=2))
    if as_json:
        sys.stdout.write(json.dumps(result.to_dict(), indent=2))
    elif not State.quiet:
        _print_comparison(result.comparison, out)
        effect = result.sensor_effect
        truth = "A" if observed == "b" else "B"
        out_console.print(
            f"side {observed.upper()} observed: side {truth} pushed through the sensor model, "
            f"both cropped by {result.cropped} samples; "
            f"{len(result.sensor.draws)} parameter draws carry its estimation uncertainty")
        if effect is not None and effect.chain is not None:
            out_console.print(f"the sensor alone: {truth}'s ground truth against its own "
                              f"observation, chain p = {effect.chain.pvalue:.3g}, distance "
                              f"{100 * (effect.distance or 0):.2f} %")


def _compare_hidden(a, b, observed, calibration, method, as_json) -> None:
    """``compare --observed --calibration``: path b (issue 23); of the method's options it
    takes features, bins, alpha, permutations (its resamples) and seed."""
    from simcred.compare.hidden import compare_hidden
    from simcred.traces import TraceSet

    paths = split(calibration) or []
    if len(paths) != 2:
        raise OptionError(f"--calibration must be GT,SD (two paths), got {calibration!r}")
    names = split(method["features"])
    if names is None:
        raise OptionError("--calibration needs --features (the hidden state's signals)")
    number = parse_bins(method["bins"])
    if not isinstance(number, int):
        raise OptionError("--calibration takes one --bins for every feature")
    alpha, resamples = check_alpha(method["alpha"]), method["permutations"]
    check_count(resamples, "permutations", "--permutations")
    result = compare_hidden(a, b, observed=observed, features=names, bins=number, alpha=alpha,
                            calibration=(TraceSet.read(paths[0]), TraceSet.read(paths[1])),
                            n_resamples=resamples, seed=method["seed"])
    if as_json:
        sys.stdout.write(json.dumps(result.to_dict(), indent=2))
    elif not State.quiet:
        verdict = "DIFFERENT hidden chains" if result.rejected else "no difference detected"
        out_console.print(
            f"path b (HMM, side {observed.upper()} observed): {verdict}, p = {result.pvalue:.3g}"
            f" ({result.n_resamples} parametric-bootstrap replicates), statistic "
            f"{result.statistic:.4g}, {result.n_states} hidden states, delays {result.lags} "
            f"samples, {100 * result.dropout:.1f} % dropouts")
        out_console.print(
            f"assumption checks: first-order Markov p = {result.markov_pvalue:.3g}, "
            f"time-invariant emissions p = {result.emission_pvalue:.3g} (small: the level is "
            "not guaranteed)")


@app.command("estimate-sensor")
@one_line_errors
def estimate_sensor(
    truth: Annotated[Path, typer.Argument(help="Ground truth of the calibration runs.")],
    recorded: Annotated[Path, typer.Argument(help="The sensor's recording of the same runs "
                                                  "(paired by run id, same times).")],
    out: Annotated[Path, typer.Option(help="Sensor model JSON to write.")],
    features: Features = None,
    max_delay: Annotated[float, typer.Option(help="Largest delay considered (s).")] = 2.0,
    bootstrap: Annotated[int, typer.Option(help="Bootstrap draws of the parameters (runs "
                                                "resampled): the estimation uncertainty.")] = 200,
    seed: Seed = None,
    overwrite: Overwrite = False,
) -> None:
    """Estimate a per-signal sensor model (offset, delay, noise, dropouts) from GT/SD pairs."""
    from simcred.compare.observed import estimate_sensor as estimate
    from simcred.outputs import write_atomic
    from simcred.traces import TraceSet

    check_finite(max_delay, "--max-delay", minimum=0)
    check_output(out, truth, recorded, kind="file", overwrite=overwrite)
    model = estimate(TraceSet.read(truth), TraceSet.read(recorded), signals=split(features),
                     max_delay=max_delay, bootstrap=bootstrap, seed=seed)
    write_atomic(out, json.dumps(model.to_dict(), indent=2) + "\n")
    if not State.quiet:
        for name, s in model.signals.items():
            out_console.print(f"{name}: offset {s.offset:.4g}, delay {s.delay:.3g} s, noise "
                              f"{s.noise_sd:.4g}, dropouts {100 * s.dropout:.1f} %")
        out_console.print(f"wrote {out}")


def _print_comparison(result, out: Path | None) -> None:
    table = Table(title=f"{result.inputs[0].source}  vs  {result.inputs[1].source}")
    table.add_column("quantity")
    table.add_column("value", justify="right")
    if result.response is not None:
        _response_rows(table, result)
    elif result.chain is not None:
        _chain_rows(table, result)
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
    if result.interval is not None:
        table.add_row(f"distance re-test spread ({100 * result.interval.level:.0f} %, "
                      "bootstrap, biased up)",
                      f"{100 * result.interval.low:.2f} – {100 * result.interval.high:.2f} %")
    out_console.print(table)
    if result.relevance:
        _print_relevance(result)
    if out is not None:
        out_console.print(f"wrote {out / 'comparison.json'} and {out / 'state_map.png'}")


def _chain_rows(table: Table, result) -> None:
    """The chain verdict and the baseline first: what a reader needs to judge the distance."""
    chain, options = result.chain, result.options
    verdict = "DIFFERENT processes" if chain.rejected else "no difference detected"
    table.add_row("chain verdict (run-level)",
                  f"{verdict}: p = {chain.pvalue:.4g} (α = {options.alpha:g}, "
                  f"{chain.permutations} permutations)")
    distance = f"{100 * result.distance:.2f} %"
    if result.baseline is not None:
        base = result.baseline
        table.add_row(f"distance vs same-model baseline ({options.multiplicity})",
                      f"{distance} where {len(base.distances)} splits of A give "
                      f"{100 * base.low:.2f}–{100 * base.high:.2f} % "
                      f"({base.nonzero} of {len(base.distances)} > 0)")
    table.add_section()


def _response_rows(table: Table, result) -> None:
    """The response verdict, the effect with its interval, equivalence, then the named tests."""
    chain, options, analysis = result.chain, result.options, result.response
    design = analysis.design
    verdict = "DIFFERENT response" if chain.rejected else "no difference shown"
    table.add_row("response verdict",
                  f"{verdict}: p = {chain.pvalue:.4g} (α = {options.alpha:g}, "
                  f"{chain.permutations} permutations, {design.kind}: {design.units_a} vs "
                  f"{design.units_b} units)")
    effect = analysis.effect
    for f in effect.features:
        equivalence = "" if f.margin is None else \
            (f"; equivalent within {f.margin:g}" if f.equivalent
             else f"; NOT shown equivalent within {f.margin:g}"
             + (" (these data cannot show it: the floor is above it)"
                if f.floor >= f.margin else ""))
        value = "not estimable (see the warning)" if effect.states == 0 else \
            (f"{f.estimate:.3g} ({100 * effect.level:.0f} % CI {f.low:.3g}–{f.high:.3g}; "
             f"detectable shift {f.mde:.3g}; upper bounds' floor {f.floor:.3g})")
        table.add_row(f"deviation of d{f.feature}/dt [{f.unit}]", value + equivalence)
    for test in analysis.scenario:
        table.add_row(f"{test.name} law (not part of the verdict)",
                      f"{'differs' if test.rejected else 'no difference shown'}, "
                      f"p = {test.pvalue:.4g}")
    for warning in analysis.warnings:
        table.add_row("warning", warning)
    table.add_section()


def _print_relevance(result) -> None:
    table = Table(title="feature relevance (chain p-value)")
    for column in ("feature", "alone", "left out"):
        table.add_column(column, justify="right" if column != "feature" else "left")
    for row in result.relevance:
        without = "–" if row.without_pvalue is None else f"{row.without_pvalue:.4g}"
        table.add_row(row.feature, f"{row.alone_pvalue:.4g}", without)
    out_console.print(table)


@app.command()
@one_line_errors
@method_options("matrix")
def matrix(
    sets: Annotated[list[Path], typer.Argument(metavar="SETS...", help="Two or more trace "
                                                                      "sets.")],
    names: Annotated[str | None, typer.Option(help="Comma-separated labels (default: file "
                                                   "names).")] = None,
    method: dict | None = None,  # the method options (method_options)
    workers: Workers = None,
    scheduler: Scheduler = None,
    out: Annotated[Path | None, typer.Option(help="Directory for matrix.json, matrix.csv and "
                                                  "matrix.png.")] = None,
    overwrite: Overwrite = False,
    resume: Resume = False,
    as_json: Json = False,
) -> None:
    """Distance matrix of N trace sets (as Table 3 of Neurohr et al.); with --out, finished
    pairs are checkpointed and --resume continues an interrupted run."""
    if resume and out is None:
        raise OptionError("--resume continues an interrupted run with --out: give --out")
    settings = build_method(method)
    if out is None:
        result = matrix_of_sets(sets, settings, names=split(names), workers=workers,
                                scheduler=scheduler, progress=progress("comparing pairs"))
    else:
        from simcred.report.figures import distance_heatmap

        with writing(out, *sets, overwrite=overwrite, resume=resume) as target, \
                target.engine(workers, scheduler) as runner:
            if settings.seed is None:  # fresh entropy, kept for a resumed run
                settings = replace(settings, seed=target.value("seed",
                                                               lambda: resolve_seed(None)))
            result = matrix_of_sets(sets, settings, names=split(names), runner=runner,
                                    progress=progress("comparing pairs"))
            (target.path / "matrix.json").write_text(result.to_json())
            (target.path / "matrix.csv").write_text(result.to_csv())
            distance_heatmap(result, target.path / "matrix.png")
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
    seed: Annotated[int, typer.Option(min=0, help="Seed.")] = 0,
    duration_scale: Annotated[float, typer.Option(help="Lane-change duration of the variant "
                                                       "relative to the baseline.")] = 0.8,
    parquet: Annotated[bool, typer.Option(help="Write Parquet files instead of CSV "
                                               "directories.")] = False,
    overwrite: Overwrite = False,
) -> None:
    """Write the built-in example trace sets (seeded lane changes: baseline and variant)."""
    from simcred.examples import lane_change_sets

    suffix = ".parquet" if parquet else ""
    with writing(out, overwrite=overwrite) as target:
        sets = lane_change_sets(runs, steps, seed=seed, duration_scale=duration_scale)
        for traces, name in zip(sets, ("baseline", "variant"), strict=True):
            traces.write(target.path / f"{name}{suffix}")
    if not State.quiet:
        for traces, name in zip(sets, ("baseline", "variant"), strict=True):
            out_console.print(f"wrote {out / f'{name}{suffix}'} ({traces.n_runs} runs)",
                              highlight=False)


