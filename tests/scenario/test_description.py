"""simcred.scenario: splines, eq. (1) integration, the position fit, JSON and OpenSCENARIO."""

from __future__ import annotations

import contextlib
import datetime as dt
import io
import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad

from simcred.errors import SimcredError
from simcred.kinematics import Track
from simcred.scenario import (
    ObjectTrack,
    ScenarioDescription,
    Spline,
    StopReason,
    build_openscenario,
    fit_scenario,
    fit_track,
    to_openscenario,
    validate_openscenario,
)
from simcred.scenario.openscenario import trajectory_times


def one_line(exc: pytest.ExceptionInfo) -> str:
    message = str(exc.value)
    assert "\n" not in message
    return message


def cut_in(sections: int = 6) -> ObjectTrack:
    """A known 20 s cut-in: lane change (heading bump near 6 s), braking 25 → 17 m/s near 12 s."""
    grid = np.linspace(0.0, 20.0, 401)
    speed = 25.0 - 8.0 / (1.0 + np.exp(-(grid - 12.0)))
    heading = 0.08 * np.exp(-(((grid - 6.0) / 1.2) ** 2))
    return ObjectTrack(0.0, 3.5,
                       Spline.least_squares(grid, speed, t0=0.0, t1=20.0, sections=sections),
                       Spline.least_squares(grid, heading, t0=0.0, t1=20.0, sections=sections))


def constant(t1: float, value: float, sections: int = 3) -> Spline:
    return Spline(0.0, t1, [value] * (sections + 3))


@pytest.fixture(scope="module")
def truth() -> ObjectTrack:
    return cut_in()


@pytest.fixture(scope="module")
def description(truth: ObjectTrack) -> ScenarioDescription:
    ego = ObjectTrack(-30.0, 0.0, constant(20.0, 22.0), constant(20.0, 0.0), length=4.8)
    return ScenarioDescription({"ego": ego, "to": truth}, dt=0.01,
                               metadata={"road": {"lane_width": 3.5, "lane_centres": [0, 3.5]}})


# -- splines and eq. (1) --------------------------------------------------------------------------


def test_spline_basis_and_derivatives():
    rng = np.random.default_rng(0)
    s = Spline(1.0, 5.0, rng.normal(size=7))
    assert s.sections == 4 and len(s.knots) == 4 + 3 + 4
    t = np.linspace(1.0, 5.0, 41)
    np.testing.assert_allclose(s.design(t) @ s.coefficients, s(t), atol=1e-12)
    np.testing.assert_allclose(s.design(t).sum(axis=1), 1.0, atol=1e-12)
    h = 1e-6
    inner = t[1:-1]
    np.testing.assert_allclose(s.derivative(inner), (s(inner + h) - s(inner - h)) / (2 * h),
                               atol=1e-6)
    assert float(s(5.0 + 1e-12)) == float(s(5.0))  # rounding at the end is clamped
    with pytest.raises(SimcredError) as exc:
        s(5.1)
    assert "outside" in one_line(exc) and "5.1" in str(exc.value)
    with pytest.raises(SimcredError):
        s.derivative(3.0, order=4)
    with pytest.raises(SimcredError):
        Spline(0.0, 1.0, [1.0, 2.0, 3.0])


def test_integration_matches_adaptive_quadrature():
    rng = np.random.default_rng(1)
    speed = Spline(0.0, 20.0, 20.0 + 3.0 * rng.standard_normal(9))
    heading = Spline(0.0, 20.0, 0.5 * rng.standard_normal(9))
    track = ObjectTrack(1.0, -2.0, speed, heading)
    t = np.concatenate([[0.0, 20.0], rng.uniform(0.0, 20.0, 12)])  # unsorted on purpose
    states = track.states(t)

    bounds = speed.knots[4:-4]  # section bounds, where the integrand is only C²

    def exact(f, upper):
        return quad(f, 0.0, upper, epsabs=1e-12, epsrel=1e-13, limit=400,
                    points=bounds[bounds < upper])[0]

    x = [1.0 + exact(lambda s: speed(s) * np.cos(heading(s)), u) for u in t]
    y = [-2.0 + exact(lambda s: speed(s) * np.sin(heading(s)), u) for u in t]
    assert np.max(np.abs(states.x - x)) < 1e-6
    assert np.max(np.abs(states.y - y)) < 1e-6
    np.testing.assert_allclose(states.acceleration, speed.derivative(t))
    np.testing.assert_allclose(states.yaw_rate, heading.derivative(t))


def test_constant_speed_and_yaw_rate_is_a_circle_arc():
    v, omega, sections, t1 = 12.0, 0.4, 5, 20.0
    knots = Spline(0.0, t1, np.zeros(sections + 3)).knots
    greville = (knots[1:-3] + knots[2:-2] + knots[3:-1]) / 3  # reproduces linear functions
    track = ObjectTrack(3.0, 4.0, constant(t1, v, sections), Spline(0.0, t1, omega * greville))
    t = np.linspace(0.0, t1, 257)
    states = track.states(t)
    np.testing.assert_allclose(states.heading, omega * t, atol=1e-12)
    assert np.max(np.abs(states.x - (3.0 + v / omega * np.sin(omega * t)))) < 1e-9
    assert np.max(np.abs(states.y - (4.0 + v / omega * (1 - np.cos(omega * t))))) < 1e-9
    np.testing.assert_allclose(states.yaw_rate, omega, atol=1e-12)


def test_track_validation():
    with pytest.raises(SimcredError) as exc:
        ObjectTrack(0.0, 0.0, constant(10.0, 1.0, 3), constant(10.0, 0.0, 4))
    assert "share" in one_line(exc)
    with pytest.raises(SimcredError):
        ObjectTrack(0.0, math.nan, constant(10.0, 1.0), constant(10.0, 0.0))
    with pytest.raises(SimcredError):
        ObjectTrack(0.0, 0.0, constant(10.0, 1.0), constant(10.0, 0.0), width=0.0)
    with pytest.raises(SimcredError):
        ScenarioDescription({"a.b": ObjectTrack(0, 0, constant(1, 1), constant(1, 0))})


# -- the fit --------------------------------------------------------------------------------------


def test_fit_recovers_known_scenario_with_dgps_noise(truth: ObjectTrack):
    t = np.linspace(0.0, 20.0, 2001)  # 20 s at 100 Hz
    states = truth.states(t)
    rng = np.random.default_rng(2)
    x = states.x + 0.01 * rng.standard_normal(t.size)
    y = states.y + 0.01 * rng.standard_normal(t.size)
    fit = fit_track(t, x, y)  # its speed is measured in benchmarks/reprocess.py
    assert fit.stop_reason is StopReason.THRESHOLD
    assert fit.rmse <= 0.05 and fit.rmse == fit.history[-1][1]
    assert fit.sections <= 2 * truth.sections  # the search stops, far below max_sections
    got = fit.track.states(t)
    dv, dh = got.v - states.v, got.heading - states.heading
    assert np.max(np.abs(dv)) < 0.3 and np.sqrt(np.mean(dv**2)) < 0.1  # m/s
    assert np.max(np.abs(dh)) < 0.01 and np.sqrt(np.mean(dh**2)) < 0.003  # rad
    assert abs(fit.track.x0 - truth.x0) < 0.05 and abs(fit.track.y0 - truth.y0) < 0.05


def test_fit_noise_free_is_exact_once_the_basis_contains_the_truth(truth: ObjectTrack):
    t = np.linspace(0.0, 20.0, 2001)
    states = truth.states(t)
    fit = fit_track(t, states.x, states.y, threshold=1e-4)
    # 5 → 8 → 12 sections; 12 uniform sections contain the 6 of the truth
    assert fit.stop_reason is StopReason.THRESHOLD and fit.sections == 12
    assert fit.rmse < 1e-8
    got = fit.track.states(t)
    np.testing.assert_allclose(got.v, states.v, atol=1e-7)
    np.testing.assert_allclose(got.heading, states.heading, atol=1e-8)
    default = fit_track(t, states.x, states.y)
    assert default.rmse < 0.05 / 2


def test_fit_stops_at_the_noise_floor_of_sensor_noise(truth: ObjectTrack):
    t = np.linspace(0.0, 20.0, 2001)
    states = truth.states(t)
    rng = np.random.default_rng(3)
    fit = fit_track(t, states.x + 0.5 * rng.standard_normal(t.size),
                    states.y + 0.5 * rng.standard_normal(t.size))
    assert fit.stop_reason is StopReason.NOISE_FLOOR and not fit.reached
    assert abs(fit.noise - 0.5 * np.sqrt(2.0)) < 0.05  # the estimate finds the planted noise
    assert len(fit.history) == 1  # the first step is already at the noise: no more sections
    assert 0.6 < fit.rmse < 0.8  # √2 · 0.5 m: the noise, not the fit


def test_fit_stalls_without_progress(truth: ObjectTrack):
    t = np.linspace(0.0, 20.0, 2001)
    states = truth.states(t)
    rng = np.random.default_rng(3)
    # Noise the estimate cannot see (a slow random walk, smooth on the sample scale) and a
    # threshold below it: no step makes progress, and the search gives up after `patience`.
    walk = np.cumsum(rng.standard_normal((2, t.size)), axis=1) * 0.02
    fit = fit_track(t, states.x + walk[0], states.y + walk[1], threshold=1e-3, min_gain=0.5,
                    patience=2)
    assert fit.stop_reason is StopReason.STALLED and not fit.reached
    gains = [1 - b / a for (_, a), (_, b) in zip(fit.history, fit.history[1:], strict=False)]
    assert len(gains) >= 2 and all(g < 0.5 for g in gains[-2:])  # the last 2 steps: no progress
    if len(gains) >= 3:  # ... and not earlier: the two steps before were not both without progress
        assert not (gains[-3] < 0.5 and gains[-2] < 0.5)


def test_fit_stops_at_max_sections(truth: ObjectTrack):
    t = np.linspace(0.0, 20.0, 401)
    states = truth.states(t)
    fit = fit_track(t, states.x, states.y, threshold=1e-12, min_gain=0.0, max_sections=7)
    assert fit.stop_reason is StopReason.MAX_SECTIONS and fit.sections == 7
    assert [s for s, _ in fit.history] == [5, 7]


def test_fit_heading_wraps_on_a_circle():
    t = np.linspace(0.0, 30.0, 601)  # 15 rad: more than two turns
    x, y = 20.0 * np.sin(0.5 * t), 20.0 * (1 - np.cos(0.5 * t))
    fit = fit_track(t, x, y)
    assert fit.rmse < 0.05
    np.testing.assert_allclose(fit.track.heading(t), 0.5 * t, atol=0.01)
    np.testing.assert_allclose(fit.track.speed(t), 10.0, atol=0.05)


def test_fit_scenario_from_traceset_and_from_triples(description: ScenarioDescription):
    traces = description.to_traceset(run_id="drive")
    assert set(traces.signals) == {f"{o}.{c}" for o in ("ego", "to")
                                   for c in ("x", "y", "v", "heading")}
    result = fit_scenario(traces)
    assert set(result.description.objects) == {"ego", "to"} and result.rmse < 0.05
    assert result.description.dt == pytest.approx(0.01)
    assert result.description.metadata["fit"]["objects"]["to"]["stop_reason"] == "threshold"
    t = traces.run(0)["t"]
    triples = {"to": (t, traces.column("to.x"), traces.column("to.y"))}
    only = fit_scenario(triples, dimensions={"to": (5.0, 2.0)})
    assert list(only.fits) == ["to"] and only.description.objects["to"].length == 5.0
    np.testing.assert_array_equal(only.description.objects["to"].speed.coefficients,
                                  result.fits["to"].track.speed.coefficients)
    track = Track.from_columns(traces.run(0), "to")
    tracked = fit_scenario({"to": track}, dimensions={"to": (5.0, 2.0)})
    assert tracked.description.to_json() == only.description.to_json()


t20 = np.linspace(0.0, 2.0, 21)


@pytest.mark.parametrize(("t", "x", "y", "needle"), [
    (t20[:1], t20[:1], t20[:1], "at least 2"),
    (t20, t20, t20[:-1], "different lengths"),
    (t20, np.where(t20 == 1.0, np.nan, t20), t20, "column 'x', sample 11"),
    (t20[::-1], t20, t20, "not strictly increasing"),
    (np.r_[t20[:3], t20[2:]], np.r_[t20[:3], t20[2:]], np.r_[t20[:3], t20[2:]],
     "not strictly increasing at sample 4"),
    (t20, t20, np.ones((21, 2)), "must be 1-D"),
    (t20, ["a"] * 21, t20, "not numeric"),
])
def test_fit_bad_inputs(t, x, y, needle):
    with pytest.raises(SimcredError) as exc:
        fit_track(t, x, y, name="to")
    message = one_line(exc)
    assert needle in message and "'to'" in message


@pytest.mark.parametrize(("options", "needle"), [
    ({"threshold": 0.0}, "threshold"),
    ({"min_gain": 1.0}, "min_gain"),
    ({"growth": 1.0}, "growth"),
    ({"max_sections": 0}, "max_sections"),
    ({"max_sections": 50}, "at most 8"),
])
def test_fit_bad_options(options, needle):
    with pytest.raises(SimcredError) as exc:
        fit_track(t20, t20, t20, **options)
    assert needle in one_line(exc)


def test_fit_scenario_bad_columns(description: ScenarioDescription):
    traces = description.to_traceset()
    with pytest.raises(SimcredError) as exc:
        fit_scenario(traces, objects=["cyclist"])
    assert "cyclist.x" in one_line(exc)
    with pytest.raises(SimcredError) as exc:
        fit_scenario({"to": (t20, t20)})
    assert "'to'" in one_line(exc)


# -- JSON -----------------------------------------------------------------------------------------

finite = st.floats(allow_nan=False, allow_infinity=False, width=64)


@settings(max_examples=40, deadline=None)
@given(data=st.data(), sections=st.integers(1, 12), t0=st.floats(-1e6, 1e6),
       span=st.floats(1e-3, 1e4), x0=finite, y0=finite)
def test_json_round_trip_is_exact(data, sections, t0, span, x0, y0):
    coefficients = st.lists(finite, min_size=sections + 3, max_size=sections + 3)
    t1 = t0 + span
    if not t1 > t0:
        return
    track = ObjectTrack(x0, y0, Spline(t0, t1, data.draw(coefficients)),
                        Spline(t0, t1, data.draw(coefficients)))
    original = ScenarioDescription({"to": track}, dt=data.draw(st.floats(1e-4, 10.0)),
                                   metadata={"source": "hypothesis"})
    text = json.dumps(original.to_dict(), allow_nan=False)
    back = ScenarioDescription.from_json(json.loads(text))
    assert back.equals(original)
    got = back.objects["to"]
    for a, b in ((got.speed, track.speed), (got.heading, track.heading)):
        assert a.coefficients.tobytes() == b.coefficients.tobytes()
    assert (got.x0, got.y0, got.t0, got.t1) == (track.x0, track.y0, track.t0, track.t1)


def test_write_read_round_trip(tmp_path, description: ScenarioDescription):
    path = description.write(tmp_path / "scenario.json")
    back = ScenarioDescription.read(path)
    assert back.equals(description) and back.metadata["road"]["lane_width"] == 3.5
    t = description.times()
    assert t[0] == 0.0 and t[-1] == 20.0 and len(t) == 2001
    for key, value in description.sample(t).items():
        np.testing.assert_array_equal(back.sample(t)[key], value)


def _break(document: dict, how: str) -> dict | str:
    obj = document["objects"]["to"]
    if how == "missing key":
        del obj["x0"]
    elif how == "sections mismatch":
        obj["sections"] += 1
    elif how == "wrong shape":
        obj["speed"] = [[c] for c in obj["speed"]]
    elif how == "non-finite":
        obj["y0"] = float("nan")
    elif how == "bad span":
        obj["t1"] = obj["t0"]
    elif how == "no objects":
        document["objects"] = {}
    elif how == "wrong kind":
        document["kind"] = "comparison"
    elif how == "future schema":
        document["schema_version"] = 2
    return document


@pytest.mark.parametrize(("how", "needle"), [
    ("missing key", "objects.to: missing key 'x0'"),
    ("sections mismatch", "objects.to.speed: 9 coefficients, expected sections + 3 = 10"),
    ("wrong shape", "objects.to.speed: coefficients must be a flat list of finite numbers"),
    ("non-finite", "objects.to: 'y0' must be a finite number"),
    ("bad span", "t0 < t1"),
    ("no objects", "'objects' is empty"),
    ("wrong kind", "kind is 'comparison'"),
    ("future schema", "schema_version 2 is not supported"),
])
def test_malformed_json_names_the_file(tmp_path, description, how, needle):
    path = tmp_path / "bad.json"
    document = _break(description.to_dict(), how)
    path.write_text(json.dumps(document))  # NaN is written as the token NaN
    with pytest.raises(SimcredError) as exc:
        ScenarioDescription.read(path)
    message = one_line(exc)
    assert message.startswith(str(path)) and needle in message


def test_unreadable_json_names_the_file(tmp_path):
    path = tmp_path / "broken.json"
    path.write_text('{"objects": ')
    with pytest.raises(SimcredError) as exc:
        ScenarioDescription.read(path)
    assert one_line(exc).startswith(f"{path}: not valid JSON")
    with pytest.raises(SimcredError) as exc:
        ScenarioDescription.read(tmp_path / "missing.json")
    assert "missing.json: cannot read" in one_line(exc)


def test_sample_outside_an_objects_span(description: ScenarioDescription):
    with pytest.raises(SimcredError) as exc:
        description.sample([0.0, 25.0])
    assert "object 'ego'" in one_line(exc) and "25.0" in str(exc.value)


# -- OpenSCENARIO ---------------------------------------------------------------------------------


def _parse(path):
    from scenariogeneration import xosc

    with contextlib.redirect_stdout(io.StringIO()):  # the parser prints the version
        return xosc.ParseOpenScenario(str(path))


@pytest.mark.parametrize("minor", [1, 2, 3])
def test_openscenario_validates_and_round_trips(tmp_path, description, minor):
    date = dt.datetime(2024, 1, 2, 3, 4, 5)
    written = build_openscenario(description, osc_minor_version=minor, creation_date=date)
    path = to_openscenario(description, tmp_path / "cut_in.xosc", osc_minor_version=minor,
                           creation_date=date)
    validate_openscenario(path)
    parsed = _parse(path)
    assert parsed == written
    groups = parsed.storyboard.stories[0].acts[0].maneuvergroup
    assert [g.actors.actors[0].entity for g in groups] == ["to"]  # the ego gets no trajectory
    follow = groups[0].maneuvers[0].events[0].action[0].action
    polyline = follow.trajectory.shapes
    track = description.objects["to"]
    times = trajectory_times(track, 0.1)
    expected = track.states(times)
    assert polyline.time == times.tolist() and len(times) == 201
    assert [p.x for p in polyline.positions] == expected.x.tolist()
    assert [p.y for p in polyline.positions] == expected.y.tolist()
    assert [p.h for p in polyline.positions] == expected.heading.tolist()
    assert follow.timeref.reference_domain.get_name() == "absolute"


def test_broken_openscenario_fails_validation(tmp_path, description):
    path = to_openscenario(description, tmp_path / "ok.xosc")
    text = path.read_text()
    broken = tmp_path / "broken.xosc"
    broken.write_text(text.replace('followingMode="position"', 'followingMode="teleport"'))
    with pytest.raises(SimcredError) as exc:
        validate_openscenario(broken)
    message = one_line(exc)
    assert message.startswith(f"{broken}: not valid OpenSCENARIO 1.2") and "teleport" in message
    truncated = tmp_path / "truncated.xosc"
    truncated.write_text(text[: len(text) // 2])
    with pytest.raises(SimcredError) as exc:
        validate_openscenario(truncated)
    assert "not well-formed XML" in one_line(exc)


def test_openscenario_options(tmp_path, description):
    with pytest.raises(SimcredError) as exc:
        to_openscenario(description, tmp_path / "x.xosc", ego="hero")
    assert "'hero'" in one_line(exc)
    only_ego = ScenarioDescription({"ego": description.objects["ego"]})
    validate_openscenario(to_openscenario(only_ego, tmp_path / "ego.xosc"))
    replay = to_openscenario(description, tmp_path / "replay.xosc", ego_trajectory=True,
                             road_file="road.xodr")
    validate_openscenario(replay)
    assert replay.read_text().count("<FollowTrajectoryAction") == 2


def test_openscenario_export_is_byte_identical_on_rerun(tmp_path, description):
    first = to_openscenario(description, tmp_path / "a.xosc").read_bytes()
    second = to_openscenario(description, tmp_path / "b.xosc").read_bytes()
    assert first == second
    assert b'date="1970-01-01T00:00:00"' in first  # no date in the inputs: NO_DATE


def test_openscenario_date_comes_from_the_description(tmp_path, description):
    dated = ScenarioDescription(description.objects, dt=description.dt,
                                metadata={"date": "2024-05-06T07:08:09"})
    assert b'date="2024-05-06T07:08:09"' in to_openscenario(dated, tmp_path / "a.xosc"
                                                            ).read_bytes()
    with pytest.raises(SimcredError, match="not an ISO 8601 date"):
        to_openscenario(ScenarioDescription(description.objects, dt=description.dt,
                                            metadata={"date": "yesterday"}), tmp_path / "b.xosc")
