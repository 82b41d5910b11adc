"""CommonRoad XML scenarios (2018b/2020a) as trace sets, read with commonroad-io.

Two layouts:

* ``layout="obstacles"`` (default): every dynamic obstacle with a trajectory is a run ``obj<id>``
  with signals ``x``, ``y``, ``heading``, ``v`` and, when every state has them, ``acceleration``,
  ``yaw_rate``, ``slip_angle``.
* ``layout="scenario"``: the scenario is one run (id = scenario id) with ``obj<id>.<signal>``
  signals; obstacles that enter or leave follow the long-format missing-row rule (``missing``).

A state's time is ``time_step * dt`` (seconds, float64). Each obstacle's states are its initial
state followed by its trajectory. Values are commonroad-io's floats, unchanged. Obstacles with
fewer than two states (no trajectory) cannot form a run and are listed in the metadata under
``obstacles_without_trajectory``; a quantity that only some states carry (commonroad-io fills
``acceleration`` etc. of initial states the file does not give) is not a signal and is listed
under ``partial_quantities``. Uncertain states (shapes, intervals) are one-line errors.
"""

from __future__ import annotations

import contextlib
import logging
import math
import warnings
from collections.abc import Collection
from pathlib import Path

import numpy as np

from simcred.errors import OptionError, TraceSetError
from simcred.io._xml import xml_root
from simcred.io.longformat_records import Records, to_traceset
from simcred.kinematics import LANE_WIDTH
from simcred.traces import TraceSet

LAYOUTS = ("obstacles", "scenario")
BASE = ("x", "y", "heading", "v")
OPTIONAL = ("acceleration", "yaw_rate", "slip_angle")
_ATTRIBUTE = {"heading": "orientation", "v": "velocity"}


def _open(path: Path):
    from commonroad.common.file_reader import CommonRoadFileReader

    root = xml_root(path)  # refuses DTDs and entities before commonroad-io's parser sees the file
    if root != "commonRoad":
        raise TraceSetError(f"{path}: root element <{root}> is not <commonRoad>")
    try:
        with warnings.catch_warnings(), _quiet("commonroad"):
            warnings.simplefilter("ignore")
            scenario, _ = CommonRoadFileReader(str(path)).open(lanelet_assignment=False)
    except Exception as exc:  # commonroad-io raises many kinds (assert, KeyError, lxml errors)
        reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise TraceSetError(f"{path}: unreadable CommonRoad scenario ({reason})") from None
    return scenario


@contextlib.contextmanager
def _quiet(name: str):
    """Silence a library's log warnings (commonroad-io logs one per deprecated lanelet tag)."""
    logger = logging.getLogger(name)
    level = logger.level
    logger.setLevel(logging.ERROR)
    try:
        yield
    finally:
        logger.setLevel(level)


def obstacle_states(obstacle) -> list:
    """Initial state followed by the trajectory's states (commonroad-io objects)."""
    prediction = obstacle.prediction
    trajectory = getattr(prediction, "trajectory", None)
    return [obstacle.initial_state, *(trajectory.state_list if trajectory is not None else [])]


def _number(value, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating | np.integer):
        raise TraceSetError(f"{where}: value {type(value).__name__} is not an exact number "
                            "(uncertain states are not supported)")
    return float(value)


def _state_row(state, where: str, quantities: tuple[str, ...]) -> list[float]:
    position = state.position
    if not isinstance(position, np.ndarray) or position.shape != (2,):
        raise TraceSetError(f"{where}: position is not an exact point (uncertain states are not "
                            "supported)")
    row = [_number(state.time_step, where), float(position[0]), float(position[1])]
    for name in quantities[2:]:
        row.append(_number(getattr(state, _ATTRIBUTE.get(name, name)), where))
    return row


def _quantities(obstacles) -> tuple[tuple[str, ...], list[str]]:
    """Signals every state of every obstacle has, and the optional ones only some have."""
    have = {name: True for name in OPTIONAL}
    seen = dict.fromkeys(OPTIONAL, False)
    for obstacle in obstacles:
        for state in obstacle_states(obstacle):
            for name in OPTIONAL:
                present = state.has_value(name)
                have[name] &= present
                seen[name] |= present
    signals = BASE + tuple(n for n in OPTIONAL if have[n])
    return signals, [n for n in OPTIONAL if seen[n] and not have[n]]


def read(path: str | Path, *, layout: str = "obstacles", missing: str = "error") -> TraceSet:
    """Read a CommonRoad XML scenario (see the module docstring for layouts and rules).

    Parameters
    ----------
    path : path
        A CommonRoad ``.xml`` scenario file.
    layout : {"obstacles", "scenario"}
        Each dynamic obstacle a run, or the whole scenario one run with ``obj<id>.`` signals.
    missing : {"error", "intersect"}
        Scenario layout: what an obstacle absent at a time step means (long-format rule).
    """
    if layout not in LAYOUTS:
        raise OptionError(f"layout must be one of {', '.join(LAYOUTS)}, got {layout!r}")
    path = Path(path)
    scenario = _open(path)
    dt = float(scenario.dt)
    if not (math.isfinite(dt) and dt > 0):  # a negative step would reverse every run's time
        raise TraceSetError(f"{path}: timeStepSize must be a positive number of seconds, got "
                            f"{scenario.dt}")
    moving = [o for o in scenario.dynamic_obstacles if len(obstacle_states(o)) >= 2]
    still = [o.obstacle_id for o in scenario.dynamic_obstacles if len(obstacle_states(o)) < 2]
    if not moving:
        raise TraceSetError(f"{path}: no dynamic obstacle with a trajectory")
    quantities, partial = _quantities(moving)
    rows, labels = [], []
    for obstacle in moving:
        for k, state in enumerate(obstacle_states(obstacle)):
            where = f"{path}: obstacle {obstacle.obstacle_id}, state {k}"
            rows.append(_state_row(state, where, quantities))
            labels.append(str(obstacle.obstacle_id))
    table = np.asarray(rows, dtype=np.float64)
    present = np.ones(len(table), dtype=bool)
    records = Records(
        where=str(path),
        time=table[:, 0] * dt,
        runs=None,
        objects=np.asarray(labels, dtype=object),
        fields={name: (table[:, j + 1], present) for j, name in enumerate(quantities)},
        default_run=str(scenario.scenario_id),
        row_name="state",
    )
    metadata = {"format": "commonroad", "scenario_id": str(scenario.scenario_id), "dt": dt,
                "layout": layout}
    metadata["obstacles"] = {str(o.obstacle_id): _obstacle_kind(o) for o in moving}
    if still:
        metadata["obstacles_without_trajectory"] = still
    if partial:
        metadata["partial_quantities"] = partial
    return to_traceset(records, objects_as="runs" if layout == "obstacles" else "signals",
                       missing=missing, metadata=metadata, source=str(path))


def lanelets(path: str | Path) -> dict[int, dict]:
    """The scenario's lanelet network: per lanelet id its ``centre`` line and its ``left`` and
    ``right`` bounds ((n, 2) arrays, in driving direction, vertices paired), its
    ``successors`` and ``predecessors`` (ids) and its ``left_neighbour`` and
    ``right_neighbour`` (the adjacent lanelet's id where it runs in the same direction, else
    None)."""
    scenario = _open(Path(path))
    return {int(lane.lanelet_id): {"centre": np.asarray(lane.center_vertices, dtype=np.float64),
                                   "left": np.asarray(lane.left_vertices, dtype=np.float64),
                                   "right": np.asarray(lane.right_vertices, dtype=np.float64),
                                   "successors": [int(i) for i in lane.successor],
                                   "predecessors": [int(i) for i in lane.predecessor],
                                   "left_neighbour": _same_way(lane.adj_left,
                                                               lane.adj_left_same_direction),
                                   "right_neighbour": _same_way(lane.adj_right,
                                                                lane.adj_right_same_direction)}
            for lane in scenario.lanelet_network.lanelets}


def _same_way(neighbour, same_direction) -> int | None:
    return int(neighbour) if neighbour is not None and same_direction else None


def _obstacle_kind(obstacle) -> dict:
    """The obstacle's type (CommonRoad ``ObstacleType`` value) and, for a rectangle or a circle,
    its footprint ``length`` × ``width`` (m; a circle: its diameter both)."""
    kind = {"type": str(obstacle.obstacle_type.value)}
    shape = obstacle.obstacle_shape
    if hasattr(shape, "length") and hasattr(shape, "width"):
        kind.update(length=float(shape.length), width=float(shape.width))
    elif hasattr(shape, "radius"):
        kind.update(length=2 * float(shape.radius), width=2 * float(shape.radius))
    return kind


# -- choosing the EGO for reprocessing one obstacle ------------------------------------------------

#: A vehicle drives "in the same direction" when its heading is within this of the obstacle's.
SAME_DIRECTION = math.pi / 4


def follower(traces: TraceSet, obstacle: str, *, lane_width: float = LANE_WIDTH,
             skip: Collection[str] = ()) -> tuple[str, str] | None:
    """The EGO for reprocessing ``obstacle`` as the traffic object: its follower.

    Only runs that share at least 2 time steps with the obstacle (what a fit needs) count. At
    every time step both are recorded, another run is *behind* the obstacle when, in the
    obstacle's frame (x along its heading), it lies at x < 0 and drives in the same direction
    (headings within 45°); of those, the one with the smallest |x| is the obstacle's nearest
    follower at that step. The EGO is the run that is the nearest follower at the most steps
    (ties: the one listed first), counting first only runs within half a lane laterally
    (|y| < ``lane_width`` / 2: the follower in the obstacle's lane, e.g. the vehicle a cut-in
    pulls in front of), and, if there is none, runs in any lane. If no run is ever behind the
    obstacle in its direction (the last vehicle of a platoon, an oncoming or parked car), the
    EGO is the run nearest to it on average over the time steps both have (at least 2).

    Parameters
    ----------
    traces : TraceSet
        :func:`read` with ``layout="obstacles"`` (runs ``obj<id>``, signals x, y, heading).
    obstacle : str
        The traffic object's run id.
    lane_width : float, default: 3.5
    skip : collection of str, default: ()
        Obstacle types (``metadata["obstacles"][id]["type"]``) that are never chosen, e.g. the
        pedestrians and bicycles an ACC cannot drive: the follower is then the nearest run of
        another type, and a pedestrian behind the obstacle does not hide the car behind it.

    Returns
    -------
    (run id, rule) or None
        ``rule`` is ``"follower in its lane"``, ``"nearest vehicle behind (another lane)"`` or
        ``"nearest vehicle (none behind it in its direction)"``; None if no other run (of a
        type not skipped) shares two time steps with the obstacle.
    """
    kinds = traces.metadata.get("obstacles", {})
    to = traces.run(traces.run_ids.index(obstacle))
    others = {r: c for r, c in ((r, traces.run(i)) for i, r in enumerate(traces.run_ids))
              if r != obstacle and kinds.get(r[3:], {}).get("type") not in skip
              and len(np.intersect1d(to["t"], c["t"])) >= 2}  # a fit needs 2 shared samples
    for rule, lane in (("follower in its lane", lane_width / 2),
                       ("nearest vehicle behind (another lane)", math.inf)):
        nearest = _nearest_behind(to, others, lane)
        if nearest:
            counts = {r: nearest.count(r) for r in dict.fromkeys(nearest)}
            best = max(counts.values())
            return next(r for r in others if counts.get(r) == best), rule
    return _nearest(to, others)


def _nearest(to: dict[str, np.ndarray], others: dict[str, dict[str, np.ndarray]]
             ) -> tuple[str, str] | None:
    """The run with the smallest mean distance to ``to`` over at least 2 shared time steps."""
    best = None
    for name, run in others.items():
        _, i, j = np.intersect1d(to["t"], run["t"], return_indices=True)
        if len(i) >= 2:
            distance = float(np.mean(np.hypot(run["x"][j] - to["x"][i],
                                              run["y"][j] - to["y"][i])))
            if best is None or distance < best[0]:
                best = (distance, name)
    return None if best is None else (best[1], "nearest vehicle (none behind it in its "
                                                "direction)")


def _nearest_behind(to: dict[str, np.ndarray], others: dict[str, dict[str, np.ndarray]],
                    half_width: float) -> list[str]:
    """Per time step of ``to``, the run behind it with the smallest gap (absent if none)."""
    if not others:  # the obstacle alone (or every other one skipped): no one behind it
        return []
    t = to["t"]
    gap = np.full((len(others), len(t)), np.inf)
    names = list(others)
    c, s = np.cos(to["heading"]), np.sin(to["heading"])
    for k, run in enumerate(others.values()):
        _, i, j = np.intersect1d(t, run["t"], return_indices=True)
        dx, dy = run["x"][j] - to["x"][i], run["y"][j] - to["y"][i]
        lon, lat = dx * c[i] + dy * s[i], -dx * s[i] + dy * c[i]
        same = np.cos(run["heading"][j] - to["heading"][i]) > math.cos(SAME_DIRECTION)
        behind = same & (lon < 0) & (np.abs(lat) < half_width)
        gap[k, i[behind]] = -lon[behind]
    found = np.isfinite(gap).any(axis=0)
    return [names[k] for k in np.argmin(gap[:, found], axis=0)]
