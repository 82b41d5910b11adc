"""The road a drive is reprocessed on: a reference line, and the drive in its Frenet frame.

The AD function, the risk's lateral geometry and the reaction rules assume one straight road
along +x. On a real road that holds in the road's own (Frenet) frame: x the arc length along a
reference line, y the signed offset from it (left positive), the heading relative to the line's
tangent. The reference line is

* a **lane centre line from a file** (long format, ``--reference-path FILE``: a table with
  columns ``x`` and ``y``, its vertices in driving direction), or
* the **CommonRoad lanelet centre line through the EGO's start** (``--road-frame lanelet``): the
  lanelet whose centre line passes nearest to the EGO's first position with a direction within
  45° of the EGO's heading, extended by predecessors and successors (at each junction the one
  whose centre line passes nearest to the EGO's recorded positions) up to
  :data:`MAX_LANELETS` either way.

Positions are projected onto the polyline (:func:`simcred.scenario.frenet.path_coordinates`);
speeds are kept (the speed along a curved line differs from the speed along its offset by the
factor 1 − κ·d, under 2 % for d = 3.5 m on radii above 175 m; not corrected).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from simcred.errors import SimcredError, TraceSetError
from simcred.kinematics import Track
from simcred.scenario.frenet import path_coordinates

MAX_LANELETS = 30  # lanelets added before and after the start lanelet, at most
SAME_DIRECTION = math.pi / 4


def reference_line_file(path: str | Path) -> np.ndarray:
    """The (n, 2) vertices of a reference line table (``x``, ``y`` columns, CSV or Parquet)."""
    import pyarrow.csv as pacsv
    import pyarrow.parquet as pq

    path = Path(path)
    try:
        table = (pq.read_table(path) if path.suffix.lower() in (".parquet", ".pq")
                 else pacsv.read_csv(path))
    except Exception as exc:  # pyarrow raises several kinds for unreadable files
        raise TraceSetError(f"{path}: unreadable reference path "
                            f"({str(exc).splitlines()[0] if str(exc) else type(exc).__name__})"
                            ) from None
    missing = [c for c in ("x", "y") if c not in table.column_names]
    if missing:
        raise TraceSetError(f"{path}: a reference path needs columns x and y (columns: "
                            f"{', '.join(table.column_names)})")
    try:
        line = np.column_stack([np.asarray(table.column(c).to_numpy(zero_copy_only=False),
                                           dtype=np.float64) for c in ("x", "y")])
    except (TypeError, ValueError):
        raise TraceSetError(f"{path}: reference path columns x and y must be numeric") from None
    return _checked(line, str(path))


def _checked(line: np.ndarray, where: str) -> np.ndarray:
    if len(line) < 2 or not np.isfinite(line).all():
        raise TraceSetError(f"{where}: a reference path needs at least 2 finite vertices")
    if np.hypot(*np.diff(line, axis=0).T).sum() < 1.0:
        raise TraceSetError(f"{where}: the reference path is shorter than 1 m")
    return line


def lanelet_line(network: Mapping[int, Mapping[str, Any]], ego: Track, where: str
                 ) -> tuple[np.ndarray, list[int]]:
    """The centre line through the EGO's start (module docstring) and its lanelet ids."""
    start = _start_lanelet(network, ego, where)
    points = np.column_stack([ego.x, ego.y])
    chain = [start]
    for direction, link in ((1, "successors"), (-1, "predecessors")):
        current = start
        for _ in range(MAX_LANELETS):
            options = [i for i in network[current][link] if i in network and i not in chain]
            if not options:
                break
            current = min(options, key=lambda i: _distance(network[i]["centre"], points))
            chain = [*chain, current] if direction > 0 else [current, *chain]
    return chain_line(network, chain, where), chain


def chain_line(network: Mapping[int, Mapping[str, Any]], chain: list[int], where: str
               ) -> np.ndarray:
    """The centre lines of the lanelets ``chain`` (in driving order) joined into one line (a
    successor's first vertex, its predecessor's last, is kept once)."""
    missing = [i for i in chain if i not in network]
    if missing:
        raise SimcredError(f"{where}: no lanelet {missing[0]} in the lanelet network")
    line = np.concatenate([network[i]["centre"] if k == 0 else network[i]["centre"][1:]
                           for k, i in enumerate(chain)])
    return _checked(line, where)


def _start_lanelet(network: Mapping[int, Mapping[str, Any]], ego: Track, where: str) -> int:
    x, y, heading = float(ego.x[0]), float(ego.y[0]), float(ego.heading[0])
    best, best_distance = None, math.inf
    for number, lane in network.items():
        centre = lane["centre"]
        if len(centre) < 2:
            continue
        _, d, tangent = path_coordinates(centre[:, 0], centre[:, 1], np.array([x]),
                                         np.array([y]))
        turn = abs(math.remainder(heading - float(tangent[0]), 2 * math.pi))
        s_inside = _inside(centre, x, y)
        if turn < SAME_DIRECTION and s_inside and abs(d[0]) < best_distance:
            best, best_distance = number, abs(float(d[0]))
    if best is None:
        raise SimcredError(f"{where}: no lanelet runs under the EGO's first position "
                           f"({x:.1f}, {y:.1f}) in its direction: no lanelet frame")
    return best


def _inside(centre: np.ndarray, x: float, y: float) -> bool:
    """Whether (x, y) projects between the centre line's ends."""
    s, _, _ = path_coordinates(centre[:, 0], centre[:, 1], np.array([x]), np.array([y]))
    return 0.0 <= float(s[0]) <= float(np.hypot(*np.diff(centre, axis=0).T).sum())


def _distance(centre: np.ndarray, points: np.ndarray) -> float:
    """Smallest distance from the recorded points to a centre line's vertices."""
    return float(np.min(np.hypot(points[:, None, 0] - centre[None, :, 0],
                                 points[:, None, 1] - centre[None, :, 1])))


def to_frenet(tracks: Mapping[str, Track], line: np.ndarray) -> dict[str, Track]:
    """``tracks`` in the Frenet frame of the reference ``line`` (module docstring); the EGO's
    lane, if the line is its centre, at y = 0."""
    out = {}
    for name, t in tracks.items():
        s, d, tangent = path_coordinates(line[:, 0], line[:, 1], t.x, t.y)
        relative = np.angle(np.exp(1j * (t.heading - tangent)))  # wrapped, then continuous
        out[name] = Track(t.t, s, d, t.v, np.unwrap(relative))
    return out
