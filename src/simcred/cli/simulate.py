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

simulate_app = typer.Typer(help="Simulate seeded campaigns of runs into trace sets.")
app.add_typer(simulate_app, name="simulate")
Runs = Annotated[int, typer.Option(help="Number of runs.")]
CampaignSeed = Annotated[int, typer.Option(min=0, help="Campaign seed: run i uses the stream "
                                                "SeedSequence(seed, spawn_key=(i,)).")]
TraceOut = Annotated[Path, typer.Option(help="Trace set to write: a directory (CSV, one file per "
                                             "run) or a .parquet file.")]
ChunkSize = Annotated[int, typer.Option(help="Runs per task.")]


def _simulate(name: str, out: Path, params: dict, *, overwrite: bool = False,
              resume: bool = False) -> None:
    """Run the simulator ``name`` of :data:`simcred.sim.registry.SIMULATORS` (its checks first,
    then its runs written atomically to ``out``)."""
    from simcred.sim.registry import SIMULATORS

    simulator = SIMULATORS[name]
    params = simulator.defaults(**params)
    simulator.check(params)
    kind = trace_set_kind(out) if simulator.trace_set else "directory"
    with writing(out, *simulator.inputs(params), kind=kind, overwrite=overwrite,
                 resume=resume if simulator.resumable else None) as target:
        if simulator.runner:
            with target.engine(params["workers"], params["scheduler"]) as runner:
                summary = simulator.write(target.path, params, runner,
                                          progress(simulator.progress))
        else:
            summary = simulator.write(target.path, params, None, None)
    if not State.quiet:
        say(f"wrote {out}{'/' if simulator.slash else ''}: {summary}")


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
    _simulate("simplecar", out, {"lam": lam, "runs": runs, "seed": seed, "dt": dt,
                                 "duration": duration, "chunk_size": chunk_size,
                                 "workers": workers, "scheduler": scheduler},
              overwrite=overwrite, resume=resume)


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
    _simulate("tjunction", out, {"category": category, "runs": runs, "seed": seed,
                                 "chunk_size": chunk_size, "workers": workers,
                                 "scheduler": scheduler}, overwrite=overwrite, resume=resume)


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
    _simulate("cutin", out, {"seed": seed, "ego_model": ego_model}, overwrite=overwrite)


SumoModels = Annotated[str, typer.Option(
    "--models", help="Comma-separated SUMO car-following models (Krauss, IDM, EIDM, ACC, CACC, "
    "KraussPS, Wiedemann, W99); vType attributes after a colon, separated by '+': "
    "IDM:tau=1.2+accel=1.5.")]


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
    _simulate("sumo-following", out, {"traces": traces, "models": models, "seed": seed,
                                      "chunk_size": chunk_size, "workers": workers,
                                      "scheduler": scheduler},
              overwrite=overwrite, resume=resume)
