"""Commands of seed 000: compare, matrix, example."""

from __future__ import annotations

import json
import sys
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
from simcred.cli._writing import Overwrite, Resume, writing
from simcred.compare import compare as compare_sets
from simcred.compare import matrix as matrix_of_sets
from simcred.compare.kernels import Kernel
from simcred.compare.mmd import Estimator, Test
from simcred.compare.runs import ChainStatistic, Multiplicity, OneSided
from simcred.errors import OptionError
from simcred.limits import check_count, check_finite
from simcred.seeds import resolve_seed


class Side(StrEnum):
    """The recorded side of an observed comparison."""

    A = "a"
    B = "b"


def _split(text: str | None) -> list[str] | None:
    return None if text is None else [part.strip() for part in text.split(",")]


#: Below this, 1/alpha and log(1/alpha) lose the precision the bound and the p-values need.
MIN_ALPHA = 1e-15


def _bins(text: str) -> int | list[int]:
    try:
        values = [int(part) for part in text.split(",")]
    except ValueError:
        raise OptionError(f"--bins must be an integer or a comma-separated list, got {text!r}"
                          ) from None
    for value in values:
        check_count(value, "bins", "--bins", minimum=2)
    return values[0] if len(values) == 1 else values


Features = Annotated[str | None, typer.Option(
    "--features", "-f", help="Comma-separated signals spanning the state space "
    "(default: all signals, which both sets must share).")]
Bins = Annotated[str, typer.Option(help="Equal-frequency bins per feature (≥ 2), or one per "
                                        "feature: 10,8.")]
KernelOpt = Annotated[Kernel, typer.Option(help="MMD kernel.")]
EstimatorOpt = Annotated[Estimator, typer.Option(help="MMD estimator: the paper's biased "
                                                      "MMD_b or the unbiased MMD²_u.")]
TestOpt = Annotated[Test, typer.Option(
    help="runs: run-level permutation test with a chain verdict (whole runs reassigned, valid "
         "when transitions within a run are dependent); response: the law of the response "
         "given the state (run lengths, visit frequencies and declared inputs are not part of "
         "it; paired/grouped designs, effect with interval, equivalence); bound / permutation: "
         "the paper's per-transition tests.")]
MultiplicityOpt = Annotated[Multiplicity | None, typer.Option(
    help="Per-state verdicts of the runs test: family-wise (max-T), FDR (Benjamini-Hochberg) or "
         "uncorrected. Default: fwer for --test runs, none otherwise.")]
ChainOpt = Annotated[ChainStatistic, typer.Option(
    "--chain", help="Chain statistic of the runs test: sum or max of standardised state "
                    "statistics.")]
OneSidedOpt = Annotated[OneSided, typer.Option(
    "--one-sided", help="Runs test: a state reached by one set only counts as evidence of a "
                        "difference, or as neutral.")]
History = Annotated[int, typer.Option(help="States are the last K binned feature vectors "
                                           "(1 = the paper's first-order chain).")]
TimeBins = Annotated[int | None, typer.Option(
    "--time-bins", help="Split time since run start into N equal-frequency windows that become "
                        "part of the state (N >= 2).")]
Resample = Annotated[float | None, typer.Option(
    help="Resample every run to this period in seconds (linear interpolation); needed when the "
         "sets have different sample periods.")]
Alpha = Annotated[float, typer.Option(help="Level of each test, in (0, 1).")]
Permutations = Annotated[int, typer.Option(help="Resamples of the permutation test.")]
Continue = Annotated[bool, typer.Option("--continue-on-start-difference",
                                        help="Test transitions even if the start "
                                             "distributions differ.")]
StopEarly = Annotated[bool, typer.Option(
    "--stop-early/--all-permutations",
    help="Permutation test: stop once rejection is impossible (same verdicts; p-values above "
         "alpha are then sequential estimates), or always draw all permutations.")]


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


def _margin(text: str | None) -> float | dict[str, float] | None:
    """``0.2`` (every response feature) or ``v=0.1,gap=0.3``."""
    if text is None:
        return None
    try:
        if "=" not in text:
            return float(text)
        pairs = [part.split("=") for part in text.split(",")]
        return {name.strip(): float(value) for name, value in pairs}
    except ValueError:
        raise OptionError(f"--margin must be a number or FEATURE=NUMBER,...; got {text!r}"
                          ) from None


def _options(features, bins, kernel, estimator, test, alpha, permutations, seed,
             continue_on_start_difference, stop_early, multiplicity=None, chain=ChainStatistic.SUM,
             one_sided=OneSided.EVIDENCE, history=1, time_bins=None, resample=None) -> dict:
    check_finite(alpha, "--alpha", minimum=MIN_ALPHA, maximum=1, open_maximum=True)
    check_count(permutations, "permutations", "--permutations")
    return dict(features=_split(features), bins=_bins(bins), kernel=kernel.value,
                estimator=estimator.value, test=test.value, alpha=alpha,
                permutations=permutations, seed=seed,
                continue_on_start_difference=continue_on_start_difference,
                stop_early=stop_early, multiplicity=None if multiplicity is None
                else multiplicity.value, chain=chain.value, one_sided=one_sided.value,
                history=history, time_bins=time_bins, resample=resample)


@app.command()
@one_line_errors
def compare(
    a: Annotated[str, typer.Argument(metavar="A", help="Trace set A: a CSV directory, a "
                                                        "Parquet file, or a Parquet data set "
                                                        "(folder, glob or URI; read out of "
                                                        "core).")],
    b: Annotated[str, typer.Argument(metavar="B", help="Trace set B, as A.")],
    features: Features = None,
    bins: Bins = "10",
    kernel: KernelOpt = Kernel.GAUSSIAN,
    estimator: EstimatorOpt = Estimator.BIASED,
    test: TestOpt = Test.RUNS,
    alpha: Alpha = 0.01,
    permutations: Permutations = 999,
    seed: Seed = None,
    multiplicity: MultiplicityOpt = None,
    chain: ChainOpt = ChainStatistic.SUM,
    one_sided: OneSidedOpt = OneSided.EVIDENCE,
    history: History = 1,
    time_bins: TimeBins = None,
    resample: Resample = None,
    baseline: Annotated[int, typer.Option(
        help="Runs test: random half-splits of A compared with each other (the distance's "
             "same-model baseline); 0 = none.")] = 10,
    bootstrap: Annotated[int, typer.Option(
        help="Runs test: bootstrap replicates for the distance's 95 % re-test spread "
             "(biased upward, not a confidence interval); 0 = none.")] = 0,
    relevance: Annotated[bool, typer.Option(
        help="Runs test: chain test per feature alone and per feature left out.")] = False,
    inputs: Annotated[str | None, typer.Option(
        help="Response test: comma-separated features the model does not control (a recorded "
             "leader's speed); they condition the state and are not compared.")] = None,
    pair_by: Annotated[str | None, typer.Option(
        "--pair-by", help="Response test: run_id or a per-run fact pairing each run of B with "
                          "the run of A it replays (the null swaps within pairs).")] = None,
    group_by: Annotated[str | None, typer.Option(
        "--group-by", help="Response test: a per-run fact (driver, recording, parent run) whose "
                           "runs form one unit, permuted and resampled whole.")] = None,
    margin: Annotated[str | None, typer.Option(
        help="Response test: equivalence margin of the response deviation, per second: one "
             "number for every response feature, or FEATURE=NUMBER,...")] = None,
    continue_on_start_difference: Continue = False,
    stop_early: StopEarly = True,
    read: Annotated[list[str] | None, typer.Option(
        "--read", help="A reader option KEY=VALUE for both inputs, repeatable (the format's own, "
                       "as in `simcred convert`: e.g. runs=namespace for ROS 2 bags, "
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
    check_count(baseline, "permutations", "--baseline", minimum=0)  # before any work: each
    check_count(bootstrap, "permutations", "--bootstrap", minimum=0)  # repeats the whole test
    if (observed is None) != (sensor is None and calibration is None) \
            or (sensor is not None and calibration is not None):
        raise OptionError("--observed goes with one of --sensor (observation model) or "
                          "--calibration (path b, HMM): name the recorded side and how it is seen")
    if calibration is not None:
        _compare_hidden(a, b, observed.value, calibration, features, bins, alpha, permutations,
                        seed, as_json)
        return
    extra = dict(baseline=baseline, bootstrap=bootstrap, relevance=relevance) \
        if test is Test.RUNS else {}
    if test is Test.RESPONSE:
        extra = dict(bootstrap=bootstrap, inputs=_split(inputs) or (), pair_by=pair_by,
                     group_by=group_by, margin=_margin(margin))
    elif inputs or pair_by or group_by or margin:
        raise OptionError("--inputs, --pair-by, --group-by and --margin need --test response")
    options = _options(features, bins, kernel, estimator, test, alpha, permutations, seed,
                       continue_on_start_difference, stop_early, multiplicity, chain, one_sided,
                       history, time_bins, resample)
    if observed is not None:
        if read:
            raise OptionError("--read does not combine with --observed yet: convert the inputs "
                              "first (simcred convert)")
        _compare_observed(a, b, observed.value, sensor, out, overwrite, as_json,
                          **extra, **options)
        return
    sets = _read_sets(*given, _reader_options(read))
    from simcred.io.dataset import is_dataset

    steps = progress("partitions (3 passes)" if any(map(is_dataset, sets)) else "testing states")
    if out is None:
        result = compare_sets(*sets, progress=steps, **extra, **options)
    else:
        from simcred.report.figures import state_map

        with writing(out, a, b, overwrite=overwrite) as target:
            result = compare_sets(*sets, progress=steps, **extra, **options)
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


def _compare_observed(a, b, observed, sensor, out, overwrite, as_json, **options) -> None:
    """``compare --observed``: the observation-model route (issue 23)."""
    from simcred.compare.observed import compare_observed

    def run():
        return compare_observed(a, b, observed=observed, sensor=sensor, sensor_effect=True,
                                progress=progress("testing states"), **options)

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


def _compare_hidden(a, b, observed, calibration, features, bins, alpha, resamples, seed,
                    as_json) -> None:
    """``compare --observed --calibration``: path b (issue 23)."""
    from simcred.compare.hidden import compare_hidden
    from simcred.traces import TraceSet

    paths = _split(calibration) or []
    if len(paths) != 2:
        raise OptionError(f"--calibration must be GT,SD (two paths), got {calibration!r}")
    names = _split(features)
    if names is None:
        raise OptionError("--calibration needs --features (the hidden state's signals)")
    number = _bins(bins)
    if not isinstance(number, int):
        raise OptionError("--calibration takes one --bins for every feature")
    check_finite(alpha, "--alpha", minimum=MIN_ALPHA, maximum=1, open_maximum=True)
    check_count(resamples, "permutations", "--permutations")
    result = compare_hidden(a, b, observed=observed, features=names, bins=number, alpha=alpha,
                            calibration=(TraceSet.read(paths[0]), TraceSet.read(paths[1])),
                            n_resamples=resamples, seed=seed)
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
    model = estimate(TraceSet.read(truth), TraceSet.read(recorded), signals=_split(features),
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
             else f"; NOT shown equivalent within {f.margin:g}")
        value = "not estimable (see the warning)" if effect.states == 0 else \
            (f"{f.estimate:.3g} ({100 * effect.level:.0f} % CI {f.low:.3g}–{f.high:.3g}; "
             f"detectable {f.mde:.3g})")
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
def matrix(
    sets: Annotated[list[Path], typer.Argument(metavar="SETS...", help="Two or more trace "
                                                                      "sets.")],
    names: Annotated[str | None, typer.Option(help="Comma-separated labels (default: file "
                                                   "names).")] = None,
    features: Features = None,
    bins: Bins = "10",
    kernel: KernelOpt = Kernel.GAUSSIAN,
    estimator: EstimatorOpt = Estimator.BIASED,
    test: TestOpt = Test.RUNS,
    alpha: Alpha = 0.01,
    permutations: Permutations = 999,
    seed: Seed = None,
    multiplicity: MultiplicityOpt = None,
    chain: ChainOpt = ChainStatistic.SUM,
    one_sided: OneSidedOpt = OneSided.EVIDENCE,
    history: History = 1,
    time_bins: TimeBins = None,
    resample: Resample = None,
    continue_on_start_difference: Continue = False,
    stop_early: StopEarly = True,
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
    options = _options(features, bins, kernel, estimator, test, alpha, permutations, seed,
                       continue_on_start_difference, stop_early, multiplicity, chain, one_sided,
                       history, time_bins, resample)
    if out is None:
        result = matrix_of_sets(sets, names=_split(names), workers=workers,
                                scheduler=scheduler, progress=progress("comparing pairs"),
                                **options)
    else:
        from simcred.report.figures import distance_heatmap

        with writing(out, *sets, overwrite=overwrite, resume=resume) as target, \
                target.engine(workers, scheduler) as runner:
            if options["seed"] is None:  # fresh entropy, kept for a resumed run
                options["seed"] = target.value("seed", lambda: resolve_seed(None))
            result = matrix_of_sets(sets, names=_split(names), runner=runner,
                                    progress=progress("comparing pairs"), **options)
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


