"""Vehicle models against oracles: CommonRoad's per-state functions, closed forms, each other."""

import numpy as np
import pytest

from simcred.sim.vehicles import (
    KinematicSingleTrack,
    SimpleCar,
    SingleTrack,
    initial_state,
    rk4_step,
)

KS, ST = KinematicSingleTrack(), SingleTrack()
P = KS.params  # CommonRoad vehicle 2 (BMW 320i)
WHEELBASE = P.a + P.b
DT = 0.01


def random_states(model, runs, rng):
    """States and inputs over every regime: both sides of every constraint and of ST's switch."""
    state = rng.uniform(-3.0, 3.0, size=(runs, len(model.state_names)))
    state[:, 2] = rng.uniform(-1.3, 1.3, runs)  # steering, limits ±1.066
    state[:, 3] = np.where(rng.random(runs) < 0.3, rng.uniform(-0.15, 0.15, runs),  # crawling
                           rng.uniform(-16.0, 55.0, runs))  # speed limits -13.9, 50.8
    inputs = np.column_stack([rng.uniform(-1.0, 1.0, runs),  # steering rate, limits ±0.4
                              rng.uniform(-15.0, 15.0, runs)])  # acceleration, limit 11.5
    return state, inputs


def boundary_states(model):
    """Every input exactly at and across the limits, at speeds and steering angles at the limits."""
    s, lon = P.steering, P.longitudinal
    grid = np.array(np.meshgrid(
        [s.min, -0.3, 0.0, 0.3, s.max],
        [lon.v_min, -0.1, -0.05, 0.0, 0.1, lon.v_switch, 20.0, lon.v_max],
        [s.v_min, -0.1, 0.0, 0.1, s.v_max],
        [-lon.a_max, -1.0, 0.0, 1.0, lon.a_max, 20.0],
    )).reshape(4, -1).T
    state = np.zeros((len(grid), len(model.state_names)))
    state[:, 2:4] = grid[:, :2]
    state[:, 4:] = 0.2  # heading, and ST's yaw rate and slip angle
    return state, grid[:, 2:]


@pytest.mark.parametrize("model", [KS, ST], ids=lambda m: m.name)
@pytest.mark.parametrize("cases", [random_states, boundary_states])
def test_derivatives_equal_commonroad(model, cases):
    state, inputs = (cases(model, 20_000, np.random.default_rng(7)) if cases is random_states
                     else cases(model))
    oracle = model.reference().derivatives(state, inputs)
    # same arithmetic in the same order: only numpy's and libm's sin/cos/tan may differ in the
    # last bit, so relative 1e-12 is 1000× looser than what is seen (≈ 1e-15)
    np.testing.assert_allclose(model.derivatives(state, inputs), oracle, rtol=1e-12, atol=0)


def test_cases_cover_both_st_branches_and_active_constraints():
    state, inputs = random_states(ST, 20_000, np.random.default_rng(7))
    crawl = np.abs(state[:, 3]) < 0.1
    rates = ST.derivatives(state, inputs)[:, 2:4]
    assert 0.2 < crawl.mean() < 0.4
    assert np.mean(rates[:, 0] == 0) > 0.05  # steering into a limit
    assert np.mean(np.abs(rates[:, 0]) == P.steering.v_max) > 0.3
    assert np.mean(rates[:, 1] == -P.longitudinal.a_max) > 0.05
    assert np.mean((state[:, 3] > P.longitudinal.v_switch)  # engine power limit
                   & (rates[:, 1] < inputs[:, 1]) & (rates[:, 1] > 0)) > 0.05


@pytest.mark.parametrize("model", [KS, ST], ids=lambda m: m.name)
def test_trajectory_equals_commonroad_through_the_switch(model):
    """From rest, accelerating and steering: ST crosses its kinematic/dynamic switch."""
    state = initial_state(model, x=[0.0, 3.0], y=[1.0, -2.0], heading=[0.0, 2.0], speed=0.0)
    reference, expected = model.reference(), state
    inputs = np.array([[0.1, 2.0], [-0.2, 0.5]])
    for _ in range(300):
        state = rk4_step(model, state, inputs, DT)
        expected = rk4_step(reference, expected, inputs, DT)
    assert np.all(np.abs(expected[:, 3]) > 0.1)
    np.testing.assert_allclose(state, expected, rtol=1e-10, atol=1e-10)


def circle(t, x0, y0, heading0, speed, steering):
    """Eq. (8) with constant speed and steering angle φ: a circle of radius L / tan φ."""
    radius = WHEELBASE / np.tan(steering)
    heading = heading0 + speed / radius * t
    return (x0 + radius * (np.sin(heading) - np.sin(heading0)),
            y0 - radius * (np.cos(heading) - np.cos(heading0)), heading)


@pytest.mark.parametrize("speed, steering", [(10.0, 0.2), (3.0, -0.5), (-4.0, 0.3), (25.0, 0.02)])
def test_simplecar_constant_inputs_drive_the_closed_form_circle(speed, steering):
    car = SimpleCar(wheelbase=WHEELBASE)
    x0, y0, heading0 = 1.0, -2.0, 0.3
    state = initial_state(car, x=x0, y=y0, heading=heading0, steering=steering)
    for step in range(1, 1001):
        state = rk4_step(car, state, np.array([[speed, 0.0]]), DT)
        if step % 100 == 0:
            np.testing.assert_allclose(state[0, :3], circle(step * DT, x0, y0, heading0, speed,
                                                            steering), rtol=0, atol=1e-9)
    assert state[0, 3] == steering


def test_simplecar_straight_line_without_steering():
    car = SimpleCar()
    state = initial_state(car, x=[0.0, 5.0], y=[1.0, -1.0], heading=[0.0, -2.5])
    for _ in range(1000):
        state = rk4_step(car, state, np.array([[7.0, 0.0], [-3.0, 0.0]]), DT)
    x, y, heading = car.pose(state)
    np.testing.assert_allclose(x, [70.0, 5.0 - 30.0 * np.cos(-2.5)], rtol=0, atol=1e-11)
    np.testing.assert_allclose(y, [1.0, -1.0 - 30.0 * np.sin(-2.5)], rtol=0, atol=1e-11)
    np.testing.assert_array_equal(heading, [0.0, -2.5])


def drive_all(speed, steering_rate, seconds):
    """SimpleCar, KS and ST from the same pose at constant speed; centre-of-gravity positions.

    KS and SimpleCar are referenced at the rear axle, ST at the centre of gravity, b ahead.
    """
    car = SimpleCar(wheelbase=WHEELBASE)
    states = {car: initial_state(car, x=0.0, y=0.0, heading=0.5),
              KS: initial_state(KS, x=0.0, y=0.0, heading=0.5, speed=speed),
              ST: initial_state(ST, x=P.b * np.cos(0.5), y=P.b * np.sin(0.5), heading=0.5,
                                speed=speed)}
    paths = {model: [] for model in states}
    for step in range(round(seconds / DT)):
        rate = steering_rate(step * DT)
        for model, state in states.items():
            inputs = [[speed, rate]] if model is car else [[rate, 0.0]]
            states[model] = state = rk4_step(model, state, np.array(inputs), DT)
            x, y, heading = model.pose(state)
            if model is not ST:
                x, y = x + P.b * np.cos(heading), y + P.b * np.sin(heading)
            paths[model].append(np.column_stack([x, y])[0])
    return [np.array(paths[model]) for model in (car, KS, ST)]


def lane_change(t):
    """Steering rate of a lane change to ±0.05 rad and back (inside the rate limit)."""
    return 0.05 if t < 1 else -0.05 if t < 3 else 0.05 if t < 4 else 0.0


def test_models_agree_at_low_speed_and_small_steering():
    car, ks, st = drive_all(5.0, lane_change, 5.0)
    np.testing.assert_array_equal(car, ks)  # eq. (8) is KS with the speed as an input
    assert np.max(np.hypot(*(ks - st).T)) < 0.05
    assert np.ptp(ks[:, 1]) > 2.0  # the car did move sideways


def test_single_track_leaves_the_kinematic_path_at_speed():
    _, ks, st = drive_all(20.0, lambda t: 0.4 if t < 0.5 else 0.0, 2.0)  # 0.2 rad at 20 m/s
    assert np.hypot(*(ks[-1] - st[-1])) > 2.0


@pytest.mark.parametrize("model", [SimpleCar(), KS, ST], ids=lambda m: m.name)
def test_stepping_a_batch_equals_stepping_each_run_alone(model):
    rng = np.random.default_rng(3)
    state, inputs = random_states(model, 257, rng)
    if model.name == "simplecar":
        inputs[:, 0] = state[:, 3] * 10  # speed input
        state[:, 3] = np.clip(state[:, 3], -1.0, 1.0)
    batch = state
    for _ in range(20):
        batch = rk4_step(model, batch, inputs, DT)
    for run in range(len(state)):
        alone = state[run:run + 1]
        for _ in range(20):
            alone = rk4_step(model, alone, inputs[run:run + 1], DT)
        np.testing.assert_array_equal(alone[0], batch[run])


def test_initial_state_by_name():
    state = initial_state(ST, x=[1.0, 2.0], y=3.0, heading=0.5, speed=10.0, steering=0.1)
    np.testing.assert_array_equal(state, [[1.0, 3.0, 0.1, 10.0, 0.5, 0.0, 0.0],
                                          [2.0, 3.0, 0.1, 10.0, 0.5, 0.0, 0.0]])
    with pytest.raises(ValueError, match="'simplecar' has no state 'speed'"):
        initial_state(SimpleCar(), x=0.0, y=0.0, heading=0.0, speed=3.0)
    with pytest.raises(ValueError, match="'heading' must be finite"):
        initial_state(KS, x=0.0, y=0.0, heading=np.nan)
    with pytest.raises(ValueError, match="'x' must be a scalar or 1-D"):
        initial_state(KS, x=np.zeros((2, 2)))


def test_parameters_are_commonroads():
    from vehiclemodels.parameters_vehicle1 import parameters_vehicle1

    escort = KinematicSingleTrack(parameters_vehicle1())
    state = initial_state(escort, x=0.0, y=0.0, heading=0.0, speed=10.0, steering=0.1)
    assert escort.params.a + escort.params.b != WHEELBASE
    np.testing.assert_allclose(escort.derivatives(state, np.zeros((1, 2)))[0, 4],
                               10.0 / (escort.params.a + escort.params.b) * np.tan(0.1))
