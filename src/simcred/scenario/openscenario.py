"""Export a scenario description to OpenSCENARIO 1.x and validate the file against the schema.

The export hands the description to a simulation framework, [1] sec. II-B: "a standardized
implementation of the scenario interpretation module within the simulation framework, for
example, a trajectory follower for the simulated TO". Every object becomes a vehicle entity; the
EGO starts from its initial state (the function under test drives it); every other object follows
a timed polyline sampled from the description. Built with scenariogeneration [2]; validated with
xmlschema against the XSDs shipped with it.

References
----------
[1] Wagner, Groh, Kühbeck, Knoll, Towards Cross-Verification and Use of Simulation in the
    Assessment of Automated Driving (paper 002), sec. II-B.
[2] scenariogeneration (pyoscx), https://github.com/pyoscx/scenariogeneration.
[3] ASAM OpenSCENARIO 1.x: FollowTrajectoryAction, Timing (time = value · scale + offset).
"""

from __future__ import annotations

import datetime as dt
import functools
import math
from pathlib import Path
from typing import Any

import numpy as np

from simcred._xml import read_xml
from simcred.errors import OptionError, SimcredError
from simcred.kinematics import Track
from simcred.scenario.description import (
    ObjectTrack,
    ScenarioDescription,
    sample_times,
)
from simcred.scenario.map_frame import MapFrame, PathFrame, RigidFrame

STEP = 0.1
#: OpenSCENARIO vehicle category per recorded (CommonRoad) type; other types are cars.
VEHICLE_CATEGORIES = {"truck": "truck", "bus": "bus", "bicycle": "bicycle",
                      "motorcycle": "motorbike", "train": "train"}
PEDESTRIAN_HEIGHT = 1.8  # m
PEDESTRIAN_MASS = 80.0  # kg
"""Default time step (s) of the exported trajectory vertices."""
HEIGHT = 1.5
"""Height (m) of the exported bounding boxes (the description has none)."""
MINOR_VERSION = 2
"""Default OpenSCENARIO minor version (1.2)."""


#: Header date of an export whose inputs carry no date (the wall clock would break
#: byte-identical reruns).
NO_DATE = dt.datetime(1970, 1, 1)


def to_openscenario(description: ScenarioDescription, path: str | Path, **options: Any) -> Path:
    """Write :func:`build_openscenario` of ``description`` to ``path`` (``.xosc``); return it.

    ``options`` are the keyword options of :func:`build_openscenario`.
    """
    path = Path(path)
    build_openscenario(description, **options).write_xml(str(path))
    return path


def build_openscenario(
    description: ScenarioDescription,
    *,
    ego: str = "ego",
    road_file: str | None = None,
    frame: MapFrame | None = None,
    step: float = STEP,
    ego_trajectory: bool = False,
    osc_minor_version: int = MINOR_VERSION,
    name: str = "simcred scenario",
    author: str = "simcred",
    creation_date: dt.datetime | None = None,
) -> Any:
    """``description`` as an OpenSCENARIO 1.x ``scenariogeneration.xosc.Scenario``.

    Parameters
    ----------
    description : ScenarioDescription
        The scenario.
    ego : str, default: "ego"
        The object under test: it is placed by the Init (TeleportAction to its WorldPosition at
        the start, AbsoluteSpeedAction with a step) and gets no trajectory.
    road_file : str, optional
        OpenDRIVE file for the RoadNetwork's ``LogicFile`` (written as given: a relative path
        is read from the .xosc's directory).
    frame : RigidFrame or PathFrame, optional
        Where the description's frame lies in the map (:mod:`simcred.scenario.map_frame`):
        every exported position and heading is taken back to map coordinates, so the file
        lines up with ``road_file``. Default: positions as the description holds them.
    step : float, default: 0.1
        Vertex spacing (s); vertices at t0 + k·step of every object's span, plus its t1.
    ego_trajectory : bool, default: False
        Also let the EGO follow its trajectory (a replay rather than a test).
    osc_minor_version : int, default: 2
        OpenSCENARIO 1.``osc_minor_version``, 1 to 3.
    name, author : str
        File header.
    creation_date : datetime, optional
        Header date. Default: the description's ``metadata["date"]`` (ISO 8601) if it has one,
        else :data:`NO_DATE` (1970-01-01T00:00:00): never the wall clock, so the same
        description gives the same file byte for byte.

    Returns
    -------
    scenariogeneration.xosc.Scenario

    Notes
    -----
    Vertices are ``WorldPosition(x, y, h=θ)`` with ``time`` = the description's time, sampled by
    :meth:`ObjectTrack.states`; the heading is the unwrapped θ (not folded into (−π, π]). Timing
    is absolute with scale 1 and offset −T0, T0 the earliest start of any object, so simulation
    time 0 is T0 [3]. The trajectory following mode is ``position``. Every object starts at its
    own first state (Init); the storyboard stops at simulation time T1 − T0, T1 the latest end.
    The entity reference point is the centre of the bounding box (the point the description
    tracks), not the rear axle; axles are placed at ±30 % of the length. scenariogeneration and
    xmlschema are imported on first use (they take most of a second to import).
    """
    _to_openscenario_iv(description, ego, frame, step, osc_minor_version)
    from scenariogeneration import xosc

    start = min(track.t0 for track in description.objects.values())
    end = max(track.t1 for track in description.objects.values())
    entities = xosc.Entities()
    init = xosc.Init()
    act = xosc.Act("replay", _at_time(xosc, 0.0, "start"))
    followers = 0
    for obj, track in description.objects.items():
        entities.add_scenario_object(obj, _entity(xosc, obj, track,
                                                  object_type(description, obj)))
        first = _placed(track.states(np.array([track.t0])), frame)
        init.add_init_action(obj, xosc.TeleportAction(_position(xosc, first, 0)))
        init.add_init_action(obj, xosc.AbsoluteSpeedAction(
            float(first.v[0]), xosc.TransitionDynamics(xosc.DynamicsShapes.step,
                                                       xosc.DynamicsDimension.time, 0.0)))
        if obj != ego or ego_trajectory:
            act.add_maneuver_group(_follow(xosc, obj, track, step, start, osc_minor_version,
                                           frame))
            followers += 1
    storyboard = xosc.StoryBoard(init, _at_time(xosc, end - start, "stop"))
    if followers:
        storyboard.add_story(xosc.Story("replay").add_act(act))
    date = creation_date or _date_of(description)
    scenario = xosc.Scenario(name, author, xosc.ParameterDeclarations(), entities, storyboard,
                             xosc.RoadNetwork(roadfile=road_file), xosc.Catalog(),
                             osc_minor_version=osc_minor_version, creation_date=date)
    return scenario


def trajectory_times(track: ObjectTrack, step: float = STEP) -> np.ndarray:
    """The vertex times of ``track`` in the export: t0 + k·step while ≤ t1, then t1."""
    return sample_times(track.t0, track.t1, step)


def _to_openscenario_iv(description: ScenarioDescription, ego: str, frame: Any, step: float,
                        minor: int) -> None:
    if not isinstance(description, ScenarioDescription):
        raise OptionError(f"expected a ScenarioDescription, got {type(description).__name__}")
    if ego not in description.objects:
        raise OptionError(f"ego object '{ego}' is not in the description (objects: "
                          f"{', '.join(description.objects)})")
    if frame is not None and not isinstance(frame, RigidFrame | PathFrame):
        raise OptionError(f"frame must be a RigidFrame or a PathFrame, got "
                          f"{type(frame).__name__}")
    if not (math.isfinite(step) and step > 0):
        raise OptionError(f"step must be a finite number > 0, got {step!r}")
    if isinstance(minor, bool) or minor not in (1, 2, 3):
        raise OptionError(f"osc_minor_version must be 1, 2 or 3, got {minor!r}")


def object_type(description: ScenarioDescription, name: str) -> str:
    """The recorded type of object ``name`` (``metadata["objects"][name]["type"]``, e.g. a
    CommonRoad obstacle type), ``"car"`` where the description does not say."""
    return str(description.metadata.get("objects", {}).get(name, {}).get("type", "car"))


def _entity(xosc: Any, name: str, track: ObjectTrack, kind: str) -> Any:
    """A pedestrian as an OpenSCENARIO ``Pedestrian``, anything else as a ``Vehicle`` of the
    category its type names (:data:`VEHICLE_CATEGORIES`; others: car); the footprint is the
    track's."""
    if kind == "pedestrian":
        box = xosc.BoundingBox(track.width, track.length, PEDESTRIAN_HEIGHT, 0.0, 0.0,
                               PEDESTRIAN_HEIGHT / 2)
        return xosc.Pedestrian(name, PEDESTRIAN_MASS, xosc.PedestrianCategory.pedestrian, box,
                               model="pedestrian")
    return _vehicle(xosc, name, track, getattr(xosc.VehicleCategory,
                                               VEHICLE_CATEGORIES.get(kind, "car")))


def _vehicle(xosc: Any, name: str, track: ObjectTrack, category: Any) -> Any:
    box = xosc.BoundingBox(track.width, track.length, HEIGHT, 0.0, 0.0, HEIGHT / 2)
    axle = round(0.3 * track.length, 6)
    front = xosc.Axle(0.5, 0.6, round(0.85 * track.width, 6), axle, 0.3)
    rear = xosc.Axle(0.0, 0.6, round(0.85 * track.width, 6), -axle, 0.3)
    return xosc.Vehicle(name, category, box, front, rear, 70.0, 10.0, 10.0)


def _position(xosc: Any, states: Track, i: int) -> Any:
    return xosc.WorldPosition(x=float(states.x[i]), y=float(states.y[i]),
                              h=float(states.heading[i]))


def _placed(states: Track, frame: MapFrame | None) -> Track:
    return states if frame is None else frame.to_map(states)


def _follow(xosc: Any, name: str, track: ObjectTrack, step: float, start: float, minor: int,
            frame: MapFrame | None) -> Any:
    times = trajectory_times(track, step)
    states = _placed(track.states(times), frame)
    polyline = xosc.Polyline([float(t) for t in times],
                             [_position(xosc, states, i) for i in range(len(times))])
    trajectory = xosc.Trajectory(f"{name}_trajectory", False)
    trajectory.add_shape(polyline)
    follow = xosc.FollowTrajectoryAction(trajectory, xosc.FollowingMode.position,
                                         xosc.ReferenceContext.absolute, 1.0, -start)
    priority = xosc.Priority.override if minor >= 2 else xosc.Priority.overwrite
    event = xosc.Event(f"{name}_follow", priority)
    event.add_action(f"{name}_follow_trajectory", follow)
    event.add_trigger(_at_time(xosc, 0.0, "start"))
    maneuver = xosc.Maneuver(f"{name}_maneuver")
    maneuver.add_event(event)
    group = xosc.ManeuverGroup(f"{name}_group")
    group.add_actor(name)
    group.add_maneuver(maneuver)
    return group


def _at_time(xosc: Any, seconds: float, point: str) -> Any:
    condition = xosc.SimulationTimeCondition(float(seconds), xosc.Rule.greaterThan)
    return xosc.ValueTrigger(f"simulation_time_{point}", 0.0, xosc.ConditionEdge.rising,
                             condition, triggeringpoint=point)


# -- validation -----------------------------------------------------------------------------------


def schema_directory() -> Path:
    """The directory of the OpenSCENARIO XSDs installed with scenariogeneration."""
    import scenariogeneration

    return Path(scenariogeneration.__file__).resolve().parent.parent / "schemas"


@functools.lru_cache(maxsize=4)
def _schema(minor: int) -> Any:
    import xmlschema

    stem = "OpenSCENARIO_1_3_1" if minor == 3 else f"OpenSCENARIO_1_{minor}"
    xsd = schema_directory() / f"{stem}.xsd"
    if not xsd.is_file():
        raise SimcredError(f"{xsd}: OpenSCENARIO 1.{minor} schema not found (is "
                           "scenariogeneration installed with its schemas?)")
    return xmlschema.XMLSchema(str(xsd))


def _date_of(description: ScenarioDescription) -> dt.datetime:
    """The header date the inputs give: ``metadata["date"]``, else :data:`NO_DATE`."""
    text = description.metadata.get("date")
    if text is None:
        return NO_DATE
    try:
        return dt.datetime.fromisoformat(str(text)).replace(microsecond=0, tzinfo=None)
    except ValueError:
        raise OptionError(f"description metadata 'date' is not an ISO 8601 date: {text!r}"
                          ) from None


def validate_openscenario(path: str | Path) -> None:
    """Validate an OpenSCENARIO 1.x file against the XSD of its header's ``revMinor``.

    Raises :class:`~simcred.errors.SimcredError` with one line naming the file and the first
    schema error (its reason and XPath), or what keeps the file from being read.
    """
    path = Path(path)
    tree = read_xml(path)
    header = tree.getroot().find("FileHeader")
    if header is None:
        raise SimcredError(f"{path}: no FileHeader: not an OpenSCENARIO file")
    major, minor = header.get("revMajor"), header.get("revMinor")
    if major != "1" or minor not in ("0", "1", "2", "3"):
        raise SimcredError(f"{path}: OpenSCENARIO version {major}.{minor} is not supported "
                           "(1.0 to 1.3)")
    error = next(_schema(int(minor)).iter_errors(tree), None)
    if error is not None:
        reason = error.reason or error.message
        raise SimcredError(f"{path}: not valid OpenSCENARIO 1.{minor}: {reason} "
                           f"(at {error.path})")
