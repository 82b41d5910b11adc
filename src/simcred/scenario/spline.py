"""The time curves of a scenario description and the integration that turns them into positions.

A :class:`Spline` is a cubic spline on uniform sections, stored as a clamped cubic B-spline
(speed v(t) and heading θ(t) of [1] sec. II-B). :class:`Quadrature` is the one integration scheme
of eq. (1) (Gauss–Legendre on a fixed grid) that *defines* the positions, so that the
description is unambiguous.

References
----------
[1] Wagner, Groh, Kühbeck, Knoll, Towards Cross-Verification and Use of Simulation in the
    Assessment of Automated Driving (paper 002), sec. II-B, eq. (1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np
from numpy.typing import ArrayLike
from scipy.interpolate import BSpline

from simcred.errors import SimcredError
from simcred.kinematics import read_only

DEGREE = 3


MAX_STEP = 0.05
"""Largest step (s) of the integration grid of eq. (1)."""


GAUSS_NODES = 4
"""Gauss–Legendre nodes per integration interval (exact for polynomials of degree 7)."""


_XI, _W = np.polynomial.legendre.leggauss(GAUSS_NODES)


_SPAN_TOLERANCE = 1e-9  # relative to max(1 s, t1 - t0): times this close to the span are clamped


@dataclass(frozen=True, slots=True, eq=False)
class Spline:
    """A cubic spline of time on ``sections`` uniform sections of [t0, t1].

    Stored as a clamped cubic B-spline: knots t0 (4 times), the ``sections - 1`` interior section
    bounds ``t0 + k (t1 - t0) / sections``, t1 (4 times); ``sections + 3`` coefficients. The spline
    is C² across section bounds. Equality is identity (floats are not compared); compare
    :attr:`coefficients` explicitly.

    Parameters
    ----------
    t0, t1 : float
        The time span, ``t0 < t1``.
    coefficients : array_like, shape (sections + 3,)
        B-spline coefficients; at least 4 (one section).

    Notes
    -----
    Evaluation outside [t0, t1] raises :class:`~simcred.errors.SimcredError`: there is no
    extrapolation. Times within ``1e-9 · max(1 s, t1 - t0)`` (plus 4 ulp of the times) of the
    span are clamped onto it, so that grids computed as ``t0 + k·dt`` reach ``t1`` despite
    rounding.

    Examples
    --------
    >>> s = Spline(0.0, 2.0, [1.0, 1.0, 1.0, 1.0, 1.0])
    >>> s.sections, float(s(1.5)), float(s.derivative(1.5))
    (2, 1.0, 0.0)
    """

    t0: float
    t1: float
    coefficients: np.ndarray
    _bspline: BSpline = field(init=False, repr=False)

    def __repr__(self) -> str:
        return f"Spline([{self.t0:g}, {self.t1:g}] s, {self.sections} sections)"


    def __post_init__(self) -> None:
        t0, t1 = float(self.t0), float(self.t1)
        if not (math.isfinite(t0) and math.isfinite(t1) and t0 < t1):
            raise SimcredError(f"spline span must be finite with t0 < t1, got [{t0!r}, {t1!r}]")
        c = read_only(self.coefficients)
        if c.ndim != 1 or len(c) < DEGREE + 1:
            raise SimcredError(f"spline needs a 1-D array of at least {DEGREE + 1} coefficients "
                               f"(sections + 3), got shape {c.shape}")
        if not np.all(np.isfinite(c)):
            raise SimcredError("spline coefficients must be finite")
        object.__setattr__(self, "t0", t0)
        object.__setattr__(self, "t1", t1)
        object.__setattr__(self, "coefficients", c)
        # The knots are valid by construction and c is checked above: skip BSpline's checks.
        object.__setattr__(self, "_bspline", BSpline.construct_fast(
            _knots(t0, t1, len(c) - DEGREE), c, DEGREE, extrapolate=False))

    def __reduce__(self) -> tuple:
        # Rebuilt through __init__, which copies the coefficients: Dask's out-of-band pickle
        # buffers can arrive unaligned, and scipy's spline evaluation refuses those.
        return (Spline, (self.t0, self.t1, self.coefficients))

    @property
    def sections(self) -> int:
        return len(self.coefficients) - DEGREE

    @property
    def knots(self) -> np.ndarray:
        return self._bspline.t

    def __call__(self, t: ArrayLike) -> np.ndarray:
        """Values at times ``t`` (any shape, inside [t0, t1])."""
        return self._bspline(self._in_span(t))

    def derivative(self, t: ArrayLike, order: int = 1) -> np.ndarray:
        """The ``order``-th time derivative (1, 2 or 3) at times ``t``."""
        if order not in (1, 2, 3):
            raise SimcredError(f"derivative order must be 1, 2 or 3, got {order!r}")
        return self._bspline(self._in_span(t), nu=order)

    def design(self, t: ArrayLike) -> np.ndarray:
        """The basis matrix ``B`` (len(t), sections + 3): ``self(t) == B @ self.coefficients``."""
        return design_matrix(self.t0, self.t1, self.sections, self._in_span(t))

    @classmethod
    def least_squares(cls, t: ArrayLike, values: ArrayLike, *, t0: float, t1: float,
                      sections: int, weights: ArrayLike | None = None) -> Spline:
        """The spline on ``sections`` sections of [t0, t1] closest to ``values`` at ``t``.

        Minimises Σ wᵢ (s(tᵢ) − valuesᵢ)²; the minimum-norm solution where the data do not pin
        every coefficient down.
        """
        t = np.asarray(t, dtype=np.float64)
        values = np.asarray(values, dtype=np.float64)
        if weights is not None:
            weights = np.asarray(weights, dtype=np.float64)
        if cls is not Spline or t.size > _CACHED_VALUES or values.shape != t.shape:
            return cls(t0, t1, _lstsq(t, values, float(t0), float(t1), sections, weights))
        # The fit smooths the same positions several times (speed, initial guess, reversals).
        return _least_squares_cached(
            float(t0), float(t1), sections, t.shape, t.tobytes(), values.tobytes(),
            None if weights is None else weights.tobytes())

    def _in_span(self, t: ArrayLike) -> np.ndarray:
        return in_span(t, self.t0, self.t1)


def _lstsq(t: np.ndarray, values: np.ndarray, t0: float, t1: float, sections: int,
           weights: np.ndarray | None) -> np.ndarray:
    basis = _design(t0, t1, sections, np.clip(t, t0, t1))
    if weights is not None:
        root = np.sqrt(weights)
        basis, values = basis * root[:, None], values * root
    return np.linalg.lstsq(basis, values, rcond=None)[0]


@lru_cache(maxsize=16)
def _least_squares_cached(t0: float, t1: float, sections: int, shape: tuple[int, ...],
                          times: bytes, values: bytes, weights: bytes | None) -> Spline:
    """:meth:`Spline.least_squares` of recent data (splines are immutable: shared)."""
    return Spline(t0, t1, _lstsq(np.frombuffer(times).reshape(shape), np.frombuffer(values),
                                 t0, t1, sections,
                                 None if weights is None else np.frombuffer(weights)))


def spline_knots(t0: float, t1: float, sections: int) -> np.ndarray:
    """Clamped cubic knot vector on ``sections`` uniform sections of [t0, t1]."""
    return np.concatenate([[t0] * DEGREE, np.linspace(t0, t1, sections + 1), [t1] * DEGREE])


@lru_cache(maxsize=256)
def _knots(t0: float, t1: float, sections: int) -> np.ndarray:
    """:func:`spline_knots`, computed once per span and sections (read-only)."""
    knots = spline_knots(t0, t1, sections)
    knots.setflags(write=False)
    return knots


def design_matrix(t0: float, t1: float, sections: int, t: np.ndarray) -> np.ndarray:
    """Dense B-spline basis matrix at times ``t`` (inside [t0, t1]), shape (len(t), sections+3)."""
    return _design(float(t0), float(t1), sections, t).copy()


_CACHED_VALUES = 1 << 16  # larger time arrays are not cached (memory) ...
_CACHED_BASIS = 1 << 17  # ... nor bases of more values (1 MiB): at most 32 MiB of bases


def _design(t0: float, t1: float, sections: int, t: np.ndarray) -> np.ndarray:
    """:func:`design_matrix`, read-only, cached for recent (span, sections, times): the refits of
    a variation campaign sample every variation at the same times (the same bytes as computed
    anew: it is the same computation)."""
    t = np.asarray(t, dtype=np.float64)
    if t.size > _CACHED_VALUES or t.size * (sections + DEGREE) > _CACHED_BASIS:
        return _design_of(t0, t1, sections, t)
    return _design_cached(t0, t1, sections, t.shape, t.tobytes())


@lru_cache(maxsize=32)
def _design_cached(t0: float, t1: float, sections: int, shape: tuple[int, ...], times: bytes
                   ) -> np.ndarray:
    return _design_of(t0, t1, sections, np.frombuffer(times).reshape(shape))


def _design_of(t0: float, t1: float, sections: int, t: np.ndarray) -> np.ndarray:
    flat = BSpline.design_matrix(t.ravel(), _knots(t0, t1, sections), DEGREE)
    basis = flat.toarray().reshape(*t.shape, sections + DEGREE)
    basis.setflags(write=False)
    return basis


def in_span(t: ArrayLike, t0: float, t1: float) -> np.ndarray:
    """``t`` as floats, clamped onto [t0, t1] within the tolerance; SimcredError beyond it."""
    t = np.asarray(t, dtype=np.float64)
    tol = _SPAN_TOLERANCE * max(1.0, t1 - t0) + 4 * np.spacing(max(abs(t0), abs(t1)))
    if t.size and not (np.all(np.isfinite(t)) and t.min() >= t0 - tol and t.max() <= t1 + tol):
        bad = t[~(np.isfinite(t) & (t >= t0 - tol) & (t <= t1 + tol))].flat[0]
        raise SimcredError(f"time {float(bad)!r} is outside the description's span "
                           f"[{t0!r}, {t1!r}] (no extrapolation)")
    return np.clip(t, t0, t1)


# -- integration of eq. (1) -----------------------------------------------------------------------


def integration_grid(t0: float, t1: float, sections: int) -> np.ndarray:
    """The grid of eq. (1)'s quadrature: every section cut into q equal steps, q = ⌈H / 0.05 s⌉.

    H = (t1 - t0) / sections. The grid has ``sections · q + 1`` points from t0 to t1, contains the
    section bounds, and its step is at most :data:`MAX_STEP`.
    """
    q = max(1, math.ceil((t1 - t0) / sections / MAX_STEP - 1e-9))
    return np.linspace(t0, t1, sections * q + 1)


@dataclass(frozen=True, slots=True)
class Quadrature:
    """Gauss–Legendre nodes and weights that integrate from t0 to every query time.

    ``full_*`` (intervals, nodes) cover the grid intervals; ``part_*`` (queries, nodes) cover
    [g_i, t] for each query t, with ``index`` = i the grid interval that holds t. Then
    ∫_{t0}^{t} f = cumsum over intervals < i of Σ w f + Σ w_part f_part.
    """

    grid: np.ndarray
    full_nodes: np.ndarray
    full_weights: np.ndarray
    index: np.ndarray
    part_nodes: np.ndarray
    part_weights: np.ndarray

    @classmethod
    def build(cls, t0: float, t1: float, sections: int, t: np.ndarray) -> Quadrature:
        """The quadrature to the times ``t``; its arrays are read-only and shared: cached for
        recent (span, sections, times), computed as anew."""
        t = np.asarray(t, dtype=np.float64)
        if t.size > _CACHED_VALUES:
            return cls._build(float(t0), float(t1), sections, t)
        return _quadrature_cached(float(t0), float(t1), sections, t.shape, t.tobytes())

    @classmethod
    def _build(cls, t0: float, t1: float, sections: int, t: np.ndarray) -> Quadrature:
        grid = integration_grid(t0, t1, sections)
        full_nodes, full_weights = _gauss(grid[:-1], grid[1:])
        index = np.clip(np.searchsorted(grid, t, side="right") - 1, 0, len(grid) - 2)
        part_nodes, part_weights = _gauss(grid[index], t)
        arrays = (grid, full_nodes, full_weights, index, part_nodes, part_weights)
        for array in arrays:
            array.setflags(write=False)
        return cls(*arrays)

    def integrate(self, full_values: np.ndarray, part_values: np.ndarray) -> np.ndarray:
        """∫_{t0}^{t} f for every query t, from f at the full and partial nodes.

        Extra trailing axes (e.g. one per basis function) are integrated alongside.
        """
        extra = (slice(None), slice(None)) + (None,) * (full_values.ndim - 2)
        per_interval = np.sum(self.full_weights[extra] * full_values, axis=1)
        cumulative = np.concatenate([np.zeros((1, *per_interval.shape[1:])),
                                     np.cumsum(per_interval, axis=0)])
        partial = np.sum(self.part_weights[extra] * part_values, axis=1)
        return cumulative[self.index] + partial


@lru_cache(maxsize=32)
def _quadrature_cached(t0: float, t1: float, sections: int, shape: tuple[int, ...],
                       times: bytes) -> Quadrature:
    return Quadrature._build(t0, t1, sections, np.frombuffer(times).reshape(shape))


def _gauss(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    half = 0.5 * (b - a)
    nodes = (0.5 * (a + b))[:, None] + half[:, None] * _XI
    return nodes, half[:, None] * _W


# -- object tracks --------------------------------------------------------------------------------
