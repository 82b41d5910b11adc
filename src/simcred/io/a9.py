"""The A9 highway recording (OSC-Generator sensor-data CSV): ego GNSS plus objects relative to it.

One CSV file is one drive at 10 Hz: ``timestamp`` [s], the ego's ``lat``/``long`` [deg, WGS84],
``heading`` [deg, from North, clockwise] and ``speed`` [km/h]; lane markings relative to the ego
(``lin_left_*``, ``lin_right_*``); and objects ``#`` = 1, 2, ... with ``pos_x_#``/``pos_y_#`` [m,
ego frame, x forward, y left], ``speed_x_#``/``speed_y_#`` [km/h] and ``class_#``. An empty cell
means "no object". :func:`read_a9` turns a file into an :class:`A9Recording` in a local metric frame
(x east, y north, metres, angles counter-clockwise from x); :meth:`A9Recording.to_traceset` gives a
one-run :class:`~simcred.traces.TraceSet` with signals ``ego.*`` and, for a chosen object, ``to.*``.

The conventions below were checked against the four files of OSC-Generator's ``tests/test_data``
(see ``docs/realdata.md`` for the numbers):

* ``heading`` turns the same way as the GNSS track and reads ≈ 90° when driving east, so it is a
  compass angle; in this module it becomes ``pi/2 - radians(heading)``. It differs from the GNSS
  track by a constant (7.3° in ``trajectories_file.csv``), which :func:`read_a9` removes.
* The GNSS fix is updated about once a second and linearly interpolated in between; it is held at
  the start and end of the drive. The ego position is dead-reckoned from ``speed`` and the aligned
  heading and shifted onto the GNSS fixes (mean offset).
* ``speed_x``/``speed_y`` are over ground (not relative to the ego), in ego-frame components.
"""

from __future__ import annotations

import csv
import re
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np
import pyproj

from simcred.errors import TraceSetError
from simcred.io._columns import check_width
from simcred.kinematics import MOTION_SIGNALS, Track, read_only
from simcred.traces import TIME, TraceSet

EGO_COLUMNS = ("timestamp", "lat", "long", "heading", "speed")
OBJECT_FIELDS = ("pos_x", "pos_y", "speed_x", "speed_y")
LANE_COLUMNS = {
    "left_y": "lin_left_y_abstand",
    "right_y": "lin_right_y_abstand",
    "left_curvature": "lin_left_kruemm",
    "right_curvature": "lin_right_kruemm",
}
KMH = 1 / 3.6  # km/h -> m/s
STALE_SPEED = 1.0  # m/s: a fix repeated while the ego is faster than this is a held (stale) fix
MIN_TRACK = 1.0  # m of GNSS track needed to estimate the heading offset
_OBJECT_COLUMN = re.compile(r"^(pos_x|pos_y|speed_x|speed_y|class)_(\d+)$")


@dataclass(frozen=True, slots=True, eq=False)
class A9Object:
    """One detected object over the rows where it is present: its track and what the file adds.

    Parameters
    ----------
    id : int
        The object number ``#`` of the columns ``pos_x_#`` etc.
    rows : ndarray of int, shape (n,)
        Rows of the recording (0-based) where the object is present, increasing.
    track : Track
        Its motion in the local frame, SI units, at ``timestamp[rows]``: position ``x, y`` [m]
        (ego position + ego heading rotation of ``rel_x, rel_y``), speed over ground ``v`` [m/s]
        (the norm of ``speed_x_#, speed_y_#``), ``heading`` [rad, counter-clockwise from east]:
        the direction of the velocity over ground, unwrapped.
    rel_x, rel_y : ndarray, shape (n,)
        Position relative to the ego as recorded [m, x forward, y left].
    object_class : int or None
        The most frequent ``class_#`` over the present rows (7 = car), None without a class column.
    """

    id: int
    rows: np.ndarray
    track: Track
    rel_x: np.ndarray
    rel_y: np.ndarray
    object_class: int | None = None

    def __post_init__(self) -> None:
        object.__setattr__(self, "rows", read_only(self.rows, np.int64))
        for name in ("rel_x", "rel_y"):
            object.__setattr__(self, name, read_only(getattr(self, name)))
        track = self.track
        object.__setattr__(self, "track", Track(
            *(read_only(getattr(track, s)) for s in ("t", *MOTION_SIGNALS))))

    def __len__(self) -> int:
        return len(self.rows)

    def segments(self) -> list[tuple[int, int]]:
        """Contiguous presence as ``(first_row, stop_row)`` pairs of recording rows."""
        breaks = np.flatnonzero(np.diff(self.rows) != 1) + 1
        starts = np.concatenate([[0], breaks])
        stops = np.concatenate([breaks, [len(self.rows)]])
        return [(int(self.rows[a]), int(self.rows[b - 1]) + 1) for a, b in zip(starts, stops,
                                                                               strict=True)]


@dataclass(frozen=True, slots=True, eq=False)
class A9Recording:
    """One A9 drive in a local metric frame (x east, y north, metres; angles CCW from x).

    Parameters
    ----------
    source : str
        The CSV file.
    time : ndarray, shape (rows,)
        ``timestamp`` [s] as recorded (strictly increasing).
    ego : mapping of str to ndarray
        ``x``, ``y`` [m]: dead-reckoned position shifted onto the GNSS fixes; ``v`` [m/s];
        ``heading`` [rad], the recorded heading plus :attr:`heading_offset`, unwrapped;
        ``gnss_x``, ``gnss_y`` [m]: the GNSS fixes as recorded, projected.
    objects : mapping of int to A9Object
        Every object present in at least one row, by id.
    lanes : mapping of str to ndarray
        ``left_y``, ``right_y`` [m], ``left_curvature``, ``right_curvature`` [1/m] of the ego's
        lane markings (ego frame); NaN where not recorded.
    origin : tuple of float
        ``(lat, long)`` of the first fix: the centre of the projection.
    crs : str
        The PROJ string of the local frame.
    heading_offset : float
        Constant [rad] added to the recorded heading to align it with the GNSS track.
    gnss_rms : float
        RMS distance [m] between the ego position and the fresh (not held) GNSS fixes.
    """

    source: str
    time: np.ndarray
    ego: Mapping[str, np.ndarray]
    objects: Mapping[int, A9Object]
    lanes: Mapping[str, np.ndarray]
    origin: tuple[float, float]
    crs: str
    heading_offset: float
    gnss_rms: float

    def __post_init__(self) -> None:
        object.__setattr__(self, "time", read_only(self.time))
        for name in ("ego", "lanes"):
            arrays = {k: read_only(v) for k, v in getattr(self, name).items()}
            object.__setattr__(self, name, MappingProxyType(arrays))
        object.__setattr__(self, "objects", MappingProxyType(dict(sorted(self.objects.items()))))

    def __repr__(self) -> str:
        return (f"A9Recording({self.source!r}, rows={len(self.time)}, "
                f"objects={list(self.objects)})")

    def metadata(self) -> dict[str, Any]:
        """JSON-serialisable provenance: file, projection, heading offset, GNSS residual."""
        return {
            "source": self.source,
            "format": "a9-csv",
            "origin_lat_long": list(self.origin),
            "crs": self.crs,
            "heading_offset_deg": float(np.degrees(self.heading_offset)),
            "gnss_rms_m": float(self.gnss_rms),
        }

    def to_traceset(self, object_id: int | None = None, *, name: str = "to") -> TraceSet:
        """One run with ``ego.{x,y,v,heading}`` and, for ``object_id``, ``<name>.{x,y,v,heading}``.

        Parameters
        ----------
        object_id : int or None, default: None
            The object to include; the run then covers its longest contiguous presence (the first
            of equally long ones). None: the ego alone over the whole drive.
        name : str, default: "to"
            Prefix of the object's signals.

        Returns
        -------
        TraceSet
            One run, time column ``t`` = ``timestamp``; metadata from :meth:`metadata` plus the
            object id, class and recording rows.
        """
        meta = self.metadata()
        stem = Path(self.source).stem
        if object_id is None:
            run = {TIME: self.time, **{f"ego.{s}": self.ego[s] for s in MOTION_SIGNALS}}
            return TraceSet.from_runs([run], run_ids=[stem], metadata=meta, source=self.source)
        detected = self._detected(object_id, name)
        lo, hi = max(detected.segments(), key=lambda seg: seg[1] - seg[0])
        if hi - lo < 2:
            raise TraceSetError(f"{self.source}: object {object_id} is present in 1 row only "
                                "(at least 2 are needed)")
        k = np.searchsorted(detected.rows, lo)
        part = slice(k, k + hi - lo)
        run = {TIME: self.time[lo:hi], **{f"ego.{s}": self.ego[s][lo:hi] for s in MOTION_SIGNALS}}
        run.update(detected.track[part].to_columns(name))
        meta.update(object_id=object_id, object_class=detected.object_class, rows=[lo, hi])
        return TraceSet.from_runs([run], run_ids=[f"{stem}:obj{object_id}"], metadata=meta,
                                  source=self.source)

    def _detected(self, object_id: int, name: str) -> A9Object:
        if name in ("", "ego") or "." in name:
            raise TraceSetError(f"{self.source}: object prefix {name!r} must be a plain name "
                                "other than 'ego'")
        return self.object(object_id)

    def object(self, object_id: int) -> A9Object:
        """Object ``object_id``; a one-line error names the objects present if there is none."""
        if object_id not in self.objects:
            raise TraceSetError(f"{self.source}: no object {object_id} (objects present: "
                                f"{list(self.objects)})")
        return self.objects[object_id]


# -- reading --------------------------------------------------------------------------------------


def read_a9(path: str | Path) -> A9Recording:
    """Read one A9 CSV file into the local metric frame.

    Parameters
    ----------
    path : str or Path
        The CSV file (header row, then one row per 0.1 s).

    Returns
    -------
    A9Recording
        Ego and objects in a transverse Mercator frame centred on the first fix.

    Raises
    ------
    TraceSetError
        One line naming the file and, where possible, the row and column: empty file, missing
        required column, non-numeric or non-finite cell, missing ego value, short or long row,
        non-increasing ``timestamp``, an object row with a position but no speed (or vice versa).

    Notes
    -----
    * Projection: ``+proj=tmerc`` on WGS84 centred on the first fix (scale 1), x east, y north.
    * Heading: the recorded compass heading ``h`` becomes ``psi = pi/2 - radians(h) + delta``, where
      ``delta`` is the angle of ``sum_i d_i exp(-1j psi_i)`` over the GNSS steps ``d_i`` (the
      length-weighted mean angle between the GNSS track and the recorded heading).
    * Ego position: trapezoidal dead reckoning of ``speed`` along ``psi``, shifted by the mean of
      (GNSS fix - dead-reckoned position) over the fresh fixes (a fix is stale when it repeats the
      previous or next row's while the ego moves faster than 1 m/s).
    * Objects: ``p = p_ego + R(psi) (pos_x, pos_y)``; the ego reference point is its GNSS position
      (the sensor's mounting offset is not in the file). Velocity over ground
      ``R(psi) (speed_x, speed_y) / 3.6``.
    * Columns the importer does not use (lane types, ranges, ``heading_new``) are not checked.

    Examples
    --------
    >>> rec = read_a9("trajectories_file.csv")  # doctest: +SKIP
    >>> rec.to_traceset(lane_changer(rec)).signals  # doctest: +SKIP
    ('ego.x', 'ego.y', 'ego.v', 'ego.heading', 'to.x', 'to.y', 'to.v', 'to.heading')
    """
    path = Path(path)
    header, rows = _read_rows(path)
    table = _Table(str(path), header, rows)
    columns = {c: table.numbers(c, required=True) for c in EGO_COLUMNS}
    _check_time(table, columns["timestamp"])
    _check_coordinates(str(path), columns["lat"], columns["long"])
    proj = _projection(columns["lat"][0], columns["long"][0])
    ego, offset, rms = _ego(columns, proj)
    objects = {k: _object(table, k, columns["timestamp"], ego)
               for k in _object_ids(str(path), header)}
    lanes = {key: table.numbers(col) if col in header else np.full(len(rows), np.nan)
             for key, col in LANE_COLUMNS.items()}
    return A9Recording(
        source=str(path), time=columns["timestamp"], ego=ego,
        objects={k: track for k, track in objects.items() if track is not None}, lanes=lanes,
        origin=(float(columns["lat"][0]), float(columns["long"][0])), crs=proj.srs,
        heading_offset=offset, gnss_rms=rms,
    )


def _read_rows(path: Path) -> tuple[list[str], list[tuple[int, list[str]]]]:
    """Header and ``(line number, cells)`` of every non-blank data line."""
    try:
        with path.open(newline="", encoding="utf-8-sig") as handle:
            reader = csv.reader(handle)
            header = next(reader, None)
            rows = [(reader.line_num, cells) for cells in reader if cells]
    except FileNotFoundError:
        raise TraceSetError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise TraceSetError(f"{path}: unreadable CSV ({type(exc).__name__}: {exc})") from None
    if not header:
        raise TraceSetError(f"{path}: empty file (no header row)")
    header = [h.strip() for h in header]
    check_width(len(header), str(path))
    duplicates = sorted(h for h, n in Counter(header).items() if n > 1)  # linear, not quadratic
    if duplicates:
        raise TraceSetError(f"{path}: duplicate column names {duplicates}")
    if len(rows) < 2:
        raise TraceSetError(f"{path}: {len(rows)} data row(s); at least 2 are needed")
    for i, (line, cells) in enumerate(rows):
        if len(cells) != len(header):
            raise TraceSetError(f"{path}: row {i + 1} (line {line}) has {len(cells)} cells, "
                                f"the header has {len(header)}")
    return header, rows


class _Table:
    """Cells as text, parsed to float columns on demand with one-line errors."""

    def __init__(self, where: str, header: Sequence[str], rows: Sequence[tuple[int, list[str]]]):
        self.where = where
        self.header = list(header)
        self.rows = rows

    def numbers(self, column: str, *, required: bool = False) -> np.ndarray:
        """Column as float64, NaN for empty cells (an error if ``required``)."""
        if column not in self.header:
            raise TraceSetError(f"{self.where}: no column '{column}' (required: "
                                f"{', '.join(EGO_COLUMNS)})")
        j = self.header.index(column)
        out = np.empty(len(self.rows))
        for i, (line, cells) in enumerate(self.rows):
            out[i] = self._cell(cells[j].strip(), column, i, line, required)
        return out

    def _cell(self, text: str, column: str, i: int, line: int, required: bool) -> float:
        at = f"{self.where}: column '{column}', row {i + 1} (line {line})"
        if not text:
            if required:
                raise TraceSetError(f"{at}: value is missing")
            return np.nan
        try:
            value = float(text)
        except ValueError:
            raise TraceSetError(f"{at}: {text!r} is not a number") from None
        if not np.isfinite(value):
            raise TraceSetError(f"{at}: value is {text!r} (values must be finite)")
        return value


def _check_time(table: _Table, t: np.ndarray) -> None:
    bad = np.flatnonzero(~(t[1:] > t[:-1]))
    if bad.size:
        i = int(bad[0]) + 1
        now, before = float(t[i]), float(t[i - 1])
        raise TraceSetError(f"{table.where}: column 'timestamp' is not strictly increasing at row "
                            f"{i + 1} (line {table.rows[i][0]}): t={now!r} after {before!r}")


def _object_ids(where: str, header: Sequence[str]) -> list[int]:
    """Object numbers named in the header; each must have all of pos_x/pos_y/speed_x/speed_y."""
    found: dict[int, set[str]] = {}
    for column in header:
        match = _OBJECT_COLUMN.match(column)
        if match:
            found.setdefault(int(match.group(2)), set()).add(match.group(1))
    for k, fields in sorted(found.items()):
        missing = [f"{f}_{k}" for f in OBJECT_FIELDS if f not in fields]
        if missing:
            raise TraceSetError(f"{where}: object {k} has no column(s) {', '.join(missing)}")
    return sorted(found)


# -- geometry -------------------------------------------------------------------------------------


def _check_coordinates(where: str, lat: np.ndarray, lon: np.ndarray) -> None:
    """One line for a fix off the globe (latitude beyond ±90°, longitude beyond ±180°)."""
    for name, values, bound in (("lat", lat, 90.0), ("long", lon, 180.0)):
        bad = np.flatnonzero(np.abs(values) > bound)
        if bad.size:
            raise TraceSetError(f"{where}: column '{name}', row {int(bad[0]) + 1}: "
                                f"{values[bad[0]]:g} is outside [-{bound:g}, {bound:g}] degrees")


def _projection(lat0: float, lon0: float) -> pyproj.Proj:
    """Transverse Mercator on WGS84 centred on ``(lat0, lon0)``: x east, y north, metres."""
    return pyproj.Proj(proj="tmerc", lat_0=lat0, lon_0=lon0, k=1, x_0=0, y_0=0, ellps="WGS84",
                       units="m")


def _ego(columns: Mapping[str, np.ndarray], proj: pyproj.Proj
         ) -> tuple[dict[str, np.ndarray], float, float]:
    gx, gy = proj(columns["long"], columns["lat"])
    v = columns["speed"] * KMH
    recorded = np.unwrap(np.pi / 2 - np.radians(columns["heading"]))
    offset = heading_offset(gx, gy, recorded)
    psi = recorded + offset
    x, y = _dead_reckon(columns["timestamp"], v, psi)
    fresh = _fresh_fixes(columns["lat"], columns["long"], v)
    x += np.mean(gx[fresh] - x[fresh])
    y += np.mean(gy[fresh] - y[fresh])
    rms = float(np.sqrt(np.mean((gx[fresh] - x[fresh]) ** 2 + (gy[fresh] - y[fresh]) ** 2)))
    ego = {"x": x, "y": y, "v": v, "heading": psi, "gnss_x": gx, "gnss_y": gy}
    return ego, offset, rms


def heading_offset(x: np.ndarray, y: np.ndarray, heading: np.ndarray) -> float:
    """Constant [rad] to add to ``heading`` (CCW from x) so that it follows the track ``x, y``.

    The angle of ``sum_i d_i exp(-1j psi_i)``: each step ``d_i = (x, y)[i+1] - (x, y)[i]`` (as a
    complex number) is turned by minus the mean heading of its two rows, so longer steps weigh
    more and repeated (held) fixes weigh nothing. 0 when the track is shorter than 1 m.

    >>> t = np.linspace(0.0, 1.0, 11)
    >>> round(float(np.degrees(heading_offset(t, t, np.zeros(11)))), 6)
    45.0
    """
    step = np.diff(x) + 1j * np.diff(y)
    if np.sum(np.abs(step)) < MIN_TRACK:
        return 0.0
    mid = 0.5 * (heading[1:] + heading[:-1])
    return float(np.angle(np.sum(step * np.exp(-1j * mid))))


def _dead_reckon(t: np.ndarray, v: np.ndarray, psi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Trapezoidal integration of speed along heading, starting at the origin."""
    ds = 0.5 * (v[1:] + v[:-1]) * np.diff(t)
    mid = 0.5 * (psi[1:] + psi[:-1])
    x = np.concatenate([[0.0], np.cumsum(ds * np.cos(mid))])
    y = np.concatenate([[0.0], np.cumsum(ds * np.sin(mid))])
    return x, y


def _fresh_fixes(lat: np.ndarray, lon: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Rows whose fix is not a repeat of a neighbour's while the ego moves (all rows if none)."""
    same = (lat[1:] == lat[:-1]) & (lon[1:] == lon[:-1])
    repeated = np.concatenate([[False], same]) | np.concatenate([same, [False]])
    fresh = ~(repeated & (v > STALE_SPEED))
    return fresh if fresh.any() else np.ones_like(fresh)


def _rotate(psi: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ego-frame components ``(a forward, b left)`` in the local frame."""
    c, s = np.cos(psi), np.sin(psi)
    return c * a - s * b, s * a + c * b


def _object(table: _Table, k: int, time: np.ndarray, ego: Mapping[str, np.ndarray]
            ) -> A9Object | None:
    cells = {f: table.numbers(f"{f}_{k}") for f in OBJECT_FIELDS}
    present = ~np.isnan(cells["pos_x"])
    for f in OBJECT_FIELDS[1:]:
        bad = np.flatnonzero(np.isnan(cells[f]) == present)
        if bad.size:
            i = int(bad[0])
            has, lacks = ("pos_x", f) if present[i] else (f, "pos_x")
            raise TraceSetError(f"{table.where}: row {i + 1} (line {table.rows[i][0]}): object "
                                f"{k} has '{has}_{k}' but no '{lacks}_{k}'")
    rows = np.flatnonzero(present)
    if rows.size == 0:
        return None
    psi = ego["heading"][rows]
    rel_x, rel_y = cells["pos_x"][rows], cells["pos_y"][rows]
    dx, dy = _rotate(psi, rel_x, rel_y)
    vx, vy = cells["speed_x"][rows] * KMH, cells["speed_y"][rows] * KMH
    track = Track(time[rows], ego["x"][rows] + dx, ego["y"][rows] + dy, np.hypot(vx, vy),
                  np.unwrap(psi + np.arctan2(vy, vx)))
    return A9Object(
        id=k, rows=rows, track=track, rel_x=rel_x, rel_y=rel_y,
        object_class=_object_class(table, k, rows),
    )


def _object_class(table: _Table, k: int, rows: np.ndarray) -> int | None:
    if f"class_{k}" not in table.header:
        return None
    values = table.numbers(f"class_{k}")[rows]
    values = values[np.isfinite(values)]
    return int(Counter(values.tolist()).most_common(1)[0][0]) if values.size else None


__all__ = ["A9Object", "A9Recording", "heading_offset", "read_a9"]
