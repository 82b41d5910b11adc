"""Processing frames back to the map (scenario.map_frame, frenet.path_points) and the lanelet
network as OpenDRIVE (scenario.opendrive): issue 24 point 5."""

from __future__ import annotations

import datetime as dt
import math
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from simcred.errors import OptionError, SimcredError
from simcred.kinematics import Track
from simcred.reprocess.inputs import road_frame
from simcred.reprocess.map_export import map_frame
from simcred.reprocess.road import to_frenet
from simcred.scenario.frenet import path_coordinates, path_points
from simcred.scenario.map_frame import PathFrame, RigidFrame
from simcred.scenario.opendrive import validate_opendrive, write_opendrive

R = 200.0  # m, radius of the test arc


def _arc(step: float = 1.0) -> np.ndarray:
    s = np.arange(0.0, 150.0 + step / 2, step)
    return np.column_stack([R * np.sin(s / R), R - R * np.cos(s / R)])


def _track(x, y, heading) -> Track:
    t = np.arange(len(x)) * 0.1
    return Track(t, np.asarray(x, float), np.asarray(y, float), np.full(len(x), 10.0),
                 np.asarray(heading, float))


def test_path_points_invert_path_coordinates_inside_segments():
    line = _arc()
    s = np.array([0.3, 10.5, 74.25, 149.5, -2.0, 152.0])  # before the start, beyond the end
    d = np.array([1.5, -3.5, 0.0, 2.0, -1.0, 0.5])
    x, y, tangent = path_points(line[:, 0], line[:, 1], s, d)
    s2, d2, tangent2 = path_coordinates(line[:, 0], line[:, 1], x, y)
    np.testing.assert_allclose(s2, s, atol=1e-9)
    np.testing.assert_allclose(d2, d, atol=1e-9)
    np.testing.assert_allclose(tangent2, tangent, atol=1e-12)
    # closed form on the arc: the point at s, d to the left, lies at radius R − d
    inside = (s >= 0) & (s <= 150)
    np.testing.assert_allclose(np.hypot(x, y - R)[inside], (R - d)[inside], atol=1.0 / (8 * R))


def test_a_rigid_frame_inverts_the_rigid_road_frame_exactly():
    ego = _track([5.0, 7.0, 9.5, 12.0], [-3.0, -4.5, -6.0, -7.75], [-0.6, -0.62, -0.6, -0.61])
    to = _track([15.0, 17.0, 19.0, 21.0], [-10.0, -11.0, -12.5, -13.0], [-0.5] * 4)
    moved, frame = road_frame({"ego": ego, "to": to})
    placed = RigidFrame(tuple(frame["origin"]), frame["angle"])
    for name, original in (("ego", ego), ("to", to)):
        back = placed.to_map(moved[name])
        for q in ("x", "y", "heading", "v", "t"):
            np.testing.assert_allclose(getattr(back, q), getattr(original, q), atol=1e-12)


def test_a_path_frame_inverts_the_frenet_frame():
    line = _arc(0.5)
    phi = np.linspace(0.05, 0.5, 20)
    offset = 3.5  # m left of the line: radius R − 3.5
    track = _track((R - offset) * np.sin(phi), R - (R - offset) * np.cos(phi), phi + 0.01)
    back = PathFrame(line).to_map(to_frenet({"to": track}, line)["to"])
    np.testing.assert_allclose(back.x, track.x, atol=1e-9)
    np.testing.assert_allclose(back.y, track.y, atol=1e-9)
    np.testing.assert_allclose(back.heading, track.heading, atol=1e-9)


def test_frames_refuse_what_is_not_a_frame():
    with pytest.raises(OptionError, match="rigid frame needs a finite origin"):
        RigidFrame((0.0, math.nan), 0.0)
    with pytest.raises(OptionError, match=r"path frame needs an \(n, 2\) line"):
        PathFrame(np.zeros((1, 2)))


def test_map_frame_reads_the_drive_metadata(tmp_path):
    rigid = map_frame({"frame": {"origin": [1.0, 2.0], "angle": 0.5, "direction": "EGO chord"}})
    assert rigid == RigidFrame((1.0, 2.0), 0.5)
    table = tmp_path / "centre.csv"
    table.write_text("x,y\n0,0\n10,0\n20,5\n")
    placed = map_frame({"format": "long", "frame": {"road": "Frenet", "path": str(table)}})
    np.testing.assert_array_equal(placed.line, [[0, 0], [10, 0], [20, 5]])


# -- OpenDRIVE -------------------------------------------------------------------------------

def _lanelet(centre: np.ndarray, width: float, successors=(), predecessors=()) -> dict:
    step = np.diff(centre, axis=0)
    normal = np.vstack([step, step[-1:]])[:, ::-1] * [-1, 1]
    normal /= np.hypot(*normal.T)[:, None]
    return {"left": centre + normal * width / 2, "right": centre - normal * width / 2,
            "successors": list(successors), "predecessors": list(predecessors)}


def _network() -> dict[int, dict]:
    """1 → 2 one to one; 2 splits into 3 and 4 (a junction in OpenDRIVE: left unlinked)."""
    a = np.array([[0.0, 0.0], [50.0, 0.0]])
    b = np.array([[50.0, 0.0], [80.0, 0.0], [100.0, 2.0]])
    return {1: _lanelet(a, 3.5, [2]), 2: _lanelet(b, 3.0, [3, 4], [1]),
            3: _lanelet(np.array([[100.0, 2.0], [150.0, 7.0]]), 3.0, [], [2]),
            4: _lanelet(np.array([[100.0, 2.0], [150.0, -3.0]]), 3.0, [], [2])}


def test_opendrive_roads_follow_the_centre_lines_with_the_lanelet_widths(tmp_path):
    path = write_opendrive(_network(), tmp_path / "n.xodr", date=dt.datetime(2019, 7, 17))
    validate_opendrive(path)
    root = ET.parse(path).getroot()
    assert root.find("header").get("date") == "2019-07-17T00:00:00"
    road = root.find("road[@id='2']")
    geometries = road.findall("planView/geometry")
    assert [float(g.get("x")) for g in geometries] == [50.0, 80.0]
    assert float(geometries[1].get("hdg")) == pytest.approx(math.atan2(2.0, 20.0))
    assert float(road.get("length")) == pytest.approx(30.0 + math.hypot(20.0, 2.0))
    lane = road.find("lanes/laneSection/right/lane")
    assert lane.get("id") == "-1" and lane.get("type") == "driving"
    widths = [float(w.get("a")) for w in lane.findall("width")]
    offsets = [float(o.get("a")) for o in road.findall("lanes/laneOffset")]
    assert widths == pytest.approx([3.0, 3.0], abs=0.01)
    assert offsets == pytest.approx([1.5, 1.5], abs=0.01)  # centred on the reference line
    # one-to-one links only: 1 → 2; 2's split into 3 and 4 needs a junction
    assert road.find("link/predecessor").get("elementId") == "1"
    assert road.find("link/successor") is None
    assert root.find("road[@id='1']/link/successor").get("elementId") == "2"
    assert root.find("road[@id='3']/link") is None


def test_opendrive_is_byte_identical_on_rerun_and_refuses_bad_lanelets(tmp_path):
    first = write_opendrive(_network(), tmp_path / "a.xodr").read_bytes()
    assert write_opendrive(_network(), tmp_path / "b.xodr").read_bytes() == first
    bad = {7: {**_lanelet(np.array([[0.0, 0.0], [1.0, 0.0]]), 3.0),
               "right": np.zeros((3, 2))}}
    with pytest.raises(OptionError, match="lanelet 7: left and right bounds"):
        write_opendrive(bad, tmp_path / "c.xodr")
    with pytest.raises(OptionError, match="at least one lanelet"):
        write_opendrive({}, tmp_path / "d.xodr")


def test_an_invalid_opendrive_file_is_a_one_line_error(tmp_path):
    path = write_opendrive(_network(), tmp_path / "a.xodr")
    broken = tmp_path / "broken.xodr"
    broken.write_text(path.read_text().replace('junction="-1"', "", 1))
    with pytest.raises(SimcredError, match="broken.xodr: not valid OpenDRIVE 1.7"):
        validate_opendrive(broken)
