"""The reprocessing pipeline of [1] Fig. 1: measurement → description → resimulation → refit →
assessment, for GT and for SD, with the ideal and the scenario-based sensor model.

Names of the representations (as in [1]): ``GT``, ``SD`` (the measurement); ``fit(GT)``,
``fit(SD)`` (their scenario descriptions); ``rGT``, ``rSD`` (resimulations of those descriptions
with the *ideal* sensor, as in [1] §III); ``fit(rGT)``, ``fit(rSD)``. With a scenario-based
sensor model ([1] §IV, estimated from the measurement's GT/SD pair) the resimulations are
``rGT[sb]`` (full model: the GT description lacks the sensor's offset) and ``rSD[sb]`` (dynamic
part only: the SD description already holds the offset) and their fits ``fit(rGT[sb])``, ...

All representations are compared on the drive's common time base
(:mod:`simcred.reprocess.timebase`: the coarser recording's samples outside gaps; GT and SD may
come at different rates); resimulated traces (100 Hz) are interpolated linearly onto them,
headings unwrapped first. Each recording is fitted on its own samples.

References
----------
[1] Wagner, Groh et al., Towards Cross-Verification and Use of Simulation in the Assessment of
    Automated Driving, IEEE IV 2019.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from simcred._json import JsonResult, fields_dict
from simcred.errors import OptionError, SimcredError
from simcred.io.measurement import Measurement
from simcred.kinematics import MOTION_SIGNALS, Track
from simcred.reprocess.ad_function import RECORDED_PARAMETERS, resimulation_driver
from simcred.reprocess.decomposition import ErrorStats, decompose
from simcred.reprocess.reaction import (
    Reaction,
    ReactionAnalysis,
    ReactionCriteria,
    reaction,
    reaction_analysis,
)
from simcred.reprocess.representation import GT, SD, Rep, SensorKind, Source
from simcred.reprocess.timebase import MAX_GAP, Aligned, Drive, align
from simcred.reprocess.units import check_units
from simcred.risk import Lanes, VehicleStates, risk, time_headway, time_to_collision
from simcred.scenario.description import ScenarioDescription
from simcred.scenario.fit import ScenarioFit, fit_scenario
from simcred.sim.driver import DriverConfig
from simcred.sim.resimulation import resimulate
from simcred.sim.sensors import IdealSensor, OffsetDelaySensor, estimate_sensor
from simcred.sim.sensors import Sensor as SensorModel
from simcred.traces import TIME, TraceSet

SENSORS = tuple(sensor.value for sensor in SensorKind)
LOG_RISK_FLOOR = 1e-9  # risk below this counts as this on the log scale
LANE_SOURCES = ("map", "configuration")

Progress = Callable[[str], None]


@dataclass(frozen=True, slots=True)
class ReprocessConfig:
    """Options of :func:`reprocess` (defaults: [1]'s pipeline on the cut-in)."""

    vehicle: str = "ks"
    dt: float = 0.01
    risk_dt: float = 0.1
    seed: int = 0
    threshold: float = 0.02  # m, fit RMSE target: above DGPS noise (1.4 cm), far below SD's
    ego: str = "ego"
    objects: tuple[str, ...] = ("to",)
    driver: DriverConfig = field(default_factory=DriverConfig)
    scenario_based: bool = True
    criteria: ReactionCriteria = field(default_factory=ReactionCriteria)
    max_gap: float = MAX_GAP  # s: longer gaps are refused or cut away (long_gaps)
    long_gaps: str = "error"  # or "longest": reprocess the longest stretch without one
    # a scenario-based sensor model estimated on other drives ([1] §IV: "a set of drives");
    # None: estimated from this measurement's own GT/SD pair
    sensor_model: OffsetDelaySensor | None = None
    # AD-function parameters taken from the recorded EGO instead of ``driver``: "set_speed",
    # "lanes", "time_gap" (:mod:`simcred.reprocess.ad_function`)
    from_recording: tuple[str, ...] = ()
    # "map": where the drive carries its map's lanes (a CommonRoad scenario, metadata ``lanes``,
    # :mod:`simcred.reprocess.lanes`) they are the AD function's lanes (before ``from_recording``)
    # and the risk's and the reaction rules' lane geometry; "configuration": ``driver`` and
    # ``criteria`` as given, the risk's lanes 3.5 m about y = 0 (as without a map)
    lanes: str = "map"

    def __post_init__(self) -> None:
        if self.lanes not in LANE_SOURCES:
            raise OptionError(f"lanes: one of {', '.join(LANE_SOURCES)}, got {self.lanes!r}")
        unknown = sorted(set(self.from_recording) - set(RECORDED_PARAMETERS))
        if unknown:
            raise OptionError(f"from_recording: unknown parameter(s) {', '.join(unknown)} "
                              f"(known: {', '.join(RECORDED_PARAMETERS)})")


@dataclass(frozen=True, slots=True, eq=False)
class RiskSeries(JsonResult):
    """The assessment of one representation ([1] §II-D), per scene every ``risk_dt`` on its
    description: the scene times ``t`` (s), the TTR risk and the least TTR (s) of
    :func:`simcred.risk.risk`, TTC and THW to the lead (s, :mod:`simcred.risk.measures`). Its
    document (one entry of ``risk.json``) is its fields, arrays as lists."""

    t: np.ndarray
    risk: np.ndarray
    ttr_min: np.ndarray
    ttc: np.ndarray
    thw: np.ndarray

    @property
    def max_risk(self) -> float:
        """The highest risk of the series (``reprocess.json``'s ``max_risk``)."""
        return float(self.risk.max())

    def to_dict(self) -> dict[str, Any]:
        return fields_dict(self)


@dataclass(frozen=True, slots=True, eq=False)
class Reprocessed(JsonResult):
    """Everything the pipeline produced; :meth:`to_dict` is ``reprocess.json``'s body."""

    config: ReprocessConfig
    times: np.ndarray
    states: dict[Rep, dict[str, Track]]  # representation -> object -> track on ``times``
    descriptions: dict[str, ScenarioDescription]
    fits: dict[str, ScenarioFit]
    resimulations: dict[str, TraceSet]
    errors: dict[str, dict[str, dict[str, dict[str, ErrorStats]]]]
    reactions: dict[str, Reaction]
    analysis: ReactionAnalysis | None  # [1] §IV's eqs. (4)-(7); None without GT
    risk: dict[str, RiskSeries]  # representation -> its risk, TTC and THW series
    sensor_model: OffsetDelaySensor | None
    inputs: dict[str, str] = field(default_factory=dict)  # GT / SD -> content hash
    ad_function: dict[str, Any] = field(default_factory=dict)  # the resimulations' parameters
    aligned: Aligned | None = None  # the time base and its gaps (without the tracks)
    drive_metadata: dict[str, Any] = field(default_factory=dict)  # the drive's provenance

    @property
    def input_report(self) -> dict[str, Any]:
        """``reprocess.json``'s ``input``: the drive's provenance, time base and every gap."""
        if self.aligned is None:
            return {}
        return {"drive": dict(self.drive_metadata), **self.aligned.to_dict()}

    @property
    def analysis_report(self) -> dict[str, Any]:
        """``reprocess.json``'s ``analysis``: :meth:`ReactionAnalysis.to_dict` (flat, [1]'s
        symbols as keys), empty without GT."""
        return {} if self.analysis is None else self.analysis.to_dict()

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(self.states)

    def __repr__(self) -> str:
        reactions = ", ".join(f"{k}: {r.manoeuvre}" for k, r in self.reactions.items())
        return f"Reprocessed({len(self.states)} representations; reactions {reactions})"

    def to_dict(self) -> dict[str, Any]:
        """Options, fits, sensor model, reactions, eqs. (4)-(7), max risk per representation."""
        c = self.config
        return {
            "options": {"vehicle": c.vehicle, "dt": c.dt, "risk_dt": c.risk_dt, "seed": c.seed,
                        "ego": c.ego, "objects": list(c.objects), "threshold": c.threshold,
                        "scenario_based": c.scenario_based, "max_gap": c.max_gap,
                        "long_gaps": c.long_gaps, "lanes": c.lanes},
            "input": self.input_report,
            "ad_function": self.ad_function,
            "fits": {name: {obj: {"sections": f.sections, "rmse": f.rmse,
                                  "stop_reason": str(f.stop_reason),
                                  "phantom_acceleration": f.phantom_acceleration}
                            for obj, f in fit.fits.items()} for name, fit in self.fits.items()},
            "sensor_model": None if self.sensor_model is None else self.sensor_model.to_dict(),
            "reactions": {k: r.to_dict() for k, r in self.reactions.items()},
            "analysis": self.analysis_report,
            "max_risk": {k: r.max_risk for k, r in self.risk.items()},
        }


def reprocess(measurement: Measurement | Drive, config: ReprocessConfig | None = None,
              progress: Progress | None = None) -> Reprocessed:
    """Run the whole pipeline on ``measurement`` (GT optional: without it only SD's part)."""
    c = ReprocessConfig() if config is None else config
    say = progress or (lambda _: None)
    objects = (c.ego, *c.objects)
    drive = measurement if isinstance(measurement, Drive) else Drive.of_measurement(measurement)
    check_units(drive, objects)
    aligned = align(drive, objects, max_gap=c.max_gap, long_gaps=c.long_gaps)
    times = aligned.times
    raw = {name: aligned.tracks[str(name)] for name in (SD, GT) if str(name) in aligned.tracks}
    states = {name: {o: t.interpolate(times) for o, t in tracks.items()}
              for name, tracks in raw.items()}
    fits, resims = {}, {}
    dimensions = footprints(drive, objects)
    recorded = {o: dict(k) for o, k in drive.metadata.get("objects", {}).items() if o in objects}
    kinds = {"objects": recorded} if recorded else None  # types for the .xosc, stated
    for name, tracks in raw.items():
        say(f"fit {name}")
        fits[name.fit()] = fit_scenario(tracks,
                                        objects=list(objects), threshold=c.threshold,
                                        dimensions=dimensions, metadata=kinds)
    sensor_model = c.sensor_model if c.sensor_model is not None else (
        _sensor_model(times, states, c) if c.scenario_based and GT in raw else None)
    road = drive.metadata.get("lanes") if c.lanes == "map" else None
    recorded_ego = fits[(GT if GT in raw else SD).fit()].description
    driver, ad_report = resimulation_driver(recorded_ego, c, road, "lanes" in drive.metadata)
    for name in raw:
        for kind, sensor in _sensors(name, sensor_model):
            say(f"resimulate {name} ({sensor.name} sensor)")
            key = name.resimulation(kind)
            resims[key] = replace(resimulate(
                fits[name.fit()].description, sensor=sensor, vehicle=c.vehicle,
                driver=driver, dt=c.dt, seed=c.seed, ego=c.ego), run_ids=(key,), source=key)
            states[key] = _interpolated_tracks(resims[key], times, objects)
            say(f"refit {key}")
            fits[key.fit()] = fit_scenario(resims[key], objects=list(objects),
                                           threshold=c.threshold, dimensions=dimensions,
                                           metadata=kinds)
    descriptions = {k: f.description for k, f in fits.items()}
    for key, description in descriptions.items():
        states[key] = _description_tracks(description, times, objects)
    say("assess")
    assessed = {k.unfitted: d for k, d in descriptions.items()}
    criteria = c.criteria if road is None else replace(c.criteria,
                                                       lane_width=road["lane_width"])
    lanes = Lanes() if road is None else Lanes(road["lane_width"], road["lane_centres"][0])
    ad_report.update(risk_lanes={"width": lanes.width, "centre": lanes.centre},
                     reaction_lane_width=criteria.lane_width)
    reactions = {k: _reaction(d, c, criteria) for k, d in assessed.items()}
    risk = {k: _risk(d, c, lanes) for k, d in assessed.items()}
    errors = {SensorKind.IDEAL: decompose(states, objects)}
    if sensor_model is not None:
        errors[SensorKind.SCENARIO_BASED] = decompose(_as_ideal(states), objects)
    return Reprocessed(c, times, states, descriptions, fits, resims, errors, reactions,
                       _analysis(states, reactions, c), risk, sensor_model,
                       {name: r.digest for name, r in drive.recordings().items()},
                       ad_function=ad_report, aligned=replace(aligned, tracks={}),
                       drive_metadata=dict(drive.metadata))


def footprints(drive: Drive, objects: tuple[str, ...]) -> dict[str, tuple[float, float]]:
    """(length, width) of each object whose recording gives its footprint (the drive's
    ``objects`` metadata, e.g. a CommonRoad obstacle's shape); the others are fitted, resimulated
    and assessed as a 4.5 × 1.8 m car."""
    given = drive.metadata.get("objects", {})
    return {o: (float(given[o]["length"]), float(given[o]["width"])) for o in objects
            if "length" in given.get(o, {}) and "width" in given.get(o, {})}


def _sensors(name: Rep, model: OffsetDelaySensor | None
             ) -> list[tuple[SensorKind, SensorModel]]:
    """The resimulations' sensors: ideal, and the scenario-based model (its dynamic part only
    for SD, whose description already contains the offset, [1] §IV)."""
    chosen: list[tuple[SensorKind, SensorModel]] = [(SensorKind.IDEAL, IdealSensor())]
    if model is not None:
        chosen.append((SensorKind.SCENARIO_BASED,
                       model if name.source is Source.GT else model.dynamic_only()))
    return chosen


def _sensor_model(times: np.ndarray, states: dict[Rep, dict[str, Track]],
                  c: ReprocessConfig) -> OffsetDelaySensor:
    """The scenario-based sensor model from the measurement's own GT/SD pair of the first TO,
    on the common time base."""
    to = c.objects[0]
    return estimate_sensor(times, states[GT][c.ego].states()[:, :2], states[GT][to].states(),
                           states[SD][to].states())


def _tracks(traces: TraceSet, objects: tuple[str, ...]) -> dict[str, Track]:
    run = traces.run(0)
    missing = [f"{o}.{s}" for o in objects for s in MOTION_SIGNALS if f"{o}.{s}" not in run]
    if missing:
        raise SimcredError(f"{traces.source}: missing signal(s) {', '.join(missing)}")
    return {o: Track.from_columns(run, o, time=TIME, source=traces.source) for o in objects}


def _interpolated_tracks(traces: TraceSet, times: np.ndarray, objects: tuple[str, ...]
                         ) -> dict[str, Track]:
    return {o: track.interpolate(times) for o, track in _tracks(traces, objects).items()}


def _description_tracks(description: ScenarioDescription, times: np.ndarray,
                        objects: tuple[str, ...]) -> dict[str, Track]:
    """The description's tracks on ``times`` (held at its ends outside its span)."""
    inside = np.clip(times, description.t0, description.t1)
    return {o: replace(description.objects[o].states(inside), t=times) for o in objects}


def _as_ideal(states: dict[Rep, dict[str, Track]]) -> dict[Rep, dict[str, Track]]:
    """Representations renamed so that the scenario-based ones take the place of the ideal."""
    renamed = {k: v for k, v in states.items() if not k.scenario_based}
    renamed.update({k.ideal(): v for k, v in states.items() if k.scenario_based})
    return renamed


def _reaction(description: ScenarioDescription, c: ReprocessConfig,
              criteria: ReactionCriteria) -> Reaction:
    s = description.objects[c.ego].states(description.times(c.dt))
    return reaction(s.t, s.y, s.v, s.heading, s.acceleration, criteria)


def _risk(description: ScenarioDescription, c: ReprocessConfig, lanes: Lanes) -> RiskSeries:
    """Risk, TTC and THW per scene every ``risk_dt`` on the description ([1] §II-D)."""
    t = description.times(c.risk_dt)
    ego_track, tracks = description.objects[c.ego], [description.objects[o] for o in c.objects]
    ego = VehicleStates.of_tracks(ego_track.states(t), name=c.ego, length=ego_track.length,
                                  width=ego_track.width)
    others = VehicleStates.of_tracks([track.states(t) for track in tracks], name="objects",
                                     length=np.array([track.length for track in tracks]),
                                     width=np.array([track.width for track in tracks]))
    result = risk(ego, others, lanes=lanes)
    return RiskSeries(t, result.risk, result.ttr_min, time_to_collision(ego, others),
                      time_headway(ego, others))


def log_risk(risk: np.ndarray) -> np.ndarray:
    return np.log10(np.maximum(risk, LOG_RISK_FLOOR))


def log_risk_rmse(a: RiskSeries, b: RiskSeries) -> float:
    """RMSE of log10 risk over the common sample times of two risk series."""
    n = min(len(a.risk), len(b.risk))
    return float(np.sqrt(np.mean((log_risk(a.risk[:n]) - log_risk(b.risk[:n])) ** 2)))


def _analysis(states: dict[Rep, dict[str, Track]], reactions: dict[str, Reaction],
              c: ReprocessConfig) -> ReactionAnalysis | None:
    """Eqs. (4)-(7) for the ideal sensor, and the same for the scenario-based model."""
    if GT not in states:
        return None
    to = c.objects[0]
    offset = float(np.mean(np.hypot(states[SD][to].x - states[GT][to].x,
                                    states[SD][to].y - states[GT][to].y)))
    gt = reactions[GT]
    speed = gt.speed_at_reaction if not math.isnan(gt.speed_at_reaction) else float(
        np.mean(states[GT][c.ego].v))
    sb = {k.ideal(): v for k, v in reactions.items() if k.scenario_based}
    if sb:
        sb[GT] = gt
    return ReactionAnalysis(offset, speed, reaction_analysis(reactions, offset, speed),
                            reaction_analysis(sb, offset, speed) if sb else None)
