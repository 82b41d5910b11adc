"""Track: conversions from/to trace-set columns, heading-unwrapping interpolation; TrackBatch."""

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from simcred.errors import SimcredError
from simcred.kinematics import MOTION_SIGNALS, Track, TrackBatch


def _track(n=5, rates=False):
    t = np.arange(n) * 0.1
    extra = (np.full(n, 0.5), np.full(n, 0.01)) if rates else ()
    return Track(t, 10 * t, 0 * t + 1.0, np.full(n, 10.0), np.linspace(0, 0.1, n), *extra)


def test_columns_round_trip():
    track = _track(rates=True)
    columns = {"t": track.t, **track.to_columns("to", rates=True)}
    assert set(columns) == {"t", "to.x", "to.y", "to.v", "to.heading", "to.acceleration",
                            "to.yaw_rate"}
    assert Track.from_columns(columns, "to").equals(track)
    without = {k: v for k, v in columns.items() if k != "to.yaw_rate"}
    assert Track.from_columns(without, "to").acceleration is None  # rates need both columns


def test_missing_columns_are_named():
    with pytest.raises(SimcredError, match=r"run\.csv: missing signal\(s\) to\.v, to\.heading"):
        Track.from_columns({"t": [0.0], "to.x": [0.0], "to.y": [0.0]}, "to", source="run.csv")


def test_states_is_the_batched_view():
    track = _track()
    states = track.states()
    assert states.shape == (5, 4)
    for j, name in enumerate(MOTION_SIGNALS):
        np.testing.assert_array_equal(states[:, j], getattr(track, name))
    assert Track.from_states(track.t, states).equals(track)
    assert TrackBatch.of_tracks([track, track]).states().shape == (5, 2, 4)
    with pytest.raises(SimcredError, match="different lengths"):
        TrackBatch.of_tracks([track, _track(3)])


@given(st.floats(-3.0, 3.0), st.floats(0.01, 0.99))
def test_interpolation_follows_the_short_way_round(start, fraction):
    # heading jumps by 2π − 0.2 in the stored (wrapped) values: the true turn is 0.2 rad
    wrapped = np.angle(np.exp(1j * np.array([np.pi - 0.1, np.pi + 0.1])))
    track = Track([0.0, 1.0], [start, start], [0.0, 0.0], [1.0, 1.0], wrapped)
    heading = track.interpolate([fraction]).heading[0]
    assert heading == pytest.approx(np.pi - 0.1 + 0.2 * fraction)


def test_shapes_are_checked():
    with pytest.raises(SimcredError, match="'x' has shape"):
        Track([0.0, 1.0], [0.0], [0.0, 0.0], [1.0, 1.0], [0.0, 0.0])
    assert repr(_track()) == "Track(5 samples, [0, 0.4] s)"


def test_a_batch_of_tracks_holds_their_columns_and_gives_them_back():
    with_rates, without = _track(rates=True), _track()
    single = TrackBatch.of_tracks(without)
    assert single.shape == (5,) and single.acceleration is None and single.yaw_rate is None
    batch = TrackBatch.of_tracks([with_rates, without])
    assert batch.shape == (5, 2)
    for k, track in enumerate((with_rates, without)):
        for name in MOTION_SIGNALS:
            np.testing.assert_array_equal(getattr(batch, name)[:, k], getattr(track, name))
    np.testing.assert_array_equal(batch.acceleration, [[0.5, 0.0]] * 5)  # missing rate: 0
    assert batch.track(with_rates.t, (slice(None), 0)).equals(with_rates)
    back = TrackBatch.from_states(batch.states())
    np.testing.assert_array_equal(back.states(), batch.states())
    assert back.acceleration is None
    with pytest.raises(ValueError):
        batch.x[0, 0] = 1.0  # read-only
    with pytest.raises(SimcredError, match="no tracks"):
        TrackBatch.of_tracks([])


def test_a_batch_broadcasts_scalars_and_refuses_other_shapes():
    batch = TrackBatch(x=[[0.0, 1.0]], y=0.0, v=[[1.0], [2.0]], heading=0.0)
    assert batch.shape == (2, 2) and repr(batch) == "TrackBatch(shape=(2, 2))"
    with pytest.raises(SimcredError, match="do not broadcast"):
        TrackBatch(x=[0.0, 1.0], y=[0.0, 1.0, 2.0], v=0.0, heading=0.0)

