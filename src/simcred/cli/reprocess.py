"""Commands of paper 002: reprocess, vary."""

from __future__ import annotations

import sys
from dataclasses import replace
from enum import StrEnum
from pathlib import Path
from typing import Annotated

import typer

from simcred.cli._app import (
    Json,
    ResimVehicle,
    Scheduler,
    State,
    Workers,
    _steps,
    app,
    one_line_errors,
    out_console,
    plain_table,
    progress,
    say,
)
from simcred.cli._writing import Overwrite, Resume, writing
from simcred.errors import OptionError, SimcredError
from simcred.limits import check_count, check_finite


class CrossingSide(StrEnum):
    left = "left"
    right = "right"


class RoadFrame(StrEnum):
    given = "given"
    ego = "ego"
    lanelet = "lanelet"


class AdParameters(StrEnum):
    recording = "recording"
    default = "default"


class LaneSource(StrEnum):
    map = "map"
    configuration = "configuration"


class LongGaps(StrEnum):
    error = "error"
    longest = "longest"


@app.command()
@one_line_errors
def reprocess(
    measurement: Annotated[Path, typer.Argument(help=(
        "A measurement directory (simcred simulate cutin), an A9 sensor-data CSV, a CommonRoad "
        "XML scenario or a long-format CSV/Parquet table (with --time-column etc.)."))],
    out: Annotated[Path, typer.Option(help="Directory for the results.")],
    vehicle: ResimVehicle = "ks",
    object_id: Annotated[str | None, typer.Option(
        "--object", help="The traffic object: A9 object number (default: the lane changer); "
                         "CommonRoad obstacle id, or 'all' (one reprocessing per obstacle); "
                         "long format: object label (default 'to').")] = None,
    ego: Annotated[str | None, typer.Option(
        help="The EGO: CommonRoad obstacle id (default: the object's follower); long format: "
             "object label (default 'ego').")] = None,
    time_column: Annotated[str | None, typer.Option(
        help="Long format: the time column [s] (default t).")] = None,
    run_column: Annotated[str | None, typer.Option(help="Long format: the run column.")] = None,
    object_column: Annotated[str | None, typer.Option(
        help="Long format: the object column (else columns ego.x, to.x, ...).")] = None,
    run: Annotated[str | None, typer.Option(
        help="Long format: the run to reprocess when the table has several.")] = None,
    gt: Annotated[Path | None, typer.Option(
        help="Long format: a second table with the ground truth (same columns).")] = None,
    time_scale: Annotated[float, typer.Option(
        help="Long format: seconds per unit of the time column (0.001 for milliseconds).")
    ] = 1.0,
    road_frame: Annotated[RoadFrame | None, typer.Option(
        help="The road frame. Long format: 'given' (default: the table's x axis is the road, "
             "refused if the EGO does not travel along +x) or 'ego' (rotate into the EGO's "
             "direction of travel, a straight road assumed). CommonRoad: 'ego' (default, the "
             "same rotation) or 'lanelet' (Frenet frame along the lanelet centre line through "
             "the EGO's start).")] = None,
    reference_path: Annotated[Path | None, typer.Option(
        help="Long format: a lane centre line (table with columns x, y in driving direction); "
             "the drive is reprocessed in its Frenet frame.")] = None,
    max_gap: Annotated[float, typer.Option(
        help="Longest gap [s] in an object's samples that is reprocessed (gaps are reported, "
             "never bridged silently).")] = 0.5,
    long_gaps: Annotated[LongGaps, typer.Option(
        help="A longer gap: error, or reprocess the longest stretch without one.")] = "error",
    ad_parameters: Annotated[AdParameters | None, typer.Option(
        help="The resimulated EGO's set speed, lanes and ACC time gap: 'recording' (the recorded "
             "EGO's highest speed, its lane centred on its first position, the time gap of its "
             "gap to the object; default for A9, CommonRoad and long-format input) or 'default' "
             "(100 km/h, lanes at y = 0 and 3.5 m, 1.5 s: the manufactured universe's AD "
             "function; default for a measurement directory).")
    ] = None,
    set_speed: Annotated[float | None, typer.Option(
        help="Set speed [m/s] of the resimulated EGO's ACC (instead of the recorded or "
             "default one).")] = None,
    lanes: Annotated[LaneSource, typer.Option(
        help="Lane width and centres of the AD function, the risk and the reaction rules: "
             "'map' (a CommonRoad scenario's lanelets under the EGO; input without a map keeps "
             "the others) or 'configuration' (3.5 m lanes as --ad-parameters says).")] = "map",
    seed: Annotated[int, typer.Option(min=0, help="Seed of the resimulations' sensor noise.")] = 0,
    threshold: Annotated[float, typer.Option(help="Position RMSE [m] at which the fit stops "
                                                  "adding sections.")] = 0.02,
    scenario_based: Annotated[bool, typer.Option(
        help="Also resimulate with the scenario-based sensor model (needs GT).")] = True,
    overwrite: Overwrite = False,
    as_json: Json = False,
) -> None:
    """Reprocess a drive: fit, resimulate, refit, assess; errors per step (Wagner, Groh et al.)."""
    from simcred.report.reprocessing import write_reprocessed
    from simcred.reprocess.inputs import LongColumns, read_measurement
    from simcred.reprocess.output import summary_text
    from simcred.reprocess.pipeline import ReprocessConfig
    from simcred.reprocess.pipeline import reprocess as run_pipeline
    from simcred.sim.vehicles import vehicle_model

    vehicle_model(vehicle)  # validates the name before any work
    check_finite(threshold, "--threshold", minimum=0, open_minimum=True)
    check_finite(max_gap, "--max-gap", minimum=0, open_minimum=True)
    inputs = (measurement, *(p for p in (gt, reference_path) if p is not None))
    check_finite(time_scale, "--time-scale", minimum=0, open_minimum=True)
    is_xml = measurement.suffix.lower() == ".xml"
    if road_frame is RoadFrame.lanelet and not is_xml:
        raise OptionError("--road-frame lanelet is for a CommonRoad scenario (.xml)")
    if is_xml and road_frame is RoadFrame.given:
        raise OptionError("--road-frame given is for long-format tables (CommonRoad: ego or "
                          "lanelet)")
    if is_xml and reference_path is not None:
        raise OptionError("--reference-path is for long-format tables (CommonRoad: "
                          "--road-frame lanelet)")
    frame = road_frame.value if is_xml and road_frame is not None else None
    config = ReprocessConfig(vehicle=vehicle, seed=seed, threshold=threshold,
                             scenario_based=scenario_based, max_gap=max_gap,
                             long_gaps=long_gaps.value, lanes=LaneSource(lanes).value,
                             **_ad_options(measurement, ad_parameters, set_speed))
    if object_id is not None and object_id.lower() == "all":
        _reprocess_all(measurement, ego, config, out, as_json, overwrite, frame or "ego")
        return
    table_frame = None if is_xml or road_frame is None else road_frame.value
    long_options = (time_column, run_column, object_column, run,
                    None if time_scale == 1.0 else time_scale, table_frame, reference_path)
    columns = (None if all(v is None for v in long_options)
               else LongColumns(time_column or "t", run_column, object_column, run,
                                time_scale, table_frame or "given",
                                None if reference_path is None else str(reference_path)))
    with writing(out, *inputs, overwrite=overwrite) as target:
        drive = read_measurement(measurement, object_id, ego=ego, long=columns, gt=gt,
                                 frame=frame)
        try:
            result = run_pipeline(drive, config, _steps("reprocessing"))
        except SimcredError as exc:  # a step's message names the object, not the input
            raise SimcredError(f"{_where(measurement, drive.metadata)}: {exc}") from None
        write_reprocessed(result, target.path)
    if as_json:
        sys.stdout.write(summary_text(result))
    elif not State.quiet:
        _print_input(result.input_report)
        _print_ad_function(result.ad_function)
        _print_reactions(result)
        say(f"wrote errors.json, reaction.json, descriptions, scenario.xosc and "
            f"figures to {out}")


def _ad_options(measurement: Path, parameters: AdParameters | None,
                set_speed: float | None) -> dict:
    """``driver`` and ``from_recording`` of the ReprocessConfig for the AD-function options."""
    from simcred.reprocess.ad_function import RECORDED_PARAMETERS
    from simcred.sim.driver import DriverConfig

    if parameters is None:
        parameters = AdParameters.default if measurement.is_dir() else AdParameters.recording
    recorded = RECORDED_PARAMETERS if parameters is AdParameters.recording else ()
    if set_speed is None:
        return {"from_recording": recorded}
    check_finite(set_speed, "--set-speed", minimum=0, open_minimum=True)
    return {"driver": DriverConfig(set_speed=set_speed),
            "from_recording": tuple(p for p in recorded if p != "set_speed")}


def _reprocess_all(path: Path, ego: str | None, config, out: Path, as_json: bool,
                   overwrite: bool, frame: str) -> None:
    """``--object all``: every CommonRoad obstacle; exit 1 if any could not be reprocessed."""
    from simcred._json import dumps, envelope
    from simcred.report.reprocessing import write_reprocessed
    from simcred.reprocess.obstacles import reprocess_obstacles

    if path.suffix.lower() != ".xml" or ego is not None:
        raise OptionError("--object all is for a CommonRoad scenario (.xml), without --ego "
                          "(each obstacle gets its follower)")
    with writing(out, path, overwrite=overwrite) as target:
        batch = reprocess_obstacles(path, config, target.path, write_reprocessed,
                                    _steps("reprocessing"), frame=frame)
        summary = dumps(envelope("reprocess_all", batch.to_dict()))
        (target.path / "reprocess_all.json").write_text(summary)
    if as_json:
        sys.stdout.write(summary)
    elif not State.quiet:
        rows = [(str(o.obstacle), o.status, str(o.summary.get("ego", "—")),
                 o.reason or ", ".join(f"{k}: {v}" for k, v in o.summary["reactions"].items()))
                for o in batch.outcomes]
        out_console.print(plain_table("obstacles", ("obstacle", "status", "EGO",
                                                    "reactions / reason"), rows))
        say(f"{len(batch.outcomes) - len(batch.failed)} of {len(batch.outcomes)} obstacles "
            f"reprocessed; wrote reprocess_all.json and obj<ID>/ to {out}")
    if batch.failed:
        raise typer.Exit(1)


def _where(path: Path, metadata) -> str:
    """The input and the chosen objects, for a message of a pipeline step."""
    chosen = [f"{role} {metadata[key]}" for role, key in (("TO", "object"), ("EGO", "ego"))
              if key in metadata]
    return f"{path}" + (f" ({', '.join(chosen)})" if chosen else "")


def _print_input(report: dict) -> None:
    """The time base and every gap of the input, so that none goes unnoticed."""
    say(f"input: {report['samples']} samples on the {report['time_base']} time base, "
        f"{report['span'][0]:.2f}-{report['span'][1]:.2f} s, {len(report['gaps'])} gap(s)")
    for g in report["gaps"]:
        say(f"  gap: {g['recording']} object '{g['object']}' {g['start']:.3f}-{g['end']:.3f} s "
            f"({g['duration']:.3f} s, {g['missing_samples']} sample(s) missing)")
    if report.get("cut_to_longest_stretch"):
        lo, hi = report["cut_to_longest_stretch"]
        say(f"  cut to the longest stretch without a gap over the limit: {lo:.3f}-{hi:.3f} s")


@app.command()
@one_line_errors
def vary(
    description: Annotated[Path, typer.Argument(help="Scenario description JSON (e.g. "
                                                     "descriptions/fit_GT.json of reprocess).")],
    out: Annotated[Path, typer.Option(help="Directory for variations, runs and figures.")],
    n: Annotated[int, typer.Option("-n", "--n", help="Variations to generate.")] = 300,
    seed: Annotated[int, typer.Option(min=0, help="Seed: variation i uses SeedSequence(seed, "
                                           "spawn_key=(i,)); paper 002 varies with its seed "
                                           "+ 1.")] = 0,
    vehicle: ResimVehicle = "ks",
    crossing_side: Annotated[CrossingSide | None, typer.Option(
        help="Boundary of the EGO's lane the TO crosses: left (e.g. a cut-in from the left) or "
             "right (a cut-in from the right). Default: whichever it crosses first.")] = None,
    crossing_time: Annotated[float | None, typer.Option(
        help="Time [s] of the lane crossing (instead of detecting it).")] = None,
    boundary_y: Annotated[float | None, typer.Option(
        help="Lateral position [m] of the boundary the TO crosses (instead of the EGO's lane "
             "± lane width / 2).")] = None,
    lane_width: Annotated[float, typer.Option(
        help="Width [m] of the EGO's lane when the boundary is detected.")] = 3.5,
    workers: Workers = None,
    scheduler: Scheduler = None,
    overwrite: Overwrite = False,
    resume: Resume = False,
    as_json: Json = False,
) -> None:
    """Local variations of the TO's lane change (Wagner, Groh et al. sec. V): vary, resimulate,
    risk. The crossing is detected from the description (the first crossing of a boundary of
    the EGO's lane) unless given."""
    from simcred.report.reprocessing import write_variations
    from simcred.reprocess.vary import VaryConfig, run_campaign, summary_text
    from simcred.scenario.description import ScenarioDescription
    from simcred.sim.vehicles import vehicle_model

    vehicle_model(vehicle)
    check_count(n, "variations", "-n")
    options = replace(VaryConfig().options, crossing_time=crossing_time, boundary_y=boundary_y,
                      crossing_side=None if crossing_side is None else crossing_side.value,
                      lane_width=lane_width)
    with writing(out, description, overwrite=overwrite, resume=resume) as target:
        original = ScenarioDescription.read(description)
        with target.engine(workers, scheduler) as runner:
            campaign = run_campaign(original, VaryConfig(n=n, seed=seed, vehicle=vehicle,
                                                         options=options),
                                    runner=runner, progress_for=progress)
        write_variations(campaign, target.path)
    if as_json:
        sys.stdout.write(summary_text(campaign))
    elif not State.quiet:
        _print_campaign(campaign.summary())
        say(f"wrote variations.json, variation_set.json, runs.parquet and "
            f"figures/fig8_variations.png to {out}")


def _print_campaign(summary: dict) -> None:
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
    out_console.print(plain_table("variation campaign", ("what", "value"), rows))


def _print_ad_function(ad: dict) -> None:
    """The resimulated EGO's AD function and where its parameters came from."""
    lanes = ", ".join(f"{y:.2f}" for y in ad["lane_centres"])
    say(f"AD function: set speed {ad['set_speed']:.2f} m/s ({ad['from']['set_speed']}), lanes "
        f"at y = {lanes} m, {ad['lane_width']:.2f} m wide ({ad['from']['lanes']}), time gap "
        f"{ad['time_gap']:.2f} s ({ad['from']['time_gap']})")


def _print_reactions(result) -> None:
    rows = [(str(name), r.manoeuvre, "—" if r.time != r.time else
             f"{r.time:.2f}{'' if r.measurable else ' (at the start: not measurable)'}",
             f"{result.risk[name].max_risk:.3g}") for name, r in result.reactions.items()]
    out_console.print(plain_table("EGO reaction per representation",
                                  ("trace", "manoeuvre", "reaction time [s]", "max risk"), rows))
