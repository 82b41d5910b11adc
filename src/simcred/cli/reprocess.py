"""Commands of seed 002: reprocess, vary."""

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
    check_output,
    one_line_errors,
    out_console,
    plain_table,
    progress,
    say,
)
from simcred.limits import check_count, check_finite


class CrossingSide(StrEnum):
    left = "left"
    right = "right"


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
    as_json: Json = False,
) -> None:
    """Reprocess a drive: fit, resimulate, refit, assess; errors per step (Wagner, Groh et al.)."""
    from simcred.report.seed002 import write_reprocessed
    from simcred.reprocess.inputs import read_measurement
    from simcred.reprocess.pipeline import ReprocessConfig
    from simcred.reprocess.pipeline import reprocess as run_pipeline
    from simcred.sim.vehicles import vehicle_model

    vehicle_model(vehicle)  # validates the name before any work
    check_finite(threshold, "--threshold", minimum=0, open_minimum=True)
    check_output(out, measurement)
    config = ReprocessConfig(vehicle=vehicle, seed=seed, threshold=threshold,
                             scenario_based=scenario_based)
    result = run_pipeline(read_measurement(measurement, object_id), config,
                          _steps("reprocessing"))
    files = write_reprocessed(result, out)
    if as_json:
        sys.stdout.write(files["summary"].read_text())
    elif not State.quiet:
        _print_reactions(result)
        say(f"wrote errors.json, reaction.json, descriptions, scenario.xosc and "
            f"figures to {out}")


@app.command()
@one_line_errors
def vary(
    description: Annotated[Path, typer.Argument(help="Scenario description JSON (e.g. "
                                                     "descriptions/fit_GT.json of reprocess).")],
    out: Annotated[Path, typer.Option(help="Directory for variations, runs and figures.")],
    n: Annotated[int, typer.Option("-n", "--n", help="Variations to generate.")] = 300,
    seed: Annotated[int, typer.Option(help="Seed: variation i uses SeedSequence(seed, "
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
    as_json: Json = False,
) -> None:
    """Local variations of the TO's lane change (Wagner, Groh et al. sec. V): vary, resimulate,
    risk. The crossing is detected from the description (the first crossing of a boundary of
    the EGO's lane) unless given."""
    from simcred.engine import engine
    from simcred.report.seed002 import write_variations
    from simcred.reprocess.vary import VaryConfig, run_campaign
    from simcred.scenario.description import ScenarioDescription
    from simcred.sim.vehicles import vehicle_model

    vehicle_model(vehicle)
    check_count(n, "variations", "-n")
    options = replace(VaryConfig().options, crossing_time=crossing_time, boundary_y=boundary_y,
                      crossing_side=None if crossing_side is None else crossing_side.value,
                      lane_width=lane_width)
    check_output(out, description)
    original = ScenarioDescription.read(description)
    with engine(workers, scheduler) as runner:
        campaign = run_campaign(original, VaryConfig(n=n, seed=seed, vehicle=vehicle,
                                                     options=options),
                                runner=runner, progress_for=progress)
    files = write_variations(campaign, out)
    if as_json:
        sys.stdout.write(files["summary"].read_text())
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


def _print_reactions(result) -> None:
    rows = [(str(name), r.manoeuvre, "—" if r.time != r.time else f"{r.time:.2f}",
             f"{result.risk[name]['risk'].max():.3g}") for name, r in result.reactions.items()]
    out_console.print(plain_table("EGO reaction per representation",
                                  ("trace", "manoeuvre", "reaction time [s]", "max risk"), rows))
