"""The OpenSCENARIO export of a reprocessing in map coordinates, beside its OpenDRIVE road.

``simcred reprocess --out DIR`` writes ``scenario.xosc``: the measurement's description (GT's
fit, else SD's) for an OpenSCENARIO player. The description lives in the road frame the drive
was reprocessed in (:mod:`simcred.reprocess.road`); the export takes it back to where the drive
was recorded (:mod:`simcred.scenario.map_frame`), as the drive's metadata says:

* the rigid EGO frame (CommonRoad ``--road-frame ego``, a long table's ``--road-frame ego``):
  origin and angle, inverted exactly;
* a Frenet frame: the CommonRoad lanelet chain's centre line (``--road-frame lanelet``, rebuilt
  from the scenario file and the chain's ids) or the reference path file (``--reference-path``),
  back through the line (:func:`simcred.scenario.frenet.path_points`);
* anything else (a long table already along +x, an A9 recording straightened onto the EGO's
  own path, which is not kept) stays in the processing frame (``reprocess.json`` names it
  under ``input.drive.frame``), with no road file.

A CommonRoad scenario's lanelet network is written beside it as ``scenario.xodr``
(:func:`simcred.scenario.opendrive.write_opendrive`) and named in the RoadNetwork's
``LogicFile``; both files are validated against their XSDs.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from simcred.errors import SimcredError
from simcred.io import commonroad
from simcred.reprocess.pipeline import Reprocessed
from simcred.reprocess.representation import GT, SD
from simcred.reprocess.road import chain_line, reference_line_file
from simcred.scenario.map_frame import MapFrame, PathFrame, RigidFrame
from simcred.scenario.opendrive import validate_opendrive, write_opendrive
from simcred.scenario.openscenario import to_openscenario, validate_openscenario

XOSC = "scenario.xosc"
XODR = "scenario.xodr"


def write_scenario(result: Reprocessed, directory: str | Path) -> dict[str, Path]:
    """Write ``scenario.xosc`` (and, for a CommonRoad drive, ``scenario.xodr``) to
    ``directory``; return them by role (``openscenario``, ``opendrive``)."""
    out = Path(directory)
    metadata = result.drive_metadata
    source = GT.fit() if GT.fit() in result.descriptions else SD.fit()
    frame = map_frame(metadata)
    files = {}
    road = None
    if metadata.get("format") == "commonroad" and frame is not None:
        files["opendrive"] = write_opendrive(_lanelets(metadata), out / XODR,
                                             name=f"CommonRoad {metadata.get('scenario_id')}")
        validate_opendrive(files["opendrive"])
        road = XODR
    files["openscenario"] = to_openscenario(result.descriptions[source], out / XOSC,
                                            ego=result.config.ego, frame=frame, road_file=road)
    validate_openscenario(files["openscenario"])
    return files


def map_frame(metadata: Mapping[str, Any]) -> MapFrame | None:
    """Where the drive's processing frame lies in its map (module docstring); None if the
    metadata does not say (positions then stay in the processing frame)."""
    frame = metadata.get("frame")
    if not isinstance(frame, Mapping):
        return None
    if "origin" in frame and "angle" in frame:
        x, y = frame["origin"]
        return RigidFrame((float(x), float(y)), float(frame["angle"]))
    if "lanelets" in frame and metadata.get("format") == "commonroad":
        where = str(metadata["source"])
        return PathFrame(chain_line(_lanelets(metadata), [int(i) for i in frame["lanelets"]],
                                    where))
    if "path" in frame:
        return PathFrame(reference_line_file(frame["path"]))
    return None


def _lanelets(metadata: Mapping[str, Any]) -> dict[int, dict]:
    path = Path(str(metadata["source"]))
    if not path.is_file():
        raise SimcredError(f"{path}: the CommonRoad scenario is gone: its lanelet network is "
                           "needed for the OpenSCENARIO road")
    return commonroad.lanelets(path)
