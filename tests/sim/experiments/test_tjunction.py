"""T-junction occlusion experiment (Neurohr et al. 2023, sec. VI-B): behaviour and oracles."""

from dataclasses import replace

import numpy as np
import pytest
import shapely

from simcred.compare import matrix
from simcred.errors import OptionError
from simcred.sim.campaign import Campaign, run_id
from simcred.sim.experiments.tjunction import (
    CATEGORIES,
    SIGNALS,
    Occluders,
    Runs,
    Scenario,
    simulate,
)
from simcred.traces import concat

RUNS = 300
SCENARIO = Scenario()


@pytest.fixture(scope="module")
def sets():
    """The same seed in every category: the EGO and the cyclist draws are shared."""
    return {c: simulate(range(RUNS), 11, category=c) for c in CATEGORIES}


def grid(ts, name):
    """Signal ``name`` as a (runs, steps) array (all runs have the same length)."""
    return ts.column(name).reshape(ts.n_runs, -1)


def clearance(ts, scenario=SCENARIO):
    """Per run, the smallest distance between the cyclist's centre and the EGO's footprint."""
    dx = grid(ts, "cyclist.x") - grid(ts, "ego.x")
    dy = grid(ts, "cyclist.y") - grid(ts, "ego.y")
    heading = grid(ts, "ego.heading")
    along = np.cos(heading) * dx + np.sin(heading) * dy
    across = -np.sin(heading) * dx + np.cos(heading) * dy
    half_length, half_width = scenario.layout.ego_length / 2, 0.9
    return np.hypot(np.maximum(np.abs(along) - half_length, 0),
                    np.maximum(np.abs(across) - half_width, 0)).min(axis=1)


def mean_speed_near_junction(ts):
    """Mean EGO speed over the samples in the 30 m before the side arm (x in [-30, 0])."""
    x, v = grid(ts, "ego.x"), grid(ts, "ego.v")
    near = (x > -30) & (x < 0)
    return float(v[near].mean())


# -- reproducibility ------------------------------------------------------------------------------


@pytest.mark.parametrize("category", ["random", "occlusion"])
def test_a_run_does_not_depend_on_its_batch(category):
    batch = simulate(range(12), 5, category=category)
    for i in (0, 7, 11):
        alone = simulate([i], 5, category=category)
        assert np.array_equal(alone.values, batch.values[batch.offsets[i]:batch.offsets[i + 1]])
        assert alone.run_ids == (run_id(i),)
    chunked = concat([simulate(range(0, 5), 5, category=category),
                      simulate(range(5, 12), 5, category=category)])
    assert chunked.digest() == batch.digest()


def test_any_chunking_of_a_campaign_gives_the_same_trace_set():
    whole = Campaign(simulate, runs=10, seed=2, params={"category": "random"}, chunk_size=10)
    split = Campaign(simulate, runs=10, seed=2, params={"category": "random"}, chunk_size=3)
    assert whole.run().equals(split.run())


def test_same_seed_same_runs_other_seed_other_runs():
    a = simulate(range(4), 9, category="random", duration=5.0)
    assert a.equals(simulate(range(4), 9, category="random", duration=5.0))
    assert not np.array_equal(a.values, simulate(range(4), 10, category="random",
                                                 duration=5.0).values)


# -- interface ------------------------------------------------------------------------------------


def test_signals_time_ids_and_metadata():
    ts = simulate([3, 17], 1, category="occlusion", dt=0.25, duration=5.0)
    assert ts.signals == SIGNALS
    assert ts.run_ids == (run_id(3), run_id(17))
    assert ts.lengths.tolist() == [21, 21]
    assert np.array_equal(ts.run(1)["t"], np.arange(21) * 0.25)
    assert dict(ts.metadata) == {"model": "tjunction", "category": "occlusion", "dt": 0.25,
                                 "duration": 5.0}
    assert CATEGORIES == ("no-occlusion", "occlusion", "random")


def test_a_custom_scenario_is_recorded_in_the_metadata():
    slow = replace(SCENARIO, draws=replace(SCENARIO.draws, cruise=(8.0, 9.0)))
    ts = simulate([0], 1, category="random", duration=1.0, scenario=slow)
    assert ts.metadata["scenario"]["draws"]["cruise"] == (8.0, 9.0)
    assert "scenario" not in simulate([0], 1, category="random", duration=1.0,
                                      scenario=Scenario()).metadata


def test_unknown_category_raises_a_one_line_option_error():
    with pytest.raises(OptionError, match="'occluded'") as info:
        simulate([0], 1, category="occluded")
    assert "\n" not in str(info.value) and "no-occlusion" in str(info.value)


@pytest.mark.parametrize(("dt", "duration"), [(0.0, 10.0), (-0.1, 10.0), (0.5, 0.2)])
def test_bad_sampling_raises_option_error(dt, duration):
    with pytest.raises(OptionError):
        simulate([0], 1, category="random", dt=dt, duration=duration)


# -- behaviour ------------------------------------------------------------------------------------


def test_the_ego_never_hits_the_cyclist(sets):
    for ts in sets.values():
        assert clearance(ts).min() > 1.0  # cyclist radius 0.5 m plus 0.5 m


def test_the_collision_oracle_catches_a_driver_that_ignores_the_cyclist():
    blind = replace(SCENARIO, driver=replace(SCENARIO.driver, time_buffer=-1e9))
    ts = simulate(range(RUNS), 11, category="occlusion", scenario=blind)
    assert (clearance(ts) < 0.5).sum() > 5


def test_the_ego_is_slower_near_the_junction_with_occlusion(sets):
    free = mean_speed_near_junction(sets["no-occlusion"])
    hidden = mean_speed_near_junction(sets["occlusion"])
    mixed = mean_speed_near_junction(sets["random"])
    assert hidden < mixed < free
    assert free - hidden > 3.0  # m/s: occlusion really changes the driving


def test_without_a_cyclist_occlusion_alone_slows_every_run_and_never_stops_it():
    absent = replace(SCENARIO, draws=replace(SCENARIO.draws, cyclist_delay=(1e3, 1e3)))
    free, hidden = (simulate(range(100), 4, category=c, scenario=absent)
                    for c in ("no-occlusion", "occlusion"))
    cruise = grid(free, "ego.v")
    assert np.all(cruise == cruise[:, :1])  # nothing to react to: cruise all the way
    x, v = grid(hidden, "ego.x"), grid(hidden, "ego.v")
    slowest = np.where((x > -30) & (x < 0), v, np.inf).min(axis=1)
    assert np.all(slowest < cruise[:, 0] - 3.0) and np.all(slowest > 1.0)


def test_occlusion_comes_only_from_parked_cars(sets):
    assert not grid(sets["no-occlusion"], "occluded").any()
    assert not grid(sets["no-occlusion"], "parked").any()
    assert grid(sets["occlusion"], "parked").all()
    assert grid(sets["occlusion"], "occluded").any(axis=1).mean() > 0.5  # "occlusion likely"
    mixed = sets["random"]
    parked = grid(mixed, "parked")
    assert np.all(parked == parked[:, :1])
    assert abs(parked[:, 0].mean() - 0.5) < 4 * np.sqrt(0.25 / RUNS)
    assert not grid(mixed, "occluded")[parked[:, 0] == 0].any()


def test_the_ego_stays_in_its_lane_with_bounded_speed_and_acceleration(sets):
    lane_y, dt = SCENARIO.layout.lane_y, 0.1
    for ts in sets.values():
        y, v = grid(ts, "ego.y"), grid(ts, "ego.v")
        assert np.abs(y - lane_y).max() < 1.0 and y.std(axis=1).min() > 0
        assert v.min() >= 0 and v.max() <= SCENARIO.draws.cruise[1]
        accel = np.diff(v, axis=1) / dt
        assert accel.min() >= -SCENARIO.driver.max_decel - 1e-9
        assert accel.max() <= SCENARIO.driver.max_accel + 1e-9


def test_the_ego_waits_at_the_stop_position_never_in_the_conflict_zone(sets):
    layout = SCENARIO.layout
    for ts in sets.values():
        front = grid(ts, "ego.x")[grid(ts, "ego.v") < 0.1] + layout.ego_length / 2
        assert front.size and front.max() < layout.conflict_x[0]
        assert np.median(front) == pytest.approx(layout.stop_x + layout.ego_length / 2, abs=0.05)


# -- occlusion geometry ---------------------------------------------------------------------------


def test_sight_lines_through_a_box_are_blocked_and_beside_it_are_not():
    boxes = np.full((2, 3, 4), np.nan)
    boxes[0, 0] = (0.0, 0.0, 2.0, 1.0)  # run 0: one car [0, 2] × [0, 1]; run 1: none
    occ = Occluders.from_boxes(boxes)
    origins = np.array([[-1.0, 0.5], [-1.0, 0.5]])
    targets = np.array([
        [3.0, 0.5],   # straight through the box
        [3.0, 1.5],   # y = 0.5 + (x + 1)/4: 0.75 at x = 0, 1.25 at x = 2 — crosses the top edge
        [3.0, 2.5],   # y = 0.5 + (x + 1)/2: 1.0 at x = 0, touches the corner (0, 1)
        [3.0, 3.0],   # y = 0.5 + (x + 1)·5/8: 1.125 at x = 0 — passes above the box
        [-0.5, 0.5],  # ends before the box
    ])
    expected = [True, True, True, False, False]
    got = occ.blocked(origins, np.stack([targets, targets]))
    assert got[0].tolist() == expected
    assert not got[1].any()


def test_a_parked_car_hides_the_side_arm_from_afar_but_not_from_beside_it():
    # Car [-10.5, -6] × [-5.8, -3.9]. From (-20, -1.75) to (2, -10) the sight line is at
    # y = -1.75 - 8.25 · 9.5/22 = -5.31 at x = -10.5: inside the car. From (-5, -1.75) the car
    # is behind the EGO.
    boxes = np.full((1, 3, 4), np.nan)
    boxes[0, 0] = (-10.5, -5.8, -6.0, -3.9)
    occ = Occluders.from_boxes(boxes)
    target = np.array([[[2.0, -10.0]]])
    assert occ.blocked(np.array([[-20.0, -1.75]]), target)[0, 0]
    assert not occ.blocked(np.array([[-5.0, -1.75]]), target)[0, 0]


def test_the_occluded_signal_matches_a_plain_shapely_oracle():
    indices, seed = range(40), 21
    ts = simulate(indices, seed, category="random", duration=10.0)
    runs = Runs.draw(indices, seed, "random", SCENARIO.draws, SCENARIO.layout.lane_width, 1)
    for k in range(ts.n_runs):
        cars = [shapely.box(*b) for b in runs.boxes[k] if not np.isnan(b[0])]
        run = ts.run(k)
        for j in range(0, len(run["t"]), 5):
            sight = shapely.LineString([(run["ego.x"][j], run["ego.y"][j]),
                                        (run["cyclist.x"][j], run["cyclist.y"][j])])
            hidden = any(sight.intersects(car) for car in cars)
            assert run["occluded"][j] == float(hidden)


# -- the experiment's purpose (Table 3 in small) --------------------------------------------------


@pytest.mark.slow
def test_occlusion_is_visible_to_the_comparison():
    sets = [simulate(range(500), 100 + k, category=c) for c in ("no-occlusion", "occlusion")
            for k in range(2)]
    d = matrix(sets, names=["free1", "free2", "hidden1", "hidden2"], features=["ego.x", "ego.y"],
               bins=10, test="permutation", alpha=0.01, seed=1).distances
    same = max(d[0, 1], d[2, 3])
    cross = min(d[0, 2], d[0, 3], d[1, 2], d[1, 3])
    assert same < 0.02 and cross > same + 0.03
