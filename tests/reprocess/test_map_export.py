"""OpenSCENARIO users can play (issue 24 point 5): a CommonRoad reprocessing's ``scenario.xosc``
in map coordinates, its RoadNetwork an OpenDRIVE file converted from the lanelet network, the
.xosc checked by the ASAM Quality Checker (asam-qc-openscenarioxml), reruns byte-identical."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from asam_qc import assert_accepted, quality_check
from simcred.reprocess.inputs import commonroad_drive
from simcred.reprocess.map_export import map_frame, write_scenario
from simcred.reprocess.pipeline import reprocess
from simcred.scenario.opendrive import validate_opendrive

US101 = Path(__file__).parents[1] / "data" / "commonroad-ngsim" / "USA_US101-3_3_T-1.xml"
TO, EGO = 394, 401  # obstacle 394 and its follower (tests/reprocess/test_inputs.py)
FIT = 0.02  # m: the fit's RMSE target (ReprocessConfig.threshold)


@pytest.fixture(scope="module", params=["ego", "lanelet"])
def exported(request, tmp_path_factory):
    """The reprocessing of obstacle 394 in the road frame ``param``, its .xosc/.xodr written."""
    drive = commonroad_drive(US101, TO, frame=request.param)
    result = reprocess(drive)
    out = tmp_path_factory.mktemp(f"xosc_{request.param}")
    return request.param, drive, result, write_scenario(result, out)


def _recorded(obstacle: int) -> dict[str, np.ndarray]:
    """The obstacle's states read literally from the CommonRoad XML (time step × 0.1 s)."""
    root = ET.parse(US101).getroot()
    node = root.find(f"obstacle[@id='{obstacle}']")
    states = [node.find("initialState"), *node.findall("trajectory/state")]
    rows = np.array([[float(s.find(path).text) for path in
                      ("time/exact", "position/point/x", "position/point/y", "orientation/exact")]
                     for s in states])
    return {"t": rows[:, 0] * 0.1, "x": rows[:, 1], "y": rows[:, 2],
            "heading": np.unwrap(rows[:, 3])}


def _vertices(root: ET.Element, entity: str) -> tuple[np.ndarray, np.ndarray]:
    event = root.find(f".//Event[@name='{entity}_follow']")
    vertices = event.findall(".//Polyline/Vertex")
    times = np.array([float(v.get("time")) for v in vertices])
    xyh = np.array([[float(v.find(".//WorldPosition").get(k)) for k in "xyh"]
                    for v in vertices])
    return times, xyh


def test_the_trajectory_lies_on_the_recorded_map_positions(exported):
    frame, drive, result, files = exported
    root = ET.parse(files["openscenario"]).getroot()
    times, xyh = _vertices(root, "to")
    recorded = _recorded(TO)
    x, y, h = (np.interp(times, recorded["t"], recorded[k]) for k in ("x", "y", "heading"))
    error = np.hypot(xyh[:, 0] - x, xyh[:, 1] - y)
    # the literal oracle: the obstacle's recorded map positions, up to the fit's own error
    assert len(times) == 32 and error.max() < 5 * FIT and np.sqrt(np.mean(error**2)) < 1.5 * FIT
    assert np.abs(np.angle(np.exp(1j * (xyh[:, 2] - h)))).max() < 0.02
    # and no error beyond the fit's: the same distances as in the processing frame
    description = result.descriptions["fit(SD)"].objects["to"].states(times)
    track = drive.sd.tracks["to"]
    processed = np.hypot(description.x - np.interp(times, track.t, track.x),
                         description.y - np.interp(times, track.t, track.y))
    np.testing.assert_allclose(error, processed, atol=1e-6 if frame == "ego" else 2e-3)


def test_the_init_places_both_vehicles_where_they_were_recorded(exported):
    _, drive, _, files = exported
    root = ET.parse(files["openscenario"]).getroot()
    t0 = drive.sd.tracks["ego"].t[0]
    for entity, obstacle in (("ego", EGO), ("to", TO)):
        position = root.find(f".//Init//Private[@entityRef='{entity}']//WorldPosition")
        recorded = _recorded(obstacle)
        k = int(np.argmin(np.abs(recorded["t"] - t0)))
        assert recorded["t"][k] == pytest.approx(t0, abs=1e-9)
        assert float(position.get("x")) == pytest.approx(recorded["x"][k], abs=3 * FIT)
        assert float(position.get("y")) == pytest.approx(recorded["y"][k], abs=3 * FIT)


def test_the_road_network_is_the_lanelet_network_as_opendrive(exported):
    frame, drive, _, files = exported
    root = ET.parse(files["openscenario"]).getroot()
    assert root.find("RoadNetwork/LogicFile").get("filepath") == "scenario.xodr"
    xodr = files["openscenario"].parent / "scenario.xodr"
    assert files["opendrive"] == xodr
    validate_opendrive(xodr)
    road = ET.parse(xodr).getroot()
    lanelets = ET.parse(US101).getroot().findall("lanelet")
    assert sorted(int(r.get("id")) for r in road.findall("road")) == sorted(
        int(la.get("id")) for la in lanelets)
    # the EGO starts on its recorded lanelet's road: near that road's reference line
    if frame == "lanelet":
        first = drive.metadata["frame"]["lanelets"][0]
        geometries = road.findall(f"road[@id='{first}']/planView/geometry")
        start = root.find(".//Init//Private[@entityRef='ego']//WorldPosition")
        p = np.array([float(start.get("x")), float(start.get("y"))])
        nearest = min(np.hypot(*(p - [float(g.get("x")), float(g.get("y"))]))
                      for g in geometries)
        assert nearest < 30.0  # m: a vertex of its own lanelet's centre line


def test_reruns_write_the_same_bytes(exported, tmp_path):
    frame, _, result, files = exported
    again = write_scenario(reprocess(commonroad_drive(US101, TO, frame=frame)), tmp_path)
    for role in ("openscenario", "opendrive"):
        assert again[role].read_bytes() == files[role].read_bytes(), role


def test_a_frame_the_metadata_does_not_name_stays_unplaced():
    assert map_frame({"frame": {"road": "the table's x axis (straight road along +x)"}}) is None
    assert map_frame({}) is None


# -- the ASAM Quality Checker (tests/asam_qc.py) ----------------------------------------------

#: Per shipped real CommonRoad scene, an obstacle that has a follower (the EGO): NGSIM's first.
SHIPPED = {"commonroad-ngsim/USA_Lanker-1_1_T-1": 1213, "commonroad-ngsim/USA_Peach-4_8_T-1": 507,
           "commonroad-ngsim/USA_US101-3_3_T-1": 363, "commonroad-ngsim/USA_US101-4_1_T-1": 373,
           "commonroad-crime-ngsim/USA_Lanker-1_3_T-1": 1456,
           "commonroad-crime-ngsim/USA_US101-5_1_T-1": 431,
           # MONA: a truck, the bus and a truck as the TO (tests/data/commonroad-mona)
           "commonroad-mona/C-DEU_MONAMerge-2_1_T-299": 10015,
           "commonroad-mona/C-DEU_MONAWest-2_480_T-559": 10257,
           "commonroad-mona/DEU_MONAEast-2_4316_T-4341": 11271}


def test_the_asam_quality_checker_finds_no_error(exported, tmp_path):
    _, _, _, files = exported
    assert_accepted(quality_check(files["openscenario"], tmp_path))


@pytest.mark.slow
@pytest.mark.parametrize("scene", sorted(SHIPPED))
def test_every_shipped_real_scene_exports_what_the_quality_checker_accepts(scene, tmp_path):
    """Issue 24 acceptance: the .xosc of every shipped real CommonRoad scene (lanelet frame,
    map coordinates, its .xodr beside it) passes the ASAM Quality Checker; the A9 recording's
    is checked by its CLI test (tests/reprocess/test_inputs_real.py)."""
    path = Path(__file__).parents[1] / "data" / f"{scene}.xml"
    result = reprocess(commonroad_drive(path, SHIPPED[scene], frame="lanelet"))
    files = write_scenario(result, tmp_path)
    assert files["opendrive"].is_file()
    assert_accepted(quality_check(files["openscenario"], tmp_path))


def test_the_asam_quality_checker_sees_a_broken_reference(exported, tmp_path):
    _, _, _, files = exported
    text = files["openscenario"].read_text()
    broken = tmp_path / "broken.xosc"
    assert text.count('<EntityRef entityRef="to"/>') == 1  # the TO's maneuver group's actor
    broken.write_text(text.replace('<EntityRef entityRef="to"/>',
                                   '<EntityRef entityRef="nobody"/>'))
    rows = quality_check(broken, tmp_path)
    assert ("check_asam_xosc_reference_control_resolvable_entity_references", "COMPLETED",
            "ERROR") in rows
