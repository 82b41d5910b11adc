"""Plausibility of a track: limits on speed, acceleration, yaw rate, lateral acceleration and
curvature, named by reason. Used to reject varied trajectories (simcred's choice; [1] sec. V keeps
every variation) and, with :data:`VEHICLE_LIMITS`, held by the fit of any real track ([1] sec.
II-B asks for a description "physically realistic"; the bounds are simcred's).

References
----------
[1] Wagner, Groh, Kühbeck, Knoll, Towards Cross-Verification and Use of Simulation in the
    Assessment of Automated Driving (paper 002), sec. V.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from enum import StrEnum
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike

from simcred.errors import OptionError, SimcredError
from simcred.kinematics import Track
from simcred.scenario.description import (
    ObjectTrack,
    sample_times,
)
from simcred.scenario.spline import Spline

PLAUSIBILITY_DT = 0.01
"""Sampling step (s) of :func:`check_plausibility` for an :class:`ObjectTrack`."""


class Reason(StrEnum):
    """Why a variation is rejected; the names of :attr:`VariationSet.rejections`."""

    SPEED = "speed"
    """v outside [min_speed, max_speed]."""
    LONGITUDINAL_ACCELERATION = "longitudinal_acceleration"
    """v̇ outside [min_acceleration, max_acceleration]."""
    LATERAL_ACCELERATION = "lateral_acceleration"
    """|v θ̇| above max_lateral_acceleration."""
    YAW_RATE = "yaw_rate"
    """|θ̇| above max_yaw_rate."""
    CURVATURE = "curvature"
    """|θ̇ / v| above max_curvature where |v| > curvature_min_speed."""
    SPEED_JUMP = "speed_jump"
    """|Δv| between consecutive samples above jump_factor · max(|a_min|, a_max) · Δt."""
    HEADING_JUMP = "heading_jump"
    """|Δθ| between consecutive samples above jump_factor · max_yaw_rate · Δt."""
    REFIT_RMSE = "refit_rmse"
    """The refit's position RMSE is above max_rmse (or not finite)."""
    REFIT_FAILED = "refit_failed"
    """fit_track raised an error for the varied path."""


@dataclass(frozen=True, slots=True)
class PlausibilityLimits:
    """Driving-dynamics bounds for a track (SI units), [1] sec. V "physically feasible".

    The defaults are the bounds for a varied highway cut-in; :data:`VEHICLE_LIMITS` are the
    looser bounds of any road vehicle, which the fit holds for real tracks.

    Parameters
    ----------
    min_speed, max_speed : float, default: 0.0, 70.0
        Bounds on v (m/s): the description drives forward (v ≥ 0); 70 m/s = 252 km/h.
    min_acceleration, max_acceleration : float, default: -9.0, 4.0
        Bounds on v̇ (m/s²): −9 is full braking on dry asphalt (μ ≈ 0.9 g), 4 a strong car's
        acceleration.
    max_lateral_acceleration : float, default: 6.0
        Bound on |v θ̇| (m/s²), well inside the tyre limit (~0.9 g) and far above lane changes
        (1–3 m/s²).
    max_yaw_rate : float, default: 0.5
        Bound on |θ̇| (rad/s).
    max_curvature : float, default: 0.2
        Bound on |θ̇ / v| (1/m), a 5 m turning radius, checked where |v| > ``curvature_min_speed``.
    curvature_min_speed : float, default: 1.0
        Speed (m/s) below which curvature is not checked (θ̇ / v is ill-conditioned there).
    jump_factor : float, default: 1.5
        Consecutive samples may differ by at most this factor times what the rate limits allow
        over their time step.
    max_rmse : float, default: 0.1
        Bound on the refit's position RMSE (m): twice the default fit threshold. A refit that
        cannot follow the varied path to 10 cm means the path has kinks that smooth v(t), θ(t)
        cannot carry.
    """

    min_speed: float = 0.0
    max_speed: float = 70.0
    min_acceleration: float = -9.0
    max_acceleration: float = 4.0
    max_lateral_acceleration: float = 6.0
    max_yaw_rate: float = 0.5
    max_curvature: float = 0.2
    curvature_min_speed: float = 1.0
    jump_factor: float = 1.5
    max_rmse: float = 0.1

    def __post_init__(self) -> None:
        for name, value in asdict(self).items():
            if isinstance(value, bool) or not isinstance(value, int | float) \
                    or not math.isfinite(value):
                raise OptionError(f"plausibility limit {name} must be a finite number, got "
                                  f"{value!r}")
            if name not in ("min_speed", "min_acceleration", "curvature_min_speed") \
                    and value <= 0:
                raise OptionError(f"plausibility limit {name} must be > 0, got {value!r}")
        if self.min_acceleration >= 0:
            raise OptionError(f"min_acceleration must be < 0, got {self.min_acceleration!r}")
        if not self.min_speed < self.max_speed:
            raise OptionError(f"min_speed must be < max_speed, got {self.min_speed!r}, "
                              f"{self.max_speed!r}")
        if self.curvature_min_speed < 0:
            raise OptionError(f"curvature_min_speed must be >= 0, got "
                              f"{self.curvature_min_speed!r}")


VEHICLE_LIMITS = PlausibilityLimits(min_acceleration=-10.0, max_acceleration=6.0,
                                    max_lateral_acceleration=8.0, max_yaw_rate=1.3,
                                    max_curvature=0.2)
"""Bounds of any road vehicle, held by :func:`~simcred.scenario.fit.fit_track` on real tracks.

Chosen from vehicle physics, not from data: braking ≥ −10 m/s² (≈ 1 g, the tyre limit on dry
asphalt); acceleration ≤ 6 m/s² (a strong passenger car in first gear); lateral acceleration
≤ 8 m/s² (≈ 0.8 g, road tyres); curvature ≤ 0.2 1/m (5 m turning radius); yaw rate ≤ 1.3 rad/s
≈ √(8 m/s² · 0.2 1/m), the most that lateral acceleration and curvature allow together (reached
at ≈ 6.3 m/s); speed in [0, 70] m/s (forward driving).
"""


def check_plausibility(states: Track | ObjectTrack,
                       limits: PlausibilityLimits = PlausibilityLimits(), *,
                       t: ArrayLike | None = None, rmse: float | None = None) -> list[Reason]:
    """The limits that a track violates; empty if it is plausible.

    Parameters
    ----------
    states : Track or ObjectTrack
        Sampled states (their t, v, heading, acceleration, yaw_rate are used), or a track, which
        is sampled at ``t``.
    limits : PlausibilityLimits, default: PlausibilityLimits()
        The bounds.
    t : array_like, optional
        Times for an ObjectTrack; default every 0.01 s over its span. Not allowed with
        Track.
    rmse : float, optional
        The refit's position RMSE (m), checked against ``limits.max_rmse``.

    Returns
    -------
    list of Reason
        Violated limits, in the order of :class:`Reason`. Non-finite values count as violations.

    Examples
    --------
    >>> from simcred.scenario.spline import Spline
    >>> track = ObjectTrack(0.0, 0.0, Spline(0.0, 4.0, [20.0] * 4), Spline(0.0, 4.0, [0.0] * 4))
    >>> check_plausibility(track), check_plausibility(track, rmse=0.5)
    ([], [<Reason.REFIT_RMSE: 'refit_rmse'>])
    """
    t, v, heading, a, omega = _rates_iv(states, t)
    lim = limits
    a_bound = max(-lim.min_acceleration, lim.max_acceleration)
    dt = np.diff(t)
    moving = np.abs(v) > lim.curvature_min_speed
    checks = {
        Reason.SPEED: (v >= lim.min_speed) & (v <= lim.max_speed),
        Reason.LONGITUDINAL_ACCELERATION: (a >= lim.min_acceleration) & (a <= lim.max_acceleration),
        Reason.LATERAL_ACCELERATION: np.abs(v * omega) <= lim.max_lateral_acceleration,
        Reason.YAW_RATE: np.abs(omega) <= lim.max_yaw_rate,
        Reason.CURVATURE: ~moving | (np.abs(omega / np.where(moving, v, 1.0)) <= lim.max_curvature),
        Reason.SPEED_JUMP: np.abs(np.diff(v)) <= lim.jump_factor * a_bound * dt,
        Reason.HEADING_JUMP: np.abs(np.diff(heading)) <= lim.jump_factor * lim.max_yaw_rate * dt,
        Reason.REFIT_RMSE: np.array([rmse is None or float(rmse) <= lim.max_rmse]),
    }
    # Written as "within the limit", so that NaN fails every check it enters.
    return [reason for reason, ok in checks.items() if not np.all(ok)]


def _rates_iv(states: Track | ObjectTrack, t: ArrayLike | None
              ) -> tuple[np.ndarray, ...]:
    """t, v, θ, v̇, θ̇ of states, or of a track at ``t`` (its splines only: no quadrature)."""
    if isinstance(states, ObjectTrack):
        track = states
        if t is None:  # the default grid: the search and the campaign check one track repeatedly
            return _default_rates(track.t0, track.t1, track.speed.coefficients.tobytes(),
                                  track.heading.coefficients.tobytes())
        times = t
        times = np.asarray(times, dtype=np.float64)
        if times.ndim != 1 or len(times) < 1:
            raise SimcredError(f"times must be 1-D and not empty, got shape {times.shape}")
        return (times, track.speed(times), track.heading(times), track.speed.derivative(times),
                track.heading.derivative(times))
    if not isinstance(states, Track):
        raise SimcredError(f"states must be Track or an ObjectTrack, got "
                           f"{type(states).__name__}")
    if t is not None:
        raise SimcredError("t is only for an ObjectTrack: Track carry their own times")
    names = ("t", "v", "heading", "acceleration", "yaw_rate")
    arrays = tuple(np.asarray(getattr(states, name), dtype=np.float64) for name in names)
    for name, array in zip(names, arrays, strict=True):
        if array.shape != arrays[0].shape or array.ndim != 1:
            raise SimcredError(f"states.{name} must be 1-D like states.t {arrays[0].shape}, got "
                               f"shape {array.shape}")
    return arrays


@lru_cache(maxsize=16)
def _default_rates(t0: float, t1: float, speed: bytes, heading: bytes) -> tuple[np.ndarray, ...]:
    """t, v, θ, v̇, θ̇ every :data:`PLAUSIBILITY_DT` of the track with these splines (read-only),
    cached for recent tracks: the same numbers as sampled anew (the same computation)."""
    track = ObjectTrack(0.0, 0.0, Spline(t0, t1, np.frombuffer(speed)),
                        Spline(t0, t1, np.frombuffer(heading)))
    times = sample_times(t0, t1, PLAUSIBILITY_DT)
    out = (times, track.speed(times), track.heading(times), track.speed.derivative(times),
           track.heading.derivative(times))
    for array in out:
        array.setflags(write=False)
    return out
