"""A lanelet network as an ASAM OpenDRIVE 1.7 road network: one road per lanelet.

The OpenSCENARIO export's ``RoadNetwork/LogicFile`` (:mod:`simcred.scenario.openscenario`)
names the road its positions lie on. A CommonRoad scenario brings its lanelet network
(polylines: left bound, right bound, centre line); the converter of the CommonRoad Scenario
Designer [2] does not install beside this project's packages (it pins commonroad-io ≤ 2024.3 and
antlr4 4.9.3), so the conversion is this module's, kept to what a polyline network says:

* **one road per lanelet**, its reference line the lanelet's centre line: one ``line``
  geometry per centre-line segment ([1] sec. 7.4, straight line), so the road runs exactly
  through the lanelet's centre vertices;
* **one driving lane** (id −1, right of the reference line, driving along it: right-hand
  traffic) of the lanelet's width (|left − right| at each vertex, linear in between:
  ``width`` polynomials a + b·ds, [1] sec. 9.5.2), shifted left by half its width with a
  ``laneOffset`` ([1] sec. 9.3) so that it is centred on the centre line, as the lanelet is;
* a road ``link`` ([1] sec. 8) to a predecessor or successor only where the lanelets meet one
  to one (A's only successor is B and B's only predecessor is A), with the lane link −1 → −1.

Not modelled: splits and merges (OpenDRIVE needs a junction for them; such lanelets stay
unlinked), neighbouring lanelets as lanes of one road (each is its own road, side by side),
road marks, speed limits, traffic signs and lights, elevation. The header date follows the
OpenSCENARIO export's convention: never the wall clock, so reruns are byte-identical.

References
----------
[1] ASAM OpenDRIVE 1.7.0, https://publications.pages.asam.net/standards/ASAM_OpenDRIVE/.
[2] CommonRoad Scenario Designer (crdesigner), https://pypi.org/project/commonroad-scenario-designer/.
"""

from __future__ import annotations

import datetime as dt
import functools
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from simcred._xml import read_xml
from simcred.errors import OptionError, SimcredError

MIN_SEGMENT = 1e-6  # m: shorter centre-line segments are dropped (OpenDRIVE lengths are > 0)
DIGITS = 9  # decimals written (nm): the same numbers give the same text


def write_opendrive(lanelets: Mapping[int, Mapping[str, Any]], path: str | Path, *,
                    name: str = "simcred road network",
                    date: dt.datetime = dt.datetime(1970, 1, 1)) -> Path:
    """Write the lanelet network ``lanelets`` as OpenDRIVE 1.7 to ``path``; return it.

    Parameters
    ----------
    lanelets : mapping
        Per lanelet id: ``left`` and ``right`` bound ((n, 2) arrays, map coordinates, vertices
        paired and in driving direction, as CommonRoad keeps them), ``successors`` and
        ``predecessors`` (ids); see :func:`simcred.io.commonroad.lanelets`.
    path : str or Path
        The ``.xodr`` file.
    name : str
        The header's name.
    date : datetime, default: 1970-01-01T00:00:00
        The header's date (never the wall clock).

    Notes
    -----
    The module docstring lists what is converted and what is not.
    """
    roads = _write_opendrive_iv(lanelets)
    root = ET.Element("OpenDRIVE")
    corners = np.concatenate([np.concatenate([lane["left"], lane["right"]])
                              for lane in roads.values()])
    (west, south), (east, north) = corners.min(axis=0), corners.max(axis=0)
    ET.SubElement(root, "header", revMajor="1", revMinor="7", name=name, version="1",
                  date=date.replace(microsecond=0, tzinfo=None).isoformat(),
                  north=_num(north), south=_num(south), east=_num(east), west=_num(west),
                  vendor="simcred")
    for number in sorted(roads):
        root.append(_road(number, roads))
    ET.indent(root)
    path = Path(path)
    ET.ElementTree(root).write(path, encoding="utf-8", xml_declaration=True)
    return path


def _write_opendrive_iv(lanelets: Mapping[int, Mapping[str, Any]]) -> dict[int, dict[str, Any]]:
    roads = {}
    for number, lane in lanelets.items():
        left, right = (np.asarray(lane[k], dtype=np.float64) for k in ("left", "right"))
        if left.shape != right.shape or left.ndim != 2 or left.shape[1:] != (2,):
            raise OptionError(f"lanelet {number}: left and right bounds must be (n, 2) arrays "
                              f"of one shape, got {left.shape} and {right.shape}")
        if not (np.isfinite(left).all() and np.isfinite(right).all()):
            raise OptionError(f"lanelet {number}: bounds must be finite")
        centre = (left + right) / 2
        keep = np.concatenate([[True], np.hypot(*np.diff(centre, axis=0).T) > MIN_SEGMENT])
        if keep.sum() < 2:
            raise OptionError(f"lanelet {number}: its centre line has no length")
        roads[int(number)] = {"left": left, "right": right, "centre": centre[keep],
                              "width": np.hypot(*(left - right).T)[keep],
                              "successors": [int(i) for i in lane["successors"]],
                              "predecessors": [int(i) for i in lane["predecessors"]]}
    if not roads:
        raise OptionError("an OpenDRIVE road network needs at least one lanelet")
    return roads


def _road(number: int, roads: Mapping[int, Mapping[str, Any]]) -> ET.Element:
    lane = roads[number]
    centre, width = lane["centre"], lane["width"]
    step = np.diff(centre, axis=0)
    length = np.hypot(*step.T)
    s0 = np.concatenate([[0.0], np.cumsum(length)[:-1]])
    slope = np.diff(width) / length
    road = ET.Element("road", name=f"lanelet {number}", length=_num(length.sum()),
                      id=str(number), junction="-1", rule="RHT")
    links = {"predecessor": _one_to_one(number, "predecessors", "successors", roads),
             "successor": _one_to_one(number, "successors", "predecessors", roads)}
    if any(v is not None for v in links.values()):
        link = ET.SubElement(road, "link")
        for kind, other in links.items():
            if other is not None:
                ET.SubElement(link, kind, elementType="road", elementId=str(other),
                              contactPoint="end" if kind == "predecessor" else "start")
    plan = ET.SubElement(road, "planView")
    for k in range(len(length)):
        geometry = ET.SubElement(plan, "geometry", s=_num(s0[k]), x=_num(centre[k, 0]),
                                 y=_num(centre[k, 1]),
                                 hdg=_num(np.arctan2(step[k, 1], step[k, 0])),
                                 length=_num(length[k]))
        ET.SubElement(geometry, "line")
    lanes = ET.SubElement(road, "lanes")
    for k in range(len(length)):  # [1] 9.3: the centre lane sits half a width left
        ET.SubElement(lanes, "laneOffset", s=_num(s0[k]), a=_num(width[k] / 2),
                      b=_num(slope[k] / 2), c="0", d="0")
    section = ET.SubElement(lanes, "laneSection", s="0")
    # the centre lane has no width ([1] 9.5.1)
    ET.SubElement(ET.SubElement(section, "center"), "lane", id="0", type="none", level="false")
    driving = ET.SubElement(ET.SubElement(section, "right"), "lane", id="-1", type="driving",
                            level="false")
    if any(v is not None for v in links.values()):
        lane_link = ET.SubElement(driving, "link")
        for kind, other in links.items():
            if other is not None:
                ET.SubElement(lane_link, kind, id="-1")
    for k in range(len(length)):
        ET.SubElement(driving, "width", sOffset=_num(s0[k]), a=_num(width[k]),
                      b=_num(slope[k]), c="0", d="0")
    return road


def _one_to_one(number: int, forward: str, backward: str,
                roads: Mapping[int, Mapping[str, Any]]) -> int | None:
    """The one lanelet ``forward`` of ``number`` whose only ``backward`` link is ``number``."""
    options = [i for i in roads[number][forward] if i in roads]
    if len(options) != 1 or [i for i in roads[options[0]][backward] if i in roads] != [number]:
        return None
    return options[0]


def _num(value: float) -> str:
    return repr(round(float(value), DIGITS) + 0.0)  # + 0.0: no "-0.0"


# -- validation -----------------------------------------------------------------------------------


@functools.lru_cache(maxsize=1)
def _schema() -> Any:
    import xmlschema

    from simcred.scenario.openscenario import schema_directory

    xsd = schema_directory() / "opendrive_17_core.xsd"
    if not xsd.is_file():
        raise SimcredError(f"{xsd}: OpenDRIVE 1.7 schema not found (is scenariogeneration "
                           "installed with its schemas?)")
    return xmlschema.XMLSchema(str(xsd))


def validate_opendrive(path: str | Path) -> None:
    """Validate an OpenDRIVE file against the OpenDRIVE 1.7 XSD (shipped with
    scenariogeneration); one-line :class:`~simcred.errors.SimcredError` naming the file and the
    first schema error."""
    path = Path(path)
    tree = read_xml(path)
    error = next(_schema().iter_errors(tree), None)
    if error is not None:
        raise SimcredError(f"{path}: not valid OpenDRIVE 1.7: {error.reason or error.message} "
                           f"(at {error.path})")
