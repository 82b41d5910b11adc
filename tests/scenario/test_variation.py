"""simcred.scenario.variation: the C² Bézier path, locality, seeded variations, plausibility."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.interpolate import CubicSpline

from simcred.errors import SimcredError
from simcred.kinematics import Track
from simcred.scenario import (
    BezierPath,
    PlausibilityLimits,
    Reason,
    ScenarioDescription,
    VariationOptions,
    VariationStatus,
    check_plausibility,
    fit_track,
    generate_variations,
    influence,
    load_variations,
    vary_one,
)

THRESHOLD = 0.02  # the reprocessing pipeline's fit threshold
SEED = 20190609


def one_line(exc: pytest.ExceptionInfo) -> str:
    message = str(exc.value)
    assert "\n" not in message
    return message


def cut_in_positions(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The TO: 30 m ahead in the left lane at 25 m/s, quintic lane change to y = 0 from 2 s to
    5 s (centre crosses y = 1.75 at 3.5 s), braking at −6 m/s² from 3.2 s down to 10 m/s."""
    braking = np.clip(t - 3.2, 0.0, 15.0 / 6.0)
    x = 30.0 + 25.0 * t - 6.0 * (0.5 * braking**2 + braking * (t - 3.2 - braking))
    u = np.clip((t - 2.0) / 3.0, 0.0, 1.0)
    return x, 3.5 - 3.5 * u**3 * (10 - 15 * u + 6 * u * u)


@pytest.fixture(scope="module")
def description() -> ScenarioDescription:
    t = np.linspace(0.0, 12.0, 1201)
    to = fit_track(t, *cut_in_positions(t), threshold=THRESHOLD, name="to")
    ego = fit_track(t, 27.8 * t, 0.0 * t, threshold=THRESHOLD, name="ego")
    return ScenarioDescription({"ego": ego.track, "to": to.track}, dt=0.1,
                               metadata={"fit": {"threshold": THRESHOLD}})


# -- 1, 2: the Bézier path -------------------------------------------------------------------------


@st.composite
def fix_data(draw):
    n = draw(st.integers(1, 10))
    steps = draw(st.lists(st.floats(0.05, 5.0), min_size=n, max_size=n))
    t0 = draw(st.floats(-100.0, 100.0))
    times = t0 + np.concatenate([[0.0], np.cumsum(steps)])
    coordinate = st.floats(-1e3, 1e3)
    points = np.array(draw(st.lists(st.tuples(coordinate, coordinate), min_size=n + 1,
                                    max_size=n + 1)))
    speed = st.floats(-60.0, 60.0)
    return times, points, np.array(draw(st.tuples(speed, speed))), \
        np.array(draw(st.tuples(speed, speed)))


def one_sided(path: BezierPath, k: int, side: str) -> list[np.ndarray]:
    """Value, first and second derivative at the end (left) or start (right) of section k, from
    the control points by the Bézier derivative formulas (the oracle)."""
    c, h = path.control_points[k], path.times[k + 1] - path.times[k]
    if side == "left":
        return [c[3], 3 * (c[3] - c[2]) / h, 6 * (c[3] - 2 * c[2] + c[1]) / h**2]
    return [c[0], 3 * (c[1] - c[0]) / h, 6 * (c[2] - 2 * c[1] + c[0]) / h**2]


@settings(max_examples=150, deadline=None)
@given(fix_data())
def test_bezier_is_c2_and_meets_the_four_end_conditions(data):
    times, points, v0, v1 = data
    path = BezierPath.through(times, points, v0, v1)
    h = np.diff(times)
    scale = np.abs(points).max() + np.abs(np.concatenate([v0, v1])).max() * h.max() + 1.0
    for k in range(1, path.sections):
        left, right = one_sided(path, k - 1, "left"), one_sided(path, k, "right")
        for order in range(3):
            tolerance = 1e-9 * scale / h.min() ** order
            np.testing.assert_allclose(left[order], right[order], rtol=0, atol=tolerance,
                                       err_msg=f"C{order} at joint {k}")
    velocity = scale / h.min()
    np.testing.assert_allclose(path.derivative(times[:1])[0], v0, rtol=0, atol=1e-9 * velocity)
    np.testing.assert_allclose(path.derivative(times[-1:])[0], v1, rtol=0, atol=1e-9 * velocity)
    # The evaluator agrees with the one-sided formulas and with the clamped cubic spline.
    np.testing.assert_allclose(path.derivative(times[:-1], 2), [one_sided(path, k, "right")[2]
                               for k in range(path.sections)], rtol=0, atol=1e-9 * scale
                               / h.min() ** 2)
    t = np.linspace(times[0], times[-1], 97)
    oracle = CubicSpline(times, points, bc_type=((1, v0), (1, v1)))
    np.testing.assert_allclose(path(t), oracle(t), rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(path.derivative(t), oracle(t, 1), rtol=0, atol=1e-9 * velocity)


@settings(max_examples=100, deadline=None)
@given(fix_data(), st.lists(st.floats(-10.0, 10.0), min_size=8, max_size=8))
def test_bezier_passes_through_fix_points_and_reproduces_cubics(data, coefficients):
    times, points, v0, v1 = data
    path = BezierPath.through(times, points, v0, v1)
    np.testing.assert_array_equal(path(times), points)  # exactly, not approximately
    np.testing.assert_array_equal(path.fix_points, points)
    # p(t) = a + b s + c s² + d s³ per coordinate, s = t − τ_0: closed form.
    a, b, c, d = np.array(coefficients).reshape(4, 2)

    def cubic(t, order=0):
        s = (np.asarray(t) - times[0])[..., None]
        return [a + b * s + c * s**2 + d * s**3, b + 2 * c * s + 3 * d * s**2,
                2 * c + 6 * d * s][order]

    exact = BezierPath.through(times, cubic(times), cubic(times[0], 1), cubic(times[-1], 1))
    span = times[-1] - times[0]
    scale = 10.0 * (1 + span + span**2 + span**3)
    t = np.linspace(times[0], times[-1], 53)
    np.testing.assert_allclose(exact(t), cubic(t), rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(exact.derivative(t, 2), cubic(t, 2), rtol=0,
                               atol=1e-7 * scale / np.diff(times).min() ** 2)


def test_bezier_rejects_bad_input_in_one_line():
    with pytest.raises(SimcredError, match="strictly increasing") as exc:
        BezierPath.through([0.0, 1.0, 1.0], np.zeros((3, 2)), [1, 0], [1, 0])
    one_line(exc)
    with pytest.raises(SimcredError, match=r"points must have shape \(3, 2\)"):
        BezierPath.through([0.0, 1.0, 2.0], np.zeros((2, 2)), [1, 0], [1, 0])
    with pytest.raises(SimcredError, match="finite"):
        BezierPath.through([0.0, 1.0], np.zeros((2, 2)), [np.nan, 0], [1, 0])
    path = BezierPath.through([0.0, 1.0], np.zeros((2, 2)), [1, 0], [1, 0])
    with pytest.raises(SimcredError, match="outside the path's span"):
        path([1.5])
    with pytest.raises(SimcredError, match="order must be 1, 2 or 3"):
        path.derivative([0.5], 0)


# -- 3: locality ----------------------------------------------------------------------------------


def test_influence_decays_by_about_two_minus_sqrt3_per_section():
    profile = influence(np.arange(21.0), 10)
    assert profile[0] == pytest.approx(1.0)
    ratios = profile[1:6] / profile[:5]
    assert np.all(ratios < 0.35), ratios
    # Far from the displaced point (and from the clamped ends) the ratio is 2 − √3.
    np.testing.assert_allclose(ratios[1:], 2 - math.sqrt(3), atol=0.01)


@settings(max_examples=40, deadline=None)
@given(fix_data(), st.data())
def test_influence_is_the_change_of_the_path(data, draw):
    times, points, v0, v1 = data
    if len(times) < 3:
        return
    index = draw.draw(st.integers(1, len(times) - 2))
    moved = points.copy()
    moved[index] += [0.6, -0.8]  # a unit vector
    change = BezierPath.through(times, moved, v0, v1)
    base = BezierPath.through(times, points, v0, v1)
    profile = influence(times, index, samples=17)
    for k in range(len(times) - 1):
        t = np.linspace(times[k], times[k + 1], 17)
        distance = index - 1 - k if k < index else k - index
        deviation = np.hypot(*(change(t) - base(t)).T).max()
        scale = np.abs(points).max() + 1.0
        assert deviation <= profile[distance] + 1e-9 * scale


def test_refitted_variation_stays_local(description):
    reference = vary_one(description, 0, SEED, displacements=np.zeros((4, 2)))
    displacements = np.zeros((4, 2))
    displacements[1] = [0.0, 0.3]  # fix point 3 (t = 3 s), 0.3 m to the left
    variation = vary_one(description, 0, SEED, displacements=displacements)
    t = np.linspace(0.0, 12.0, 1201)
    before = np.column_stack(description.objects["to"].positions(t))
    after = np.column_stack(variation.description.objects["to"].positions(t))
    deviation = np.hypot(*(after - before).T)
    section = np.minimum(np.floor(t).astype(int), 11)
    distance = np.where(section < 3, 2 - section, section - 3)
    measured = np.array([deviation[distance == d].max() for d in range(distance.max() + 1)])
    path = 0.3 * influence(reference.path.times, 3, samples=101)
    np.testing.assert_allclose(measured[:len(path)], path, atol=0.005)
    assert np.all(measured[3:] < 0.01)


# -- 4: zero displacement --------------------------------------------------------------------------


@pytest.mark.parametrize("options", [VariationOptions(),
                                     VariationOptions(section=0.5, keep_residual=False)])
def test_zero_displacement_reproduces_the_description(description, options):
    t = description.times()
    variation = vary_one(description, 3, SEED, options=options,
                         displacements=np.zeros((4, 2)))
    assert variation.kept and variation.record.reasons == ()
    original = np.column_stack(description.objects["to"].positions(t))
    varied = np.column_stack(variation.description.objects["to"].positions(t))
    rmse = math.sqrt(np.mean(np.sum((varied - original) ** 2, axis=1)))
    assert rmse <= THRESHOLD
    assert variation.record.rmse <= THRESHOLD
    ego_before, ego_after = description.objects["ego"], variation.description.objects["ego"]
    assert ego_after is ego_before
    # The crossing (3.5 s) sits between fix points 3 and 4: 2 before, 2 after.
    plan = generate_variations(description, 1, SEED, options=options)
    assert plan.crossing_time == pytest.approx(3.5, abs=0.01)
    assert plan.varied == ((2, 3, 4, 5) if options.section == 1.0 else (6, 7, 8, 9))


# -- 5: determinism --------------------------------------------------------------------------------


def same(a, b) -> bool:
    ta, tb = a.description.objects["to"], b.description.objects["to"]
    return (np.array_equal(a.displacements, b.displacements)
            and np.array_equal(ta.speed.coefficients, tb.speed.coefficients)
            and np.array_equal(ta.heading.coefficients, tb.heading.coefficients)
            and a.record.status is b.record.status)


def test_variation_i_does_not_depend_on_n_batching_or_order(description):
    five = generate_variations(description, 5, SEED)
    ten = generate_variations(description, 10, SEED, chunk_size=3)
    assert five.seed == ten.seed == SEED
    by_index = {v.index: v for v in ten.variations}
    for variation in five.variations:
        assert same(variation, by_index[variation.index])
    for i in (4, 1):  # any order, one at a time
        alone = vary_one(description, i, SEED)
        assert np.array_equal(alone.displacements, ten.records[i].displacements)
        if alone.kept:
            assert same(alone, by_index[i])
    assert [r.index for r in ten.records] == list(range(10))
    assert five.to_json() == generate_variations(description, 5, SEED).to_json()


def test_different_seeds_and_indices_differ(description):
    a, b = vary_one(description, 0, SEED), vary_one(description, 0, SEED + 1)
    c = vary_one(description, 1, SEED)
    assert not np.allclose(a.displacements, b.displacements)
    assert not np.allclose(a.displacements, c.displacements)
    assert not np.allclose(a.description.objects["to"].heading.coefficients,
                           b.description.objects["to"].heading.coefficients)


def test_displacements_follow_the_truncated_normal(description):
    options = VariationOptions(sigma_lon=0.3, sigma_lat=0.3, truncation=2.0)
    result = generate_variations(description, 1, SEED, options=options)
    from simcred.scenario import draw_displacements

    z = np.concatenate([draw_displacements(SEED, i, 4, options) for i in range(2000)]) / 0.3
    assert np.abs(z).max() <= 2.0
    # Std of N(0, 1) truncated at ±2: 0.8796; mean 0; the columns are independent.
    assert np.std(z) == pytest.approx(0.8796, abs=0.02)
    assert abs(np.mean(z)) < 0.03
    assert abs(np.corrcoef(z[:, 0], z[:, 1])[0, 1]) < 0.05
    assert result.records[0].displacements.shape == (4, 2)


# -- 6: plausibility -------------------------------------------------------------------------------


def states_from_positions(t, x, y) -> Track:
    vx, vy = np.gradient(x, t), np.gradient(y, t)
    v, heading = np.hypot(vx, vy), np.unwrap(np.arctan2(vy, vx))
    return Track(t=t, x=x, y=y, v=v, heading=heading, acceleration=np.gradient(v, t),
                       yaw_rate=np.gradient(heading, t))


def test_a_lateral_jump_is_rejected_and_a_smooth_lane_change_passes(description):
    t = np.linspace(0.0, 4.0, 401)
    y = np.clip((t - 2.0) / 0.2, 0.0, 1.0) * 3.0  # 3 m to the left within 0.2 s
    reasons = check_plausibility(states_from_positions(t, 25.0 * t, y))
    assert Reason.HEADING_JUMP in reasons and Reason.YAW_RATE in reasons
    assert Reason.LATERAL_ACCELERATION in reasons
    smooth = states_from_positions(t, *cut_in_positions(t))
    assert check_plausibility(smooth) == []
    assert check_plausibility(description.objects["to"]) == []


def test_each_limit_names_its_reason():
    t = np.linspace(0.0, 1.0, 11)
    ones = np.ones_like(t)

    def states(v=20.0, heading=0.0, acceleration=0.0, yaw_rate=0.0):
        return Track(t=t, x=t, y=t, v=v * ones, heading=heading * ones,
                           acceleration=acceleration * ones, yaw_rate=yaw_rate * ones)

    assert check_plausibility(states(acceleration=-9.5)) == [Reason.LONGITUDINAL_ACCELERATION]
    assert check_plausibility(states(acceleration=4.5)) == [Reason.LONGITUDINAL_ACCELERATION]
    assert check_plausibility(states(yaw_rate=0.4)) == [Reason.LATERAL_ACCELERATION]
    assert check_plausibility(states(v=2.0, yaw_rate=0.45)) == [Reason.CURVATURE]
    assert check_plausibility(states(v=0.5, yaw_rate=0.45)) == []  # too slow for curvature
    assert check_plausibility(states(v=1.0, yaw_rate=0.6)) == [Reason.YAW_RATE]
    jump = states()
    jump.v[5:] += 2.0
    assert check_plausibility(jump) == [Reason.SPEED_JUMP]
    assert check_plausibility(states(), rmse=0.2) == [Reason.REFIT_RMSE]
    assert check_plausibility(states(), rmse=math.nan) == [Reason.REFIT_RMSE]
    nan = states()
    nan.acceleration[3] = np.nan
    assert check_plausibility(nan) == [Reason.LONGITUDINAL_ACCELERATION]
    loose = PlausibilityLimits(max_acceleration=5.0)
    assert check_plausibility(states(acceleration=4.5), loose) == []


def test_infeasible_variations_are_rejected_and_counted(description):
    big = np.zeros((4, 2))
    big[2] = [0.0, 3.0]
    variation = vary_one(description, 0, SEED, displacements=big)
    assert not variation.kept and variation.record.status is VariationStatus.REJECTED
    assert Reason.LATERAL_ACCELERATION in variation.record.reasons
    wild = generate_variations(description, 12, SEED,
                               options=VariationOptions(sigma_lon=2.0, sigma_lat=1.5))
    assert wild.rejected > 0 and wild.generated == wild.kept + wild.rejected == 12
    assert len(wild.variations) == wild.kept
    assert all(v.kept and not v.record.reasons for v in wild.variations)
    for reason, count in wild.rejections.items():
        assert count == sum(Reason(reason) in r.reasons for r in wild.records) > 0
    assert all(bool(r.reasons) == (r.status is VariationStatus.REJECTED) for r in wild.records)
    assert sum(wild.rejections.values()) >= wild.rejected
    assert wild.original_reasons == ()


# -- JSON ------------------------------------------------------------------------------------------


def test_json_is_deterministic_exact_and_loads_back(description, tmp_path):
    result = generate_variations(description, 6, SEED,
                                 options=VariationOptions(sigma_lon=1.0, sigma_lat=0.6))
    text = result.to_json()
    document = json.loads(text)
    assert document["kind"] == "variation_set" and document["seed"] == SEED
    assert document["generated"] == 6 and document["kept"] == result.kept
    for record, entry in zip(result.records, document["records"], strict=True):
        assert np.array_equal(np.array(entry["displacements"]), record.displacements)
        assert entry["status"] == record.status.value
        assert ("track" in entry) == (record.status is VariationStatus.KEPT)
    loaded = load_variations(result.write(tmp_path / "variations.json"))
    assert sorted(loaded) == [v.index for v in result.variations]
    for variation in result.variations:
        assert loaded[variation.index].equals(variation.description)
    with pytest.raises(SimcredError, match="not a variations document") as exc:
        load_variations(description.to_dict())
    one_line(exc)


def test_unseeded_set_records_its_entropy(description):
    result = generate_variations(description, 2, None)
    replay = generate_variations(description, 2, result.seed)
    assert result.to_json() == replay.to_json()


# -- validation ------------------------------------------------------------------------------------


@pytest.mark.parametrize(("call", "message"), [
    (lambda d: generate_variations(d, 0, 1), "n must be an integer >= 1"),
    (lambda d: generate_variations(d, 2, -1), "seed must be an integer >= 0"),
    (lambda d: generate_variations(d, 2, np.random.default_rng(1)), "integer seed"),
    (lambda d: vary_one(d, -1, 1), "index must be an integer >= 0"),
    (lambda d: vary_one(d, 0, 1, to="bus"), "to object 'bus' is not in the description"),
    (lambda d: vary_one(d, 0, 1, ego="to"), "to and ego must be different"),
    (lambda d: vary_one(d, 0, 1, displacements=np.zeros((3, 2))),
     r"displacements must have shape \(4, 2\)"),
    (lambda d: vary_one(d, 0, 1, options=VariationOptions(boundary_y=10.0)),
     "never crosses the lane boundary y = 10.0"),
    (lambda d: vary_one(d, 0, 1, options=VariationOptions(section=20.0)),
     "no inner fix point"),
    (lambda d: VariationOptions(section=0.0), "section must be a finite number > 0"),
    (lambda d: VariationOptions(window=0), "window must be an integer >= 1"),
    (lambda d: VariationOptions(sigma_lat=-1.0), "sigma_lat must be a finite number >= 0"),
    (lambda d: PlausibilityLimits(min_acceleration=1.0), "min_acceleration must be < 0"),
    (lambda d: PlausibilityLimits(max_yaw_rate=math.inf), "max_yaw_rate must be a finite"),
])
def test_bad_input_gives_one_line_errors(description, call, message):
    with pytest.raises(SimcredError, match=message) as exc:
        call(description)
    one_line(exc)


def test_crossing_time_and_boundary_options(description):
    by_boundary = generate_variations(description, 1, 1,
                                      options=VariationOptions(boundary_y=3.0))
    assert by_boundary.crossing_time < 3.0 and by_boundary.boundary_y == 3.0
    assert by_boundary.varied == (1, 2, 3, 4)
    metadata = {**description.metadata, "road": {"boundary_y": 3.0}}
    from_metadata = ScenarioDescription(description.objects, dt=description.dt,
                                        metadata=metadata)
    assert generate_variations(from_metadata, 1, 1).crossing_time == by_boundary.crossing_time
    given_time = generate_variations(description, 1, 1,
                                     options=VariationOptions(crossing_time=6.0, window=1))
    assert given_time.varied == (6, 7) and given_time.boundary_y is None
    assert given_time.threshold == THRESHOLD
