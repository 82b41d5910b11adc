"""Road frames (issue 24 item 1): a Frenet frame along a reference path (long format) or the
CommonRoad lanelet centre line through the EGO's start."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from simcred.cli import run
from simcred.reprocess.inputs import LongColumns, commonroad_drive, long_drive

US101 = Path(__file__).parents[1] / "data" / "commonroad-ngsim" / "USA_US101-3_3_T-1.xml"
R = 300.0  # m, radius of the curved road (centre of the EGO's lane)
T = np.round(np.arange(0.0, 6.0 + 0.05, 0.1), 10)


def _curved(tmp_path: Path) -> tuple[Path, Path]:
    """A left curve of radius R: the EGO on its lane centre at 20 m/s, the TO 30 m ahead on the
    lane to its left (radius R − 3.5) at 18 m/s along the curve; and the centre line file."""
    def on_arc(s, offset):
        phi = s / R
        return (R - offset) * np.sin(phi), R - (R - offset) * np.cos(phi), phi

    lines = ["t,object,x,y,v,heading"]
    for name, s, offset, v in (("ego", 20 * T, 0.0, 20.0), ("to", 30 + 18 * T, 3.5, 18.0)):
        x, y, phi = on_arc(s, offset)
        speed = v * (R - offset) / R
        lines += [f"{float(t)!r},{name},{float(a)!r},{float(b)!r},{speed!r},{float(h)!r}"
                  for t, a, b, h in zip(T, x, y, phi, strict=True)]
    table = tmp_path / "curve.csv"
    table.write_text("\n".join(lines) + "\n")
    s = np.arange(0.0, 400.0, 0.5)
    x, y, _ = on_arc(s, 0.0)
    centre = tmp_path / "centre.csv"
    centre.write_text("x,y\n" + "\n".join(f"{float(a)!r},{float(b)!r}"
                                           for a, b in zip(x, y, strict=True)))
    return table, centre


def test_a_curved_road_in_the_frenet_frame_of_its_centre_line(tmp_path):
    table, centre = _curved(tmp_path)
    drive = long_drive(table, LongColumns(object_column="object", reference=str(centre)))
    ego, to = drive.sd.tracks["ego"], drive.sd.tracks["to"]
    # closed form: arc length along the centre line, offset left, heading along the tangent;
    # up to the polyline's 0.5 m segments: an offset d projects up to d·0.5/(2R) = 2.9 mm off
    np.testing.assert_allclose(ego.x, 20 * T, atol=1e-3)
    np.testing.assert_allclose(ego.y, 0.0, atol=1e-3)
    np.testing.assert_allclose(to.x, 30 + 18 * T, atol=3.5 * 0.5 / (2 * R) + 1e-4)
    np.testing.assert_allclose(to.y, 3.5, atol=2e-3)
    np.testing.assert_allclose([ego.heading, to.heading], 0.0, atol=2e-3)
    assert "reference path" in drive.metadata["frame"]["road"]


def test_a_curved_road_in_world_coordinates_is_refused_without_a_frame(tmp_path, capsys):
    table, _ = _curved(tmp_path)
    assert run(["reprocess", str(table), "--object-column", "object",
                "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err.strip()
    assert "not along +x" in err and len(err.splitlines()) == 1


@pytest.mark.parametrize("args, message", [
    (["--road-frame", "lanelet"], "--road-frame lanelet is for a CommonRoad scenario"),
    (["--road-frame", "ego", "--reference-path", "centre.csv"],
     "--reference-path gives the road frame"),
])
def test_frame_options_that_do_not_fit_the_input_are_one_line(tmp_path, capsys, args, message):
    table, centre = _curved(tmp_path)
    args = [str(centre) if a == "centre.csv" else a for a in args]
    assert run(["reprocess", str(table), "--object-column", "object",
                "--out", str(tmp_path / "o"), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1


def test_on_a_straight_road_the_lanelet_frame_is_the_rigid_frame_shifted():
    lanelet = commonroad_drive(US101, 394, frame="lanelet")
    rigid = commonroad_drive(US101, 394)
    assert lanelet.metadata["frame"]["lanelets"]
    for name in ("ego", "to"):
        a, b = lanelet.sd.tracks[name], rigid.sd.tracks[name]
        # the EGO's chord (rigid x axis) and the lane differ by a small rotation: the offset
        # between the frames is linear in x, with a slope of at most a degree, up to the
        # lane's own gentle curve (6 cm over these 40 m of US-101)
        slope, shift = np.polyfit(b.x, a.y - b.y, 1)
        assert abs(slope) < math.radians(1)
        assert np.abs(a.y - b.y - (shift + slope * b.x)).max() < 0.1
        assert np.ptp(a.x - b.x) < 0.1
        assert np.abs(a.heading - b.heading - slope).max() < 0.02
    # the EGO starts within half a lane of its lanelet's centre line
    assert abs(lanelet.sd.tracks["ego"].y[0]) < 1.75
    assert math.isfinite(float(lanelet.sd.tracks["to"].y[0]))


@pytest.mark.parametrize("args, message", [
    (["--road-frame", "given"], "--road-frame given is for long-format tables"),
    (["--reference-path", "centre.csv"], "--reference-path is for long-format tables"),
])
def test_commonroad_frame_options_that_do_not_fit_are_one_line(tmp_path, capsys, args,
                                                               message):
    _, centre = _curved(tmp_path)
    args = [str(centre) if a == "centre.csv" else a for a in args]
    assert run(["reprocess", str(US101), "--object", "394", "--out", str(tmp_path / "o"),
                *args]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1


def test_cli_reprocesses_a_commonroad_obstacle_in_the_lanelet_frame(tmp_path):
    import json

    out = tmp_path / "lanelet"
    assert run(["reprocess", str(US101), "--object", "394", "--road-frame", "lanelet",
                "--no-scenario-based", "--out", str(out), "--json"]) == 0
    document = json.loads((out / "reprocess.json").read_text())
    frame = document["input"]["drive"]["frame"]
    assert frame["road"].startswith("Frenet frame along the lanelet centre line")
    # the map's lanes by default (tests/reprocess/test_lanes.py)
    assert document["ad_function"]["from"]["lanes"] == "map"
    assert document["ad_function"]["lane_width"] == document["input"]["drive"]["lanes"][
        "lane_width"] == document["ad_function"]["reaction_lane_width"]
    assert document["options"]["lanes"] == "map"
    assert frame["lanelets"] == commonroad_drive(US101, 394, frame="lanelet"
                                                 ).metadata["frame"]["lanelets"]
