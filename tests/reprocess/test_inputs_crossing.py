"""Varying any lane change (issue 14 part 2): the crossing found from the EGO's lane, or given
by side, time or boundary, in the library and on the CLI; the A9 cut-in from the right."""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.optimize import brentq

from simcred import data
from simcred.cli import run
from simcred.errors import SimcredError
from simcred.kinematics import LANE_WIDTH
from simcred.reprocess.inputs import read_measurement
from simcred.reprocess.pipeline import ReprocessConfig, reprocess
from simcred.reprocess.vary import VaryConfig, run_campaign
from simcred.scenario.description import ScenarioDescription
from simcred.scenario.variation import (
    PlausibilityLimits,
    VariationOptions,
    ego_lane_boundaries,
    generate_variations,
)
from simcred.sim.experiments import cutin

OPTIONS = VariationOptions(sample_dt=0.1)


@pytest.fixture(scope="module")
def a9():
    """The A9 lane changer (object 1): a cut-in from the right, fitted from SD."""
    drive = read_measurement(data.path("a9/trajectories_file.csv"))
    return reprocess(drive, ReprocessConfig(threshold=0.1)).descriptions["fit(SD)"]


@pytest.fixture(scope="module")
def from_left():
    config = ReprocessConfig(scenario_based=False)
    return reprocess(cutin.simulate(0, cutin.CutInConfig(duration=8.0)), config
                     ).descriptions["fit(GT)"]


def _first_crossing(description, boundary: float) -> float:
    """Oracle: the root of y_TO(t) - boundary by Brent's method on the description."""
    track = description.objects["to"]
    t = np.linspace(track.t0, track.t1, 2001)
    s = track.positions(t)[1] - boundary
    i = int(np.flatnonzero(np.sign(s[:-1]) != np.sign(s[1:]))[0])
    return brentq(lambda u: float(track.positions(np.array([u]))[1][0]) - boundary,
                  t[i], t[i + 1], xtol=1e-12)


def test_the_ego_lane_boundaries_are_its_y_plus_minus_half_a_lane(a9):
    track = a9.objects["ego"]
    y0 = float(track.positions(np.array([track.t0]))[1][0])
    left, right = ego_lane_boundaries(a9, "ego", track.t0)
    assert (left, right) == pytest.approx((y0 + LANE_WIDTH / 2, y0 - LANE_WIDTH / 2))


def test_a_cut_in_from_the_right_is_found_on_the_right_boundary(a9):
    varied = generate_variations(a9, 2, 0, options=OPTIONS)
    right = ego_lane_boundaries(a9, "ego", a9.objects["to"].t0)[1]
    assert varied.boundary_y == pytest.approx(right)
    assert varied.crossing_time == pytest.approx(_first_crossing(a9, right), abs=0.01)
    assert varied.generated == 2


def test_a_cut_in_from_the_left_is_found_on_the_left_boundary(from_left):
    varied = generate_variations(from_left, 1, 0, options=OPTIONS)
    left = ego_lane_boundaries(from_left, "ego", from_left.objects["to"].t0)[0]
    assert varied.boundary_y == pytest.approx(left)
    assert varied.crossing_time == pytest.approx(_first_crossing(from_left, left), abs=0.01)
    assert varied.crossing_time == pytest.approx(3.5, abs=0.05)  # the configured cut-in


def test_the_side_restricts_the_search_and_a_wrong_side_says_what_to_pass(a9):
    right = generate_variations(a9, 1, 0, options=VariationOptions(sample_dt=0.1,
                                                                   crossing_side="right"))
    assert right.boundary_y == generate_variations(a9, 1, 0, options=OPTIONS).boundary_y
    with pytest.raises(SimcredError) as info:
        generate_variations(a9, 1, 0, options=VariationOptions(crossing_side="left"))
    assert "never crosses" in str(info.value) and "--crossing-side" in str(info.value)


def test_a_given_boundary_or_time_wins(a9):
    boundary = generate_variations(a9, 1, 0, options=VariationOptions(sample_dt=0.1,
                                                                      boundary_y=-1.0))
    assert boundary.boundary_y == -1.0
    assert boundary.crossing_time == pytest.approx(_first_crossing(a9, -1.0), abs=0.01)
    timed = generate_variations(a9, 1, 0, options=VariationOptions(sample_dt=0.1,
                                                                   crossing_time=2.0))
    assert timed.crossing_time == 2.0 and timed.boundary_y is None


@pytest.mark.parametrize("kwargs, message", [
    ({"crossing_side": "up"}, "crossing_side must be one of left, right"),
    ({"lane_width": 0.0}, "lane_width must be a finite number > 0"),
])
def test_bad_crossing_options(kwargs, message):
    with pytest.raises(SimcredError, match=message):
        VariationOptions(**kwargs)


def test_cli_varies_the_a9_cut_in_from_the_right(a9, tmp_path):
    path = a9.write(tmp_path / "fit_SD.json")
    out = tmp_path / "vary"
    assert run(["--quiet", "vary", str(path), "-n", "3", "--out", str(out)]) == 0
    document = json.loads((out / "variation_set.json").read_text())
    right = ego_lane_boundaries(a9, "ego", a9.objects["to"].t0)[1]
    assert document["boundary_y"] == pytest.approx(right)
    assert document["options"]["crossing_side"] is None
    timed = tmp_path / "timed"
    assert run(["--quiet", "vary", str(path), "-n", "6", "--crossing-time", "1.0",
                "--out", str(timed)]) == 0
    assert json.loads((timed / "variation_set.json").read_text())["crossing_time"] == 1.0


def test_a_campaign_without_any_kept_variation_is_a_one_line_error(from_left):
    limits = PlausibilityLimits(max_lateral_acceleration=1e-6)  # nothing passes
    with pytest.raises(SimcredError) as info:
        run_campaign(from_left, VaryConfig(n=2, limits=limits))
    message = str(info.value)
    assert "all 2 variations of object 'to' were rejected (lateral_acceleration: 2" in message
    assert "\n" not in message


@pytest.mark.parametrize("args, message", [
    (["--crossing-side", "up"], "'up' is not one of"),
    (["--crossing-side", "left"], "never crosses the lane boundary"),
    (["--lane-width", "-1"], "lane_width must be a finite number > 0"),
    (["--crossing-time", "99"], "crossing_time 99.0 is outside the span"),
])
def test_cli_vary_bad_crossing_options_are_one_line(a9, tmp_path, capsys, args, message):
    path = a9.write(tmp_path / "fit_SD.json")
    assert run(["vary", str(path), "-n", "1", "--out", str(tmp_path / "o"), *args]) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and len(err.splitlines()) == 1


def test_cli_varies_a_commonroad_cut_out_to_the_left(tmp_path):
    """US-101-3 obstacle 394 leaves its follower's lane to the left: found on the left boundary.
    (Fitted at 0.1 m: NGSIM positions at 10 Hz carry decimetre noise, a 2 cm fit follows it.)"""
    path = "tests/data/commonroad-ngsim/USA_US101-3_3_T-1.xml"
    rep, out = tmp_path / "rep", tmp_path / "vary"
    assert run(["--quiet", "reprocess", path, "--object", "394", "--threshold", "0.1",
                "--out", str(rep)]) == 0
    assert run(["--quiet", "vary", str(rep / "descriptions" / "fit_SD.json"), "-n", "4",
                "--out", str(out)]) == 0
    document = json.loads((out / "variation_set.json").read_text())
    description = ScenarioDescription.read(rep / "descriptions" / "fit_SD.json")
    left = ego_lane_boundaries(description, "ego", description.objects["to"].t0)[0]
    assert document["boundary_y"] == pytest.approx(left)
    assert document["crossing_time"] == pytest.approx(_first_crossing(description, left),
                                                      abs=0.01)
