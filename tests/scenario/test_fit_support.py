"""The local acceleration behind ``unsupported_acceleration``: the stacked computation gives the
numbers of the one-window-at-a-time loop, bit for bit (issue 24: the variation's refit)."""

from __future__ import annotations

import numpy as np
import pytest

from simcred.scenario.fit_support import _local_acceleration_loop, local_acceleration


def _track(n: int, dt: float, seed: int, jitter: float = 0.0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt + rng.uniform(0, jitter * dt, n)
    v = 20.0 + 2.0 * np.sin(t / 3.0)
    x = np.cumsum(v) * dt + rng.normal(0, 0.03, n)
    y = 0.5 * np.tanh(t - t.mean()) + rng.normal(0, 0.03, n)
    return t, x, y


@pytest.mark.parametrize(("n", "dt", "jitter"), [
    (124, 0.1, 0.0), (1200, 0.01, 0.0), (301, 0.04, 0.9), (60, 0.37, 0.5),
    *((n, 0.1, 0.3) for n in range(1, 14)), (40, 0.2, 0.0)])
def test_stacked_windows_equal_the_loop_bit_for_bit(n, dt, jitter):
    t, x, y = _track(n, dt, n, jitter)
    for noise in (0.0, 0.03):
        stacked = local_acceleration(t, x, y, noise)
        loop = _local_acceleration_loop(t, x, y, noise)
        for a, b in zip(stacked, loop, strict=True):
            np.testing.assert_array_equal(a, b)


def test_standing_and_unordered_samples():
    t = np.arange(30) * 0.1
    accel, error = local_acceleration(t, np.zeros(30), np.zeros(30), 0.02)
    assert np.isnan(accel).all() and np.isnan(error).all()      # speed 0: no tangent
    t, x, y = _track(50, 0.1, 3)
    order = np.random.default_rng(0).permutation(50)            # falls back to the loop
    for a, b in zip(local_acceleration(t[order], x[order], y[order], 0.03),
                    _local_acceleration_loop(t[order], x[order], y[order], 0.03), strict=True):
        np.testing.assert_array_equal(a, b)
