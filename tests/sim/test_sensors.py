"""Sensor models and their estimation against closed forms built independently in the test.

Oracles: the definitions of the models written out literally (offset along the line of sight,
pure delay), the closed form of a least-squares slope over a quadratic, and the sampling
distribution of the estimators (tolerances of five standard errors, derived where used).
"""

from dataclasses import replace

import numpy as np
import pytest

from simcred.errors import SimcredError
from simcred.scenario.description import ObjectTrack, ScenarioDescription, Spline
from simcred.sim.closed_loop import run_closed_loop
from simcred.sim.driver import ADFunction, DriverConfig
from simcred.sim.experiments.cutin import CutInScript, scripted_object
from simcred.sim.resimulation import resimulate, simulate_batch
from simcred.sim.sensors import (
    IdealSensor,
    OffsetDelaySensor,
    TrackerSensor,
    estimate_sensor,
    perceive_recording,
)
from simcred.sim.vehicles import vehicle_model

DT = 0.01


# -- synthetic GT: an object with a smoothly varying velocity vector, an EGO it pulls away from --


def object_xy(t):
    """Position of the object (m): analytic, so its velocity is known exactly."""
    return np.column_stack([30.0 + 20.0 * t + 2.0 * np.sin(0.7 * t), 3.0 * np.sin(0.4 * t)])


def object_velocity(t):
    """d/dt of :func:`object_xy`."""
    return np.column_stack([20.0 + 1.4 * np.cos(0.7 * t), 1.2 * np.cos(0.4 * t)])


def ego_xy(t):
    """The EGO drives slower along x: the range grows from 30 m to about 130 m over 20 s."""
    return np.column_stack([15.0 * t, np.zeros_like(t)])


def states(xy, velocity):
    """Columns x, y, v, heading from positions and velocity vectors."""
    return np.column_stack([xy, np.hypot(*velocity.T), np.arctan2(velocity[:, 1], velocity[:, 0])])


def synthetic_pair(a, b, delay, sd, seed, duration=20.0):
    """GT and SD of one object, built from the definitions: SD position = GT position +
    (a + b·range)·unit(line of sight) + N(0, sd²) per axis; SD velocity = GT's at t − delay
    (evaluated analytically, so any real delay is exact)."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(round(duration / DT)) + 1) * DT
    ego, xy = ego_xy(t), object_xy(t)
    delta = xy - ego
    distance = np.hypot(*delta.T)
    unit = delta / distance[:, None]
    seen_xy = xy + (a + b * distance)[:, None] * unit + sd * rng.standard_normal(xy.shape)
    gt = states(xy, object_velocity(t))
    sd_states = states(seen_xy, object_velocity(t - delay))
    return t, ego, gt, sd_states, distance


# -- estimate_sensor -----------------------------------------------------------------------------


@pytest.mark.parametrize(("a", "b", "delay", "sd", "seed"), [
    (1.4, 0.0, 0.37, 0.05, 0),
    (0.8, 0.01, 0.255, 0.10, 1),  # half-way between samples: rounding alone is off by dt/2
    (-0.5, 0.004, 0.0, 0.02, 2),
    (2.0, -0.005, 1.2337, 0.20, 3),
])
def test_estimate_sensor_recovers_offset_slope_delay_and_noise(a, b, delay, sd, seed):
    t, ego, gt, sd_states, distance = synthetic_pair(a, b, delay, sd, seed)
    model = estimate_sensor(t, ego, gt, sd_states)
    # OLS on [1, range]: the along-sight noise is N(0, sd²), so cov(coef) = sd² (XᵀX)⁻¹
    design = np.column_stack([np.ones_like(distance), distance])
    se = sd * np.sqrt(np.diag(np.linalg.inv(design.T @ design)))
    assert abs(model.offset - a) < 5 * se[0]
    assert abs(model.offset_per_metre - b) < 5 * se[1]
    # the delay: within half a sample of the true (real) delay, as documented; and as the cost
    # is nearly a parabola in the shift for a smooth velocity, the refinement is much closer
    assert abs(model.delay - delay) <= DT / 2
    assert abs(model.delay - delay) <= 0.05 * DT
    # sample sd over 2n residuals: relative standard error 1/sqrt(2·2n) ≈ 1.1 % for n = 2001
    n = len(t)
    assert abs(model.position_sd / sd - 1) < 5 / np.sqrt(4 * n)
    assert model.fit["samples"] == n


def test_estimate_sensor_is_exact_without_noise():
    t, ego, gt, sd_states, _ = synthetic_pair(1.1, 0.007, 0.5, 0.0, 0)
    model = estimate_sensor(t, ego, gt, sd_states)
    assert model.offset == pytest.approx(1.1, abs=1e-9)
    assert model.offset_per_metre == pytest.approx(0.007, abs=1e-11)
    assert model.position_sd < 1e-9
    # a whole number of samples: the cost is zero there, the parabola barely moves it
    assert model.delay == pytest.approx(0.5, abs=1e-3 * DT)


def test_constant_offset_only_when_asked_or_when_the_range_barely_varies():
    t, ego, gt, sd_states, _ = synthetic_pair(1.4, 0.0, 0.2, 0.0, 0)
    constant = estimate_sensor(t, ego, gt, sd_states, offset_vs_range=False)
    assert constant.offset == pytest.approx(1.4, abs=1e-9) and constant.offset_per_metre == 0.0
    # 2 s at a nearly constant range (< 5 m of variation): a constant, even though asked
    short = slice(0, 201)
    narrow = estimate_sensor(t[short], ego[short] + np.column_stack(
        [5.0 * t[short], np.zeros(201)]), gt[short], sd_states[short])
    assert narrow.offset_per_metre == 0.0


def test_estimate_sensor_rejects_uneven_times():
    t, ego, gt, sd_states, _ = synthetic_pair(1.0, 0.0, 0.1, 0.0, 0, duration=1.0)
    uneven = t.copy()
    uneven[50] += 0.003
    with pytest.raises(SimcredError, match="equally spaced"):
        estimate_sensor(uneven, ego, gt, sd_states)


# -- OffsetDelaySensor: the closed form, streamed ------------------------------------------------


def stream(sensor, ego, truth, noise, dt=DT):
    """Feed ``truth`` (runs, steps, 4) to ``sensor`` step by step as the closed loop does."""
    runs, steps, _ = truth.shape
    memory = sensor.start(runs, dt)
    return np.stack([sensor.perceive(memory, ego[:, k], truth[:, k], noise[:, k])
                     for k in range(steps)], axis=1)


def batch_of_two(duration=6.0):
    """Two runs: the synthetic object and a mirrored copy, with their EGOs."""
    t = np.arange(int(round(duration / DT)) + 1) * DT
    xy, velocity, ego = object_xy(t), object_velocity(t), ego_xy(t)
    mirror = np.array([1.0, -1.0])
    truth = np.stack([states(xy, velocity), states(xy * mirror, velocity * mirror)])
    return t, np.stack([ego, ego + [0.0, 1.0]]), truth


@pytest.mark.parametrize(("offset", "per_metre", "delay_steps", "sd"), [
    (1.4, 0.0, 37, 0.0), (0.6, 0.012, 50, 0.3), (-0.8, 0.0, 0, 0.1)])
def test_offset_delay_sensor_streams_its_closed_form(offset, per_metre, delay_steps, sd):
    t, ego, truth = batch_of_two()
    noise = np.random.default_rng(4).standard_normal((*truth.shape[:2], 2))
    sensor = OffsetDelaySensor(offset, per_metre, delay_steps * DT, sd)
    seen = stream(sensor, ego, truth, noise)
    delta = truth[..., :2] - ego
    distance = np.hypot(delta[..., 0], delta[..., 1])
    expected_xy = (truth[..., :2] + (offset + per_metre * distance)[..., None]
                   * delta / distance[..., None] + sd * noise)
    np.testing.assert_allclose(seen[..., :2], expected_xy, rtol=0, atol=1e-9)
    # velocity and heading: the truth delay_steps earlier, held at the first sample before that
    earlier = np.maximum(np.arange(len(t)) - delay_steps, 0)
    np.testing.assert_allclose(seen[..., 2], truth[:, earlier, 2], rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(seen[..., 3], truth[:, earlier, 3], rtol=0, atol=1e-12)


def test_dynamic_only_zeroes_the_static_part_and_keeps_the_delay():
    full = OffsetDelaySensor(1.4, 0.01, 0.3, 0.05, fit={"samples": 10.0})
    dynamic = full.dynamic_only()
    assert (dynamic.offset, dynamic.offset_per_metre, dynamic.position_sd) == (0.0, 0.0, 0.0)
    assert (dynamic.delay, dynamic.name, dict(dynamic.fit)) == (0.3, full.name, {"samples": 10.0})
    t, ego, truth = batch_of_two(2.0)
    noise = np.random.default_rng(0).standard_normal((*truth.shape[:2], 2))
    seen = stream(dynamic, ego, truth, noise)
    np.testing.assert_array_equal(seen[..., :2], truth[..., :2])  # no offset, no noise at all
    np.testing.assert_allclose(seen[:, 30:, 2], truth[:, :-30, 2], rtol=1e-12)


def test_estimate_sensor_recovers_an_offset_delay_sensor():
    """Round trip: data made by the model (streamed, with noise) give back its parameters."""
    t, ego, truth = batch_of_two(20.0)
    noise = np.random.default_rng(9).standard_normal((*truth.shape[:2], 2))
    sensor = OffsetDelaySensor(offset=1.2, offset_per_metre=0.006, delay=0.42, position_sd=0.08)
    seen = stream(sensor, ego, truth, noise)
    model = estimate_sensor(t, ego[0], truth[0], seen[0])
    distance = np.hypot(*(truth[0, :, :2] - ego[0]).T)
    design = np.column_stack([np.ones_like(distance), distance])
    se = 0.08 * np.sqrt(np.diag(np.linalg.inv(design.T @ design)))
    assert abs(model.offset - 1.2) < 5 * se[0]
    assert abs(model.offset_per_metre - 0.006) < 5 * se[1]
    assert abs(model.delay - 0.42) <= DT / 2
    assert abs(model.position_sd / 0.08 - 1) < 5 / np.sqrt(4 * len(t))


# -- TrackerSensor ---------------------------------------------------------------------------------


@pytest.mark.parametrize(("window", "dt"), [(1.0, 0.01), (0.5, 0.05), (0.3, 0.1)])
def test_tracker_velocity_is_the_true_one_half_a_window_ago(window, dt):
    """The least-squares slope over a window of samples of a quadratic equals its derivative at
    the window's centre (Σ τ³ = 0 on a symmetric window), so on a constant-acceleration
    trajectory the tracker reports the velocity vector at t − window/2 exactly."""
    t = np.arange(int(round(6.0 / dt)) + 1) * dt
    v0, acc, p0 = np.array([12.0, 1.5]), np.array([-2.0, 0.8]), np.array([40.0, -3.0])
    xy = p0 + np.outer(t, v0) + 0.5 * np.outer(t * t, acc)
    truth = states(xy, v0 + np.outer(t, acc))[None]
    ego = np.zeros((1, len(t), 2))
    sensor = TrackerSensor(offset=0.0, position_sd=0.0, window=window)
    seen = stream(sensor, ego, truth, np.zeros((1, len(t), 2)), dt)
    np.testing.assert_allclose(seen[0, :, :2], xy, rtol=0, atol=1e-12)
    size = int(round(window / dt)) + 1
    filled = np.arange(size - 1, len(t))
    lagged = states(xy[filled], v0 + np.outer(t[filled] - window / 2, acc))
    np.testing.assert_allclose(seen[0, filled, 2], lagged[:, 2], rtol=0, atol=1e-9)
    np.testing.assert_allclose(seen[0, filled, 3], lagged[:, 3], rtol=0, atol=1e-10)
    # before the window is filled the fresh track reports the truth
    np.testing.assert_array_equal(seen[0, :size - 1, 2:], truth[0, :size - 1, 2:])


def test_tracker_offset_makes_the_object_look_farther_by_exactly_the_offset():
    t, ego, truth = batch_of_two()
    seen = stream(TrackerSensor(offset=1.4, position_sd=0.0), ego, truth,
                  np.zeros((*truth.shape[:2], 2)))
    seen_range = np.hypot(*np.moveaxis(seen[..., :2] - ego, -1, 0))
    true_range = np.hypot(*np.moveaxis(truth[..., :2] - ego, -1, 0))
    np.testing.assert_allclose(seen_range - true_range, 1.4, rtol=0, atol=1e-9)
    # and along the line of sight only: the bearing is unchanged
    bearing = np.arctan2(*np.moveaxis(seen[..., 1::-1] - ego[..., ::-1], -1, 0))
    true_bearing = np.arctan2(*np.moveaxis(truth[..., 1::-1] - ego[..., ::-1], -1, 0))
    np.testing.assert_allclose(bearing, true_bearing, rtol=0, atol=1e-12)


def test_tracker_on_the_line_of_sight_keeps_the_lagged_speed_exactly():
    """EGO and object on one line along x: the offset is a constant shift, so the regression
    speed is still the true speed half a window earlier."""
    t = np.arange(601) * DT  # the speed 20 - 3t stays positive
    x = 25.0 + 20.0 * t - 1.5 * t * t
    truth = states(np.column_stack([x, np.zeros_like(t)]),
                   np.column_stack([20.0 - 3.0 * t, np.zeros_like(t)]))[None]
    ego = np.column_stack([10.0 * t, np.zeros_like(t)])[None]
    seen = stream(TrackerSensor(offset=1.4, position_sd=0.0, window=1.0), ego, truth,
                  np.zeros((1, len(t), 2)))
    np.testing.assert_allclose(seen[0, :, 0], x + 1.4, rtol=0, atol=1e-9)
    np.testing.assert_allclose(seen[0, 100:, 2], 20.0 - 3.0 * (t[100:] - 0.5), rtol=0,
                               atol=1e-9)


def test_ideal_sensor_is_the_truth_and_a_copy():
    truth = np.arange(8.0).reshape(2, 4)
    seen = IdealSensor().perceive(None, np.zeros((2, 2)), truth, np.ones((2, 2)))
    np.testing.assert_array_equal(seen, truth)
    seen[0, 0] = -1.0
    assert truth[0, 0] == 0.0


# -- the noise stream: seeded per run, independent of the batch ------------------------------------


def constant(t1, value):
    return Spline(0.0, t1, [value] * 4)


def description(to_start, to_speeds, t1=6.0):
    """EGO at 100 km/h; a slower TO ahead in its lane, decelerating along ``to_speeds``."""
    ego = ObjectTrack(0.0, 0.0, constant(t1, 100 / 3.6), constant(t1, 0.0))
    to = ObjectTrack(to_start, 0.0, Spline(0.0, t1, to_speeds),
                     Spline(0.0, t1, np.zeros(len(to_speeds))))
    return ScenarioDescription({"ego": ego, "to": to}, dt=0.1)


BATCH = [description(60.0, [24.0, 22.0, 15.0, 12.0]),
         description(45.0, [25.0, 25.0, 18.0, 14.0]),
         description(55.0, [26.0, 20.0, 20.0, 10.0])]
NOISY = OffsetDelaySensor(offset=1.0, delay=0.2, position_sd=0.5)


def _ego(record, signal):
    """The EGO's recorded states (runs, steps, 4), acceleration or steering (runs, steps)."""
    if signal == "states":
        return record.ego.states()
    return record.steering if signal == "steering" else record.ego.acceleration


@pytest.mark.parametrize("sensor", [NOISY, TrackerSensor(position_sd=0.3)],
                         ids=["offset-delay", "tracker"])
def test_a_runs_perception_does_not_depend_on_its_batch(sensor):
    names, t = ["to"], np.arange(601) * DT
    common = {"sensor": sensor, "vehicle": "ks", "driver": DriverConfig(), "seed": 7,
              "ego": "ego"}
    batch = simulate_batch(BATCH, names, t, indices=[0, 1, 2], **common)
    alone = simulate_batch(BATCH[1:2], names, t, indices=[1], **common)
    np.testing.assert_array_equal(alone.perceived.states()[0], batch.perceived.states()[1])
    for signal in ("states", "acceleration", "steering"):
        np.testing.assert_array_equal(_ego(alone, signal)[0], _ego(batch, signal)[1])
    # the noise matters: the same description drawn as run 0 is perceived differently
    other = simulate_batch(BATCH[1:2], names, t, indices=[0], **common)
    assert not np.array_equal(other.perceived.states()[0, :, :, :2],
                          alone.perceived.states()[0, :, :, :2])
    # the same through resimulate: run ids follow the indices, values do not depend on the batch
    whole = resimulate(BATCH, sensor=sensor, seed=7, indices=[0, 1, 2])
    single = resimulate(BATCH[1], sensor=sensor, seed=7, indices=[1])
    assert single.run_ids == (whole.run_ids[1],) == ("run_00001",)
    for name, values in single.run(0).items():
        np.testing.assert_array_equal(values, whole.run(1)[name], err_msg=name)


def test_same_seed_same_perception_other_seed_other_perception():
    names, t = ["to"], np.arange(301) * DT
    common = {"sensor": NOISY, "vehicle": "ks", "driver": DriverConfig(), "ego": "ego",
              "indices": [0, 1, 2]}
    first = simulate_batch(BATCH, names, t, seed=3, **common)
    again = simulate_batch(BATCH, names, t, seed=3, **common)
    other = simulate_batch(BATCH, names, t, seed=4, **common)
    np.testing.assert_array_equal(first.perceived.states(), again.perceived.states())
    for signal in ("states", "acceleration", "steering"):
        np.testing.assert_array_equal(_ego(first, signal), _ego(again, signal))
    assert not np.array_equal(first.perceived.states()[..., :2], other.perceived.states()[..., :2])
    # the seed moves only the noise: without noise the seed is irrelevant
    quiet = replace(NOISY, position_sd=0.0)
    a = simulate_batch(BATCH, names, t, seed=3, **{**common, "sensor": quiet})
    b = simulate_batch(BATCH, names, t, seed=4, **{**common, "sensor": quiet})
    np.testing.assert_array_equal(a.perceived.states(), b.perceived.states())


# -- a sensor run over a recording (a model evaluated on another drive) ---------------------------


def test_perceive_recording_is_the_literal_offset_and_delay():
    """Offset along the line of sight on the current position; velocity vector of k samples ago
    (the first one before that), written out from the definitions."""
    t = np.arange(400) * DT
    ego, xy, velocity = ego_xy(t), object_xy(t), object_velocity(t)
    k = 25
    seen = perceive_recording(OffsetDelaySensor(offset=1.4, delay=k * DT), t, ego,
                              states(xy, velocity))
    sight = (xy - ego) / np.hypot(*(xy - ego).T)[:, None]
    np.testing.assert_allclose(seen[:, :2], xy + 1.4 * sight, rtol=0, atol=1e-12)
    late = velocity[np.maximum(np.arange(len(t)) - k, 0)]
    np.testing.assert_allclose(seen[:, 2:], states(xy, late)[:, 2:], rtol=0, atol=1e-12)


def test_perceive_recording_replays_what_the_closed_loop_perceived_without_noise():
    t = np.arange(601) * DT
    truth = scripted_object(CutInScript(), t)
    sensor = TrackerSensor()
    record = run_closed_loop(vehicle_model("ks"), np.array([[0.0, 0.0, 27.0, 0.0]]),
                             truth[None, :, None, :], sensor, ADFunction(), DT,
                             np.zeros((1, len(t), 1, 2)))
    replayed = perceive_recording(sensor, t, record.ego.states()[0, :, :2], truth)
    np.testing.assert_allclose(replayed, record.perceived.states()[0, :, 0], rtol=0, atol=1e-12)
