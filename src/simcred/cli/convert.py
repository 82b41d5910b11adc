"""simcred convert: any supported trace-set format in, any writable format out."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from simcred.cli._app import Json, _emit, app, one_line_errors

FORMAT_HELP = "csv-dir, parquet, long, sumo-fcd, commonroad, osi, levelx, mdf, ros2"


def _signals(text: str | None) -> list[str] | None:
    return None if text is None else [part.strip() for part in text.split(",") if part.strip()]


@app.command()
@one_line_errors
def convert(
    source: Annotated[Path, typer.Argument(metavar="IN", help="Input: a CSV directory, .parquet, "
                                           "long .csv/.parquet, SUMO FCD .xml, CommonRoad .xml, "
                                           "OSI .osi/.mcap, a highD-family folder, MDF4 .mf4, "
                                           "a ROS 2 bag directory.")],
    target: Annotated[Path, typer.Argument(metavar="OUT", help="Output: a directory (CSV, one "
                                           "file per run), .parquet, .csv (long), .osi or .mcap.")],
    output_format: Annotated[str | None, typer.Option(
        "--format", help=f"Output format ({FORMAT_HELP}; default: from OUT).")] = None,
    input_format: Annotated[str | None, typer.Option(
        "--from", help="Input format (default: from IN's suffix or XML root).")] = None,
    run_column: Annotated[str | None, typer.Option(help="Long format: column naming the run "
                                                        "(default: the file is one run).")] = None,
    time_column: Annotated[str | None, typer.Option(help="Long format: column of the time in "
                                                         "seconds (default: t).")] = None,
    object_column: Annotated[str | None, typer.Option(
        help="Long format: column naming the object; objects become <object>.<column> "
             "signals (integer ids: obj<id>.<column>).")] = None,
    time_scale: Annotated[float | None, typer.Option(
        help="Long format: seconds per unit of the time column (0.04 for 25 Hz frame numbers, "
             "0.001 for ms; default: 1).")] = None,
    signals: Annotated[str | None, typer.Option(help="Long format: comma-separated value "
                                                     "columns to keep (default: all numeric).")
                       ] = None,
    objects_as: Annotated[str | None, typer.Option(
        help="signals (dotted names in one run) or runs (each object its own run).")] = None,
    missing: Annotated[str | None, typer.Option(
        help="An object without a row at a time step: error, or intersect (keep the time steps "
             "all objects share).")] = None,
    object_prefix: Annotated[str | None, typer.Option(help="Prefix of every object name "
                                                           "(default: obj before integer ids).")
                             ] = None,
    layout: Annotated[str | None, typer.Option(
        help="CommonRoad: obstacles (each dynamic obstacle a run) or scenario (one run, "
             "obj<id>. signals).")] = None,
    host: Annotated[str | None, typer.Option(help="OSI output: the object that is the host "
                                                  "vehicle (default: ego, if present).")] = None,
    channels: Annotated[str | None, typer.Option(
        help="MDF4: comma-separated channels to read (default: every numeric one).")] = None,
    resample_method: Annotated[str | None, typer.Option(
        help="MDF4: linear or previous, to put channels of different rates on the fastest "
             "one's time stamps (default: refused).")] = None,
    run_channel: Annotated[str | None, typer.Option(
        help="MDF4: channel naming the run of each sample (default: run, if present).")] = None,
    recordings: Annotated[str | None, typer.Option(
        help="highD family: comma-separated recordings to read (default: all).")] = None,
    direction: Annotated[str | None, typer.Option(
        help="highD: normalise (every vehicle drives towards +x) or keep.")] = None,
    topics: Annotated[str | None, typer.Option(
        help="ROS 2 bag: comma-separated topics (default: every Odometry and PoseStamped "
             "topic).")] = None,
    fields: Annotated[str | None, typer.Option(
        help="ROS 2 bag: comma-separated message field paths (twist.twist.linear.x) instead "
             "of the known types' signals.")] = None,
    runs: Annotated[str | None, typer.Option(
        help="ROS 2 bag: bag (a bag is a run) or namespace (a topic namespace is a run). "
             "highD family: tracks (a track is a run) or recordings (a recording is a run, "
             "its tracks obj<id>. signals).")
                    ] = None,
    overwrite: Annotated[bool, typer.Option("--overwrite", help="Replace an existing OUT (never "
                                                                "the input).")] = False,
    as_json: Json = False,
) -> None:
    """Convert a trace set between formats (docs/formats.md); bad input exits 2 with one line."""
    from simcred.io.formats import convert as convert_traces

    given = dict(run_column=run_column, time_column=time_column, object_column=object_column,
                 time_scale=time_scale,
                 signals=_signals(signals), objects_as=objects_as, missing=missing,
                 object_prefix=object_prefix, layout=layout, host=host,
                 channels=_signals(channels), resample=resample_method, run_channel=run_channel,
                 recordings=_signals(recordings), direction=direction,
                 topics=_signals(topics), fields=_signals(fields), runs=runs)
    options = {k: v for k, v in given.items() if v is not None}
    result = convert_traces(source, target, source_format=input_format,
                            target_format=output_format, overwrite=overwrite, **options)
    _emit(result.to_dict(), as_json,
          f"wrote {result.target} ({result.target_format}): {result.runs} runs, {result.rows} "
          f"rows, {len(result.signals)} signals from {result.source} ({result.source_format})")
