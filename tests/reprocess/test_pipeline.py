"""Reprocessing: error statistics, reactions, the path frame, and the pipeline end to end.

Oracles: numpy's own statistics, closed forms of synthetic manoeuvres (the first threshold
crossing of a quintic lane change found by root finding), the geometry of a circular arc, and,
end to end, what the manufactured universe was built with (1.4 m offset, the real EGO brakes,
an ideal one evades).
"""

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.optimize import brentq

from simcred.io.measurement import Measurement
from simcred.kinematics import Track
from simcred.reprocess.decomposition import STEPS, ErrorStats, decompose, state_errors, wrap
from simcred.reprocess.pipeline import RiskSeries, reprocess
from simcred.reprocess.reaction import (
    Reaction,
    ReactionCriteria,
    ReactionTiming,
    reaction,
    reaction_analysis,
)
from simcred.scenario.frenet import path_coordinates
from simcred.sim.experiments.cutin import CutInConfig, simulate

SEEDED = settings(derandomize=True, database=None, deadline=None, max_examples=50)
CONFIG = CutInConfig()


# -- error statistics -----------------------------------------------------------------------------


@SEEDED
@given(arrays(np.float64, st.integers(1, 60), elements=st.floats(-1e6, 1e6)))
def test_error_stats_are_numpys_statistics(values):
    stats = ErrorStats.of(values)
    q25, median, q75 = np.percentile(values, [25, 50, 75])
    expected = (q25, median, q75, np.min(values), np.max(values), np.mean(values),
                np.std(values), values.size)
    assert (stats.q25, stats.median, stats.q75, stats.low, stats.high, stats.mean, stats.std,
            stats.n) == pytest.approx(expected, rel=1e-12, abs=1e-9)
    assert stats.low <= stats.q25 <= stats.median <= stats.q75 <= stats.high
    assert stats.to_dict()["n"] == values.size


@pytest.mark.parametrize("eps", [1e-6, 0.01, 0.3])
def test_heading_errors_wrap_across_pi(eps):
    out = Track.from_states([0.0], [[0.0, 0.0, 10.0, math.pi - eps]])
    ref = Track.from_states([0.0], [[3.0, 4.0, 12.5, -math.pi + eps]])
    errors = state_errors(out, ref)
    assert errors["heading"][0] == pytest.approx(-2 * eps, abs=1e-12)
    assert state_errors(ref, out)["heading"][0] == pytest.approx(2 * eps, abs=1e-12)
    assert errors["d"][0] == pytest.approx(5.0) and errors["v"][0] == pytest.approx(-2.5)


@SEEDED
@given(st.floats(-50.0, 50.0))
def test_wrap_lands_in_the_half_open_interval_and_keeps_the_direction(angle):
    wrapped = float(wrap(angle))
    assert -math.pi < wrapped <= math.pi
    assert math.cos(wrapped) == pytest.approx(math.cos(angle), abs=1e-9)
    assert math.sin(wrapped) == pytest.approx(math.sin(angle), abs=1e-9)


def test_wrap_maps_both_ends_of_the_circle_to_pi():
    np.testing.assert_array_equal(wrap(np.array([math.pi, -math.pi, 3 * math.pi])),
                                  [math.pi, math.pi, math.pi])


def test_decompose_skips_steps_with_missing_inputs_and_uses_state_errors():
    rng = np.random.default_rng(0)
    objects = ("ego", "to")
    reps = {name: {o: Track.from_states(np.arange(40.0), rng.normal(size=(40, 4)))
                   for o in objects}
            for name in ("SD", "fit(SD)", "rSD")}
    table = decompose(reps, objects)
    assert set(table) == {"FIT_SD", "SIM_SD"}  # every other step needs GT or a refit
    for step in table:
        out, ref = STEPS[step]
        for o in objects:
            expected = state_errors(reps[out][o], reps[ref][o])
            for q, stats in table[step][o].items():
                assert stats == ErrorStats.of(expected[q])
    assert decompose({"GT": reps["SD"]}, objects) == {}
    assert len(STEPS) == 9


# -- reactions ------------------------------------------------------------------------------------


DT = 0.01
T = np.arange(0, 8.0 + DT / 2, DT)


def test_braking_reacts_when_the_acceleration_first_drops_below_the_threshold():
    accel = np.where(T >= 3.0, -5.0, 0.0)
    speed = 25.0 + np.cumsum(accel) * DT
    r = reaction(T, np.zeros_like(T), speed, np.zeros_like(T), accel)
    assert r.manoeuvre == "brake" and r.time == pytest.approx(3.0)
    assert r.speed_at_reaction == pytest.approx(speed[300])
    assert r.min_acceleration == -5.0 and r.max_lateral == 0.0
    # comfort braking (above -decel) is no reaction
    gentle = reaction(T, np.zeros_like(T), speed, np.zeros_like(T), np.where(T >= 3, -2.0, 0.0))
    assert gentle.manoeuvre == "none"


def test_a_lane_change_is_an_evasion_timed_at_the_first_lateral_speed_above_threshold():
    start, duration, width, speed = 2.0, 3.0, 3.5, 25.0

    def lateral_speed(t):
        u = np.clip((t - start) / duration, 0.0, 1.0)
        return width * 30 * u ** 2 * (1 - u) ** 2 / duration

    u = np.clip((T - start) / duration, 0.0, 1.0)
    y = width * u ** 3 * (10 - 15 * u + 6 * u * u)
    heading = np.arctan2(lateral_speed(T), speed)
    v = np.hypot(speed, lateral_speed(T))
    criteria = ReactionCriteria()
    r = reaction(T, y, v, heading, np.zeros_like(T), criteria)
    # continuous crossing of v·sin θ = threshold, by root finding on the closed form
    crossing = brentq(lambda t: lateral_speed(t) - criteria.lateral_speed, start + 1e-9,
                      start + duration / 2)
    assert r.manoeuvre == "evade"
    assert crossing <= r.time < crossing + DT
    assert r.max_lateral == pytest.approx(width)
    # half a lane is not an evasion: the reaction is there, the manoeuvre is "brake"
    small = reaction(T, y * 0.4, v, heading, np.zeros_like(T), criteria)
    assert small.manoeuvre == "brake" and small.time == r.time


def test_nothing_happening_is_no_reaction():
    r = reaction(T, np.full_like(T, 0.2), np.full_like(T, 20.0), np.zeros_like(T),
                 np.full_like(T, -1.0))
    assert math.isnan(r.time) and math.isnan(r.speed_at_reaction) and r.manoeuvre == "none"
    assert r.to_dict()["time"] is None and r.to_dict()["manoeuvre"] == "none"


def at(time, manoeuvre="brake"):
    return Reaction(time, manoeuvre, 27.0, -8.0, 0.0)


def test_reaction_analysis_eqs_4_to_7():
    result = reaction_analysis({"GT": at(3.76), "rGT": at(3.5), "rSD": at(3.56)},
                               sensor_offset=1.4, ego_speed=28.0)
    assert result.dt_react_gt_rgt == pytest.approx(0.26)  # eq. (4): positive, rGT earlier
    assert result.t_offset == pytest.approx(0.05)  # eq. (5): 1.4 m / 28 m/s
    assert result.ratio_eq6 == pytest.approx(5.2)  # eq. (6)
    assert result.dt_react_rgt_rsd == pytest.approx(0.06)  # eq. (7)


def test_reaction_analysis_reports_undefined_terms_as_none():
    result = reaction_analysis({"GT": at(3.0), "rGT": at(math.nan, "none")}, sensor_offset=0.0,
                               ego_speed=28.0)
    assert result == ReactionTiming(None, 0.0, None, None, None, None, None)
    assert result.to_dict() == {"dt_react_GT_rGT": None, "t_offset": 0.0, "ratio_eq6": None,
                                "dt_react_rGT_rSD": None, "dt_onset_GT_rGT": None,
                                "dt_onset_rGT_rSD": None, "ratio_onset_eq6": None}


def test_the_onset_is_where_the_speed_first_drops_below_its_running_maximum():
    """Speed rises to 28 m/s at 2 s (a bump the running maximum keeps), holds, then falls at
    1 m/s² from 4 s: 0.3 m/s below the maximum at 4.3 s; a reaction at −2.5 m/s² never comes."""
    speed = np.where(T < 2, 27.0 + 0.5 * T, np.where(T < 4, 28.0, 28.0 - (T - 4)))
    accel = np.gradient(speed, T)
    r = reaction(T, np.zeros_like(T), speed, np.zeros_like(T), accel)
    assert r.onset == pytest.approx(4.3, abs=0.011) and math.isnan(r.time)
    flat = reaction(T, np.zeros_like(T), np.full_like(T, 28.0), np.zeros_like(T),
                    np.zeros_like(T))
    assert math.isnan(flat.onset)


def test_reaction_analysis_reports_onset_differences():
    result = reaction_analysis({"GT": replace(at(3.7), onset=2.9),
                                "rGT": replace(at(3.0), onset=2.7),
                                "rSD": replace(at(3.05), onset=2.8)}, 1.4, 28.0)
    assert result.dt_onset_gt_rgt == pytest.approx(0.2)
    assert result.dt_onset_rgt_rsd == pytest.approx(0.1)
    assert result.ratio_onset_eq6 == pytest.approx(0.2 / 0.05)  # eq. (6) on the onset


# -- the path frame -------------------------------------------------------------------------------


def arc(radius, angles):
    """Points at ``angles`` on a left turn of ``radius`` starting at the origin heading +x
    (centre (0, radius))."""
    return radius * np.sin(angles), radius * (1 - np.cos(angles))


def test_path_coordinates_on_a_circular_arc():
    radius, sweep = 200.0, 0.5
    px, py = arc(radius, np.linspace(0.0, sweep, 4001))  # segments of 2.5 cm
    rng = np.random.default_rng(1)
    phi = rng.uniform(0.02, sweep - 0.02, 200)
    d = rng.uniform(-5.0, 5.0, 200)  # left of the path (towards the centre) is positive
    x, y = (radius - d) * np.sin(phi), radius - (radius - d) * np.cos(phi)  # centre (0, R)
    s, lateral, heading = path_coordinates(px, py, x, y)
    # a polyline of chords, not the arc: within a segment of angle Δφ the projection of a point
    # d off the path is off by up to R·Δφ/2 · |d|/R = 0.3 mm, the sagitta is R·Δφ²/8 = 0.4 µm
    # and the nearest segment's tangent is within a segment's angle Δφ of the point's
    step = sweep / 4000
    np.testing.assert_allclose(s, radius * phi, rtol=0, atol=(radius * step / 2) * 5 / radius)
    np.testing.assert_allclose(lateral, d, rtol=0, atol=2 * radius * step ** 2 / 8)
    np.testing.assert_allclose(heading, phi, rtol=0, atol=step)


def test_points_on_the_path_have_no_offset_and_their_chord_length():
    px, py = arc(80.0, np.linspace(0.0, 1.0, 301))
    s, lateral, _ = path_coordinates(px, py, px, py)
    np.testing.assert_allclose(lateral, 0.0, rtol=0, atol=1e-9)
    chords = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(px), np.diff(py)))])
    np.testing.assert_allclose(s, chords, rtol=0, atol=1e-9)


def test_points_beyond_the_path_ends_lie_on_its_extensions():
    px, py = np.array([0.0, 10.0, 20.0]), np.zeros(3)
    s, lateral, heading = path_coordinates(px, py, np.array([-5.0, 27.0]), np.array([1.0, -2.0]))
    np.testing.assert_allclose(s, [-5.0, 27.0])
    np.testing.assert_allclose(lateral, [1.0, -2.0])
    np.testing.assert_allclose(heading, 0.0)


# -- the pipeline end to end ---------------------------------------------------------------------


@pytest.fixture(scope="module")
def measurement():
    return simulate(0)


@pytest.fixture(scope="module")
def result(measurement):
    return reprocess(measurement)


def test_the_ideal_resimulation_reacts_far_earlier_than_reality(result):
    """Eq. (4) > 0 and eq. (6): the AD function's cut-in trigger reads the perceived lateral
    motion, which the real sensor delays; the shift is far above t_ΔS,d (the offset's share)."""
    gt, rgt = result.reactions["GT"], result.reactions["rGT"]
    assert gt.manoeuvre == "brake" and rgt.manoeuvre == "brake"
    assert gt.time - rgt.time > 5 * result.analysis.ideal.t_offset
    assert gt.onset > rgt.onset


def test_the_scenario_based_sensor_restores_the_real_reaction(result):
    gt, sb = result.reactions["GT"], result.reactions["rGT[sb]"]
    assert sb.manoeuvre == "brake"
    assert abs(sb.time - gt.time) <= 0.2
    assert result.reactions["rSD[sb]"].manoeuvre == "brake"


def test_the_estimated_sensor_model_matches_the_real_tracker(result):
    model, tracker = result.sensor_model, CONFIG.sensor
    assert abs(model.offset - tracker.offset) < 0.05
    assert abs(model.delay - tracker.window / 2) < 0.05  # regression window: lag ≈ window / 2
    assert abs(model.position_sd / tracker.position_sd - 1) < 0.1


def test_the_sensor_error_step_sees_the_offset(result):
    step = result.errors["ideal"]["S"]["to"]["d"]
    assert abs(step.median - CONFIG.sensor.offset) < 0.1
    a = result.analysis
    assert a.sensor_offset_d == pytest.approx(step.mean)
    assert a.ideal.t_offset == pytest.approx(a.sensor_offset_d / a.ego_speed)
    assert a.ideal.ratio_eq6 == pytest.approx(a.ideal.dt_react_gt_rgt / a.ideal.t_offset)


def test_the_analysis_writes_the_flat_layout_of_reprocess_json(result):
    """ΔS,d, v_EGO, eqs. (4)-(7) with the ideal sensor, then with the scenario-based model under
    [1]'s symbols with the suffix [sb]: the keys reprocess.json has always had."""
    a = result.analysis
    eqs = ["dt_react_GT_rGT", "t_offset", "ratio_eq6", "dt_react_rGT_rSD", "dt_onset_GT_rGT",
           "dt_onset_rGT_rSD", "ratio_onset_eq6"]
    assert list(a.to_dict()) == ["sensor_offset_d", "ego_speed", *eqs, *(f"{k}[sb]" for k in eqs)]
    assert a.to_dict()["dt_react_GT_rGT[sb]"] == a.scenario_based.dt_react_gt_rgt
    assert result.to_dict()["analysis"] == a.to_dict() == result.analysis_report


def test_every_representation_has_a_typed_risk_series_written_as_its_fields(result):
    """risk.json's entry of a representation is its RiskSeries' fields in order, arrays as
    lists; reprocess.json's max_risk is each series' max_risk."""
    assert set(result.risk) == set(result.reactions)
    for name, series in result.risk.items():
        assert isinstance(series, RiskSeries)
        assert list(series.to_dict()) == ["t", "risk", "ttr_min", "ttc", "thw"]
        assert series.to_dict()["thw"] is series.thw and len(series.risk) == len(series.t)
        assert result.to_dict()["max_risk"][name] == series.max_risk == float(series.risk.max())

def test_fitting_gt_costs_far_less_than_fitting_sd(result):
    """Fit residuals follow the noise of what was fitted: the 2-D distance of isotropic noise of
    sd σ per axis is Rayleigh with median σ·sqrt(2 ln 2) ≈ 1.18 σ (1 cm for GT, 5 cm for SD)."""
    fit_gt = result.errors["ideal"]["FIT_GT"]["to"]["d"].median
    fit_sd = result.errors["ideal"]["FIT_SD"]["to"]["d"].median
    rayleigh = math.sqrt(2 * math.log(2))
    assert fit_sd == pytest.approx(rayleigh * CONFIG.sensor.position_sd, rel=0.3)
    assert fit_gt < 0.5 * fit_sd


def test_the_sd_fit_speed_is_closer_to_gt_than_the_raw_sd_speed(result):
    gt = result.states["GT"]["to"].v

    def rmse(name):
        return float(np.sqrt(np.mean((result.states[name]["to"].v - gt) ** 2)))

    assert rmse("fit(SD)") < rmse("SD")


def test_the_error_table_has_every_step_for_both_sensors(result):
    assert set(result.errors) == {"ideal", "scenario-based"}
    for table in result.errors.values():
        assert list(table) == list(STEPS)
        for step in table.values():
            assert set(step) == {"ego", "to"}
            assert all(s.n == len(result.times) for q in step.values() for s in q.values())


def test_without_gt_only_the_sd_side_is_reprocessed(measurement):
    only_sd = reprocess(Measurement(sd=measurement.sd, metadata=measurement.metadata))
    assert set(only_sd.errors) == {"ideal"}
    assert set(only_sd.errors["ideal"]) == {"FIT_SD", "SIM_SD", "FIT_rSD"}
    assert set(only_sd.reactions) == {"SD", "rSD"}
    assert only_sd.sensor_model is None and only_sd.analysis is None
    assert only_sd.to_dict()["analysis"] == {}
    assert not any("GT" in name for name in only_sd.names)
