"""The lanes a CommonRoad drive is reprocessed with: the map's lane width and lane centres.

The AD function (:class:`~simcred.sim.driver.DriverConfig` ``lane_width``, ``lane_centres``), the
risk's lateral geometry (:class:`~simcred.risk.Lanes`) and the reaction rules
(:class:`~simcred.reprocess.reaction.ReactionCriteria` ``lane_width``) assume straight lanes of
one width along +x of the road frame. For a CommonRoad scenario they are taken from its lanelet
network (:func:`map_lanes`), in the road frame the drive is reprocessed in:

* **width**: at each recorded EGO position, the lanelet under it (the position lies between its
  left and right bounds, projects between the ends of its centre line, and the EGO's heading is
  within 45° of the line's direction; of several, the one whose centre line is nearest) and
  that lanelet's width there (the distance between its bounds across the position: the signed
  offset from the right bound minus that from the left); the lane width is the **median** over
  the positions that have a lanelet under them;
* **centres**: the lanelet under the EGO's first such position and its neighbours in the same
  direction (CommonRoad ``adjacentLeft``/``adjacentRight`` with ``drivingDir="same"``, at most
  :data:`MAX_NEIGHBOURS` either way); each one's centre line at the EGO's station (the foot of
  the EGO's position on it) in the road frame's lateral coordinate. The AD function's lanes are
  the EGO's lane then its left neighbours (it starts in the first and evades to the left); the
  right neighbours are stated (``right_lane_centres``) but not driven into. The risk's lanes are
  the map's width, one centre at the EGO's lane.

A position with no lanelet under it (a shoulder, a gap in the map) is left out; a drive with
none at all has no map lanes (None: the configured ones are used, and the outputs say so).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from simcred.kinematics import Track
from simcred.reprocess.road import SAME_DIRECTION, chain_line
from simcred.scenario.frenet import path_coordinates, path_points

MAX_NEIGHBOURS = 8  # neighbouring lanelets followed either way, at most
INSIDE = 0.05  # m: a position this far outside a lanelet's bounds still counts as in it

Network = Mapping[int, Mapping[str, Any]]


def lanelets_under(network: Network, ego: Track) -> tuple[np.ndarray, np.ndarray]:
    """Per EGO position the id of the lanelet under it (-1: none) and its width there (NaN)."""
    x, y, heading = np.asarray(ego.x), np.asarray(ego.y), np.asarray(ego.heading)
    best = np.full(len(x), -1)
    nearest = np.full(len(x), np.inf)
    width = np.full(len(x), np.nan)
    for number, lane in network.items():
        centre = lane["centre"]
        if len(centre) < 2 or len(lane["left"]) < 2 or len(lane["right"]) < 2:
            continue
        s, d, tangent = path_coordinates(centre[:, 0], centre[:, 1], x, y)
        length = float(np.hypot(*np.diff(centre, axis=0).T).sum())
        turn = np.abs(np.remainder(heading - tangent + math.pi, 2 * math.pi) - math.pi)
        candidate = (s >= 0) & (s <= length) & (turn < SAME_DIRECTION) & (np.abs(d) < nearest)
        if not candidate.any():
            continue
        left, right = lane["left"], lane["right"]
        _, from_left, _ = path_coordinates(left[:, 0], left[:, 1], x, y)
        _, from_right, _ = path_coordinates(right[:, 0], right[:, 1], x, y)
        take = candidate & (from_left <= INSIDE) & (from_right >= -INSIDE)
        best[take], nearest[take] = number, np.abs(d[take])
        width[take] = (from_right - from_left)[take]
    return best, width


def neighbours(network: Network, start: int, side: str) -> list[int]:
    """The lanelets beside ``start`` on ``side`` ("left" or "right") in the same direction,
    nearest first."""
    chain, current = [], start
    for _ in range(MAX_NEIGHBOURS):
        current = network[current].get(f"{side}_neighbour")
        if current is None or current not in network or current in chain or current == start:
            break
        chain.append(current)
    return chain


def map_lanes(network: Network, ego: Track, frame: Mapping[str, Any], where: str
              ) -> dict[str, Any] | None:
    """The drive's lanes from the map (module docstring): ``lane_width``, ``lane_centres``
    (the EGO's lane, then its left neighbours), ``right_lane_centres``, the ``lanelets`` they
    belong to, and how the width was found; ``ego`` in map coordinates, ``frame`` the drive's
    road frame (``origin``/``angle`` of the rigid frame, or the ``lanelets`` of the Frenet
    frame's chain). None where no lanelet lies under any EGO position."""
    under, widths = lanelets_under(network, ego)
    found = np.flatnonzero(under >= 0)
    if len(found) == 0:
        return None
    k = int(found[0])
    start = int(under[k])
    lateral = _lateral(network, frame, where)
    left, right = neighbours(network, start, "left"), neighbours(network, start, "right")
    point = (np.array([float(ego.x[k])]), np.array([float(ego.y[k])]))

    def centre(number: int) -> float:
        line = network[number]["centre"]
        s, _, _ = path_coordinates(line[:, 0], line[:, 1], *point)
        fx, fy, _ = path_points(line[:, 0], line[:, 1], s, np.zeros(1))
        return float(lateral(fx, fy)[0])

    valid = widths[found]
    return {"lane_width": float(np.median(valid)),
            "lane_centres": [centre(i) for i in (start, *left)],
            "right_lane_centres": [centre(i) for i in right],
            "lanelets": [start, *left], "right_lanelets": right,
            "width": "median over the EGO's positions of the width of the lanelet under it",
            "width_range": [float(valid.min()), float(valid.max())],
            "positions": [len(found), len(under)]}


def _lateral(network: Network, frame: Mapping[str, Any], where: str):
    """The road frame's lateral coordinate of map points (x, y)."""
    if "origin" in frame:
        (x0, y0), angle = frame["origin"], float(frame["angle"])
        c, s = math.cos(angle), math.sin(angle)
        return lambda x, y: -s * (x - x0) + c * (y - y0)
    line = chain_line(network, [int(i) for i in frame["lanelets"]], where)
    return lambda x, y: path_coordinates(line[:, 0], line[:, 1], x, y)[1]
