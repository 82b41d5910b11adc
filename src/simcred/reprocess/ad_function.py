"""The resimulations' AD function: the configured one, with parameters taken from the recording.

A recorded drive has no AD function: its EGO is a human (NGSIM, MONA) or an unknown system. To
resimulate it, the configured ACC stands in, and the parameters named by
``ReprocessConfig.from_recording`` are read off the recorded EGO instead of the configuration:

* ``set_speed``: its highest described speed;
* ``lanes``: the configured lane spacing with its lane centred on its first position (a map's
  lanes, :mod:`simcred.reprocess.lanes`, take their place where the drive has them);
* ``time_gap``: the ACC time gap ``T`` at which the ACC's equilibrium gap ``s0 + T v`` (its
  standstill gap ``s0``, speed ``v``) equals the gap the recorded EGO keeps to the first object
  — measured as the ACC measures it, the distance along x less its vehicle length — as the
  median of ``(gap − s0) / v`` over the samples where that object is ahead of the EGO within
  half a lane width of its y and the EGO drives at least :data:`FOLLOWING_SPEED`; at least 0.
  Without such a sample the configured time gap stays (and the report says so).
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from simcred.scenario.description import ScenarioDescription
from simcred.sim.driver import DriverConfig

if TYPE_CHECKING:
    from simcred.reprocess.pipeline import ReprocessConfig

RECORDED_PARAMETERS = ("set_speed", "lanes", "time_gap")
FOLLOWING_SPEED = 5.0  # m/s: slower, (gap − s0) / v is dominated by the standstill gap


def resimulation_driver(description: ScenarioDescription, c: ReprocessConfig,
                road: dict[str, Any] | None, has_map: bool = False
                ) -> tuple[DriverConfig, dict[str, Any]]:
    """``c.driver`` with the parameters ``c.from_recording`` names taken from the recorded
    EGO's ``description`` (GT's if there is one, else SD's; module docs), sampled every
    ``c.dt``. The map's lanes ``road``, where given, are the lanes and the lane width instead
    (``has_map``: the drive has a map, none of whose lanelets lies under the EGO; stated).
    Returns the AD function's configuration and its report (``reprocess.json``'s
    ``ad_function``)."""
    driver, ego = c.driver, description.objects[c.ego]
    source = {p: ("recorded EGO" if p in c.from_recording else "configuration")
              for p in RECORDED_PARAMETERS}
    if "set_speed" in c.from_recording:
        driver = replace(driver, set_speed=float(ego.speed(description.times(c.dt)).max()))
    if road is not None:
        driver = replace(driver, lane_centres=tuple(road["lane_centres"]),
                         lane_width=road["lane_width"])
    elif "lanes" in c.from_recording:
        y0 = float(ego.states(np.array([description.t0])).y[0])
        first = driver.lane_centres[0]
        driver = replace(driver, lane_centres=tuple(y0 + y - first for y in driver.lane_centres))
    if "time_gap" in c.from_recording:
        time_gap = recorded_time_gap(description, c.ego, c.objects[0], driver, c.dt)
        if time_gap is None:
            source["time_gap"] = "configuration (the recorded EGO never follows the object)"
        else:
            driver = replace(driver, time_gap=time_gap)
    report = {"set_speed": driver.set_speed, "lane_centres": list(driver.lane_centres),
              "lane_width": driver.lane_width, "time_gap": driver.time_gap,
              "standstill_gap": driver.standstill_gap, "from": source}
    if road is not None:
        source["lanes"] = "map"
        report["map"] = {k: v for k, v in road.items()
                         if k not in ("lane_centres", "lane_width")}
    elif has_map and c.lanes == "map":
        report["map"] = "no lanelet under the EGO: lanes not from the map"
    return driver, report


def recorded_time_gap(description: ScenarioDescription, ego: str, lead: str,
                      driver: DriverConfig, dt: float) -> float | None:
    """The time gap of ``driver``'s ACC whose equilibrium gap is the recorded EGO's gap to
    ``lead`` (module docs), from their tracks in ``description`` every ``dt`` over its span;
    None where the EGO never follows ``lead``."""
    t = description.times(dt)
    e, o = description.objects[ego].states(t), description.objects[lead].states(t)
    gap = o.x - e.x - driver.vehicle_length
    following = ((gap > 0) & (np.abs(o.y - e.y) < driver.lane_width / 2)
                 & (e.v >= FOLLOWING_SPEED))
    if not following.any():
        return None
    headway = (gap[following] - driver.standstill_gap) / e.v[following]
    return max(float(np.median(headway)), 0.0)
