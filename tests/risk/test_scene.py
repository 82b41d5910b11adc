"""VehicleStates: the kinematics batched view plus the vehicles' size."""

import numpy as np

from simcred.kinematics import Track, TrackBatch
from simcred.risk import VehicleStates


def test_vehicle_states_are_a_batch_with_zero_rates_by_default():
    t = np.arange(5) * 0.1
    track = Track(t, 10 * t, 0 * t + 1.0, np.full(5, 10.0), np.linspace(0, 0.1, 5))
    states = VehicleStates.of_tracks(track, name="ego")
    assert isinstance(states, TrackBatch) and states.name == "ego"
    np.testing.assert_array_equal(states.acceleration, np.zeros(5))
    np.testing.assert_array_equal(states.yaw_rate, np.zeros(5))
    np.testing.assert_array_equal(states.v, track.v)
    assert states.length.shape == (5,) and float(states.width[0]) == 1.8
