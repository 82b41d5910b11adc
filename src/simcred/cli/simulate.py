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
from simcred.cli._writing import Overwrite, Resume, trace_set_kind, writing
from simcred.errors import OptionError
from simcred.limits import check_count, check_finite

simulate_app = typer.Typer(help="Simulate seeded campaigns of runs into trace sets.")
app.add_typer(simulate_app, name="simulate")
Runs = Annotated[int, typer.Option(help="Number of runs.")]
CampaignSeed = Annotated[int, typer.Option(min=0, help="Campaign seed: run i uses the stream "
                                                "SeedSequence(seed, spawn_key=(i,)).")]
TraceOut = Annotated[Path, typer.Option(help="Trace set to write: a directory (CSV, one file per "
                                             "run) or a .parquet file.")]
ChunkSize = Annotated[int, typer.Option(help="Runs per task.")]


def _simulate(experiment, params: dict, runs: int, seed: int, out: Path, chunk_size: int,
              workers: int | None, scheduler: str | None, overwrite: bool, resume: bool) -> None:
    from simcred.sim.campaign import Campaign

    campaign = Campaign(experiment, runs, seed, params, chunk_size)
    with writing(out, kind=trace_set_kind(out), overwrite=overwrite, resume=resume) as target, \
            target.engine(workers, scheduler) as runner:
        traces = campaign.run(runner=runner, progress=progress("simulating chunks"))
        traces.write(target.path)
    if not State.quiet:
        say(f"wrote {out}: {traces.n_runs} runs, {traces.n_rows} rows, "
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
    overwrite: Overwrite = False,
    resume: Resume = False,
) -> None:
    """SimpleCar runs of the λ sweep (Neurohr et al. sec. VI-A, eq. 8)."""
    from simcred.sim.experiments import simplecar_sweep

    check_finite(lam, "--lambda", minimum=0.01, open_minimum=True, maximum=100)
    check_finite(dt, "--dt", minimum=0, open_minimum=True)
    check_finite(duration, "--duration", minimum=0, open_minimum=True)
    steps = check_count(round(duration / dt) + 1, "steps", "--duration / --dt + 1")
    check_count(check_count(runs, "runs", "--runs") * steps, "rows", "--runs × steps")
    _simulate(simplecar_sweep.simulate, {"lam": lam, "dt": dt, "duration": duration}, runs,
              seed, out, chunk_size, workers, scheduler, overwrite, resume)


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
    overwrite: Overwrite = False,
    resume: Resume = False,
) -> None:
    """T-junction runs with static occlusion (Neurohr et al. sec. VI-B)."""
    from simcred.sim.experiments import tjunction

    if category not in tjunction.CATEGORIES:
        raise OptionError(f"category must be one of {', '.join(tjunction.CATEGORIES)}; "
                          f"got {category!r}")
    _simulate(tjunction.simulate, {"category": category}, runs, seed, out, chunk_size,
              workers, scheduler, overwrite, resume)


@simulate_app.command("cutin")
@one_line_errors
def simulate_cutin(
    out: Annotated[Path, typer.Option(help="Measurement directory to write (gt.parquet, "
                                           "sd.parquet, measurement.json).")],
    seed: Annotated[int, typer.Option(min=0, help="Seed of the sensor and DGPS noise.")] = 0,
    ego_model: Annotated[str, typer.Option(help="EGO vehicle model of 'reality': st or ks.")
                         ] = "st",
    overwrite: Overwrite = False,
) -> None:
    """Cut-in and brake, the manufactured universe of Wagner, Groh et al. (GT and SD)."""
    from simcred.sim.experiments import cutin

    with writing(out, overwrite=overwrite) as target:
        measurement = cutin.simulate(seed, cutin.CutInConfig(ego_model=ego_model))
        measurement.write(target.path)
    if not State.quiet:
        say(f"wrote {out}: GT and SD, {measurement.sd.n_rows} samples each")




SumoModels = Annotated[str, typer.Option(
    "--models", help="Comma-separated SUMO car-following models (Krauss, IDM, EIDM, ACC, CACC, "
    "KraussPS, Wiedemann, W99); vType attributes after a colon, separated by '+': "
    "IDM:tau=1.2+accel=1.5.")]


def _sumo_models(text: str) -> list[str]:
    return [part.strip().replace("+", ",") for part in text.split(",") if part.strip()]


@simulate_app.command("sumo-following")
@one_line_errors
def simulate_sumo_following(
    traces: Annotated[Path, typer.Argument(help="Car-following episodes: a trace set (CSV "
                                                "directory or Parquet) with signals gap [m], "
                                                "v [m/s] (follower) and v_leader [m/s].")],
    out: Annotated[Path, typer.Option(help="Directory for <model>.parquet per model and "
                                           "sumo-following.json (provenance).")],
    models: SumoModels = "Krauss,IDM,EIDM",
    seed: Annotated[int, typer.Option(min=0, help="Campaign seed: episode r runs with SUMO "
                                                  "--seed from SeedSequence(seed, hash(r)).")] = 0,
    chunk_size: Annotated[int, typer.Option(help="Episodes per task.")] = 50,
    workers: Workers = None,
    scheduler: Scheduler = None,
    overwrite: Overwrite = False,
    resume: Resume = False,
) -> None:
    """Replay the recorded leaders in SUMO; each model drives the follower (lane changes off).

    The leader's recorded speed [m/s] is imposed every step; the follower starts from the
    recorded gap [m] and speed [m/s]. Outputs: gap [m], dv [m/s] (leader −
    follower), v [m/s], a [m/s²], v_leader [m/s] on the input's time stamps [s].
    """
    from simcred.sim.sumo import replay, write_replays
    from simcred.traces import TraceSet

    with writing(out, traces, overwrite=overwrite, resume=resume) as target, \
            target.engine(workers, scheduler) as runner:
        source = TraceSet.read(traces)
        results = replay(source, _sumo_models(models), seed=seed, runner=runner,
                         chunk_size=chunk_size, progress=progress("SUMO episodes (chunks)"))
        written = write_replays(results, target.path, options={"models": models, "seed": seed,
                                                           "chunk_size": chunk_size})
    if not State.quiet:
        say(f"wrote {out}/: {', '.join(p.name for p in written)}: "
            f"{source.n_runs} episodes x {len(results)} models")
