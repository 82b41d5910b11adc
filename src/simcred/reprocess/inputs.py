"""What ``simcred reprocess`` reads, as a :class:`~simcred.reprocess.timebase.Drive`.

* a **measurement directory** (``simcred simulate cutin``): GT and SD as recorded, at any rates;
* an **A9 sensor-data CSV** (OSC-Generator): SD only; the chosen object (default: the lane
  changer) is the TO over its longest contiguous presence, straightened onto the EGO's path
  (:mod:`simcred.scenario.frenet`);
* a **CommonRoad XML** scenario: one obstacle is the TO, the EGO is another recorded obstacle
  (given, or the TO's follower, :func:`simcred.io.commonroad.follower`); both over the time steps
  they share, in a road frame (:func:`road_frame`); the recording enters the pipeline as SD;
  each one's CommonRoad type and footprint (rectangle; a circle's diameter) go into the
  metadata (``objects``), and a pedestrian or bicycle is refused as the EGO; with
  ``frame="lanelet"`` the road frame is instead the Frenet frame along the lanelet centre line
  through the EGO's start (:mod:`simcred.reprocess.road`); the map's lanes under the EGO
  (:mod:`simcred.reprocess.lanes`) go into the metadata (``lanes``);
* a **long-format CSV/Parquet** table (:mod:`simcred.io.longformat`): the EGO's and the TO's
  ``x, y`` and optionally ``v, heading`` per time (by object column, or as ``<name>.x``
  columns; a missing ``v`` / ``heading`` column is derived from the positions, central
  differences, and listed in the metadata as ``derived``; optional ``length``, ``width`` and
  ``type`` columns give the objects' footprints and types, metadata ``objects``); times are
  scaled by ``LongColumns.time_scale`` (stated); rows with a missing or NaN value are
  dropouts (removed, counted, and their gaps reported by
  :func:`~simcred.reprocess.timebase.align`); the table is SD, an optional second table GT.
  There is no map: the pipeline's AD function, risk and reaction rules assume a straight road
  along +x, so a table whose EGO does not travel along +x (within :data:`ROAD_TOLERANCE`) is
  refused with one line, unless ``road_frame="ego"`` rotates it rigidly into the EGO's
  direction of travel (:func:`road_frame`, as for CommonRoad; a straight road is then assumed,
  and stated in the metadata), or ``LongColumns.reference`` names a lane centre line file
  whose Frenet frame is used (:mod:`simcred.reprocess.road`).

A single recording (A9, CommonRoad, long format without GT) runs the SD half of the pipeline:
"SD" then means "the one recording there is"; there is no sensor error, sensor model or
eqs. (4)-(7).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from simcred._json import file_digest
from simcred.errors import OptionError, TraceSetError
from simcred.io import commonroad, longformat
from simcred.io.a9_lanes import lane_changer
from simcred.io.formats import PARQUET_SUFFIXES as LONG_SUFFIXES
from simcred.io.sources import detect_source, read_source
from simcred.kinematics import TIME_TOLERANCE, Track
from simcred.reprocess.lanes import map_lanes
from simcred.reprocess.road import lanelet_line, reference_line_file, to_frenet
from simcred.reprocess.timebase import Drive, RecordedTracks, tracks_digest
from simcred.scenario.fit import MIN_SAMPLES
from simcred.scenario.frenet import to_path_frame
from simcred.traces import TIME, TraceSet

EGO, TO = "ego", "to"
NOT_DRIVEN = ("pedestrian", "bicycle")  # CommonRoad types an ACC does not drive: never the EGO
COMMONROAD_FRAMES = ("ego", "lanelet")
ROAD_TOLERANCE = 0.2  # rad: a long table's EGO must travel this close to +x (else no road frame)
ROAD_FRAMES = ("given", "ego")  # long format without a reference path
MIN_CHORD = 5.0  # m: an EGO that moves less than this gives the road direction by its heading
SHAPE_COLUMNS = ("length", "width", "type")  # optional per object: footprint (m) and type
REQUIRED_SIGNALS = ("x", "y")
OPTIONAL_SIGNALS = ("v", "heading")  # derived from the positions where a table has none


@dataclass(frozen=True, slots=True)
class LongColumns:
    """How a long-format table names things (``simcred reprocess --time-column ...``)."""

    time_column: str = TIME
    run_column: str | None = None
    object_column: str | None = None
    run: str | None = None  # the run to reprocess when the table has several
    time_scale: float = 1.0  # seconds per unit of the time column (0.001: milliseconds)
    road_frame: str = "given"  # or "ego": rotate into the EGO's direction of travel
    reference: str | None = None  # a reference path file (x, y): its Frenet frame instead


def read_measurement(path: str | Path, object_id: int | str | None = None, *,
                     ego: str | None = None, long: LongColumns | None = None,
                     gt: str | Path | None = None, frame: str | None = None) -> Drive:
    """The drive in ``path`` (see the module docstring for what each kind gives).

    Parameters
    ----------
    path : path
        Measurement directory, A9 ``.csv``, CommonRoad ``.xml``, or long-format ``.csv`` /
        ``.parquet`` (a ``.csv`` is long format when ``long`` is given, else A9).
    object_id : int or str, optional
        The TO: A9 object number (default the lane changer), CommonRoad obstacle id (required),
        long-format object label or signal prefix (default ``to``).
    ego : str, optional
        The EGO: CommonRoad obstacle id (default the TO's follower), long-format object label
        or signal prefix (default ``ego``).
    long : LongColumns, optional
        Column names of a long-format table.
    gt : path, optional
        Long format: a second table with the GT (same columns and labels).
    frame : {"ego", "lanelet"}, optional
        CommonRoad: the rigid frame of the EGO's direction (default) or the lanelet centre
        line's Frenet frame (long format: ``long.road_frame`` and ``long.reference``).
    """
    path = Path(path)
    if not path.exists():
        raise TraceSetError(f"{path}: no such file or directory")
    suffix = path.suffix.lower()
    if gt is not None and not (long is not None or suffix in LONG_SUFFIXES):
        raise OptionError("--gt is for long-format tables (a measurement directory has its own "
                          "gt.parquet)")
    if frame is not None and suffix != ".xml":
        raise OptionError("--road-frame lanelet is for a CommonRoad scenario (a long table "
                          "takes --road-frame given|ego or --reference-path)")
    kind = detect_source(path, role="drive", long=long is not None)  # a .csv is A9 here
    if kind == "measurement":
        _no_choice(path, object_id, ego, "a measurement directory")
        return Drive.of_measurement(read_source(path, "measurement"))
    if kind == "commonroad":
        if object_id is None:
            raise OptionError(f"{path}: a CommonRoad scenario needs --object ID (an obstacle "
                              "id, or 'all')")
        return commonroad_drive(path, object_id, ego, frame=frame or "ego")
    if kind == "long":
        return long_drive(path, long or LongColumns(), to=object_id, ego=ego, gt=gt)
    if ego is not None:  # an A9 recording
        raise OptionError(f"{path}: an A9 recording's EGO is the recording car (--ego is "
                          "for CommonRoad and long-format input)")
    return a9_drive(path, None if object_id is None else _integer(object_id, "--object"))


def _no_choice(path: Path, object_id, ego, what: str) -> None:
    if object_id is not None or ego is not None:
        raise OptionError(f"{path}: {what} names its EGO and TO itself (--object and --ego are "
                          "for A9, CommonRoad and long-format input)")


def _integer(value: int | str, option: str) -> int:
    try:
        return int(value)
    except (TypeError, ValueError):
        raise OptionError(f"{option} must be an integer id, got {value!r}") from None


# -- A9 ------------------------------------------------------------------------------------------


def a9_drive(path: Path, object_id: int | None = None) -> Drive:
    """An A9 recording: SD only, the chosen object straightened onto the EGO's path."""
    recording = read_source(path, "a9")
    chosen = lane_changer(recording) if object_id is None else object_id
    sd = to_path_frame(recording.to_traceset(chosen, name=TO))
    metadata = {"source": str(path), "object": chosen, "kind": "A9 sensor data",
                **recording.metadata(), "rows": sd.metadata.get("rows")}
    return Drive(RecordedTracks.of_traceset(sd), None, metadata)


# -- CommonRoad ----------------------------------------------------------------------------------


def commonroad_obstacles(path: str | Path) -> tuple[TraceSet, list[int]]:
    """The scenario's obstacles with a trajectory (runs ``obj<id>``) and their ids."""
    traces = commonroad.read(path)
    return traces, [int(r[3:]) for r in traces.run_ids]


def commonroad_drive(path: str | Path, obstacle: int | str, ego: int | str | None = None, *,
                     traces: TraceSet | None = None, frame: str = "ego") -> Drive:
    """Obstacle ``obstacle`` as the TO of a CommonRoad scenario, with its EGO.

    The EGO is obstacle ``ego`` if given, else the TO's follower
    (:func:`simcred.io.commonroad.follower`) among the obstacles an ACC can drive (not a
    pedestrian or bicycle, :data:`NOT_DRIVEN`: a pedestrian behind the TO is passed over).
    Both are cut to the time steps both have, and put into the road frame of :func:`road_frame`.
    A CommonRoad planning problem's initial state is not an EGO here: it is no recorded vehicle
    (in the NGSIM scenarios it replaces one): nothing to compare its resimulation with.
    """
    path = Path(path)
    traces = commonroad.read(path) if traces is None else traces
    to_run = _obstacle_run(path, traces, obstacle, "--object")
    if ego is None:
        chosen = commonroad.follower(traces, to_run, skip=NOT_DRIVEN)
        if chosen is None:
            raise TraceSetError(f"{path}: obstacle {obstacle} shares fewer than 2 time steps "
                                f"with every other obstacle that is not a "
                                f"{' or '.join(NOT_DRIVEN)}: no EGO for it")
        ego_run, rule = chosen
    else:
        ego_run, rule = _obstacle_run(path, traces, ego, "--ego"), "given (--ego)"
        if ego_run == to_run:
            raise OptionError(f"{path}: --ego and --object are both obstacle {obstacle}")
    kinds = traces.metadata.get("obstacles", {})
    objects = {role: kinds.get(run[3:], {"type": "unknown"})
               for role, run in ((EGO, ego_run), (TO, to_run))}
    if objects[EGO]["type"] in NOT_DRIVEN:
        raise TraceSetError(f"{path}: obstacle {ego_run[3:]} is a {objects[EGO]['type']}: it "
                            "cannot be the EGO, whose resimulation is a car's ACC (choose a "
                            "vehicle with --ego)")
    tracks = _shared_steps(path, {EGO: _obstacle_track(traces, ego_run),
                                  TO: _obstacle_track(traces, to_run)}, ego_run, to_run)
    if frame not in COMMONROAD_FRAMES:
        raise OptionError(f"a CommonRoad scenario's road frame is one of "
                          f"{', '.join(COMMONROAD_FRAMES)}, got {frame!r}")
    network, on_map = commonroad.lanelets(path), tracks[EGO]
    if frame == "lanelet":
        line, chain = lanelet_line(network, tracks[EGO], str(path))
        tracks = to_frenet(tracks, line)
        placed = {"road": "Frenet frame along the lanelet centre line through the EGO's start",
                  "lanelets": chain}
    else:
        tracks, placed = road_frame(tracks)
    selection = f"to={to_run[3:]} ego={ego_run[3:]}" + ("" if frame == "ego" else f" {frame}")
    metadata = {"source": str(path), "format": "commonroad",
                "scenario_id": traces.metadata.get("scenario_id"), "object": int(to_run[3:]),
                "ego": int(ego_run[3:]), "ego_choice": rule, "frame": placed,
                "objects": objects, "lanes": map_lanes(network, on_map, placed, str(path))}
    digest = tracks_digest(tracks, file_digest(path), selection)
    return Drive(RecordedTracks(str(path), tracks, digest), None, metadata)


def _obstacle_run(path: Path, traces: TraceSet, obstacle: int | str, option: str) -> str:
    run = f"obj{_integer(obstacle, option)}"
    if run not in traces.run_ids:
        still = traces.metadata.get("obstacles_without_trajectory") or []
        extra = f"; without a trajectory: {', '.join(map(str, still))}" if still else ""
        raise TraceSetError(f"{path}: no obstacle {obstacle} with a trajectory (obstacles: "
                            f"{', '.join(r[3:] for r in traces.run_ids)}{extra})")
    return run


def _obstacle_track(traces: TraceSet, run: str) -> Track:
    columns = traces.run(traces.run_ids.index(run))
    return Track(columns[TIME], columns["x"], columns["y"], columns["v"],
                 np.unwrap(columns["heading"]))


def _shared_steps(path: Path, tracks: dict[str, Track], ego: str, to: str) -> dict[str, Track]:
    common = np.intersect1d(tracks[EGO].t, tracks[TO].t)
    if len(common) < MIN_SAMPLES:
        raise TraceSetError(f"{path}: obstacles {to[3:]} (TO) and {ego[3:]} (EGO) share "
                            f"{len(common)} time step(s); a fit needs at least {MIN_SAMPLES}")
    lo, hi = common[0] - TIME_TOLERANCE, common[-1] + TIME_TOLERANCE
    return {k: t[(t.t >= lo) & (t.t <= hi)] for k, t in tracks.items()}


def ego_direction(ego: Track) -> tuple[float, str]:
    """The EGO's direction of travel (rad) and how it was found: its first-to-last chord if it
    moves at least :data:`MIN_CHORD`, else its mean heading."""
    chord = np.array([ego.x[-1] - ego.x[0], ego.y[-1] - ego.y[0]])
    if math.hypot(*chord) >= MIN_CHORD:
        return math.atan2(chord[1], chord[0]), "EGO chord"
    return math.atan2(np.mean(np.sin(ego.heading)), np.mean(np.cos(ego.heading))), \
        "EGO mean heading"


def road_frame(tracks: dict[str, Track]) -> tuple[dict[str, Track], dict[str, Any]]:
    """A rigid road frame for a straight-road AD function: origin at the EGO's first position,
    x along the EGO's direction of travel (:func:`ego_direction`), y to the left. Distances,
    speeds and relative headings are unchanged; the EGO's lane centre is taken to be y = 0."""
    angle, rule = ego_direction(tracks[EGO])
    origin = [float(tracks[EGO].x[0]), float(tracks[EGO].y[0])]
    return _rotate(tracks, origin, angle), {"origin": origin, "angle": angle, "direction": rule}


def _rotate(tracks: Mapping[str, Track], origin: Sequence[float], angle: float
            ) -> dict[str, Track]:
    """``tracks`` in the frame with origin ``origin`` and x axis at ``angle`` (rad)."""
    (x0, y0), c, s = origin, math.cos(angle), math.sin(angle)
    return {k: Track(t.t, c * (t.x - x0) + s * (t.y - y0), -s * (t.x - x0) + c * (t.y - y0),
                     t.v, t.heading - angle) for k, t in tracks.items()}


# -- long format ---------------------------------------------------------------------------------


def long_drive(path: str | Path, columns: LongColumns = LongColumns(), *,
               to: int | str | None = None, ego: str | None = None,
               gt: str | Path | None = None) -> Drive:
    """A long-format table (and optionally its GT twin) with the EGO and the TO."""
    if columns.run is not None and columns.run_column is None:
        raise OptionError("--run needs --run-column (the column that names the runs)")
    names = (str(ego) if ego is not None else EGO, str(to) if to is not None else TO)
    if names[0] == names[1]:
        raise OptionError(f"--ego and --object are both {names[0]!r}")
    if columns.road_frame not in ROAD_FRAMES:
        raise OptionError(f"road_frame must be one of {', '.join(ROAD_FRAMES)}, got "
                          f"{columns.road_frame!r}")
    if columns.reference is not None and columns.road_frame != "given":
        raise OptionError("--reference-path gives the road frame: not with --road-frame "
                          f"{columns.road_frame}")
    if not (math.isfinite(columns.time_scale) and columns.time_scale > 0):
        raise OptionError(f"--time-scale must be a finite number > 0 (seconds per unit of the "
                          f"time column), got {columns.time_scale!r}")
    sd, derived = _long_recording(Path(path), columns, names)
    gt_recording, gt_derived = (None, []) if gt is None else _long_recording(Path(gt), columns,
                                                                             names)
    if columns.reference is not None:
        line = reference_line_file(columns.reference)
        sd, gt_recording = (None if r is None else _moved(r, to_frenet(r.tracks, line))
                            for r in (sd, gt_recording))
        frame = {"road": f"Frenet frame along the reference path {columns.reference} (x: arc "
                         "length, y: left offset)", "vertices": len(line),
                 "path": str(columns.reference)}
    else:
        frame = _long_frame(Path(path), sd, columns.road_frame)
        if frame is not None:
            sd, gt_recording = (None if r is None else _moved(r, _rotate(
                r.tracks, frame["origin"], frame["angle"])) for r in (sd, gt_recording))
    objects = _recorded_objects(Path(path), columns, names)
    if objects.get(EGO, {}).get("type") in NOT_DRIVEN:
        raise TraceSetError(f"{path}: object {names[0]!r} is a {objects[EGO]['type']}: it "
                            "cannot be the EGO, whose resimulation is a car's ACC")
    metadata = {"source": str(path), "format": "long", "ego": names[0], "object": names[1],
                "time_scale": columns.time_scale, **({"objects": objects} if objects else {}),
                "frame": frame or {"road": "the table's x axis (straight road along +x)"},
                **({"derived": sorted({*derived, *gt_derived})} if derived or gt_derived
                   else {}),
                **({"gt": str(gt)} if gt is not None else {}),
                **({"run": columns.run} if columns.run is not None else {})}
    return Drive(sd, gt_recording, metadata)


def _long_frame(path: Path, sd: RecordedTracks, rule: str) -> dict[str, Any] | None:
    """The rigid road frame to rotate into (``road_frame="ego"``), None to keep the table's;
    a one-line refusal when the EGO does not travel along +x and no rotation was asked."""
    if rule == "ego":
        return road_frame(dict(sd.tracks))[1] | {"road": "straight, along the EGO's direction "
                                                         "(rotated, --road-frame ego)"}
    angle, how = ego_direction(sd.tracks[EGO])
    if abs(angle) > ROAD_TOLERANCE:
        raise TraceSetError(f"{path}: the EGO travels at {angle:.2f} rad ({how}), not along +x; "
                            "without a map reprocessing assumes a straight road along +x: give "
                            "--road-frame ego (rotate into the EGO's direction, a straight "
                            "road assumed) or road coordinates")
    return None


def _moved(recording: RecordedTracks, tracks: Mapping[str, Track]) -> RecordedTracks:
    """``recording`` with its tracks in another frame (same source, digest and dropouts)."""
    return RecordedTracks(recording.source, dict(tracks), recording.digest, recording.dropouts)


def _long_recording(path: Path, columns: LongColumns, names: tuple[str, str]
                    ) -> tuple[RecordedTracks, list[str]]:
    """The EGO and the TO of one table, and the optional signals derived from positions."""
    by_object = columns.object_column is not None
    header = _column_names(path)
    optional = [s for s in OPTIONAL_SIGNALS
                if (s in header if by_object else all(f"{n}.{s}" in header for n in names))]
    wanted = [*REQUIRED_SIGNALS, *optional]
    derived = [s for s in OPTIONAL_SIGNALS if s not in optional]
    signals = wanted if by_object else [f"{n}.{s}" for n in names for s in wanted]
    traces = longformat.read(path, run_column=columns.run_column,
                             time_column=columns.time_column,
                             object_column=columns.object_column, signals=signals,
                             objects_as="runs" if by_object else "signals", dropouts="drop",
                             time_scale=columns.time_scale)
    dropped = traces.metadata.get("dropouts", {})
    tracks, dropouts = {}, {}
    for role, name in zip((EGO, TO), names, strict=True):
        label = longformat.object_name(name, None) if by_object else name
        run_id = _long_run(path, traces, columns, label if by_object else None)
        run = traces.run(traces.run_ids.index(run_id))
        prefix = "" if by_object else f"{name}."
        run = {TIME: run[TIME], **{f"{role}.{s}": run[f"{prefix}{s}"] for s in wanted}}
        if by_object:
            raw = name[3:] if name.startswith("obj") and name[3:].isdigit() else name
            key = raw if columns.run_column is None else f"{_run_label(run_id)}.{raw}"
        else:
            key = _run_label(run_id) if columns.run_column is not None else path.stem
        tracks[role] = _with_derived(run, role, str(path))
        dropouts[role] = int(dropped.get(key, 0))
    return RecordedTracks(str(path), tracks, tracks_digest(tracks, file_digest(path)),
                     dropouts), derived


def _recorded_objects(path: Path, columns: LongColumns, names: tuple[str, str]
                      ) -> dict[str, dict[str, Any]]:
    """Each role's ``length``, ``width`` (m, the median of its rows) and ``type`` (its one
    value, lower case) where the table has such columns (``<name>.length`` without an object
    column); roles without any are left out."""
    header = _column_names(path)
    by_object = columns.object_column is not None
    wanted = {role: {c: (c if by_object else f"{name}.{c}") for c in SHAPE_COLUMNS
                     if (c if by_object else f"{name}.{c}") in header}
              for role, name in zip((EGO, TO), names, strict=True)}
    needed = sorted({c for by in wanted.values() for c in by.values()})
    if not needed:
        return {}
    keys = [k for k in (columns.object_column, columns.run_column) if k is not None]
    table = _columns(path, [*keys, *needed])
    rows = np.ones(table.num_rows, dtype=bool)
    if columns.run is not None:
        rows &= _text(table, columns.run_column) == columns.run
    out = {}
    for (role, by), name in zip(wanted.items(), names, strict=True):
        mine = rows
        if by_object:
            label = name[3:] if name.startswith("obj") and name[3:].isdigit() else name
            mine = rows & (_text(table, columns.object_column) == label)
        kind = {}
        for key, column in by.items():
            values = table.column(column).to_numpy(zero_copy_only=False)[mine]
            kind[key] = _shape_value(path, name, key, values)
        kind = {k: v for k, v in kind.items() if v is not None}
        if kind:
            out[role] = kind
    return out


def _columns(path: Path, names: list[str]) -> pa.Table:
    import pyarrow.csv as pacsv

    if path.suffix.lower() in LONG_SUFFIXES:
        return pq.read_table(path, columns=names)
    options = pacsv.ConvertOptions(include_columns=names, strings_can_be_null=True)
    parse = pacsv.ParseOptions(delimiter=longformat.csv_delimiter(path))
    return pacsv.read_csv(path, parse_options=parse, convert_options=options)


def _text(table: pa.Table, column: str) -> np.ndarray:
    return np.asarray(table.column(column).cast(pa.string()).to_numpy(zero_copy_only=False),
                      dtype=object)


def _shape_value(path: Path, name: str, key: str, values: np.ndarray) -> float | str | None:
    """One object's footprint length or width (median, finite > 0) or type (its one value)."""
    present = [v for v in values if v is not None and not (isinstance(v, float) and
                                                           math.isnan(v))]
    if not present:
        return None
    if key == "type":
        kinds = sorted({str(v).strip().lower() for v in present})
        if len(kinds) > 1:
            raise TraceSetError(f"{path}: object {name!r} has several types "
                                f"({', '.join(kinds)})")
        return kinds[0]
    try:
        value = float(np.median(np.asarray(present, dtype=np.float64)))
    except (TypeError, ValueError):
        raise TraceSetError(f"{path}: object {name!r}: column {key!r} is not numeric") from None
    if not (math.isfinite(value) and value > 0):
        raise TraceSetError(f"{path}: object {name!r}: {key} must be > 0 m, got {value:g}")
    return value


def _column_names(path: Path) -> set[str]:
    """The header of a long-format table (a one-line error if it cannot be read)."""
    try:
        if path.suffix.lower() in LONG_SUFFIXES:
            return set(pq.read_schema(path).names)
        with open(path, encoding="utf-8") as stream:
            line = stream.readline().rstrip("\r\n")
    except (OSError, UnicodeDecodeError, pa.ArrowException) as exc:
        raise TraceSetError(f"{path}: unreadable table ({str(exc).splitlines()[0]})") from None
    return {c.strip().strip('"') for c in line.split(longformat.csv_delimiter(path))}


def _with_derived(run: dict[str, np.ndarray], role: str, source: str) -> Track:
    """The track of ``role``; speed and heading from central differences of the positions
    where the table has none (one-sided at the ends)."""
    t, x, y = run[TIME], run[f"{role}.x"], run[f"{role}.y"]
    if len(t) >= 2:
        dx, dy = np.gradient(x, t), np.gradient(y, t)
        run.setdefault(f"{role}.v", np.hypot(dx, dy))
        run.setdefault(f"{role}.heading", np.unwrap(np.arctan2(dy, dx)))
    return Track.from_columns(run, role, time=TIME, source=source)


def _run_label(run_id: str) -> str:
    return run_id.rsplit(".", 1)[0] if "." in run_id else run_id


def _long_run(path: Path, traces: TraceSet, columns: LongColumns, label: str | None) -> str:
    """The run id holding ``label`` (objects as runs) or the one run (signals) to reprocess."""
    if label is None:
        candidates = list(traces.run_ids)
    else:
        candidates = [r for r in traces.run_ids
                      if r == label or r.endswith(f".{label}")]
        if not candidates:
            objects = sorted({r.rsplit(".", 1)[-1] for r in traces.run_ids})
            raise TraceSetError(f"{path}: no object {label!r} in column "
                                f"'{columns.object_column}' (objects: {', '.join(objects)})")
    if columns.run is not None:
        chosen = [r for r in candidates if _run_label(r) == columns.run or r == columns.run]
        if not chosen:
            runs = sorted({_run_label(r) for r in candidates})
            raise TraceSetError(f"{path}: no run {columns.run!r} (runs: {', '.join(runs)})")
        return chosen[0]
    if len(candidates) > 1:
        runs = sorted({_run_label(r) for r in candidates})
        raise OptionError(f"{path}: {len(runs)} runs ({', '.join(runs[:5])}"
                          f"{', ...' if len(runs) > 5 else ''}); choose one with --run")
    return candidates[0]
