"""simcred simulate: seeded campaigns of runs into trace sets."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from simcred.cli._app import (
    Scheduler,
    State,
    Workers,
    app,
    one_line_errors,
    progress,
    say,
)
from simcred.errors import OptionError

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
        say(f"wrote {path}: {traces.n_runs} runs, {traces.n_rows} rows, "
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
        say(f"wrote {out}: GT and SD, {measurement.sd.n_rows} samples each")


