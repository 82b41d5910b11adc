"""simcred.risk against oracles: closed-form latest brake start, TTC/THW, shapely, properties."""

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from simcred.errors import OptionError, SimcredError
from simcred.risk import (
    EvasionSet,
    Lanes,
    Prediction,
    PredictionSet,
    ReactionTime,
    VehicleStates,
    max_risk,
    risk,
    risk_series,
    time_headway,
    time_to_collision,
)
from simcred.risk import ttr as ttr_module

LENGTH = 4.5
DT = 0.1
HORIZON = 10.0


# -- closed form: EGO brakes behind a TO braking to standstill ----------------------------------

def plan_collision_time(d, v_e, v_o, a_o):
    """First time the unbraked EGO (v_e) touches the TO (v_o, braking at a_o to standstill)."""
    t_o = v_o / -a_o
    # while the TO moves: d - (v_e - v_o) t + a_o t²/2 = 0 (a_o < 0), positive root
    dv = v_e - v_o
    t = (math.sqrt(dv * dv - 2 * a_o * d) - dv) / -a_o
    if t <= t_o:
        return t
    return (d + v_o * v_o / (2 * -a_o)) / v_e          # after the TO stopped


def latest_brake_start(d, v_e, v_o, a_o, a_e):
    """Closed-form latest start s* of braking at a_e that avoids the TO; < 0 if none.

    g(s) = d - Δv s + a_o s²/2 is the gap and w(s) = Δv - a_o s the closing speed when braking
    starts (Δv = v_e - v_o > 0). Case 2, speeds equalise while the TO still moves (needs
    Δa = a_o - a_e > 0 and t_m = s + w/Δa <= t_o): the gap then still shrinks by w²/(2Δa), so
    f(s) = g(s) - w(s)²/(2Δa) = 0, a concave quadratic decreasing on s >= 0, larger root:
        -a_o a_e / (2Δa) s² ... expanded below as A s² + B s + C = 0.
    Case 1, the minimum gap is at standstill of both: d + v_o²/(2|a_o|) = v_e s + v_e²/(2|a_e|).
    """
    t_o = v_o / -a_o
    dv = v_e - v_o
    s1 = (d + v_o * v_o / (2 * -a_o) - v_e * v_e / (2 * -a_e)) / v_e
    da = a_o - a_e
    if da <= 0:
        return s1
    a = a_o / 2 - a_o * a_o / (2 * da)
    b = -dv + dv * a_o / da
    c = d - dv * dv / (2 * da)
    if c <= 0:                                   # f(0) <= 0
        return s1 if dv / da > t_o else -1.0     # case 1 at s = 0, else unavoidable
    s2 = (-b - math.sqrt(b * b - 4 * a * c)) / (2 * a)   # larger root (a < 0)
    return s2 if s2 + (dv - a_o * s2) / da <= t_o else s1


def brake_only(a_o, a_e, steps=4):
    return (PredictionSet((Prediction("brake", 1.0, acceleration=a_o),), horizon=HORIZON, dt=DT),
            EvasionSet(maneuvers=("brake",), brake_acceleration=a_e, bisection_steps=steps))


def lead_scenes(d, v_e, v_o, y_o=0.0):
    d, v_e, v_o, y_o = np.broadcast_arrays(*(np.atleast_1d(np.asarray(a, float))
                                             for a in (d, v_e, v_o, y_o)))
    ego = VehicleStates(x=np.zeros(d.size), y=0.0, v=v_e, heading=0.0, name="ego")
    to = VehicleStates(x=d + LENGTH, y=y_o, v=v_o, heading=0.0, name="to")
    return ego, to


def expected_ttr(d, v_e, v_o, a_o, a_e):
    """Oracle TTR, or None where the horizon cuts the collisions it relies on."""
    t_c = plan_collision_time(d, v_e, v_o, a_o)
    if t_c > HORIZON + 0.5:
        return math.inf
    ttr = max(latest_brake_start(d, v_e, v_o, a_o, a_e), 0.0)
    # a later start must still collide visibly: before the EGO's standstill, within the horizon
    return ttr if t_c < HORIZON - 0.5 and ttr + v_e / -a_e < HORIZON - 0.2 else None


def sampling_slack(v_e, v_o, a_o, a_e):
    """How far a sampled check may overestimate the TTR: a dip of the gap between samples is at
    most |Δa| (dt/2)²/2 deep, and the minimum gap falls at >= Δv per second of later start."""
    return 0.5 * abs(a_o - a_e) * (DT / 2) ** 2 / (v_e - v_o) + 1e-9


@pytest.mark.parametrize("a_e", [-8.0, -6.0])
@pytest.mark.parametrize("a_o", [-2.0, -4.0, -6.0, -8.0])
def test_ttr_equals_closed_form_latest_brake_start(a_o, a_e):
    grid = np.array(np.meshgrid([2.0, 10.0, 25.0, 40.0], [20.0, 27.8, 33.0],
                                [0.0, 5.0, 12.0, 18.0])).reshape(3, -1)
    grid = grid[:, grid[1] - grid[2] >= 2.0]
    oracle = [expected_ttr(*case, a_o, a_e) for case in grid.T]
    keep = [e is not None for e in oracle]
    assert np.mean(keep) > 0.8
    d, v_e, v_o = grid[:, keep]
    expected = np.array([e for e in oracle if e is not None])
    predictions, evasion = brake_only(a_o, a_e)
    result = risk(*lead_scenes(d, v_e, v_o), predictions=predictions, evasion=evasion)
    got = result.ttr[:, 0, 0]
    slack = np.array([sampling_slack(ve, vo, a_o, a_e) for ve, vo in zip(v_e, v_o, strict=True)])
    assert result.resolution == DT / 16
    finite = np.isfinite(expected)
    assert finite.sum() >= 0.6 * finite.size          # the oracle is exercised
    np.testing.assert_array_equal(np.isfinite(got), finite)
    assert np.all(got[finite] <= expected[finite] + slack[finite])
    assert np.all(got[finite] > expected[finite] - result.resolution - 1e-9)
    t_c = np.array([plan_collision_time(*case, a_o) for case in zip(d, v_e, v_o, strict=True)])
    sampled = result.collision_time[finite, 0, 0]
    assert np.all((sampled >= t_c[finite] - 1e-9) & (sampled < t_c[finite] + DT + 1e-9))
    # both regimes of the oracle occur: TTR 0 and TTR > 0
    assert (expected[finite] == 0).any() and (expected[finite] > 0.5).any()


@settings(max_examples=40, deadline=None)
@given(d=st.floats(1.0, 60.0), v_e=st.floats(8.0, 40.0), dv=st.floats(2.0, 30.0),
       a_o=st.floats(-9.0, -0.5), a_e=st.floats(-10.0, -4.0))
def test_ttr_equals_closed_form_random(d, v_e, dv, a_o, a_e):
    v_o = v_e - dv
    assume(v_o >= 0)
    expected = expected_ttr(d, v_e, v_o, a_o, a_e)
    assume(expected is not None)
    predictions, evasion = brake_only(a_o, a_e)
    got = risk(*lead_scenes(d, v_e, v_o), predictions=predictions, evasion=evasion).ttr[0, 0, 0]
    if math.isinf(expected):
        assert got == math.inf
    else:
        assert expected - DT / 16 - 1e-9 < got <= expected + sampling_slack(v_e, v_o, a_o, a_e)


def test_bisection_refines_the_grid_value():
    predictions, coarse = brake_only(-4.0, -8.0, steps=0)
    scenes = lead_scenes(np.linspace(5, 40, 15), 30.0, 15.0)
    grid = risk(*scenes, predictions=predictions, evasion=coarse).ttr[:, 0, 0]
    fine = risk(*scenes, predictions=predictions, evasion=brake_only(-4.0, -8.0, 6)[1]).ttr[:, 0, 0]
    np.testing.assert_allclose(grid / DT, np.round(grid / DT), atol=1e-9)
    assert np.all((grid <= fine) & (fine < grid + DT))


# -- collision check vs shapely ---------------------------------------------------------------

def test_separating_axis_test_agrees_with_shapely():
    from shapely.geometry import Polygon

    rng = np.random.default_rng(3)
    n = 3000
    a = (np.zeros(n), np.zeros(n), rng.uniform(-1.4, 1.4, n), rng.uniform(1, 6, n),
         rng.uniform(0.5, 3, n))
    b = (rng.uniform(-7, 7, n), rng.uniform(-5, 5, n), rng.uniform(-np.pi, np.pi, n),
         rng.uniform(1, 6, n), rng.uniform(0.5, 3, n))

    def rect(x, y, h, length, width):
        c, s = np.cos(h), np.sin(h)
        corners = [(sx * length / 2, sy * width / 2) for sx, sy in
                   ((1, 1), (-1, 1), (-1, -1), (1, -1))]
        return Polygon([(x + c * u - s * v, y + s * u + c * v) for u, v in corners])

    expected = np.array([rect(*(p[i] for p in a)).intersects(rect(*(p[i] for p in b)))
                         for i in range(n)])

    def sat(p):
        return (p[0], p[1], np.cos(p[2]), np.sin(p[2]), p[3] / 2, p[4] / 2)

    got = ttr_module.rectangles_overlap(sat(a), sat(b))
    assert 0.2 < expected.mean() < 0.8
    np.testing.assert_array_equal(got, expected)


# -- TTC and THW ------------------------------------------------------------------------------

def test_ttc_and_thw_closed_forms():
    rng = np.random.default_rng(11)
    n = 500
    v_e, v_o = rng.uniform(0, 40, n), rng.uniform(0, 40, n)
    gap = rng.uniform(0.5, 80, n)
    y_o = rng.uniform(-1.7, 1.7, n)                    # laterally overlapping (widths 1.8)
    ego, to = lead_scenes(gap, v_e, v_o, y_o)
    closing = v_e - v_o
    np.testing.assert_allclose(time_headway(ego, to), gap / v_e, rtol=1e-12)
    np.testing.assert_allclose(time_to_collision(ego, to),
                               np.where(closing > 0, gap / np.where(closing > 0, closing, 1),
                                        np.inf), rtol=1e-12)


def test_ttc_and_thw_take_the_lead_in_lane():
    ego = VehicleStates(x=[0.0, 0.0, 0.0], y=0.0, v=20.0, heading=0.0, width=2.0)
    objects = VehicleStates(
        x=[[30.0, 60.0, 15.0], [-20.0, 100.0, 50.0], [2.0, 80.0, 80.0]],
        y=[[0.5, 0.0, 3.5], [0.0, 3.5, -3.0], [0.0, 10.0, 10.0]],
        v=[[10.0, 0.0, 0.0], [30.0, 0.0, 0.0], [25.0, 0.0, 0.0]], heading=0.0, width=2.0)
    # lead gaps: 25.5 (the car 15 m ahead is in the next lane); no lead; touching (gap 0)
    np.testing.assert_allclose(time_headway(ego, objects), [25.5 / 20, np.inf, 0.0])
    np.testing.assert_allclose(time_to_collision(ego, objects), [25.5 / 10, np.inf, 0.0])
    assert time_to_collision(*lead_scenes(20.0, 20.0, 25.0))[0] == np.inf   # opening gap


# -- properties of the risk -------------------------------------------------------------------

def test_no_object_nearby_means_no_risk():
    ego = VehicleStates(x=np.zeros(3), y=0.0, v=27.8, heading=0.0)
    far = VehicleStates(x=[[600.0, -300.0], [-100.0, 700.0], [0.0, 500.0]],
                        y=[[0.0, 0.0], [0.0, 3.5], [-7.0, 7.0]], v=27.8, heading=0.0)
    result = risk(ego, far)
    assert result.ttr.shape == (3, 2, 7 + PredictionSet().acceleration_nodes)
    assert np.all(result.ttr == np.inf) and np.all(result.risk == 0)
    assert np.all(result.ttr_min == np.inf) and np.all(result.maneuver == -1)
    assert np.all(result.dominant_object == -1) and np.all(result.dominant_maneuver == -1)


def test_risk_does_not_decrease_as_the_gap_shrinks():
    gaps = np.linspace(2.0, 90.0, 89)
    result = risk(*lead_scenes(gaps, 27.8, 18.0))
    assert np.all(np.diff(result.risk) <= 1e-15)
    assert np.all(np.diff(result.ttr_min) >= -1e-12)
    assert result.risk[0] > 0.5 and result.risk[-1] < 1e-3


def test_adjacent_lane_object_keeping_its_lane_does_not_collide():
    keep_and_brake = PredictionSet((Prediction("keep", 0.5), Prediction("brake", 0.5, -8.0)))
    scenes = lead_scenes(np.linspace(-10.0, 40.0, 11), 27.8, 10.0, y_o=3.5)
    result = risk(*scenes, predictions=keep_and_brake)
    assert np.all(result.ttr == np.inf) and np.all(result.risk == 0)
    default = risk(*scenes)
    names = default.prediction_names
    keep = [i for i, name in enumerate(names) if name.startswith("keep[")]
    assert len(keep) == PredictionSet().acceleration_nodes
    assert np.all(default.ttr[..., keep] == np.inf)
    assert np.all(default.ttr[..., names.index("lane-change-left")] == np.inf)
    assert np.isfinite(default.ttr[..., names.index("lane-change-right")]).any()  # cut-in


def test_mirroring_swaps_left_and_right():
    rng = np.random.default_rng(5)
    n = 300
    ego = dict(x=0.0, y=rng.uniform(-0.5, 0.5, n), v=rng.uniform(15, 35, n),
               heading=rng.uniform(-0.03, 0.03, n), acceleration=rng.uniform(-1, 1, n))
    to = dict(x=rng.uniform(5, 60, n), y=rng.uniform(-4, 4, n), v=rng.uniform(5, 30, n),
              heading=rng.uniform(-0.08, 0.08, n), yaw_rate=rng.uniform(-0.05, 0.05, n),
              acceleration=rng.uniform(-3, 1, n))

    def mirrored(d):
        return {k: -v if k in ("y", "heading", "yaw_rate") else v for k, v in d.items()}

    a = risk(VehicleStates(**ego), VehicleStates(**to))
    b = risk(VehicleStates(**mirrored(ego)), VehicleStates(**mirrored(to)))
    names = list(a.prediction_names)
    swap = [names.index(n.replace("left", "@").replace("right", "left").replace("@", "right"))
            for n in names]
    np.testing.assert_allclose(b.ttr, a.ttr[..., swap], rtol=0, atol=1e-12)
    np.testing.assert_allclose(b.risk, a.risk, rtol=1e-12, atol=1e-15)
    # codes: brake 0, left 1, right 2; ties go to the first, so "right" in a means left failed
    ma, mb = a.maneuver[..., swap], b.maneuver
    np.testing.assert_array_equal(mb <= 0, ma <= 0)
    np.testing.assert_array_equal(mb[ma <= 0], ma[ma <= 0])
    assert np.all(mb[ma == 2] == 1) and np.all(mb[ma == 1] >= 1)
    assert np.isfinite(a.ttr).mean() > 0.2 and (a.maneuver > 0).any()


def test_steering_avoids_what_braking_cannot():
    scenes = lead_scenes(40.0, 27.8, 0.0)             # standing car: braking needs 48 m
    predictions = PredictionSet((Prediction("stand", 1.0),))
    both = risk(*scenes, predictions=predictions)
    brake = risk(*scenes, predictions=predictions, evasion=EvasionSet(maneuvers=("brake",)))
    assert brake.ttr[0, 0, 0] == 0 and brake.maneuver[0, 0, 0] == -1
    assert 0.2 < both.ttr[0, 0, 0] < 1.0
    assert both.maneuver_names[both.maneuver[0, 0, 0]] == "left"
    assert both.risk[0] == pytest.approx(ReactionTime().accident_probability(both.ttr[0, 0, 0]))


def test_keep_prediction_continues_the_current_acceleration():
    ego, _ = lead_scenes([10.0, 30.0], 27.8, 20.0)
    to = VehicleStates(x=[14.5, 34.5], y=0.0, v=20.0, heading=0.0, acceleration=-4.0)
    for predictions, keep in ((PredictionSet(acceleration_sigma=0.0), "keep"),
                              (PredictionSet(), "keep[+0.00]")):
        result = risk(ego, to, predictions=predictions)
        names = result.prediction_names
        np.testing.assert_array_equal(result.ttr[..., names.index(keep)],
                                      result.ttr[..., names.index("brake-4")])
        assert result.maneuver_names[result.dominant_maneuver[1]] in result.maneuver_names


def test_overlap_now_means_ttr_zero_and_risk_from_priors():
    result = risk(*lead_scenes(-1.0, 27.8, 20.0))      # rectangles overlap at the scene
    assert np.all(result.ttr == 0) and np.all(result.collision_time == 0)
    assert result.risk[0] == pytest.approx(1.0)


def test_cut_in_scene_and_dominant_prediction():
    # slower TO 25 m ahead drifting from the left lane into the EGO's at 1 m/s
    v_o = 18.0
    ego = VehicleStates(x=[0.0], y=0.0, v=27.8, heading=0.0, name="ego")
    to = VehicleStates(x=[29.5], y=2.2, v=v_o, heading=math.asin(-1.0 / v_o), name="to")
    result = risk(ego, to)
    names = result.prediction_names
    keep = names.index("keep[+0.00]")
    assert np.isfinite(result.ttr[0, 0, keep])          # keep = complete the cut-in
    assert result.ttr[0, 0, names.index("lane-change-left")] == np.inf   # abort: back left
    assert result.dominant_object[0] == 0
    assert result.contribution[0, 0, result.dominant_prediction[0]] == result.contribution.max()


def test_chunks_and_series_give_the_same_result(monkeypatch):
    rng = np.random.default_rng(9)
    n = 200
    cols = {"ego.x": np.zeros(n), "ego.y": np.zeros(n), "ego.v": rng.uniform(20, 30, n),
            "ego.heading": np.zeros(n), "t": np.arange(n) * 0.1}
    for name in ("a", "b"):
        cols |= {f"{name}.x": rng.uniform(-20, 60, n), f"{name}.y": rng.uniform(-4, 4, n),
                 f"{name}.v": rng.uniform(5, 30, n), f"{name}.heading": np.zeros(n),
                 f"{name}.a": rng.uniform(-3, 0, n)}
    series = risk_series(cols, objects=("a", "b"))
    objects = VehicleStates(**{f: np.stack([cols[f"{o}.{f[0] if f == 'acceleration' else f}"]
                                            for o in "ab"], axis=1)
                               for f in ("x", "y", "v", "heading", "acceleration")})
    ego = VehicleStates(x=cols["ego.x"], y=0.0, v=cols["ego.v"], heading=0.0)
    monkeypatch.setattr(ttr_module, "_CHUNK_SAMPLES", 1000)  # chunks of 2 scenes
    chunked = risk(ego, objects)
    np.testing.assert_array_equal(series.ttr, chunked.ttr)
    np.testing.assert_array_equal(series.risk, chunked.risk)
    per_object = series.risk_per_object
    np.testing.assert_allclose(series.risk, 1 - (1 - per_object[:, 0]) * (1 - per_object[:, 1]))
    assert np.isfinite(series.ttr).mean() > 0.1


def _random_scenes(seed, n):
    rng = np.random.default_rng(seed)
    ego = VehicleStates(x=np.zeros(n), y=0.0, v=rng.uniform(20, 30, n), heading=0.0,
                        acceleration=rng.uniform(-1, 1, n), name="ego")
    objects = VehicleStates(**{"x": rng.uniform(-20, 60, (n, 2)), "y": rng.uniform(-4, 4, (n, 2)),
                               "v": rng.uniform(5, 30, (n, 2)), "heading": np.zeros((n, 2)),
                               "acceleration": rng.uniform(-3, 0, (n, 2))}, name="objects")
    return ego, objects


@pytest.mark.parametrize("coarse", [1, 3, 5, 500])
def test_max_risk_equals_the_maximum_of_risk_bit_for_bit(coarse):
    for seed, n in ((1, 60), (2, 7), (3, 1)):
        ego, objects = _random_scenes(seed, n)
        assert max_risk(ego, objects, coarse=coarse) == float(risk(ego, objects).risk.max())


def test_max_risk_with_a_one_scene_peak():
    """A peak one scene wide between coarse scenes: found (the neighbours of the riskiest
    coarse scene, then every scene whose bound reaches the floor)."""
    n = 40
    ego = VehicleStates(x=np.zeros(n), y=0.0, v=27.8, heading=0.0, name="ego")
    x = np.full(n, 150.0)
    x[17] = 25.0                                     # one close scene, not on the coarse grid
    x[30] = 60.0
    to = VehicleStates(x=x, y=0.0, v=20.0, heading=0.0, name="to")
    full = risk(ego, to).risk
    assert full.argmax() == 17 and full.max() > 0
    assert max_risk(ego, to, coarse=5) == float(full.max())


def test_max_risk_of_groups_is_each_groups_maximum():
    """sizes: consecutive groups of scenes (a campaign's runs in one call), one maximum each,
    the same as one call per group."""
    ego, objects = _random_scenes(4, 50)
    sizes = [12, 1, 30, 7]
    full = risk(ego, objects).risk
    bounds = np.cumsum([0] + sizes)
    grouped = max_risk(ego, objects, sizes=sizes)
    expected = [full[a:b].max() for a, b in zip(bounds[:-1], bounds[1:], strict=True)]
    np.testing.assert_array_equal(grouped, expected)
    with pytest.raises(OptionError, match="sizes"):
        max_risk(ego, objects, sizes=[10, 10])


def test_max_risk_rejects_a_bad_coarse_step():
    ego, objects = _random_scenes(1, 3)
    with pytest.raises(OptionError, match="coarse"):
        max_risk(ego, objects, coarse=0)


def test_reaction_time_mapping():
    g = ReactionTime(median=1.2, sigma=0.4).accident_probability
    assert g(0.0) == 1 and g(np.inf) == 0 and g(1.2) == pytest.approx(0.5)
    ttr = np.linspace(0, 6, 50)
    assert np.all(np.diff(g(ttr)) <= 0)


# -- validation: one-line errors --------------------------------------------------------------

@pytest.mark.parametrize("make, match", [
    (lambda: PredictionSet((Prediction("a", 0.5), Prediction("b", 0.4))), "sum to 1"),
    (lambda: Prediction("a", 1.2), "probability"),
    (lambda: Prediction("a", 1.0, lane_change=2), "lane_change"),
    (lambda: PredictionSet((Prediction("a", 0.5), Prediction("a", 0.5))), "unique"),
    (lambda: PredictionSet(horizon=5.0, dt=0.3), "integer"),
    (lambda: PredictionSet(dt=-0.1), "dt must be > 0"),
    (lambda: EvasionSet(maneuvers=("brake", "jump")), "maneuvers"),
    (lambda: EvasionSet(brake_acceleration=2.0), "brake_acceleration"),
    (lambda: Lanes(width=0.0), "lanes.width"),
    (lambda: ReactionTime(sigma=0.0), "sigma"),
])
def test_bad_configs_raise_one_line_option_errors(make, match):
    with pytest.raises(OptionError, match=match) as info:
        make()
    assert "\n" not in str(info.value)


def test_bad_states_raise_one_line_errors():
    ego, to = lead_scenes([10.0, 20.0, 30.0], 27.8, 20.0)
    cases = [
        (lambda: VehicleStates(x=[0.0, np.nan], y=0.0, v=1.0, heading=0.0, name="to"),
         r"to\.x\[1\] must be finite"),
        (lambda: VehicleStates(x=0.0, y=0.0, v=np.inf, heading=0.0, name="ego"), r"ego\.v"),
        (lambda: VehicleStates(x=0.0, y=0.0, v=1.0, heading=0.0, width=0.0), "width"),
        (lambda: VehicleStates(x=[0.0, 1.0], y=[0.0, 1.0, 2.0], v=1.0, heading=0.0),
         "broadcast"),
        (lambda: VehicleStates(x=np.zeros((2, 2, 2)), y=0.0, v=1.0, heading=0.0), "2-D"),
        (lambda: VehicleStates(x="a", y=0.0, v=1.0, heading=0.0), "numeric"),
        (lambda: risk(ego, VehicleStates(x=[1.0, 2.0], y=0.0, v=1.0, heading=0.0)), "scenes"),
        (lambda: risk(ego, to, predictions="fast"), "PredictionSet"),
        (lambda: risk_series({"ego.x": [0.0], "ego.y": [0.0], "ego.v": [1.0]}), "ego.heading"),
        (lambda: risk_series({f"{v}.{f}": [0.0] for v in ("ego", "to")
                              for f in ("x", "y", "v", "heading", "a", "acceleration")}),
         "not both"),
        (lambda: risk_series({f"{v}.{f}": [0.0] * (2 if v == "to" else 1) for v in ("ego", "to")
                              for f in ("x", "y", "v", "heading")}), "differ in length"),
    ]
    for make, match in cases:
        with pytest.raises(SimcredError, match=match) as info:
            make()
        assert "\n" not in str(info.value)


def test_states_of_tracks_match_the_columns():
    from simcred.kinematics import Track

    t = np.linspace(0.0, 1.0, 5)
    ego = Track(t, 20 * t, 0 * t, 20 + 0 * t, 0 * t, 0 * t, 0 * t)
    to = Track(t, 40 + 15 * t, 0 * t, 15 + 0 * t, 0 * t)  # no rates: 0
    columns = {**ego.to_columns("ego"), **to.to_columns("to")}
    by_columns = risk_series(columns)
    by_tracks = risk(VehicleStates.of_tracks(ego), VehicleStates.of_tracks([to]))
    np.testing.assert_array_equal(by_tracks.risk, by_columns.risk)
    np.testing.assert_array_equal(by_tracks.ttr, by_columns.ttr)
    assert VehicleStates.of_tracks([to, to]).x.shape == (5, 2)


def test_ttc_and_thw_for_oncoming_reversing_and_backward_traffic():
    ego = VehicleStates(x=[0.0, 0.0, 0.0], y=0.0, v=[20.0, 20.0, 20.0],
                        heading=[0.0, 0.0, np.pi])
    # oncoming lead 44.5 m ahead (gap 40) at 10 m/s; a lead reversing towards the EGO at 5 m/s;
    # the EGO drives along -x with a lead 44.5 m ahead of it (at x = -44.5) at 10 m/s
    objects = VehicleStates(x=[44.5, 44.5, -44.5], y=0.0, v=[10.0, -5.0, 10.0],
                            heading=[np.pi, 0.0, np.pi])
    np.testing.assert_allclose(time_to_collision(ego, objects), [40 / 30, 40 / 25, 40 / 10])
    np.testing.assert_allclose(time_headway(ego, objects), [2.0, 2.0, 2.0])


def test_to_dict_is_the_settings_then_the_per_scene_columns():
    """fields_dict in the keys' order of before; the per-prediction arrays and the configuration
    are left out."""
    result = risk(*lead_scenes([10.0, 40.0], 25.0, 15.0))
    document = result.to_dict()
    assert list(document) == ["method", "resolution", "prediction_names", "maneuver_names",
                              "risk", "ttr_min", "dominant_object", "dominant_prediction"]
    assert document["prediction_names"] == list(result.prediction_names)
    assert document["risk"] is result.risk and document["method"] == "ttr"
