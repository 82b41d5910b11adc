"""Local variation of a traffic object's trajectory, Wagner, Groh et al. [1] sec. V.

The traffic object's (TO's) path is cut into equitemporal sections. Its fix points
P_0 … P_n at the section bounds τ_0 = t0 < … < τ_n = t1 carry a piecewise cubic Bézier curve
(:class:`BezierPath`) that is C² at every inner fix point. Its inner control points follow from
C¹ and C² continuity and four end conditions: the velocity vectors at τ_0 and τ_n ([1] sec. V).
Only the fix points around the TO's crossing of the EGO's lane boundary are displaced, by seeded
random road-frame offsets. The varied path is sampled at the description's times and refitted
with :func:`~simcred.scenario.fit.fit_track`, which restores smooth v(t) and θ(t) ([1] sec. V,
second paragraph). Variations that break :class:`PlausibilityLimits` are rejected and counted by
reason.

Variation ``i`` draws only from ``stream(seed, i)``. It is therefore the same whether it is made
alone (:func:`vary_one`), within any ``n`` (:func:`generate_variations`) or on any Dask worker.

Deviations from [1], which leaves these open:

* The samples are the description's positions plus the *change* of the Bézier path,
  B(P + D) − B(P), not B(P + D) itself (``keep_residual``; see :func:`vary_one`).
* The offsets (truncated normal, road frame), the window (2 fix points each side of the crossing)
  and the section length (1 s) are simcred's choices (:class:`VariationOptions`).
* Plausibility limits and rejection by reason are simcred's; [1] keeps every variation and notes
  "a few outliers".
* The refit starts its section search at the original track's sections (``warm_sections``).

References
----------
[1] Wagner, Groh, Kühbeck, Knoll, Towards Cross-Verification and Use of Simulation in the
    Assessment of Automated Driving (seed 002), sec. V; sec. II-B (the fit).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from enum import StrEnum
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.linalg import solve_banded
from scipy.special import ndtr, ndtri

from simcred._json import dumps, envelope
from simcred.engine import Engine, Progress, shared
from simcred.errors import OptionError, SimcredError
from simcred.kinematics import Track
from simcred.scenario.description import (
    ObjectTrack,
    ScenarioDescription,
    sample_times,
)
from simcred.scenario.fit import THRESHOLD, fit_track
from simcred.seeds import stream

KIND = "variation_set"
METHOD = ("clamped C2 cubic Bezier path through equitemporal fix points, displaced around the "
          "lane crossing and refitted by fit_track; [1] sec. V")
BOUNDARY_Y = 1.75
"""Default lateral position (m) of the EGO's lane boundary: half a 3.5 m lane left of y = 0."""
PLAUSIBILITY_DT = 0.01
"""Sampling step (s) of :func:`check_plausibility` for an :class:`ObjectTrack`."""
_BERNSTEIN_FACTOR = (1.0, 3.0, 6.0, 6.0)  # 3! / (3 - order)!: the Bézier derivative factor


# -- the Bézier path ------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True, eq=False)
class BezierPath:
    """A piecewise cubic Bézier curve in the plane, parametrised by time, [1] sec. V.

    Section k covers [τ_k, τ_{k+1}] with local parameter u = (t − τ_k) / h_k,
    h_k = τ_{k+1} − τ_k, and control points C_k0 … C_k3:
    p(t) = Σ_i binom(3, i) u^i (1 − u)^(3−i) C_ki.

    Parameters
    ----------
    times : array_like, shape (n + 1,)
        Fix times τ_0 < … < τ_n (s), finite; n ≥ 1.
    control_points : array_like, shape (n, 4, 2)
        Control points (m) of every section.

    Notes
    -----
    Any control points are accepted; :meth:`through` builds the C² path of [1] sec. V. There is no
    extrapolation: times outside [τ_0, τ_n] raise :class:`~simcred.errors.SimcredError`. At an
    inner fix time, the section that starts there is evaluated. Equality is identity.

    Examples
    --------
    >>> path = BezierPath.through([0.0, 1.0, 2.0], [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0]],
    ...                           start_velocity=[1.0, 0.0], end_velocity=[1.0, 0.0])
    >>> path([0.5, 1.5]).tolist(), path.derivative([1.0]).round(12).tolist()
    ([[0.5, 0.0], [1.5, 0.0]], [[1.0, 0.0]])
    """

    times: np.ndarray
    control_points: np.ndarray

    def __post_init__(self) -> None:
        times = _fix_times_iv(self.times)
        c = np.array(self.control_points, dtype=np.float64)
        if c.shape != (len(times) - 1, 4, 2):
            raise SimcredError(f"control_points must have shape ({len(times) - 1}, 4, 2) for "
                               f"{len(times)} fix times, got {c.shape}")
        if not np.all(np.isfinite(c)):
            raise SimcredError("control_points must be finite")
        c.setflags(write=False)
        object.__setattr__(self, "times", times)
        object.__setattr__(self, "control_points", c)

    @property
    def sections(self) -> int:
        return len(self.times) - 1

    @property
    def fix_points(self) -> np.ndarray:
        """P_0 … P_n, shape (n + 1, 2): every section's first control point and the last one."""
        c = self.control_points
        return np.concatenate([c[:, 0], c[-1:, 3]])

    def __call__(self, t: ArrayLike) -> np.ndarray:
        """Positions at times ``t`` (any shape), shape (*t.shape, 2)."""
        return self._evaluate(t, 0)

    def derivative(self, t: ArrayLike, order: int = 1) -> np.ndarray:
        """The ``order``-th time derivative (1, 2 or 3) at times ``t``, shape (*t.shape, 2)."""
        if isinstance(order, bool) or order not in (1, 2, 3):
            raise SimcredError(f"derivative order must be 1, 2 or 3, got {order!r}")
        return self._evaluate(t, order)

    @classmethod
    def through(cls, times: ArrayLike, points: ArrayLike, start_velocity: ArrayLike,
                end_velocity: ArrayLike) -> BezierPath:
        """The C² path through ``points`` at ``times`` with the given end velocities, [1] sec. V.

        Parameters
        ----------
        times : array_like, shape (n + 1,)
            Fix times τ_k (s), strictly increasing; n ≥ 1.
        points : array_like, shape (n + 1, 2)
            Fix points P_k (m).
        start_velocity, end_velocity : array_like, shape (2,)
            Velocity vectors p'(τ_0) and p'(τ_n) (m/s): speed and heading at both ends.

        Returns
        -------
        BezierPath

        Notes
        -----
        With m_k = p'(τ_k), section k has the control points P_k, P_k + h_k m_k / 3,
        P_{k+1} − h_k m_{k+1} / 3, P_{k+1}; so the path is C⁰ and C¹ by construction. C² at every
        inner fix point gives, for k = 1 … n − 1,

        .. math:: h_k m_{k-1} + 2 (h_{k-1} + h_k) m_k + h_{k-1} m_{k+1}
                  = 3 (h_k d_{k-1} + h_{k-1} d_k), \\quad d_k = (P_{k+1} - P_k) / h_k,

        and the end conditions fix m_0 and m_n. The tridiagonal system is strictly diagonally
        dominant, hence uniquely solvable; it is solved by ``scipy.linalg.solve_banded`` for both
        coordinates at once. The result is the clamped cubic spline through the fix points.
        """
        tau = _fix_times_iv(times)
        p = _array_iv(points, (len(tau), 2), "points")
        v0 = _array_iv(start_velocity, (2,), "start_velocity")
        v1 = _array_iv(end_velocity, (2,), "end_velocity")
        m = _clamped_slopes(tau, p, v0, v1)  # [1] sec. V: C² joints plus four end conditions
        h = np.diff(tau)[:, None]
        control = np.stack([p[:-1], p[:-1] + h * m[:-1] / 3, p[1:] - h * m[1:] / 3, p[1:]],
                           axis=1)
        return cls(tau, control)

    def _evaluate(self, t: ArrayLike, order: int) -> np.ndarray:
        t = np.asarray(t, dtype=np.float64)
        flat = t.ravel()
        tau = self.times
        if flat.size and not (np.all(np.isfinite(flat)) and flat.min() >= tau[0]
                              and flat.max() <= tau[-1]):
            bad = flat[~(np.isfinite(flat) & (flat >= tau[0]) & (flat <= tau[-1]))][0]
            raise SimcredError(f"time {float(bad)!r} is outside the path's span "
                               f"[{tau[0]!r}, {tau[-1]!r}] (no extrapolation)")
        k = np.clip(np.searchsorted(tau, flat, side="right") - 1, 0, self.sections - 1)
        h = tau[k + 1] - tau[k]
        u = (flat - tau[k]) / h
        coefficients = np.diff(self.control_points[k], n=order, axis=1)  # (m, 4 - order, 2)
        degree = 3 - order
        basis = np.stack([math.comb(degree, i) * u**i * (1 - u) ** (degree - i)
                          for i in range(degree + 1)], axis=1)
        values = np.einsum("mi,mic->mc", basis, coefficients)
        values *= (_BERNSTEIN_FACTOR[order] / h**order)[:, None]
        return values.reshape(*t.shape, 2)


def _clamped_slopes(tau: np.ndarray, p: np.ndarray, v0: np.ndarray, v1: np.ndarray
                    ) -> np.ndarray:
    """m_k = p'(τ_k) of the clamped cubic spline through (τ_k, P_k), shape (n + 1, 2)."""
    n = len(tau) - 1
    h = np.diff(tau)
    d = np.diff(p, axis=0) / h[:, None]
    m = np.empty_like(p)
    m[0], m[-1] = v0, v1
    if n == 1:
        return m
    hl, hr = h[:-1], h[1:]  # h_{k-1}, h_k for k = 1 … n - 1
    rhs = 3 * (hr[:, None] * d[:-1] + hl[:, None] * d[1:])
    rhs[0] -= hr[0] * v0
    rhs[-1] -= hl[-1] * v1
    banded = np.zeros((3, n - 1))
    banded[0, 1:] = hl[:-1]  # superdiagonal: h_{k-1} · m_{k+1}
    banded[1] = 2 * (hl + hr)
    banded[2, :-1] = hr[1:]  # subdiagonal: h_k · m_{k-1}
    m[1:-1] = solve_banded((1, 1), banded, rhs)
    return m


def influence(times: ArrayLike, index: int, *, samples: int = 64) -> np.ndarray:
    """The locality measure: how far a unit displacement of one fix point reaches, in sections.

    Displace fix point ``index`` (an inner one) by a unit vector, keep every other fix point and
    both end velocities. By linearity the path moves by D(t), the path through the unit vector at
    ``index`` and zeros elsewhere with zero end velocities. Entry d of the result is
    max |D(t)| over the sections at distance d: the two sections that meet at the fix point are
    at distance 0, the next ones outward at distance 1, and so on.

    Parameters
    ----------
    times : array_like, shape (n + 1,)
        Fix times.
    index : int
        The displaced fix point, 0 < index < n.
    samples : int, default: 64
        Evaluation points per section (both bounds included).

    Returns
    -------
    numpy.ndarray, shape (max(index, n − index),)

    Notes
    -----
    On a long uniform grid the slopes of D decay as m_{k+1} = −(2 − √3) m_k away from the
    displaced point, so the ratio of neighbouring entries tends to 2 − √3 ≈ 0.268 per section.
    """
    tau = _fix_times_iv(times)
    n = len(tau) - 1
    if isinstance(index, bool) or not isinstance(index, int | np.integer) or not 0 < index < n:
        raise OptionError(f"index must be an inner fix point 1 … {n - 1}, got {index!r}")
    unit = np.zeros((n + 1, 2))
    unit[index, 0] = 1.0
    path = BezierPath.through(tau, unit, np.zeros(2), np.zeros(2))
    u = np.linspace(0.0, 1.0, samples)
    section_max = np.array([np.abs(path(tau[k] + u * (tau[k + 1] - tau[k]))[:, 0]).max()
                            for k in range(n)])
    distance = np.where(np.arange(n) < index, index - 1 - np.arange(n), np.arange(n) - index)
    out = np.zeros(max(index, n - index))
    np.maximum.at(out, distance, section_max)
    return out


# -- plausibility ---------------------------------------------------------------------------------


class Reason(StrEnum):
    """Why a variation is rejected; the names of :attr:`VariationSet.rejections`."""

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
    """Driving-dynamics bounds for a varied TO track (SI units), [1] sec. V "physically feasible".

    Parameters
    ----------
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
            if name not in ("min_acceleration", "curvature_min_speed") and value <= 0:
                raise OptionError(f"plausibility limit {name} must be > 0, got {value!r}")
        if self.min_acceleration >= 0:
            raise OptionError(f"min_acceleration must be < 0, got {self.min_acceleration!r}")
        if self.curvature_min_speed < 0:
            raise OptionError(f"curvature_min_speed must be >= 0, got "
                              f"{self.curvature_min_speed!r}")


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
    >>> from simcred.scenario.description import Spline
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
        times = sample_times(track.t0, track.t1, PLAUSIBILITY_DT) if t is None else t
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


# -- options --------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class VariationOptions:
    """How the TO's path is varied, [1] sec. V.

    Parameters
    ----------
    section : float, default: 1.0
        Target section length (s). The TO's span T gets n = max(1, round(T / section)) equal
        sections. 1 s puts 3–4 fix points into a 3 s lane change, fine enough to reshape it. An
        offset δ of one fix point changes the acceleration there by about 4.4 δ / section²
        (1.3 m/s² for 0.3 m), so halving the section quadruples it.
    window : int, default: 2
        Fix points varied on each side of the lane crossing: the ``window`` last fix points at or
        before it and the ``window`` first after it; never the first or last fix point, which
        carry the end conditions.
    sigma_lon, sigma_lat : float, default: 0.3, 0.3
        Standard deviations (m) of the longitudinal (x) and lateral (y) offsets of a fix point,
        in the road frame (the road runs along +x, as in simcred's scenarios). On the reference
        cut-in (braking at −6.6 m/s²) these keep 95 % of the variations; σ_lon = 1 m keeps a
        third (docs/variation.md).
    truncation : float or None, default: 2.0
        Offsets are normal, truncated at ± truncation · σ (None: not truncated). Truncation keeps
        single draws from dominating the rejections.
    boundary_y : float, optional
        Lateral position (m) of the EGO's lane boundary; default ``metadata["road"]["boundary_y"]``
        of the description, else 1.75 m.
    crossing_time : float, optional
        Time (s) of the lane crossing; default the first time the TO's y crosses ``boundary_y``
        (sampled every 0.01 s, interpolated linearly).
    sample_dt : float, optional
        Step (s) at which the varied path is sampled and refitted; default the description's
        ``dt``.
    threshold : float, optional
        Refit threshold (m); default ``metadata["fit"]["threshold"]`` of the description (the one
        it was fitted with), else :data:`~simcred.scenario.fit.THRESHOLD`.
    keep_residual : bool, default: True
        Sample the description plus the displacement of the Bézier path (True), or the Bézier path
        itself (False, literally [1]); see Notes of :func:`vary_one`.
    warm_sections : bool, default: True
        Start the refit's section search at the original TO track's sections instead of one per
        4 s (faster; the refit never has fewer sections than the original).
    """

    section: float = 1.0
    window: int = 2
    sigma_lon: float = 0.3
    sigma_lat: float = 0.3
    truncation: float | None = 2.0
    boundary_y: float | None = None
    crossing_time: float | None = None
    sample_dt: float | None = None
    threshold: float | None = None
    keep_residual: bool = True
    warm_sections: bool = True

    def __post_init__(self) -> None:
        _positive("section", self.section)
        if isinstance(self.window, bool) or not isinstance(self.window, int | np.integer) \
                or self.window < 1:
            raise OptionError(f"window must be an integer >= 1, got {self.window!r}")
        for name in ("sigma_lon", "sigma_lat"):
            value = getattr(self, name)
            if not (_is_real(value) and math.isfinite(value) and value >= 0):
                raise OptionError(f"{name} must be a finite number >= 0, got {value!r}")
        for name in ("truncation", "sample_dt", "threshold"):
            if getattr(self, name) is not None:
                _positive(name, getattr(self, name))
        for name in ("boundary_y", "crossing_time"):
            value = getattr(self, name)
            if value is not None and not (_is_real(value) and math.isfinite(value)):
                raise OptionError(f"{name} must be a finite number, got {value!r}")
        for name in ("keep_residual", "warm_sections"):
            if not isinstance(getattr(self, name), bool):
                raise OptionError(f"{name} must be True or False, got {getattr(self, name)!r}")


def _is_real(value: Any) -> bool:
    return isinstance(value, int | float | np.integer | np.floating) and not isinstance(value, bool)


def _positive(name: str, value: Any) -> None:
    if not (_is_real(value) and math.isfinite(value) and value > 0):
        raise OptionError(f"{name} must be a finite number > 0, got {value!r}")


# -- results --------------------------------------------------------------------------------------


class Status(StrEnum):
    KEPT = "kept"
    REJECTED = "rejected"


@dataclass(frozen=True, slots=True, eq=False)
class VariationRecord:
    """What happened to variation ``index``.

    Attributes
    ----------
    index : int
        The variation's index: its random stream is ``stream(seed, index)``.
    displacements : numpy.ndarray, shape (k, 2)
        Longitudinal and lateral offset (m) of each varied fix point, in the order of
        :attr:`VariationSet.varied`.
    rmse : float
        Position RMSE (m) of the refit against the sampled varied path (nan if it failed).
    sections : int
        Sections of the refitted TO track (0 if the refit failed).
    status : Status
        ``kept`` or ``rejected``.
    reasons : tuple of Reason
        Violated limits; empty for a kept variation.
    """

    index: int
    displacements: np.ndarray
    rmse: float
    sections: int
    status: Status
    reasons: tuple[Reason, ...]

    def to_json(self) -> dict[str, Any]:
        return {"index": self.index, "status": self.status.value,
                "reasons": [r.value for r in self.reasons],
                "displacements": self.displacements.tolist(),
                "rmse": self.rmse if math.isfinite(self.rmse) else None,
                "sections": self.sections}


@dataclass(frozen=True, slots=True, eq=False)
class Variation:
    """One variation: its record, the varied description and the varied Bézier path.

    ``description`` is the original with the TO's track replaced by the refit (EGO and every
    other object unchanged); it is there for rejected variations too, to inspect them (the
    original itself if the refit failed). ``path`` is the varied Bézier path B(P + D).
    """

    record: VariationRecord
    description: ScenarioDescription
    path: BezierPath

    @property
    def index(self) -> int:
        return self.record.index

    @property
    def displacements(self) -> np.ndarray:
        return self.record.displacements

    @property
    def kept(self) -> bool:
        return self.record.status is Status.KEPT


@dataclass(frozen=True, slots=True, eq=False)
class VariationSet:
    """The variations of one description, [1] sec. V (Fig. 8: 300 variations).

    Attributes
    ----------
    variations : tuple of Variation
        The kept variations, by index.
    records : tuple of VariationRecord
        Every generated variation, kept or rejected, by index.
    seed : int
        The seed (the drawn entropy if none was given): variation i uses ``stream(seed, i)``.
    to, ego : str
        The varied object and the EGO (unchanged).
    fix_times : numpy.ndarray
        τ_0 … τ_n (s).
    varied : tuple of int
        Indices of the displaced fix points.
    crossing_time : float
        The lane crossing (s) the window is centred on.
    boundary_y : float or None
        The lane boundary (m) used to find it (None if ``crossing_time`` was given).
    threshold : float
        The refit threshold (m).
    original_reasons : tuple of Reason
        Limits the original TO track itself violates: if it is not empty, most variations will
        be rejected for the same reasons.
    options, limits
        The settings used.
    base : ScenarioDescription
        The original description.
    """

    variations: tuple[Variation, ...]
    records: tuple[VariationRecord, ...]
    seed: int
    to: str
    ego: str
    fix_times: np.ndarray
    varied: tuple[int, ...]
    crossing_time: float
    boundary_y: float | None
    threshold: float
    original_reasons: tuple[Reason, ...]
    options: VariationOptions
    limits: PlausibilityLimits
    base: ScenarioDescription
    method: str = METHOD

    @property
    def generated(self) -> int:
        return len(self.records)

    @property
    def kept(self) -> int:
        return sum(r.status is Status.KEPT for r in self.records)

    @property
    def rejected(self) -> int:
        return self.generated - self.kept

    @property
    def rejections(self) -> dict[str, int]:
        """Rejected variations per violated limit (a variation counts once for each of its
        reasons, so the counts may sum to more than :attr:`rejected`); only reasons that
        occurred, in the order of :class:`Reason`."""
        counts = {reason.value: sum(reason in r.reasons for r in self.records) for reason in Reason}
        return {reason: count for reason, count in counts.items() if count}

    def to_json(self) -> dict[str, Any]:
        """The JSON document: settings, counts, every record, and each kept variation's TO track.

        Deterministic (same set, same text) and float-exact; read the descriptions back with
        :func:`load_variations`.
        """
        tracks = {v.index: v.description.to_json()["objects"][self.to] for v in self.variations}
        records = []
        for record in self.records:
            entry = record.to_json()
            if record.index in tracks:
                entry["track"] = tracks[record.index]
            records.append(entry)
        return envelope(KIND, {
            "method": self.method, "seed": self.seed, "to": self.to, "ego": self.ego,
            "options": asdict(self.options), "limits": asdict(self.limits),
            "fix_times": self.fix_times.tolist(), "varied": list(self.varied),
            "crossing_time": self.crossing_time, "boundary_y": self.boundary_y,
            "threshold": self.threshold,
            "original_reasons": [r.value for r in self.original_reasons],
            "generated": self.generated, "kept": self.kept, "rejected": self.rejected,
            "rejections": self.rejections, "records": records,
            "description": self.base.to_json(),
        })

    def write(self, path: str | Path) -> Path:
        """Write :meth:`to_json` to ``path`` (deterministic, indented JSON)."""
        path = Path(path)
        path.write_text(dumps(self.to_json()), encoding="utf-8")
        return path


def load_variations(source: Mapping[str, Any] | str | Path) -> dict[int, ScenarioDescription]:
    """The kept varied descriptions of a variations document or file, by index.

    Parameters
    ----------
    source : mapping or path
        A document from :meth:`VariationSet.to_json` or a file written by
        :meth:`VariationSet.write`.

    Returns
    -------
    dict of int to ScenarioDescription
        Equal (:meth:`ScenarioDescription.equals`) to the variations that were written.
    """
    where = "<memory>"
    if isinstance(source, str | Path):
        where = str(source)
        try:
            source = json.loads(Path(source).read_text(encoding="utf-8"))
        except OSError as exc:
            raise SimcredError(f"{where}: cannot read: {exc.strerror or exc}") from None
        except (UnicodeDecodeError, json.JSONDecodeError):
            raise SimcredError(f"{where}: not a JSON variations file") from None
    if not isinstance(source, Mapping) or source.get("kind") != KIND:
        raise SimcredError(f"{where}: not a variations document (kind must be {KIND!r})")
    for key, kind in (("description", Mapping), ("records", list), ("to", str), ("seed", int)):
        if not isinstance(source.get(key), kind):
            raise SimcredError(f"{where}: missing or malformed key '{key}'")
    base, to = source["description"], source["to"]
    out = {}
    for i, record in enumerate(source["records"]):
        if not isinstance(record, Mapping):
            raise SimcredError(f"{where}: records[{i}] must be an object")
        if record.get("status") != Status.KEPT.value:
            continue
        if "track" not in record or not isinstance(record.get("index"), int):
            raise SimcredError(f"{where}: records[{i}]: a kept record needs 'index' and 'track'")
        try:
            provenance = _provenance(VariationRecord(
                record["index"], np.array(record["displacements"], dtype=np.float64),
                float(record["rmse"]), int(record["sections"]), Status.KEPT, ()),
                source["seed"], to)
        except (KeyError, TypeError, ValueError):
            raise SimcredError(f"{where}: records[{i}]: malformed displacements, rmse or "
                               "sections") from None
        document = {**base, "objects": {**base.get("objects", {}), to: record["track"]},
                    "metadata": {**base.get("metadata", {}), "variation": provenance}}
        out[record["index"]] = ScenarioDescription.from_json(
            document, source=f"{where}: records[{i}]")
    return out


# -- variation ------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True, eq=False)
class _Plan:
    """Everything about one description's variations that does not depend on the index."""

    description: ScenarioDescription
    to: str
    options: VariationOptions
    limits: PlausibilityLimits
    fix_times: np.ndarray
    fix_points: np.ndarray
    start_velocity: np.ndarray
    end_velocity: np.ndarray
    varied: tuple[int, ...]
    crossing_time: float
    boundary_y: float | None
    threshold: float
    t: np.ndarray
    x: np.ndarray
    y: np.ndarray


def _plan(description: ScenarioDescription, to: str, ego: str, options: VariationOptions,
          limits: PlausibilityLimits) -> _Plan:
    _objects_iv(description, to, ego)
    if not isinstance(options, VariationOptions):
        raise OptionError(f"options must be VariationOptions, got {type(options).__name__}")
    if not isinstance(limits, PlausibilityLimits):
        raise OptionError(f"limits must be PlausibilityLimits, got {type(limits).__name__}")
    track = description.objects[to]
    n = max(1, round((track.t1 - track.t0) / options.section))
    tau = np.linspace(track.t0, track.t1, n + 1)
    tau[0], tau[-1] = track.t0, track.t1
    t = sample_times(track.t0, track.t1, options.sample_dt or description.dt)
    if len(t) < 8:
        raise OptionError(f"sample_dt gives {len(t)} samples over the TO's span, at least 8 are "
                          "needed for the refit")
    x, y = track.positions(t)
    ends = track.states(np.array([track.t0, track.t1]))
    velocity = np.column_stack([ends.v * np.cos(ends.heading), ends.v * np.sin(ends.heading)])
    crossing, boundary = _crossing(track, description, options, to)
    return _Plan(description, to, options, limits, tau, np.column_stack(track.positions(tau)),
                 velocity[0], velocity[1], _varied(tau, crossing, options.window, to),
                 crossing, boundary, _threshold(description, options), t, x, y)


def _crossing(track: ObjectTrack, description: ScenarioDescription, options: VariationOptions,
              to: str) -> tuple[float, float | None]:
    """The first time the TO's y crosses the boundary (linear between samples 0.01 s apart)."""
    if options.crossing_time is not None:
        c = float(options.crossing_time)
        if not track.t0 <= c <= track.t1:
            raise OptionError(f"crossing_time {c!r} is outside the span of object '{to}' "
                              f"[{track.t0!r}, {track.t1!r}]")
        return c, None
    boundary = options.boundary_y
    if boundary is None:
        road = description.metadata.get("road")
        given = road.get("boundary_y") if isinstance(road, Mapping) else None
        boundary = float(given) if _is_real(given) and math.isfinite(given) else BOUNDARY_Y
    t = sample_times(track.t0, track.t1, PLAUSIBILITY_DT)
    y = track.positions(t)[1]
    s = y - boundary
    change = np.flatnonzero((s[:-1] * s[1:] <= 0) & (s[:-1] != s[1:]))
    if change.size == 0:
        raise SimcredError(f"object '{to}' never crosses the lane boundary y = {boundary!r} m "
                           f"(y from {y.min():.3f} to {y.max():.3f} m); pass crossing_time or "
                           "boundary_y")
    i = int(change[0])
    c = t[i] + (t[i + 1] - t[i]) * s[i] / (s[i] - s[i + 1])
    return float(c), float(boundary)


def _varied(tau: np.ndarray, crossing: float, window: int, to: str) -> tuple[int, ...]:
    before = np.flatnonzero(tau <= crossing)[-window:]
    after = np.flatnonzero(tau > crossing)[:window]
    inner = [int(k) for k in np.concatenate([before, after]) if 0 < k < len(tau) - 1]
    if not inner:
        raise SimcredError(f"object '{to}': no inner fix point within {window} of the crossing "
                           f"at t = {crossing:.3f} s ({len(tau) - 1} sections): use a shorter "
                           "section")
    return tuple(inner)


def _threshold(description: ScenarioDescription, options: VariationOptions) -> float:
    if options.threshold is not None:
        return float(options.threshold)
    fit = description.metadata.get("fit")
    given = fit.get("threshold") if isinstance(fit, Mapping) else None
    if _is_real(given) and math.isfinite(given) and given > 0:
        return float(given)
    return THRESHOLD


def draw_displacements(seed: int, index: int, count: int,
                       options: VariationOptions = VariationOptions()) -> np.ndarray:
    """The offsets of variation ``index``: shape (count, 2), columns longitudinal and lateral (m).

    Drawn from ``stream(seed, index)`` only: a uniform array U of shape (count, 2), mapped by the
    inverse normal CDF onto the normal law truncated at ± ``truncation`` σ
    (z = Φ⁻¹(Φ(−c) + (Φ(c) − Φ(−c)) U)), then scaled by (σ_lon, σ_lat); without truncation,
    ``standard_normal((count, 2))``. One draw per offset, no rejection loop.
    """
    _index_iv(index, seed)
    _count_iv(count, "count")
    rng = stream(seed, index)
    if options.truncation is None:
        z = rng.standard_normal((count, 2))
    else:
        low, high = ndtr(-options.truncation), ndtr(options.truncation)
        z = ndtri(low + (high - low) * rng.random((count, 2)))
    return z * np.array([options.sigma_lon, options.sigma_lat])


def vary_one(
    description: ScenarioDescription,
    index: int,
    seed: int,
    *,
    to: str = "to",
    ego: str = "ego",
    options: VariationOptions = VariationOptions(),
    limits: PlausibilityLimits = PlausibilityLimits(),
    displacements: ArrayLike | None = None,
) -> Variation:
    """Variation ``index`` of the TO's trajectory, [1] sec. V.

    Parameters
    ----------
    description : ScenarioDescription
        The original scenario.
    index : int
        Variation index (≥ 0); its offsets come from ``stream(seed, index)`` only.
    seed : int
        Seed of the variation set (≥ 0).
    to, ego : str, default: "to", "ego"
        The varied object, and the EGO (kept unchanged; it must exist and differ from ``to``).
    options : VariationOptions, default: VariationOptions()
        Sections, window, offsets, sampling, refit.
    limits : PlausibilityLimits, default: PlausibilityLimits()
        Bounds for rejection.
    displacements : array_like, shape (k, 2), optional
        Explicit offsets (m) for the k varied fix points instead of random ones.

    Returns
    -------
    Variation
        ``kept`` if the refitted track meets every limit; else rejected, with its reasons.

    Notes
    -----
    1. Fix points P_k = TO position at τ_k (equitemporal, ``options.section``); end velocities
       v (cos θ, sin θ) at the TO's t0 and t1 ([1] sec. V: "fix the velocity and heading values
       at the start of the first and at the end of the last Bézier curve").
    2. The fix points near the crossing get offsets D_k (see :func:`draw_displacements`); the
       varied Bézier path is B(P + D) (:meth:`BezierPath.through`).
    3. The path is sampled at t0 + j · ``sample_dt`` and refitted with
       :func:`~simcred.scenario.fit.fit_track` at the description's threshold ([1] sec. V,
       "applying again the fitting algorithm"); the refit replaces the TO's track.
    4. :func:`check_plausibility` on the refit (every 0.01 s) decides kept or rejected.

    Deviation from [1]: by default (``keep_residual``) the samples are the description's own
    positions plus B(P + D) − B(P), which by linearity of :meth:`BezierPath.through` is the
    path through the offsets D with zero end velocities. [1] samples B(P + D) itself; its
    residual against the description (5 cm RMSE, 16 cm max for 1 s sections on the reference
    cut-in, which brakes abruptly) would enter every variation, even the unvaried one. With
    ``keep_residual=False`` that is what happens. The change has the same locality
    (:func:`influence`) in both.
    """
    _index_iv(index, seed)
    plan = _plan(description, to, ego, options, limits)
    return _vary(plan, int(index), int(seed), displacements)


def _vary(plan: _Plan, index: int, seed: int, displacements: ArrayLike | None) -> Variation:
    k = len(plan.varied)
    if displacements is None:
        offsets = draw_displacements(seed, index, k, plan.options)
    else:
        offsets = _array_iv(displacements, (k, 2), "displacements")
    moved = np.zeros_like(plan.fix_points)
    moved[list(plan.varied)] = offsets
    path = BezierPath.through(plan.fix_times, plan.fix_points + moved, plan.start_velocity,
                              plan.end_velocity)
    if plan.options.keep_residual:
        # B(P + D) − B(P) = B(D) with zero end velocities (the system is linear in P, v0, v1).
        # Deviation from [1] sec. V, which samples B(P + D): see the Notes of vary_one.
        shift = BezierPath.through(plan.fix_times, moved, np.zeros(2), np.zeros(2))(plan.t)
        xy = np.column_stack([plan.x, plan.y]) + shift
    else:
        xy = path(plan.t)
    original = plan.description.objects[plan.to]
    try:  # [1] sec. V: "applying again the fitting algorithm explained in section II-B"
        fit = fit_track(plan.t, xy[:, 0], xy[:, 1], threshold=plan.threshold,
                        initial_sections=original.sections if plan.options.warm_sections
                        else None, length=original.length, width=original.width, name=plan.to)
    except SimcredError:
        record = VariationRecord(index, offsets, math.nan, 0, Status.REJECTED,
                                 (Reason.REFIT_FAILED,))
        return Variation(record, plan.description, path)
    reasons = tuple(check_plausibility(fit.track, plan.limits, rmse=fit.rmse))
    record = VariationRecord(index, offsets, fit.rmse, fit.sections,
                             Status.REJECTED if reasons else Status.KEPT, reasons)
    metadata = {**plan.description.metadata, "variation": _provenance(record, seed, plan.to)}
    varied = ScenarioDescription({**plan.description.objects, plan.to: fit.track},
                                 dt=plan.description.dt, metadata=metadata)
    return Variation(record, varied, path)


def _provenance(record: VariationRecord, seed: int, to: str) -> dict[str, Any]:
    """The ``"variation"`` metadata entry of a varied description."""
    return {"index": record.index, "seed": seed, "object": to,
            "displacements": record.displacements.tolist(), "rmse": record.rmse,
            "sections": record.sections}


def generate_variations(
    description: ScenarioDescription,
    n: int,
    seed: int | None,
    *,
    to: str = "to",
    ego: str = "ego",
    options: VariationOptions = VariationOptions(),
    limits: PlausibilityLimits = PlausibilityLimits(),
    runner: Engine | None = None,
    chunk_size: int = 50,
    progress: Progress | None = None,
) -> VariationSet:
    """Variations 0 … n − 1 of the TO's trajectory, [1] sec. V; see :func:`vary_one`.

    Parameters
    ----------
    description : ScenarioDescription
        The original scenario.
    n : int
        Variations to generate (≥ 1); kept and rejected ones are both counted.
    seed : int or None
        Seed (≥ 0). None draws fresh entropy, stored in the result so that it replays.
    to, ego, options, limits
        As in :func:`vary_one`.
    runner : Engine, optional
        Where chunks of indices run (e.g. a :class:`~simcred.engine.DaskEngine`); default
        in-process. The result does not depend on it.
    chunk_size : int, default: 50
        Indices per task.
    progress : callable, optional
        Wraps the chunks, e.g. in a progress bar.

    Returns
    -------
    VariationSet

    Examples
    --------
    >>> from simcred.scenario.fit import fit_track
    >>> t = np.linspace(0.0, 8.0, 81)
    >>> lane = 3.5 - 3.5 * np.clip((t - 2.0) / 4.0, 0.0, 1.0) ** 2 * (
    ...     3.0 - 2.0 * np.clip((t - 2.0) / 4.0, 0.0, 1.0))
    >>> to = fit_track(t, 30.0 + 25.0 * t, lane).track
    >>> ego = fit_track(t, 27.0 * t, 0.0 * t).track
    >>> base = ScenarioDescription({"ego": ego, "to": to}, dt=0.1)
    >>> result = generate_variations(base, 4, seed=1)
    >>> result.generated, round(result.crossing_time, 2), result.varied
    (4, 4.0, (3, 4, 5, 6))
    >>> result.kept + result.rejected == 4, result.records[2].displacements.shape
    (True, (4, 2))
    """
    plan = _plan(description, to, ego, options, limits)
    n = _count_iv(n, "n")
    chunk_size = _count_iv(chunk_size, "chunk_size")
    seed = int(np.random.SeedSequence().entropy) if seed is None else seed
    _index_iv(0, seed)
    chunks = [range(lo, min(lo + chunk_size, n)) for lo in range(0, n, chunk_size)]
    parts = (runner or Engine()).map(_vary_chunk, chunks,
                                     shared_values={"variation_plan": plan, "variation_seed": seed},
                                     progress=progress)
    done = [variation for part in parts for variation in part]
    original = plan.description.objects[to]
    return VariationSet(
        variations=tuple(v for v in done if v.kept),
        records=tuple(v.record for v in done), seed=int(seed), to=to, ego=ego,
        fix_times=plan.fix_times, varied=plan.varied, crossing_time=plan.crossing_time,
        boundary_y=plan.boundary_y, threshold=plan.threshold,
        original_reasons=tuple(check_plausibility(original, limits)),
        options=options, limits=limits, base=description)


def _vary_chunk(indices: range) -> list[Variation]:
    plan, seed = shared("variation_plan"), shared("variation_seed")
    return [_vary(plan, i, seed, None) for i in indices]


# -- validation -----------------------------------------------------------------------------------


def _fix_times_iv(times: ArrayLike) -> np.ndarray:
    try:
        tau = np.array(times, dtype=np.float64)
    except (TypeError, ValueError):
        raise SimcredError("fix times must be numbers") from None
    if tau.ndim != 1 or len(tau) < 2:
        raise SimcredError(f"fix times must be 1-D with at least 2 entries, got shape {tau.shape}")
    if not np.all(np.isfinite(tau)):
        raise SimcredError("fix times must be finite")
    step_ok = np.diff(tau) > 0
    if not step_ok.all():
        k = int(np.flatnonzero(~step_ok)[0]) + 1
        raise SimcredError(f"fix times must be strictly increasing: times[{k}] = {tau[k]!r} after "
                           f"{tau[k - 1]!r}")
    tau.setflags(write=False)
    return tau


def _array_iv(values: ArrayLike, shape: tuple[int, ...], name: str) -> np.ndarray:
    try:
        a = np.array(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise SimcredError(f"{name} must be numbers") from None
    if a.shape != shape:
        raise SimcredError(f"{name} must have shape {shape}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise SimcredError(f"{name} must be finite")
    return a


def _objects_iv(description: ScenarioDescription, to: str, ego: str) -> None:
    if not isinstance(description, ScenarioDescription):
        raise SimcredError(f"description must be a ScenarioDescription, got "
                           f"{type(description).__name__}")
    names = ", ".join(description.objects)
    for role, name in (("to", to), ("ego", ego)):
        if name not in description.objects:
            raise SimcredError(f"{role} object '{name}' is not in the description (have: {names})")
    if to == ego:
        raise OptionError(f"to and ego must be different objects, both are '{to}'")


def _count_iv(value: Any, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int | np.integer) or value < 1:
        raise OptionError(f"{name} must be an integer >= 1, got {value!r}")
    return int(value)


def _index_iv(index: Any, seed: Any) -> None:
    if isinstance(index, bool) or not isinstance(index, int | np.integer) or index < 0:
        raise OptionError(f"index must be an integer >= 0, got {index!r}")
    if isinstance(seed, bool) or not isinstance(seed, int | np.integer) or seed < 0:
        raise OptionError(f"seed must be an integer >= 0 (per-variation streams need an integer "
                          f"seed), got {seed!r}")

