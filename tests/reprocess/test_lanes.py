"""The map's lanes (issue 24 item 1): lane width and lane centres from the CommonRoad lanelet
network flow into the AD function, the risk's lanes and the reaction rules."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from simcred.kinematics import Track
from simcred.reprocess.inputs import LongColumns, commonroad_drive, long_drive
from simcred.reprocess.lanes import map_lanes
from simcred.reprocess.pipeline import ReprocessConfig, reprocess

US101 = Path(__file__).parents[1] / "data" / "commonroad-ngsim" / "USA_US101-3_3_T-1.xml"
RIGID = {"origin": [0.0, 0.0], "angle": 0.0}


def _lanelet(right: float, left: float, length: float = 100.0, widen: float = 0.0, *,
             to_left: int | None = None, to_right: int | None = None) -> dict:
    """A straight lanelet along +x between y = ``right`` and ``left`` (the left bound moving
    out by ``widen`` over its length), 11 vertex pairs."""
    x = np.linspace(0.0, length, 11)
    left_y = left + widen * x / length
    return {"left": np.column_stack([x, left_y]), "right": np.column_stack([x, np.full(11, right)]),
            "centre": np.column_stack([x, (left_y + right) / 2]), "successors": [],
            "predecessors": [], "left_neighbour": to_left, "right_neighbour": to_right}


def _ego(y: float, x=(10.0, 30.0, 50.0, 70.0, 90.0)) -> Track:
    x = np.asarray(x, dtype=float)
    return Track(np.arange(len(x)) * 0.1, x, np.full(len(x), y), np.full(len(x), 20.0),
                 np.zeros(len(x)))


def test_a_straight_lanelet_pair_gives_its_width_and_its_centres():
    """Three 3.0 m lanelets side by side (right, the EGO's, left): the width is the literal
    distance between the EGO lanelet's bound vertices, the centres lie at 0 and ±3.0 m."""
    network = {1: _lanelet(-1.5, 1.5, to_left=2, to_right=3),
               2: _lanelet(1.5, 4.5, to_right=1), 3: _lanelet(-4.5, -1.5, to_left=1)}
    literal = float(np.median(np.hypot(*(network[1]["left"] - network[1]["right"]).T)))
    assert literal == 3.0
    for frame in (RIGID, {"lanelets": [1]}):
        lanes = map_lanes(network, _ego(0.4), frame, "hand-made")
        assert lanes["lane_width"] == pytest.approx(literal, abs=1e-12)
        assert lanes["lane_centres"] == pytest.approx([0.0, 3.0], abs=1e-12)
        assert lanes["right_lane_centres"] == pytest.approx([-3.0], abs=1e-12)
        assert lanes["lanelets"] == [1, 2] and lanes["right_lanelets"] == [3]
        assert lanes["positions"] == [5, 5]
    # in a rigid frame whose origin is the EGO's first position the centres move with it
    shifted = map_lanes(network, _ego(0.4), {"origin": [10.0, 0.4], "angle": 0.0}, "hand-made")
    assert shifted["lane_centres"] == pytest.approx([-0.4, 2.6], abs=1e-12)


def test_the_width_is_the_median_over_the_egos_positions_and_off_map_ones_are_left_out():
    # a lanelet widening from 3.0 to 4.0 m over 100 m: at x = 10, 30, 50, 70, 90 it is
    # about 3.1, 3.3, 3.5, 3.7, 3.9 m wide; the EGO's positions beyond its end are not on it
    network = {1: _lanelet(-1.5, 1.5, widen=1.0)}
    lanes = map_lanes(network, _ego(0.0, (10.0, 30.0, 50.0, 70.0, 90.0, 150.0, 170.0)), RIGID,
                      "hand-made")
    # across a position: its distance from the right bound plus its perpendicular distance
    # from the slanted left bound (slope 0.01)
    across = [1.5 + (1.5 + x / 100) * np.cos(np.arctan(0.01)) for x in (50.0, 10.0, 90.0)]
    assert lanes["lane_width"] == pytest.approx(across[0], abs=1e-12)
    assert lanes["width_range"] == pytest.approx(across[1:], abs=1e-12)
    assert lanes["positions"] == [5, 7]
    # the centre line (slope 0.005) at the foot of x = 10: y = 0.05 (to 1e-5); no neighbour
    assert lanes["lane_centres"] == pytest.approx([0.05], abs=1e-5)
    # an EGO driving against the lanelet, or beside it, has no lanelet under it: no map lanes
    against = _ego(0.0)
    against = Track(against.t, against.x, against.y, against.v, np.full(5, np.pi))
    assert map_lanes(network, against, RIGID, "hand-made") is None
    assert map_lanes(network, _ego(5.0), RIGID, "hand-made") is None


def _bound_widths(lanelet: int) -> np.ndarray:
    """The lanelet's width at each vertex pair, read literally from the scenario's XML."""
    node = ET.parse(US101).getroot().find(f"lanelet[@id='{lanelet}']")
    bound = {side: np.array([[float(p.find(k).text) for k in "xy"]
                             for p in node.find(f"{side}Bound").findall("point")])
             for side in ("left", "right")}
    return np.hypot(*(bound["left"] - bound["right"]).T)


@pytest.fixture(scope="module", params=["ego", "lanelet"])
def us101(request):
    drive = commonroad_drive(US101, 394, frame=request.param)
    return drive, reprocess(drive, ReprocessConfig(from_recording=("set_speed", "lanes")))


def test_a_real_scene_uses_the_map_width_in_the_ad_function_the_risk_and_the_reactions(us101):
    """US-101 obstacle 394 and its follower: the lane under the EGO is 3.13-3.40 m wide
    (lanelet 35), not 3.5 m; that width is what the resimulation, risk and reactions use."""
    drive, result = us101
    lanes = drive.metadata["lanes"]
    widths = _bound_widths(lanes["lanelets"][0])
    assert widths.min() - 0.01 <= lanes["lane_width"] <= widths.max() + 0.01
    assert lanes["lane_width"] == pytest.approx(3.26, abs=0.01)
    ad = result.ad_function
    assert ad["from"]["lanes"] == "map"
    assert ad["lane_width"] == ad["risk_lanes"]["width"] == ad["reaction_lane_width"] \
        == lanes["lane_width"]
    assert ad["lane_centres"] == lanes["lane_centres"] and len(ad["lane_centres"]) == 3
    assert ad["risk_lanes"]["centre"] == lanes["lane_centres"][0]
    assert ad["map"]["lanelets"] == lanes["lanelets"]
    assert np.diff(ad["lane_centres"]) == pytest.approx([3.4, 3.4], abs=0.1)
    assert result.to_dict()["options"]["lanes"] == "map"


def test_configured_lanes_keep_todays_geometry():
    drive = commonroad_drive(US101, 394, frame="lanelet")
    result = reprocess(drive, ReprocessConfig(from_recording=("set_speed", "lanes"),
                                              lanes="configuration"))
    ad = result.ad_function
    assert ad["from"]["lanes"] == "recorded EGO" and "map" not in ad
    assert ad["lane_width"] == ad["risk_lanes"]["width"] == ad["reaction_lane_width"] == 3.5
    assert ad["risk_lanes"]["centre"] == 0.0


def test_a_long_table_has_no_map_and_keeps_its_configured_lanes(tmp_path):
    t = np.round(np.arange(0.0, 3.05, 0.1), 10)
    rows = ["t,object,x,y,v,heading"]
    rows += [f"{float(a)!r},ego,{float(20 * a)!r},0.0,20.0,0.0" for a in t]
    rows += [f"{float(a)!r},to,{float(30 + 18 * a)!r},0.0,18.0,0.0" for a in t]
    table = tmp_path / "straight.csv"
    table.write_text("\n".join(rows) + "\n")
    drive = long_drive(table, LongColumns(object_column="object"))
    assert "lanes" not in drive.metadata
    ad = reprocess(drive).ad_function
    assert ad["from"]["lanes"] == "configuration" and "map" not in ad
    assert ad["lane_width"] == ad["reaction_lane_width"] == 3.5


def test_an_unknown_lane_source_is_refused():
    from simcred.errors import OptionError

    with pytest.raises(OptionError, match="lanes: one of map, configuration"):
        ReprocessConfig(lanes="osm")


def test_cli_lanes_configuration_keeps_the_configured_lanes(tmp_path):
    import json

    from simcred.cli import run

    out = tmp_path / "configured"
    assert run(["reprocess", str(US101), "--object", "394", "--lanes", "configuration",
                "--no-scenario-based", "--out", str(out), "--json"]) == 0
    document = json.loads((out / "reprocess.json").read_text())
    ad = document["ad_function"]
    assert ad["from"]["lanes"] == "recorded EGO" and "map" not in ad
    assert ad["lane_width"] == ad["reaction_lane_width"] == 3.5
    assert document["options"]["lanes"] == "configuration"
    assert document["input"]["drive"]["lanes"]["lane_width"] == pytest.approx(3.26, abs=0.01)
