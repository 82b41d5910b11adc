"""The C² cubic Bézier path through equitemporal fix points of [1] sec. V.

Its inner control points follow from C¹ and C² continuity and four end conditions: the velocity
vectors at τ_0 and τ_n. :func:`influence` says how far a fix point's displacement reaches.

References
----------
[1] Wagner, Groh, Kühbeck, Knoll, Towards Cross-Verification and Use of Simulation in the
    Assessment of Automated Driving (paper 002), sec. V.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.linalg import solve_banded

from simcred.errors import OptionError, SimcredError
from simcred.kinematics import read_only

_BERNSTEIN_FACTOR = (1.0, 3.0, 6.0, 6.0)  # 3! / (3 - order)!: the Bézier derivative factor


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
        times = fix_times_iv(self.times)
        c = read_only(self.control_points)
        if c.shape != (len(times) - 1, 4, 2):
            raise SimcredError(f"control_points must have shape ({len(times) - 1}, 4, 2) for "
                               f"{len(times)} fix times, got {c.shape}")
        if not np.all(np.isfinite(c)):
            raise SimcredError("control_points must be finite")
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
        tau = fix_times_iv(times)
        p = array_iv(points, (len(tau), 2), "points")
        v0 = array_iv(start_velocity, (2,), "start_velocity")
        v1 = array_iv(end_velocity, (2,), "end_velocity")
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
    tau = fix_times_iv(times)
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


def fix_times_iv(times: ArrayLike) -> np.ndarray:
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


def array_iv(values: ArrayLike, shape: tuple[int, ...], name: str) -> np.ndarray:
    try:
        a = np.array(values, dtype=np.float64)
    except (TypeError, ValueError):
        raise SimcredError(f"{name} must be numbers") from None
    if a.shape != shape:
        raise SimcredError(f"{name} must have shape {shape}, got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise SimcredError(f"{name} must be finite")
    return a

