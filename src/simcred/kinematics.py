"""One object's motion over time: :class:`Track`, and the constants every paper 002 layer shares.

A track is the states of one object (an EGO, a traffic object) at increasing times: position
``x, y`` of its reference point (m), speed ``v`` (m/s), heading θ (rad, unwrapped: continuous, not
folded into (−π, π]) and, where known, acceleration a = v̇ (m/s²) and yaw rate ω = θ̇ (rad/s). In a
:class:`~simcred.traces.TraceSet` the track of object ``ego`` is the columns ``ego.x, ego.y,
ego.v, ego.heading`` (:data:`MOTION_SIGNALS`), optionally ``ego.acceleration``, ``ego.yaw_rate``.

The scenario description (paper 002, [1] eq. (1)) samples into tracks, the reprocessing pipeline
compares tracks, the risk measures and the closed loop take the batched view
(:class:`TrackBatch`: the same columns as arrays of any one shape, e.g. ``(runs, steps)``; and
:meth:`Track.states`, :meth:`TrackBatch.states`: ``(..., 4)`` arrays of x, y, v, θ).

References
----------
[1] Wagner, Groh et al., Towards Cross-Verification and Use of Simulation in the Assessment of
    Automated Driving, IEEE IV 2019.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from simcred.errors import SimcredError

__all__ = [
    "LANE_WIDTH",
    "MOTION_SIGNALS",
    "RATE_SIGNALS",
    "TIME_TOLERANCE",
    "Track",
    "TrackBatch",
]

#: Width (m) of a lane where the road does not say otherwise (German motorway lanes: 3.5 to 3.75).
LANE_WIDTH = 3.5
#: Two times (s) closer than this are the same instant (float round-off of ``t0 + k·dt`` grids).
TIME_TOLERANCE = 1e-9
#: The columns of a track in a trace set (after the object's name and a dot), in state order.
MOTION_SIGNALS = ("x", "y", "v", "heading")
#: Optional rate columns: a = v̇, ω = θ̇.
RATE_SIGNALS = ("acceleration", "yaw_rate")



def read_only(values: object, dtype: type = np.float64) -> np.ndarray:
    """An own, write-protected copy of ``values`` (broadcast views and caller arrays stay
    untouched): the arrays of simcred's frozen dataclasses."""
    array = np.array(values, dtype=dtype)
    array.setflags(write=False)
    return array

@dataclass(frozen=True, slots=True, eq=False)
class Track:
    """States of one object at increasing times ``t``.

    Parameters
    ----------
    t, x, y, v, heading : ndarray, shape (n,)
        Time (s), position (m), speed (m/s), heading (rad, unwrapped).
    acceleration, yaw_rate : ndarray, shape (n,), optional
        a = v̇ (m/s²) and ω = θ̇ (rad/s), where known.

    Notes
    -----
    Columns are float arrays (given float arrays are kept, not copied: a track is a view of
    its source). Equality is identity (no float ``__eq__``); :meth:`equals` compares bitwise.
    """

    t: np.ndarray
    x: np.ndarray
    y: np.ndarray
    v: np.ndarray
    heading: np.ndarray
    acceleration: np.ndarray | None = None
    yaw_rate: np.ndarray | None = None

    def __post_init__(self) -> None:
        for name in ("t", *MOTION_SIGNALS, *RATE_SIGNALS):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, np.asarray(value, dtype=float))
        shape = self.t.shape
        if len(shape) != 1:
            raise SimcredError(f"a track's time must be one-dimensional, got shape {shape}")
        for name in (*MOTION_SIGNALS, *RATE_SIGNALS):
            value = getattr(self, name)
            if value is not None and value.shape != shape:
                raise SimcredError(f"track column {name!r} has shape {value.shape}, time {shape}")

    def __len__(self) -> int:
        return len(self.t)

    def __getitem__(self, index: slice | np.ndarray) -> Track:
        """The samples ``index`` selects (a slice or an index/boolean array), as a track.

        >>> len(Track(*[np.arange(10.0)] * 5)[::3])
        4
        """
        if isinstance(index, int | np.integer):
            raise TypeError("index a Track with a slice or an array, not an integer")
        return Track(*(None if getattr(self, f) is None else getattr(self, f)[index]
                       for f in ("t", *MOTION_SIGNALS, *RATE_SIGNALS)))

    def with_rates(self) -> Track:
        """The track with a = dv/dt and ω = dθ/dt from :func:`numpy.gradient` of v and θ."""
        return Track(self.t, self.x, self.y, self.v, self.heading, np.gradient(self.v, self.t),
                     np.gradient(self.heading, self.t))

    def __repr__(self) -> str:
        span = f"[{self.t[0]:g}, {self.t[-1]:g}] s" if len(self) else "empty"
        rates = "" if self.acceleration is None else ", with rates"
        return f"Track({len(self)} samples, {span}{rates})"

    # -- conversions --------------------------------------------------------------------------

    @classmethod
    def from_columns(cls, columns: Mapping[str, np.ndarray], name: str, *, time: str = "t",
                     source: str = "") -> Track:
        """The track of object ``name`` from a run's columns (``name.x``, … and ``time``).

        Rates are read when both ``name.acceleration`` and ``name.yaw_rate`` are present.
        """
        missing = [f"{name}.{s}" for s in MOTION_SIGNALS if f"{name}.{s}" not in columns]
        if missing:
            where = f"{source}: " if source else ""
            raise SimcredError(f"{where}missing signal(s) {', '.join(missing)}")
        rates = [f"{name}.{s}" for s in RATE_SIGNALS]
        has_rates = all(r in columns for r in rates)
        return cls(columns[time], *(columns[f"{name}.{s}"] for s in MOTION_SIGNALS),
                   *((columns[r] for r in rates) if has_rates else (None, None)))

    def to_columns(self, name: str, *, rates: bool = False) -> dict[str, np.ndarray]:
        """``{name.x: …, name.y: …, name.v: …, name.heading: …}`` (and the rates if asked)."""
        columns = {f"{name}.{s}": getattr(self, s) for s in MOTION_SIGNALS}
        if rates and self.acceleration is not None:
            columns.update({f"{name}.{s}": getattr(self, s) for s in RATE_SIGNALS})
        return columns

    def states(self) -> np.ndarray:
        """The batched view: ``(n, 4)`` array of x, y, v, heading (columns of MOTION_SIGNALS)."""
        return np.column_stack([getattr(self, s) for s in MOTION_SIGNALS])

    @classmethod
    def from_states(cls, t: np.ndarray, states: np.ndarray) -> Track:
        """Inverse of :meth:`states`: ``states[:, j]`` is ``MOTION_SIGNALS[j]``."""
        states = np.asarray(states, dtype=float)
        return cls(t, *(states[:, j] for j in range(len(MOTION_SIGNALS))))

    # -- sampling -----------------------------------------------------------------------------

    def interpolate(self, times: np.ndarray) -> Track:
        """Linear interpolation at ``times`` (held constant outside the span), heading unwrapped
        first so that a turn through ±π does not interpolate through 0.

        >>> track = Track([0.0, 1.0], [0.0, 10.0], [0.0, 0.0], [10.0, 10.0], [3.1, -3.1])
        >>> round(float(track.interpolate([0.5]).heading[0]), 4)  # not 0.0
        3.1416
        """
        times = np.asarray(times, dtype=float)
        heading = np.unwrap(self.heading)
        columns = [np.interp(times, self.t, c) for c in (self.x, self.y, self.v, heading)]
        rates = (None, None) if self.acceleration is None else tuple(
            np.interp(times, self.t, getattr(self, s)) for s in RATE_SIGNALS)
        return Track(times, *columns, *rates)

    def equals(self, other: Track) -> bool:
        """Bitwise equality of every column (missing rates equal only missing rates)."""
        return all(
            (a is None and b is None) or (a is not None and b is not None
                                          and np.array_equal(a, b))
            for a, b in ((getattr(self, f), getattr(other, f))
                         for f in ("t", *MOTION_SIGNALS, *RATE_SIGNALS)))


@dataclass(frozen=True, slots=True, eq=False)
class TrackBatch:
    """The batched view: the columns of many tracks (or of many scenes) as arrays of one shape.

    Parameters
    ----------
    x, y, v, heading : array_like
        As in :class:`Track`; arrays (and scalars) broadcast to one common shape, e.g.
        ``(runs, steps)`` for EGOs or ``(runs, steps, objects)`` for traffic objects.
    acceleration, yaw_rate : array_like, optional
        The rates where known, same shape.

    Notes
    -----
    Fields are stored as read-only float arrays (own copies: broadcast views would share memory
    with the caller). Which axis is time is the user's convention; :meth:`track` takes the times.
    """

    x: ArrayLike
    y: ArrayLike
    v: ArrayLike
    heading: ArrayLike
    acceleration: ArrayLike | None = None
    yaw_rate: ArrayLike | None = None

    def __post_init__(self) -> None:
        names = [f for f in (*MOTION_SIGNALS, *RATE_SIGNALS) if getattr(self, f) is not None]
        try:
            arrays = np.broadcast_arrays(*(np.asarray(getattr(self, f), dtype=float)
                                           for f in names))
        except ValueError:
            raise SimcredError("track batch: fields do not broadcast to one shape") from None
        for name, array in zip(names, arrays, strict=True):
            object.__setattr__(self, name, read_only(array))

    @classmethod
    def of_tracks(cls, tracks: Track | Sequence[Track], **options: object) -> TrackBatch:
        """The batch of tracks on one time grid: a :class:`Track` gives shape ``(n,)``, a
        sequence of them ``(n, len(tracks))``. A rate that some tracks lack counts as 0 in
        those; a rate none has is left to the class's default. ``options`` go to the class."""
        single = isinstance(tracks, Track)
        group = [tracks] if single else list(tracks)
        if not group:
            raise SimcredError(f"{options.get('name', 'track batch')}: no tracks")
        if any(len(track) != len(group[0]) for track in group):
            raise SimcredError(f"tracks of different lengths: {[len(t) for t in group]}")
        fields = {f: [getattr(track, f) for track in group] for f in MOTION_SIGNALS}
        for rate in RATE_SIGNALS:
            if any(getattr(track, rate) is not None for track in group):
                fields[rate] = [np.zeros_like(track.t) if getattr(track, rate) is None
                                else getattr(track, rate) for track in group]
        combine = (lambda columns: columns[0]) if single else (
            lambda columns: np.stack(columns, axis=1))
        return cls(**{f: combine(columns) for f, columns in fields.items()}, **options)

    @classmethod
    def from_states(cls, states: np.ndarray) -> TrackBatch:
        """The batch of a ``(..., 4)`` array of x, y, v, heading (the last axis)."""
        states = np.asarray(states, dtype=float)
        return cls(*(states[..., j] for j in range(len(MOTION_SIGNALS))))

    @property
    def shape(self) -> tuple[int, ...]:
        """The common shape of the fields."""
        return self.x.shape

    def states(self) -> np.ndarray:
        """``(..., 4)``: x, y, v, heading along the last axis."""
        return np.stack([getattr(self, s) for s in MOTION_SIGNALS], axis=-1)

    def track(self, t: np.ndarray, index: tuple[int | slice, ...] | int) -> Track:
        """The track at ``index`` (which must leave one axis: time), sampled at ``t``."""
        return Track(t, *(None if getattr(self, f) is None else getattr(self, f)[index]
                          for f in (*MOTION_SIGNALS, *RATE_SIGNALS)))

    def __repr__(self) -> str:
        return f"{type(self).__name__}(shape={self.shape})"
