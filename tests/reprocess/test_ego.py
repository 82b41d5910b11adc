"""The recording's EGO (issue 24 item 3): the resimulated AD function takes its set speed and
lanes from the recorded EGO (stated), and reactions at the first samples are not measurable."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from simcred.kinematics import Track
from simcred.reprocess.pipeline import ReprocessConfig, reprocess
from simcred.reprocess.reaction import ReactionCriteria, reaction, reaction_analysis
from simcred.reprocess.timebase import Drive, RecordedTracks

STEP = 0.1
T = np.round(np.arange(0.0, 8.0 + STEP / 2, STEP), 10)
Y_EGO = 117.0  # the EGO's lane, far from y = 0 (world coordinates along +x)


@pytest.fixture(scope="module")
def drive() -> Drive:
    """EGO at 12 m/s (a city street, not the 100 km/h highway) in the lane at y = 117 m; the TO
    40 m ahead in the left lane at 13 m/s: nothing for the EGO to react to."""
    ego = Track(T, 12.0 * T, np.full_like(T, Y_EGO), np.full_like(T, 12.0), np.zeros_like(T))
    to = Track(T, 40 + 13.0 * T, np.full_like(T, Y_EGO + 3.5), np.full_like(T, 13.0),
               np.zeros_like(T))
    return Drive(RecordedTracks("street", {"ego": ego, "to": to}, "sha256:test"))


@pytest.fixture(scope="module")
def results(drive):
    config = ReprocessConfig(scenario_based=False)
    return {"recording": reprocess(drive, ReprocessConfig(
                scenario_based=False, from_recording=("set_speed", "lanes", "time_gap"))),
            "default": reprocess(drive, config)}


def test_the_ad_function_takes_set_speed_and_lanes_from_the_recorded_ego(results):
    result = results["recording"]
    description = result.descriptions["fit(SD)"].objects["ego"]
    times = result.descriptions["fit(SD)"].times(result.config.dt)
    y0 = float(description.states(np.array([description.t0])).y[0])
    ad = result.ad_function
    assert ad["set_speed"] == pytest.approx(float(description.speed(times).max()), rel=1e-12)
    assert ad["set_speed"] == pytest.approx(12.0, abs=0.05)
    assert ad["lane_centres"] == pytest.approx([y0, y0 + 3.5], rel=1e-12)
    assert ad["from"] == {"set_speed": "recorded EGO", "lanes": "recorded EGO",
                          "time_gap": "configuration (the recorded EGO never follows the object)"}
    assert ad["time_gap"] == 1.5  # the TO drives in the other lane
    assert result.to_dict()["ad_function"] == ad


def test_the_resimulated_ego_stays_with_the_recorded_one_that_did_not_react(results):
    recorded = results["recording"].states["SD"]["ego"]
    resimulated = results["recording"].states["rSD"]["ego"]
    distance = np.hypot(resimulated.x - recorded.x, resimulated.y - recorded.y)
    assert distance.max() < 0.5
    # the 100 km/h highway ACC heading for a lane at y = 0 does not (why the default is not used)
    default = results["default"].states["rSD"]["ego"]
    assert np.hypot(default.x - recorded.x, default.y - recorded.y).max() > 20.0
    assert results["default"].ad_function["from"]["set_speed"] == "configuration"


HEADWAY = 25.0  # m between the centres: bumper gap 20.5 m behind a 4.5 m car


@pytest.fixture(scope="module")
def following() -> Drive:
    """EGO at 15 m/s 25 m (centres) behind the TO in its lane, both steady."""
    ego = Track(T, 15.0 * T, np.full_like(T, Y_EGO), np.full_like(T, 15.0), np.zeros_like(T))
    to = Track(T, HEADWAY + 15.0 * T, np.full_like(T, Y_EGO), np.full_like(T, 15.0),
               np.zeros_like(T))
    return Drive(RecordedTracks("following", {"ego": ego, "to": to}, "sha256:test"))


def test_the_acc_time_gap_is_the_recorded_egos_equilibrium_gap(following):
    """Literal: the ACC's equilibrium gap s0 + T v equals the recorded bumper gap, so
    T = (25 − 4.5 − 5) / 15 s; the resimulated EGO keeps the recorded gap, whereas the
    configured 1.5 s drops it back towards 27.5 m."""
    from simcred.reprocess.ad_function import recorded_time_gap

    by_recording = reprocess(following, ReprocessConfig(
        scenario_based=False, from_recording=("set_speed", "lanes", "time_gap")))
    configured = reprocess(following, ReprocessConfig(
        scenario_based=False, from_recording=("set_speed", "lanes")))
    ad, c = by_recording.ad_function, by_recording.config
    expected = (HEADWAY - c.driver.vehicle_length - c.driver.standstill_gap) / 15.0
    assert ad["time_gap"] == pytest.approx(expected, abs=2e-3)  # the fit's error only
    assert ad["time_gap"] == recorded_time_gap(by_recording.descriptions["fit(SD)"], "ego",
                                               "to", c.driver, c.dt)
    assert ad["from"]["time_gap"] == "recorded EGO" and configured.ad_function["time_gap"] == 1.5

    def distance(result):
        recorded, resimulated = result.states["SD"]["ego"], result.states["rSD"]["ego"]
        return np.hypot(resimulated.x - recorded.x, resimulated.y - recorded.y).max()

    assert distance(by_recording) < 0.3 < 2.0 < distance(configured)


def test_no_following_sample_keeps_the_configured_time_gap():
    """A lead that is never ahead within half a lane of the EGO at ≥ 5 m/s gives None."""
    from simcred.reprocess.ad_function import recorded_time_gap
    from simcred.sim.driver import DriverConfig

    slow = Track(T, 2.0 * T, np.full_like(T, Y_EGO), np.full_like(T, 2.0), np.zeros_like(T))
    to = Track(T, 10 + 2.0 * T, np.full_like(T, Y_EGO), np.full_like(T, 2.0), np.zeros_like(T))
    result = reprocess(Drive(RecordedTracks("slow", {"ego": slow, "to": to}, "sha256:t")),
                       ReprocessConfig(scenario_based=False, from_recording=("time_gap",)))
    assert recorded_time_gap(result.descriptions["fit(SD)"], "ego", "to", DriverConfig(),
                             0.01) is None
    assert result.ad_function["time_gap"] == DriverConfig().time_gap


def test_unknown_recorded_parameters_are_refused():
    with pytest.raises(ValueError, match="unknown parameter.*speed_limit"):
        ReprocessConfig(from_recording=("speed_limit",))


DT = 0.01
TT = np.arange(0, 8.0 + DT / 2, DT)


@pytest.mark.parametrize("start, measurable", [(0.0, False), (0.49, False), (0.5, True),
                                               (3.0, True)])
def test_a_reaction_near_the_first_sample_is_not_measurable(start, measurable):
    accel = np.where(start <= TT, -5.0, 0.0)
    speed = 25.0 + np.cumsum(accel) * DT
    r = reaction(TT, np.zeros_like(TT), speed, np.zeros_like(TT), accel, ReactionCriteria())
    assert r.time == pytest.approx(TT[np.argmax(start <= TT)])
    assert r.measurable is measurable
    assert r.onset_measurable is bool(r.onset - TT[0] >= 0.5)


def test_eqs_4_to_7_leave_out_a_reaction_that_is_not_measurable():
    ok = reaction(TT, np.zeros_like(TT), np.full_like(TT, 20.0), np.zeros_like(TT),
                  np.where(TT >= 3.0, -5.0, 0.0))
    early = reaction(TT, np.zeros_like(TT), np.full_like(TT, 20.0), np.zeros_like(TT),
                     np.where(TT >= 0.2, -5.0, 0.0))
    both = reaction_analysis({"GT": ok, "rGT": ok, "rSD": ok}, 1.0, 20.0)
    assert both.dt_react_gt_rgt == 0.0 and both.dt_react_rgt_rsd == 0.0
    out = reaction_analysis({"GT": ok, "rGT": early, "rSD": ok}, 1.0, 20.0)
    assert out.dt_react_gt_rgt is None and out.dt_react_rgt_rsd is None
    assert out.ratio_eq6 is None and out.t_offset == pytest.approx(0.05)
    assert math.isnan(early.time) is False and early.measurable is False


def test_the_cli_states_the_ad_function(tmp_path, capsys):
    from simcred.cli import run

    lines = ["t,object,x,y,v,heading"]
    for t in map(float, T):
        lines += [f"{t!r},ego,{12 * t!r},0.0,12.0,0.0",
                  f"{t!r},to,{40 + 13 * t!r},3.5,13.0,0.0"]
    path = Path(tmp_path / "street.csv")
    path.write_text("\n".join(lines) + "\n")
    out = tmp_path / "out"
    assert run(["reprocess", str(path), "--object-column", "object", "--out", str(out),
                "--no-scenario-based", "--set-speed", "14"]) == 0
    printed = capsys.readouterr().out
    assert "AD function: set speed 14.00 m/s (configuration), lanes at y = " in printed
    assert "(recorded EGO)" in printed
