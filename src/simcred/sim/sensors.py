"""Sensor models: what the AD function's object list makes of a traffic object's true state.

All sensors are batched over runs and streamed step by step, as in a closed loop: the simulator
calls ``start`` once and ``perceive`` every step with the EGO's pose and the object's true state
``(runs, 4)`` columns ``x, y, v, heading``; it gets back the object list entry in the same layout.
Noise comes from a pre-drawn array ``(runs, steps, 2)`` of standard normals, so a run's noise
depends only on its own seed, never on the batch it is simulated in.

* :class:`IdealSensor` — the true state (the usual simulation assumption).
* :class:`TrackerSensor` — the manufactured universe's "real" sensor ([1] §II-A, §III): a position
  offset along the line of sight (the object looks farther), white position noise, and velocity and
  heading *derived from positions* by the slope of a least-squares line through the last
  ``window`` seconds of measured positions, which delays them by about ``window / 2``.
* :class:`OffsetDelaySensor` — the scenario-based sensor model of [1] §IV: a static offset that
  depends on the object's range, a pure delay of velocity and heading, and position noise; its
  parameters are estimated from pairs of recordings by :func:`estimate_sensor`.

The two are deliberately of different families: the estimated model approximates the real
sensor, it does not copy its equations.

References
----------
[1] Wagner, Groh et al., Towards Cross-Verification and Use of Simulation in the Assessment of
    Automated Driving, IEEE IV 2019.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Protocol

import numpy as np

from simcred._json import JsonResult
from simcred.errors import SimcredError

X, Y, V, HEADING = range(4)


class Sensor(Protocol):
    """What the closed loop needs of a sensor."""

    name: str

    def start(self, runs: int, dt: float) -> object:
        """Internal state before the first step."""
        ...

    def perceive(self, memory: object, ego_xy: np.ndarray, truth: np.ndarray,
                 noise: np.ndarray) -> np.ndarray:
        """Object list entry ``(runs, 4)`` for this step; may update ``memory`` in place."""
        ...


@dataclass(frozen=True, slots=True)
class IdealSensor:
    """Perfect perception: the object list is the true state."""

    name: str = "ideal"

    def start(self, runs: int, dt: float) -> None:
        return None

    def perceive(self, memory: None, ego_xy: np.ndarray, truth: np.ndarray,
                 noise: np.ndarray) -> np.ndarray:
        return truth.copy()


def line_of_sight(ego_xy: np.ndarray, object_xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Range (m) and unit vector ``(runs, 2)`` from the EGO to the object."""
    delta = object_xy - ego_xy
    rng = np.hypot(delta[:, 0], delta[:, 1])
    return rng, delta / np.maximum(rng, 1e-9)[:, None]


def _offset_positions(ego_xy: np.ndarray, truth: np.ndarray, offset: float, per_metre: float,
                      noise_sd: float, noise: np.ndarray) -> np.ndarray:
    rng, unit = line_of_sight(ego_xy, truth[:, :2])
    return truth[:, :2] + (offset + per_metre * rng)[:, None] * unit + noise_sd * noise


def _speed_heading(velocity: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    return np.hypot(velocity[:, 0], velocity[:, 1]), np.arctan2(velocity[:, 1], velocity[:, 0])


@dataclass(slots=True)
class _History:
    """A ring of the last ``size`` values ``(runs, size, k)``, oldest first via ``ordered``."""

    values: np.ndarray
    filled: int = 0

    def push(self, value: np.ndarray) -> None:
        if self.filled == 0:  # before the first sample the history is that sample
            self.values[:] = value[:, None, :]
        else:
            self.values = np.roll(self.values, -1, axis=1)
            self.values[:, -1] = value
        self.filled += 1


@dataclass(frozen=True, slots=True)
class TrackerSensor:
    """The manufactured universe's real sensor (see the module docstring).

    Parameters
    ----------
    offset : float, default 1.4
        Static position offset along the line of sight (m); positive: the object looks farther.
    offset_per_metre : float, default 0.0
        Additional offset per metre of range.
    position_sd : float, default 0.05
        Standard deviation of the white position noise (m), per axis.
    window : float, default 1.0
        Length of the regression window for velocity and heading (s); delay ≈ window / 2.
    """

    offset: float = 1.4
    offset_per_metre: float = 0.0
    position_sd: float = 0.05
    window: float = 1.0
    name: str = "tracker"

    def start(self, runs: int, dt: float) -> tuple[_History, np.ndarray]:
        size = max(2, int(round(self.window / dt)) + 1)
        tau = (np.arange(size) - (size - 1) / 2) * dt
        slope_weights = tau / np.sum(tau * tau)
        return _History(np.zeros((runs, size, 2))), slope_weights

    def perceive(self, memory: tuple[_History, np.ndarray], ego_xy: np.ndarray,
                 truth: np.ndarray, noise: np.ndarray) -> np.ndarray:
        history, weights = memory
        xy = _offset_positions(ego_xy, truth, self.offset, self.offset_per_metre,
                               self.position_sd, noise)
        history.push(xy)
        if history.filled < len(weights):  # a fresh track: no velocity estimate yet, use truth
            speed, heading = truth[:, V], truth[:, HEADING]
        else:
            speed, heading = _speed_heading(np.einsum("rkc,k->rc", history.values, weights))
        return np.column_stack([xy, speed, heading])


@dataclass(frozen=True, slots=True)
class OffsetDelaySensor(JsonResult):
    """Scenario-based sensor model ([1] §IV): offset(range), delayed velocity/heading, noise.

    Position = truth + (offset + offset_per_metre · range) along the line of sight + noise;
    velocity vector = the true one ``delay`` seconds ago (held at the first value before that).

    Parameters
    ----------
    offset, offset_per_metre : float
        Static offset (m) and its slope with range (m per m).
    delay : float
        Delay of velocity and heading (s).
    position_sd : float
        Position noise (m), per axis.
    fit : dict
        How the parameters were estimated (residuals, sample counts); informative only.
    """

    offset: float = 0.0
    offset_per_metre: float = 0.0
    delay: float = 0.0
    position_sd: float = 0.0
    name: str = "scenario-based"
    fit: Mapping[str, float] = field(default_factory=dict, compare=False)

    def dynamic_only(self) -> OffsetDelaySensor:
        """The model without its static part: for descriptions fitted to sensor data, which
        already contain the offset ([1] §IV)."""
        return replace(self, offset=0.0, offset_per_metre=0.0, position_sd=0.0)

    def start(self, runs: int, dt: float) -> _History:
        return _History(np.zeros((runs, int(round(self.delay / dt)) + 1, 2)))

    def perceive(self, memory: _History, ego_xy: np.ndarray, truth: np.ndarray,
                 noise: np.ndarray) -> np.ndarray:
        xy = _offset_positions(ego_xy, truth, self.offset, self.offset_per_metre,
                               self.position_sd, noise)
        memory.push(truth[:, V, None] * np.column_stack([np.cos(truth[:, HEADING]),
                                                          np.sin(truth[:, HEADING])]))
        speed, heading = _speed_heading(memory.values[:, 0])
        return np.column_stack([xy, speed, heading])

    def to_dict(self) -> dict[str, float]:
        return {"offset": self.offset, "offset_per_metre": self.offset_per_metre,
                "delay": self.delay, "position_sd": self.position_sd, **self.fit}


def perceive_recording(sensor: Sensor, t: np.ndarray, ego_xy: np.ndarray, truth: np.ndarray
                       ) -> np.ndarray:
    """What ``sensor`` makes of one recorded object, without noise: ``(n, 4)`` x, y, v, heading.

    Streams the recording through the sensor as the closed loop would (``start``, then
    ``perceive`` per sample); used to evaluate a sensor model on a drive it was not estimated
    on ([1] §IV: a model derived from a set of drives, applied to others).

    Parameters
    ----------
    t : (n,) array
        Sample times (s), equally spaced.
    ego_xy : (n, 2) array
        EGO position at those times.
    truth : (n, 4) array
        The object's true (GT) states.
    """
    memory = sensor.start(1, _step(t))
    silent = np.zeros((1, 2))
    return np.concatenate([sensor.perceive(memory, ego_xy[k:k + 1], truth[k:k + 1], silent)
                           for k in range(len(t))])


def estimate_sensor(t: np.ndarray, ego_xy: np.ndarray, gt: np.ndarray, sd: np.ndarray, *,
                    max_delay: float = 2.0, offset_vs_range: bool = True) -> OffsetDelaySensor:
    """Estimate an :class:`OffsetDelaySensor` from one object's GT and SD over the same times.

    Parameters
    ----------
    t : (n,) array
        Sample times (s), equally spaced.
    ego_xy : (n, 2) array
        EGO position (GT) at those times.
    gt, sd : (n, 4) arrays
        The object's ground truth and sensor data, columns ``x, y, v, heading``.
    max_delay : float, default 2.0
        Largest delay considered (s).
    offset_vs_range : bool, default True
        Fit the offset as ``a + b · range``; with False only a constant.

    Returns
    -------
    OffsetDelaySensor
        Offset: least squares of the position error projected on the line of sight (on range,
        when asked and when the range varies by more than 5 m). Noise: the standard deviation of
        what remains, per axis. Delay: the shift of the GT velocity vector that best matches the
        SD one (least squares over whole samples, refined by a parabola through the three best
        shifts: the cross-correlation estimate).
    """
    dt = _step(t)
    rng, unit = line_of_sight(ego_xy, gt[:, :2])
    along = np.einsum("nc,nc->n", sd[:, :2] - gt[:, :2], unit)
    per_metre = offset_vs_range and float(np.ptp(rng)) > 5.0
    design = np.column_stack([np.ones_like(rng), rng]) if per_metre else np.ones((len(rng), 1))
    coef, *_ = np.linalg.lstsq(design, along, rcond=None)
    offset, slope = float(coef[0]), float(coef[1]) if per_metre else 0.0
    expected = gt[:, :2] + (offset + slope * rng)[:, None] * unit
    residual = sd[:, :2] - expected
    position_sd = float(np.sqrt(np.mean(residual * residual)))
    delay, mismatch = _velocity_delay(dt, gt, sd, max_delay)
    return OffsetDelaySensor(offset, slope, delay, position_sd, fit={
        "samples": float(len(t)), "offset_rms_residual": float(np.std(along - design @ coef)),
        "velocity_rms_mismatch": mismatch})


def _step(t: np.ndarray) -> float:
    steps = np.diff(t)
    if len(t) < 3 or not np.all(steps > 0) or np.ptp(steps) > 1e-6 * steps.mean():
        raise SimcredError("sensor estimation needs at least 3 equally spaced, increasing times")
    return float(steps.mean())


def _velocity_vector(states: np.ndarray) -> np.ndarray:
    return states[:, V, None] * np.column_stack([np.cos(states[:, HEADING]),
                                                 np.sin(states[:, HEADING])])


def _velocity_delay(dt: float, gt: np.ndarray, sd: np.ndarray, max_delay: float
                    ) -> tuple[float, float]:
    """Delay (s) of SD's velocity vector against GT's and the RMS mismatch at that delay."""
    truth, seen = _velocity_vector(gt), _velocity_vector(sd)
    shifts = np.arange(0, min(int(round(max_delay / dt)), len(gt) // 2) + 1)
    cost = np.array([np.mean((seen[k:] - truth[:len(truth) - k]) ** 2) for k in shifts])
    best = int(np.argmin(cost))
    refined = float(best)
    if 0 < best < len(cost) - 1:
        left, mid, right = cost[best - 1], cost[best], cost[best + 1]
        curvature = left - 2 * mid + right
        if curvature > 0:
            refined = best + 0.5 * (left - right) / curvature
    return float(refined * dt), math.sqrt(float(cost[best]))
