"""simcred data: the real data shipped with simcred (OpenACC, the A9 recording)."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Annotated

import typer

from simcred.cli._app import app, one_line_errors, out_console
from simcred.cli._writing import Overwrite, trace_set_kind, writing

data_app = typer.Typer(help="Real data shipped with simcred (with licences and attribution).")
app.add_typer(data_app, name="data")


@data_app.command("path")
@one_line_errors
def data_path(
    name: Annotated[str, typer.Argument(help="A shipped file or folder, e.g. "
                                             "a9/trajectories_file.csv or openacc.")],
) -> None:
    """Print the path of a shipped data file or folder."""
    from simcred import data

    typer.echo(str(data.path(name)))  # plain: a path is not rich markup


@data_app.command("list")
def data_list() -> None:
    """List every shipped data file."""
    from simcred import data

    for name in data.names():
        typer.echo(name)


@data_app.command("openacc")
@one_line_errors
def data_openacc(
    out: Annotated[Path, typer.Option(help="Trace set to write: a .parquet file or a CSV "
                                           "directory.")],
    follower: Annotated[str | None, typer.Option(help="human or acc (default: both).")] = None,
    source: Annotated[Path | None, typer.Option(help="Folder of OpenACC CSV or Parquet files "
                                                     "(default: the shipped copy).")] = None,
    duration: Annotated[float, typer.Option(help="Episode length [s].")] = 10.0,
    min_leader_speed: Annotated[float, typer.Option(help="Leader's mean speed must exceed "
                                                         "this [m/s].")] = 2.0,
    min_gap: Annotated[float, typer.Option(help="Smallest plausible gap [m].")] = 0.5,
    max_gap: Annotated[float, typer.Option(help="Largest plausible gap [m].")] = 120.0,
    overwrite: Overwrite = False,
) -> None:
    """Cut OpenACC leader–follower episodes (gap [m], dv [m/s], v [m/s], a [m/s²],
    v_leader [m/s]) into a trace set; prints what each episode rule removed."""
    from simcred import data
    from simcred.io.openacc import EpisodeRules, read_openacc

    inputs = [source if source is not None else data.path("openacc")]
    rules = EpisodeRules(duration=duration, min_leader_speed=min_leader_speed,
                         gap_range=(min_gap, max_gap))
    with writing(out, *inputs, kind=trace_set_kind(out), overwrite=overwrite) as target:
        traces = read_openacc(source, rules, follower=follower)
        traces = dataclasses.replace(traces, metadata={
            **traces.metadata, "provenance": _provenance(inputs[0], {
                "follower": follower, "duration": duration, "min_leader_speed":
                min_leader_speed, "min_gap": min_gap, "max_gap": max_gap})})
        traces.write(target.path)
    cut = traces.metadata["cut"]
    out_console.print(
        f"wrote {out}: {traces.n_runs} episodes of {duration} s from {cut['files']} files, "
        f"{cut['pairs']} pairs; of {cut['possible']} possible: {cut['removed_incomplete']} "
        f"incomplete, {cut['removed_leader_stopped']} leader stopped, {cut['removed_gap']} gap "
        f"out of range, {cut['kept']} kept", highlight=False)


def _provenance(root: Path, options: dict) -> dict:
    """What the episodes were cut from (content hashes), with which options and version."""
    from simcred._json import file_digest
    from simcred._version import __version__
    from simcred.io.openacc import recording_files

    files = recording_files(root)
    names = {p: p.relative_to(root).as_posix() if root.is_dir() else p.name for p in files}
    return {"simcred_version": __version__, "options": options,
            "inputs": {names[p]: file_digest(p) for p in files}}
