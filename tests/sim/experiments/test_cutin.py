"""The cut-in universe: scripted TO, measurement noise, the AD function, Measurement files.

Oracles: closed forms of the script (integrals of the piecewise speed, the quintic lateral
profile), the noise model's distribution (tolerances of five standard errors), the AD function's
control laws written out literally, and geometric properties that must hold (no overlap).
"""

import json
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from simcred.errors import SimcredError
from simcred.io.measurement import Measurement
from simcred.sim.closed_loop import run_closed_loop
from simcred.sim.driver import BRAKE, CRUISE, EVADE, ADFunction
from simcred.sim.experiments.cutin import (
    CutInConfig,
    CutInScript,
    drive,
    scripted_object,
    simulate,
    vehicle_model,
)
from simcred.sim.sensors import IdealSensor, OffsetDelaySensor
from simcred.traces import TraceSet, concat

CONFIG = CutInConfig()
SCRIPT = CONFIG.script
DRIVER = CONFIG.driver
WIDTH = 1.8  # m, footprint width used for the overlap test (wider than CommonRoad vehicle 2)


@pytest.fixture(scope="module")
def reality():
    return drive(CONFIG, 0)


@pytest.fixture(scope="module")
def ideal():
    return drive(replace(CONFIG, sensor=IdealSensor()), 0)


CENTRE_ONLY = replace(DRIVER, cut_in=False)  # the AD function without its cut-in trigger


@pytest.fixture(scope="module")
def ideal_centre_only():
    return drive(replace(CONFIG, sensor=IdealSensor(), driver=CENTRE_ONLY), 0)


@pytest.fixture(scope="module")
def measurement():
    return simulate(0)


# -- the scripted traffic object ------------------------------------------------------------------


def longitudinal_position(s, t):
    """x(t) = x0 + ∫ v_long: constant speed, then constant deceleration to ``brake_to``, then
    ``brake_to`` (written piecewise, independently of the implementation)."""
    t_stop = s.brake_start + (s.speed - s.brake_to) / s.brake_decel
    x_brake = s.start_distance + s.speed * s.brake_start
    x_stop = x_brake + (s.speed - s.brake_to) ** 2 / (2 * s.brake_decel) + s.brake_to * (
        t_stop - s.brake_start)
    tau = t - s.brake_start
    return np.select(
        [t <= s.brake_start, t <= t_stop],
        [s.start_distance + s.speed * t, x_brake + s.speed * tau - 0.5 * s.brake_decel * tau ** 2],
        x_stop + s.brake_to * (t - t_stop))


@pytest.mark.parametrize("script", [SCRIPT, CutInScript(start_distance=12.0, speed=30.0,
                                                        brake_start=1.0, brake_decel=4.0,
                                                        brake_to=0.0, lane_change_start=0.5,
                                                        lane_change_duration=2.0)])
def test_scripted_x_is_the_integral_of_the_piecewise_speed(script):
    t = np.arange(0, 12.0 + 1e-9, 0.01)
    state = scripted_object(script, t)
    np.testing.assert_allclose(state[:, 0], longitudinal_position(script, t), rtol=0, atol=1e-9)
    # continuity, and dx/dt = v cos θ, dy/dt = v sin θ by central differences (error O(h²))
    h = 1e-4
    ahead, behind = scripted_object(script, t + h), scripted_object(script, t - h)
    kinks = np.isclose(t, script.brake_start) | np.isclose(
        t, script.brake_start + (script.speed - script.brake_to) / script.brake_decel)
    derivative = (ahead[:, :2] - behind[:, :2]) / (2 * h)
    velocity = state[:, 2:3] * np.column_stack([np.cos(state[:, 3]), np.sin(state[:, 3])])
    np.testing.assert_allclose(derivative[~kinks], velocity[~kinks], rtol=0, atol=1e-5)
    assert np.max(np.abs(ahead[:, :2] - state[:, :2])) < 2 * script.speed * h  # no jumps


def test_scripted_lateral_profile_endpoints_and_boundary_crossing():
    s = SCRIPT
    end = s.lane_change_start + s.lane_change_duration
    t = np.array([0.0, s.lane_change_start, s.lane_change_start + s.lane_change_duration / 2,
                  end, end + 1.0])
    y = scripted_object(s, t)[:, 1]
    boundary = (s.start_lane + s.end_lane) / 2
    np.testing.assert_allclose(y, [s.start_lane, s.start_lane, boundary, s.end_lane, s.end_lane],
                               rtol=0, atol=1e-12)
    assert t[2] == 3.5  # the docstring's crossing time, after brake_start = 3.2 s
    # monotone in between, no lateral speed outside the lane change
    grid = np.linspace(0.0, 8.0, 801)
    state = scripted_object(s, grid)
    assert np.all(np.diff(state[:, 1]) <= 0)
    outside = (grid <= s.lane_change_start) | (grid >= end)
    np.testing.assert_array_equal(state[outside, 3], 0.0)


# -- simulate(): determinism and the measurement noise ---------------------------------------------


def test_simulate_is_deterministic_per_seed(measurement):
    again = simulate(0)
    assert again.gt.equals(measurement.gt) and again.sd.equals(measurement.sd)
    other = simulate(1)
    assert not np.array_equal(other.gt.values, measurement.gt.values)
    assert not np.array_equal(other.sd.values, measurement.sd.values)
    assert measurement.metadata["seed"] == 0 and other.metadata["seed"] == 1


def truth_columns(record):
    ego, to = record.ego.states()[0], record.objects.states()[0, :, 0]
    return {"ego": ego, "to": to}


def test_gt_noise_has_the_configured_dgps_levels(measurement, reality):
    """GT − truth per column: mean 0 and sd as configured. With n = 1201 independent draws the
    relative standard error of a sample sd is 1/sqrt(2(n − 1)) ≈ 2 %; of the mean σ/sqrt(n)."""
    gt, sd, n = measurement.gt.run(0), measurement.sd.run(0), CONFIG.steps
    scale = {"x": CONFIG.dgps.position, "y": CONFIG.dgps.position, "v": CONFIG.dgps.speed,
             "heading": CONFIG.dgps.heading}
    for name, truth in truth_columns(reality).items():
        for j, signal in enumerate(("x", "y", "v", "heading")):
            error = gt[f"{name}.{signal}"] - truth[:, j]
            assert abs(error.mean()) < 5 * scale[signal] / np.sqrt(n), (name, signal)
            assert abs(error.std() / scale[signal] - 1) < 5 / np.sqrt(2 * (n - 1)), (name, signal)
    # SD's odometry carries its own draws: independent of GT's (|r| < 5/sqrt(n))
    odometry = sd["ego.x"] - reality.ego.x[0]
    assert abs(odometry.std() / CONFIG.dgps.position - 1) < 5 / np.sqrt(2 * (n - 1))
    r = np.corrcoef(odometry, gt["ego.x"] - reality.ego.x[0])[0, 1]
    assert abs(r) < 5 / np.sqrt(n)


def test_sd_sees_the_to_farther_by_the_configured_offset(measurement, reality):
    sd = measurement.sd.run(0)
    ego, to = reality.ego.states()[0, :, :2], reality.objects.states()[0, :, 0, :2]
    sight = (to - ego) / np.hypot(*(to - ego).T)[:, None]
    error = np.column_stack([sd["to.x"], sd["to.y"]]) - to
    along = np.einsum("nc,nc->n", error, sight)
    across = sight[:, 0] * error[:, 1] - sight[:, 1] * error[:, 0]
    assert abs(along.mean() - CONFIG.sensor.offset) < 0.05
    assert abs(across.mean()) < 0.05
    np.testing.assert_array_equal(sd["ad.mode"], reality.mode[0])


# -- the AD function in the universe --------------------------------------------------------------


def overlapping_gap(record):
    """Bumper gap |Δx| − length at the samples where EGO and TO overlap laterally."""
    ego, to = record.ego.states()[0], record.objects.states()[0, :, 0]
    overlap = np.abs(to[:, 1] - ego[:, 1]) < WIDTH
    return np.abs(to[overlap, 0] - ego[overlap, 0]) - DRIVER.vehicle_length


def test_in_reality_the_ego_brakes_and_never_evades(reality):
    mode = reality.mode[0]
    assert (mode == BRAKE).any() and not (mode == EVADE).any()
    assert np.abs(reality.ego.y[0]).max() < 0.01  # it keeps its lane
    assert reality.ego.acceleration[0].min() < -DRIVER.react_decel  # emergency, not comfort braking
    assert overlapping_gap(reality).min() > 0


def test_without_the_cut_in_trigger_an_ideal_sensor_evades_to_the_left_lane(ideal_centre_only):
    """The evasion path: reacting only once the TO's centre is in the lane, the ideal sensor
    sees the braking TO at once and the required deceleration is above ``evade_decel``."""
    record = ideal_centre_only
    mode = record.mode[0]
    assert (mode == EVADE).any() and not (mode == BRAKE).any()
    left = DRIVER.lane_centres[1]
    assert abs(record.ego.y[0, -1] - left) < 0.05
    assert np.all(record.ego.y[0] < left + 0.1)  # no overshoot out of the road
    assert overlapping_gap(record).min() > 0


def first_slowing(record, decel=1.0):
    """Time of the first commanded deceleration beyond ``decel`` (m/s²)."""
    return record.t[np.argmax(record.ego.acceleration[0] < -decel)]


def test_the_cut_in_trigger_makes_the_reaction_depend_on_the_perceived_lateral_motion(
        reality, ideal, ideal_centre_only):
    """With the trigger, the ideal sensor starts following the TO earlier than the delayed
    tracker (its lateral velocity lags by ≈ window / 2); without it both react when the TO's
    centre reaches the lane boundary (3.5 s), whatever the sensor."""
    assert first_slowing(reality) - first_slowing(ideal) > 0.2
    assert first_slowing(ideal) < 3.0  # before the centre crossing: the trigger, not the lane
    reality_centre_only = drive(replace(CONFIG, driver=CENTRE_ONLY), 0)
    for record in (reality_centre_only, ideal_centre_only):
        assert 3.5 <= first_slowing(record) <= 3.6
    np.testing.assert_array_equal(reality.mode[0] == EVADE, False)
    np.testing.assert_array_equal(ideal.mode[0] == EVADE, False)


def test_a_pure_delay_shifts_the_reaction_monotonically_and_zero_delay_is_the_ideal_sensor():
    """OffsetDelaySensor without offset and noise: delay 0 is the truth (the same drive as the
    ideal sensor up to the rounding of speed and heading through the velocity vector); longer
    delays of the perceived velocity react later."""
    def run(sensor):
        return drive(replace(CONFIG, sensor=sensor), 0)

    ideal_record = run(IdealSensor())
    zero = run(OffsetDelaySensor())
    np.testing.assert_allclose(zero.ego.states(), ideal_record.ego.states(), rtol=0, atol=1e-9)
    np.testing.assert_allclose(zero.ego.acceleration, ideal_record.ego.acceleration, rtol=0,
                               atol=1e-9)
    times = [first_slowing(run(OffsetDelaySensor(delay=d))) for d in (0.0, 0.25, 0.5)]
    assert times[0] < times[1] < times[2]


@settings(max_examples=80, deadline=None, derandomize=True, database=None)
@given(y=st.floats(-6.0, 9.0), speed=st.floats(0.0, 40.0), heading=st.floats(-0.6, 0.6),
       lane=st.sampled_from([0, 1]))
def test_cutting_in_is_the_literal_lateral_speed_and_tlc_law(y, speed, heading, lane):
    c = DRIVER
    objects = np.array([[[50.0, y, speed, heading]]])
    got = ADFunction(c).cutting_in(objects, np.array([c.lane_centres[lane]]))[0, 0]
    offset = y - c.lane_centres[lane]
    towards = -np.sign(offset) * speed * np.sin(heading)
    gap = max(abs(offset) - c.object_width / 2 - c.lane_width / 2, 0.0)
    expected = (abs(offset) < 1.5 * c.lane_width and towards >= c.cut_in_lateral_speed
                and gap / towards <= c.cut_in_tlc)
    assert got == expected


@pytest.mark.parametrize("which", ["reality", "ideal"])
def test_the_steering_rate_stays_within_the_vehicle_limit(which, request):
    record = request.getfixturevalue(which)
    rate = np.diff(record.steering[0]) / CONFIG.dt
    assert np.abs(rate).max() <= DRIVER.max_steer_rate * (1 + 1e-9)


@settings(max_examples=60, deadline=None, derandomize=True, database=None)
@given(y=st.floats(-3.0, 7.0), speed=st.floats(0.0, 50.0), heading=st.floats(-0.5, 0.5),
       steering=st.floats(-1.0, 1.0), lane=st.sampled_from([0, 1]))
def test_the_commanded_steering_rate_is_the_literal_law_and_never_exceeds_the_limit(
        y, speed, heading, steering, lane):
    c = DRIVER
    driver = ADFunction(c)
    objects = np.array([[[500.0, 10.0, 20.0, 0.0]]])  # far away, off the road: no lead
    memory = driver.start(1, objects)
    memory.target_lane[:] = lane
    rate, _ = driver.act(memory, np.array([[0.0, y, speed, heading]]), np.array([steering]),
                         objects, 0.01)[0]
    v = max(speed, 1.0)
    lateral = np.clip(c.lateral_gain * (c.lane_centres[lane] - y)
                      - c.lateral_damping * speed * np.sin(heading),
                      -c.max_lateral_accel, c.max_lateral_accel)
    wanted = np.arctan(c.wheelbase * lateral / v ** 2)
    expected = np.clip((wanted - steering) / c.steer_tau, -c.max_steer_rate, c.max_steer_rate)
    assert rate == pytest.approx(expected, abs=1e-12)
    assert abs(rate) <= c.max_steer_rate


def keep_lane(script):
    """The TO stays in the left lane and never brakes."""
    return replace(script, lane_change_start=1e3, brake_start=1e3)


def test_acc_holds_the_set_speed_with_no_object_in_its_lane():
    record = drive(replace(CONFIG, script=keep_lane(SCRIPT)), 0)
    np.testing.assert_array_equal(record.mode[0], CRUISE)
    np.testing.assert_allclose(record.ego.v[0], DRIVER.set_speed, rtol=0, atol=1e-9)
    np.testing.assert_array_equal(record.ego.y[0], 0.0)


def test_acc_speeds_up_to_the_set_speed_by_its_literal_law():
    """Started 8 m/s slow with the lane free: v_{k+1} = v_k + dt · min(k_v (v_set − v_k), a_max)
    (zero-order hold; the vehicle's speed integrates the acceleration input exactly)."""
    config = replace(CONFIG, script=keep_lane(replace(SCRIPT, speed=20.0)), ego_speed=20.0)
    record = drive(config, 0)
    speed = np.empty(config.steps)
    speed[0] = 20.0
    for k in range(config.steps - 1):
        accel = min(DRIVER.speed_gain * (DRIVER.set_speed - speed[k]), DRIVER.max_accel)
        speed[k + 1] = speed[k] + config.dt * accel
    np.testing.assert_allclose(record.ego.v[0], speed, rtol=0, atol=1e-9)
    assert record.ego.v[0].max() < DRIVER.set_speed  # approaches, never overshoots


def test_the_collision_check_catches_a_blind_ego():
    """The overlap oracle is not vacuous: an EGO that ignores the TO (no braking at all) hits it."""
    blind = replace(DRIVER, react_decel=1e9, comfort_decel=0.0, max_accel=0.0)
    t = np.arange(CONFIG.steps) * CONFIG.dt
    objects = scripted_object(SCRIPT, t)[None, :, None, :]
    record = run_closed_loop(vehicle_model("st"), np.array([[0.0, 0.0, CONFIG.ego_speed, 0.0]]),
                             objects, IdealSensor(), ADFunction(blind), CONFIG.dt,
                             np.zeros((1, CONFIG.steps, 1, 2)))
    assert overlapping_gap(record).min() < 0


# -- Measurement files ----------------------------------------------------------------------------


def plain_json(value):
    return json.loads(json.dumps(value))


def test_measurement_write_read_round_trip_keeps_every_value(measurement, tmp_path):
    back = Measurement.read(measurement.write(tmp_path / "m"))
    for kind in ("gt", "sd"):
        written, read = getattr(measurement, kind), getattr(back, kind)
        assert read.signals == written.signals and read.run_ids == written.run_ids
        np.testing.assert_array_equal(read.time, written.time)
        np.testing.assert_array_equal(read.values, written.values)
        assert dict(read.metadata) == plain_json(dict(written.metadata))
    assert "kind" not in back.metadata  # the file's envelope is not the measurement's metadata
    assert {k: back.metadata[k] for k in measurement.metadata} == plain_json(
        dict(measurement.metadata))


def test_measurement_round_trip_equals(measurement, tmp_path):
    back = Measurement.read(measurement.write(tmp_path / "m"))
    assert back.gt.equals(measurement.gt) and back.sd.equals(measurement.sd)
    assert dict(back.metadata) == dict(measurement.metadata)


def test_measurement_without_gt_round_trips_to_none(measurement, tmp_path):
    only_sd = Measurement(sd=measurement.sd, metadata={"note": "no reference"})
    back = Measurement.read(only_sd.write(tmp_path / "sd-only"))
    assert back.gt is None and back.metadata["note"] == "no reference"
    np.testing.assert_array_equal(back.sd.values, measurement.sd.values)
    assert not (tmp_path / "sd-only" / "gt.parquet").exists()


@pytest.mark.parametrize("missing", ["measurement.json", "sd.parquet"])
def test_reading_an_incomplete_measurement_names_the_directory(measurement, tmp_path, missing):
    directory = measurement.write(tmp_path / "broken")
    (directory / missing).unlink()
    with pytest.raises(SimcredError, match=missing.replace(".", r"\.")) as info:
        Measurement.read(directory)
    message = str(info.value)
    assert "\n" not in message and str(directory) in message


def test_a_measurement_holds_one_run_per_recording(measurement):
    two = concat([measurement.sd, TraceSet.from_runs([measurement.sd.run(0)],
                                                     run_ids=["again"])])
    with pytest.raises(SimcredError, match="one run, got 2"):
        Measurement(sd=two)
