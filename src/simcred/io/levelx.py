"""The drone data sets of the levelXData family: highD, and inD, rounD, exiD, uniD.

A recording ``NN`` is three CSV files in one folder: ``NN_tracks.csv`` (a row per track and
frame), ``NN_tracksMeta.csv`` (a row per track: class, dimensions, direction) and
``NN_recordingMeta.csv`` (frame rate, location, speed limit). The folder holds one or more
recordings. The data sets themselves are not redistributable (levelXData licence): simcred
reads a copy the user obtained; its tests build files from the published column layout.

Rules (also in ``docs/formats.md``)
-----------------------------------
* **Runs** (``runs="tracks"``, default): every track is a run, id ``<recording>:<track>``
  (``01:17``), recordings and tracks in ascending order. A track with a single frame cannot be a
  run (no transition): it is left out and counted in ``metadata["short_tracks"]``.
  ``runs="recordings"``: every recording is a run with its tracks as objects ``obj<track>.*``
  (the layout of :mod:`simcred.io.levelx_scenes`); signals, direction and per-track metadata are
  those of track mode.
* **Time**: ``t = frame / frameRate`` of the recording (seconds since the recording started).
* **Signals** (SI units, in ``metadata["units"]``): ``x``, ``y`` (centre of the vehicle), ``vx``,
  ``vy``, ``ax``, ``ay``; highD adds ``lane`` (the file's ``laneId``, a feature like any other),
  the later data sets (``xCenter`` layout) add ``heading`` in degrees.
* **Direction** (highD): x grows to the right in highD's image frame, so the upper carriageway
  (``drivingDirection`` 1) drives towards -x. With ``direction="normalise"`` (default) its tracks
  are turned by 180° (x, y, velocities and accelerations negated), so every vehicle drives
  towards +x with the same handedness; ``direction="keep"`` keeps the file's frame. highD's x/y
  are the bounding box's upper-left corner; the centre is x + width/2, y + height/2.
* **Metadata**: per run under ``run_info`` the recording, track id, class, width, length and
  (highD) the driving direction; highD's bounding box ``width`` (along x) is the vehicle's
  length, its ``height`` the vehicle's width. Per recording under ``recordings`` its
  ``recordingMeta`` row (non-finite numbers as null).

Every failure is a one-line :class:`~simcred.errors.TraceSetError` naming the file, column or
track.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv

from simcred.errors import OptionError, TraceSetError
from simcred.io._columns import check_table, float_column
from simcred.io._paths import local
from simcred.io.levelx_scenes import scenes
from simcred.traces import RUN_INFO, TraceSet, handed_over, spans

TRACKS = re.compile(r"^(\d+)_tracks\.csv$")
DIRECTIONS = ("normalise", "keep")
RUNS = ("tracks", "recordings")
UNITS = {"x": "m", "y": "m", "vx": "m/s", "vy": "m/s", "ax": "m/s^2", "ay": "m/s^2",
         "lane": "", "heading": "deg"}


@dataclass(frozen=True, slots=True)
class LevelxLayout:
    """Column names of one generation of the levelX files."""

    name: str
    track: str  # track id column in tracks and tracksMeta
    x: str
    y: str
    signals: tuple[tuple[str, str], ...]  # (simcred signal, file column) after x, y
    width: str  # tracksMeta column of the vehicle's width
    length: str  # tracksMeta column of the vehicle's length
    corner: bool  # x, y are the bounding box corner (highD), not the centre


HIGHD = LevelxLayout("highD", "id", "x", "y",
               (("vx", "xVelocity"), ("vy", "yVelocity"), ("ax", "xAcceleration"),
                ("ay", "yAcceleration"), ("lane", "laneId")), "height", "width", corner=True)
LEVELX = LevelxLayout("inD/rounD/exiD/uniD", "trackId", "xCenter", "yCenter",
                (("vx", "xVelocity"), ("vy", "yVelocity"), ("ax", "xAcceleration"),
                 ("ay", "yAcceleration"), ("heading", "heading")), "width", "length",
                corner=False)
TURNED = ("x", "y", "vx", "vy", "ax", "ay")  # negated by a 180° turn


def is_levelx(directory: Path) -> bool:
    """Whether ``directory`` holds a levelX recording (an ``NN_tracks.csv`` file)."""
    return directory.is_dir() and any(TRACKS.match(p.name) for p in directory.iterdir())


def read(directory: Path, *, recordings: Sequence[str] | None = None,
         direction: str = "normalise", runs: str = "tracks") -> TraceSet:
    """Read the recordings of a levelX folder (see the module rules).

    ``recordings``: the recording numbers to read (``["01", "02"]``; default all).
    ``runs``: ``"tracks"`` (every track a run) or ``"recordings"`` (every recording a run, its
    tracks the objects ``obj<track>.<signal>``: :mod:`simcred.io.levelx_scenes`).
    """
    if direction not in DIRECTIONS:
        raise OptionError(f"direction must be one of {', '.join(DIRECTIONS)}, got {direction!r}")
    if runs not in RUNS:
        raise OptionError(f"runs must be one of {', '.join(RUNS)}, got {runs!r}")
    loaded = [_load(directory, name, path, direction)
              for name, path in _found(Path(directory), recordings)]
    for part in loaded[1:]:
        if part.signals != loaded[0].signals:
            raise TraceSetError(f"{part.where}: layout {list(part.signals)} differs from "
                                f"{loaded[0].where}: {list(loaded[0].signals)}")
    if runs == "recordings":
        return scenes(loaded, UNITS, direction, str(directory))
    parts = [_track_runs(part) for part in loaded]
    lengths = np.concatenate([p.lengths for p in parts])
    return TraceSet(
        signals=parts[0].signals,
        time=handed_over(np.concatenate([p.time for p in parts])),
        values=handed_over(np.concatenate([p.values for p in parts])),
        offsets=np.concatenate([[0], np.cumsum(lengths)]),
        run_ids=tuple(r for p in parts for r in p.run_ids),
        metadata=_merged_metadata(parts, direction),
        source=str(directory),
    )


def _found(directory: Path, recordings: Sequence[str] | None) -> list[tuple[str, Path]]:
    """The ``(recording, tracks file)`` pairs to read, in ascending order."""
    found = sorted((m.group(1), p) for p in directory.iterdir() if (m := TRACKS.match(p.name)))
    if recordings is not None:
        wanted = [str(r) for r in ([recordings] if isinstance(recordings, str) else recordings)]
        known = [n for n, _ in found]
        for name in wanted:
            if name not in known:
                raise OptionError(f"{directory}: no recording '{name}' (recordings: "
                                  f"{', '.join(known) or 'none'})")
        found = [(n, p) for n, p in found if n in wanted]
    if not found:
        raise TraceSetError(f"{directory}: no levelX recording (NN_tracks.csv) in the folder")
    return found


def _merged_metadata(parts: list[TraceSet], direction: str) -> dict:
    first = parts[0].metadata
    short = {k: v for p in parts for k, v in p.metadata.get("short_tracks", {}).items()}
    return {
        "format": first["format"], "direction": direction, "units": dict(first["units"]),
        RUN_INFO: {k: v for p in parts for k, v in p.metadata[RUN_INFO].items()},
        "recordings": {k: v for p in parts for k, v in p.metadata["recordings"].items()},
        **({"short_tracks": short} if short else {}),
    }


def _csv(path: Path, types: dict[str, pa.DataType] | None = None) -> pa.Table:
    if not path.is_file():
        raise TraceSetError(f"{path}: missing (a levelX recording needs NN_tracks.csv, "
                            "NN_tracksMeta.csv and NN_recordingMeta.csv)")
    try:
        table = check_table(pacsv.read_csv(local(path), convert_options=pacsv.ConvertOptions(
            null_values=[""], strings_can_be_null=True, column_types=types or {})), str(path))
    except (pa.ArrowInvalid, OSError, UnicodeDecodeError) as exc:
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise TraceSetError(f"{path}: unreadable CSV ({reason})") from None
    if table.num_rows == 0:
        raise TraceSetError(f"{path}: no rows")
    return table


def _text_column(table: pa.Table, name: str, where: str) -> list[str]:
    if name not in table.column_names:
        raise TraceSetError(f"{where}: no column '{name}' (columns are: "
                            f"{', '.join(table.column_names)})")
    column = table.column(name)
    if column.null_count:
        raise TraceSetError(f"{where}: column '{name}' has missing values")
    return [str(v) for v in column.to_pylist()]


def _ids(table: pa.Table, name: str, where: str) -> np.ndarray:
    """An integer id column (track ids, frames) as int64; a one-line error if not integral."""
    values = float_column(table, name, where)
    integral = np.isfinite(values) & (values == np.round(values))
    if not integral.all():
        row = int(np.flatnonzero(~integral)[0])
        raise TraceSetError(f"{where}: column '{name}', row {row + 1}: {float(values[row])!r} "
                            "is not an integer")
    return values.astype(np.int64)


def _recording_meta(path: Path) -> tuple[float, dict]:
    """The frame rate and the row of ``NN_recordingMeta.csv``, cells as written: integers and
    finite numbers as numbers, everything else (``startTime`` 08:38, lane markings) as text."""
    header = _csv(path).column_names
    meta = _csv(path, {name: pa.string() for name in header})
    if meta.num_rows != 1:
        raise TraceSetError(f"{path}: expected one row, found {meta.num_rows}")
    row = {k: _cell(v[0]) for k, v in meta.to_pydict().items()}
    if "frameRate" not in row:
        raise TraceSetError(f"{path}: no column 'frameRate' (columns are: {', '.join(header)})")
    rate = row["frameRate"]
    if isinstance(rate, bool) or not isinstance(rate, int | float) or rate <= 0:
        raise TraceSetError(f"{path}: frameRate must be a number > 0, got {rate!r}")
    return float(rate), row


def _cell(text: str | None) -> str | int | float | None:
    if text is None:
        return None
    try:
        return int(text)
    except ValueError:
        pass
    try:
        value = float(text)
    except ValueError:
        return text
    return value if math.isfinite(value) else None


@dataclass(frozen=True, slots=True)
class LevelxRecording:
    """One recording read and checked, before it becomes runs: its rows ordered by track and
    frame, the direction already normalised; track ``ids[i]`` is rows
    ``starts[i]:starts[i] + counts[i]``."""

    name: str
    where: str  # the tracks file, for errors and as the source
    layout: LevelxLayout
    signals: tuple[str, ...]
    frame: np.ndarray  # int64, per row
    time: np.ndarray  # frame / frameRate, per row
    values: np.ndarray  # (rows, signals)
    ids: np.ndarray
    starts: np.ndarray
    counts: np.ndarray
    info: dict[int, dict]  # per track id, see _track_info
    row: dict  # the recordingMeta row


def _load(directory: Path, name: str, path: Path, direction: str) -> LevelxRecording:
    tracks = _csv(path)
    layout = LEVELX if LEVELX.x in tracks.column_names else HIGHD
    meta_path = directory / f"{name}_tracksMeta.csv"
    meta = _csv(meta_path)
    rate, rec_row = _recording_meta(directory / f"{name}_recordingMeta.csv")
    where = str(path)

    track = _ids(tracks, layout.track, where)
    frame = _ids(tracks, "frame", where)
    columns = {"x": float_column(tracks, layout.x, where),
               "y": float_column(tracks, layout.y, where)}
    for signal, column in layout.signals:
        columns[signal] = float_column(tracks, column, where)
    if layout.corner:  # highD: upper-left corner of the bounding box -> centre
        columns["x"] = columns["x"] + float_column(tracks, "width", where) / 2
        columns["y"] = columns["y"] + float_column(tracks, "height", where) / 2

    info = _track_info(meta, layout, str(meta_path), name)
    order = np.lexsort((frame, track))
    track, frame = track[order], frame[order]
    ids, starts, counts = np.unique(track, return_index=True, return_counts=True)
    for tid in ids:
        if int(tid) not in info:
            raise TraceSetError(f"{where}: track {tid} is not in {meta_path.name}")
    repeated = np.flatnonzero((track[1:] == track[:-1]) & (frame[1:] == frame[:-1]))
    if repeated.size:
        i = int(repeated[0])
        raise TraceSetError(f"{where}: track {track[i]} has two rows for frame {frame[i]}")
    values = np.column_stack([columns[s][order] for s in columns])
    signals = tuple(columns)
    if direction == "normalise" and layout is HIGHD:  # upper carriageway: turn by 180°
        upper_track = np.array([info[int(t)]["driving_direction"] == 1 for t in ids])
        turned = [signals.index(s) for s in TURNED]
        values[np.ix_(np.repeat(upper_track, counts), turned)] *= -1.0
    return LevelxRecording(name, where, layout, signals, frame, frame / rate, values, ids,
                           starts, counts, info, rec_row)


def _track_runs(rec: LevelxRecording) -> TraceSet:
    """Every track of ``rec`` with two frames or more a run; single-frame tracks counted."""
    keep = rec.counts >= 2
    if not keep.any():
        raise TraceSetError(f"{rec.where}: no track has two frames or more")
    ids, name = rec.ids, rec.name
    short = {f"{name}:{t}": int(c) for t, c in zip(ids[~keep], rec.counts[~keep], strict=True)}
    rows, offsets = spans(rec.starts[keep], rec.starts[keep] + rec.counts[keep])
    metadata = {
        "format": rec.layout.name, "units": {s: UNITS[s] for s in rec.signals},
        RUN_INFO: {f"{name}:{t}": rec.info[int(t)] for t in ids[keep]},
        "recordings": {name: rec.row},
        **({"short_tracks": short} if short else {}),
    }
    return TraceSet(rec.signals, handed_over(rec.time[rows]), handed_over(rec.values[rows]),
                    offsets,
                    tuple(f"{name}:{t}" for t in ids[keep]), metadata, source=rec.where)


def _track_info(meta: pa.Table, layout: LevelxLayout, where: str, recording: str
                ) -> dict[int, dict]:
    """Per track id: recording, track, class, width, length and (highD) driving direction."""
    ids = _ids(meta, layout.track, where)
    classes = _text_column(meta, "class", where)
    width = float_column(meta, layout.width, where)
    length = float_column(meta, layout.length, where)
    direction = _ids(meta, "drivingDirection", where) if layout is HIGHD else None
    if len(set(ids.tolist())) != len(ids):
        raise TraceSetError(f"{where}: column '{layout.track}' repeats a track id")
    if direction is not None and not np.isin(direction, (1, 2)).all():
        row = int(np.flatnonzero(~np.isin(direction, (1, 2)))[0]) + 1
        raise TraceSetError(f"{where}: column 'drivingDirection', row {row}: must be 1 or 2")
    info = {}
    for i, tid in enumerate(ids.tolist()):
        entry = {"recording": recording, "track": tid, "class": classes[i],
                 "width": float(width[i]), "length": float(length[i])}
        if direction is not None:
            entry["driving_direction"] = int(direction[i])
        info[tid] = entry
    return info
