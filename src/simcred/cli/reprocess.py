"""Commands of seed 002: reprocess, vary."""

from __future__ import annotations

import sys
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
from simcred.limits import check_count, check_finite


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
    overwrite: Overwrite = False,
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
    config = ReprocessConfig(vehicle=vehicle, seed=seed, threshold=threshold,
                             scenario_based=scenario_based)
    with writing(out, measurement, overwrite=overwrite) as target:
        result = run_pipeline(read_measurement(measurement, object_id), config,
                              _steps("reprocessing"))
        summary = write_reprocessed(result, target.path)["summary"].read_text()
    if as_json:
        sys.stdout.write(summary)
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
    workers: Workers = None,
    scheduler: Scheduler = None,
    overwrite: Overwrite = False,
    resume: Resume = False,
    as_json: Json = False,
) -> None:
    """Local variations of the TO's cut-in (Wagner, Groh et al. sec. V): vary, resimulate, risk."""
    from simcred.report.seed002 import write_variations
    from simcred.reprocess.vary import VaryConfig, run_campaign
    from simcred.scenario.description import ScenarioDescription
    from simcred.sim.vehicles import vehicle_model

    vehicle_model(vehicle)
    check_count(n, "variations", "-n")
    with writing(out, description, overwrite=overwrite, resume=resume) as target:
        original = ScenarioDescription.read(description)
        with target.engine(workers, scheduler) as runner:
            campaign = run_campaign(original, VaryConfig(n=n, seed=seed, vehicle=vehicle),
                                    runner=runner, progress_for=progress)
        summary = write_variations(campaign, target.path)["summary"].read_text()
    if as_json:
        sys.stdout.write(summary)
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
