"""The inputs of a risk assessment: the vehicles' states in many scenes and the road's lanes.

See :mod:`simcred.risk.ttr` for the method and its references.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from simcred.errors import OptionError, SimcredError
from simcred.kinematics import LANE_WIDTH, TrackBatch, read_only

STATE_FIELDS = ("x", "y", "v", "heading", "acceleration", "yaw_rate", "length", "width")
# peak |d²p/dτ²| of the quintic smoothstep p(τ) = 10τ³ - 15τ⁴ + 6τ⁵, at τ = (3 ∓ √3)/6


def require(condition: bool, message: str) -> None:
    """Raise a one-line :class:`OptionError` unless ``condition``."""
    if not condition:
        raise OptionError(message)


# -- inputs ------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True, eq=False)
class VehicleStates(TrackBatch):
    """States of vehicles in many scenes: the kinematics batched view
    (:class:`~simcred.kinematics.TrackBatch`, rates 0 where not given) plus the vehicles' size.
    Any finite values are accepted (sizes > 0): traffic may drive in any direction.

    Parameters
    ----------
    x, y : array_like
        Position of the vehicle's centre (m); the road runs along +x, y points left.
    v : array_like
        Signed speed (m/s) along the heading: negative for a reversing vehicle (it moves
        against its heading), 0 for a standing one.
    heading : array_like
        Heading (rad) relative to the road's +x axis, any finite value: oncoming traffic has
        heading ≈ π, crossing traffic ≈ ±π/2 (see :func:`road_frames`).
    acceleration : array_like, default: 0
        Longitudinal acceleration (m/s²), the rate of the signed speed ``v``.
    yaw_rate : array_like, default: 0
        Yaw rate (rad/s); sets the initial curvature of the predicted paths.
    length, width : array_like, default: 4.5, 1.8
        Size of the vehicle's rectangle (m), > 0.
    name : str, default: "vehicle"
        Names the vehicle in error messages (``ego.v[3] must be finite``).

    Notes
    -----
    Shape ``(scenes,)`` for the EGO; ``(scenes,)`` (one TO per scene) or ``(scenes, objects)``
    for the TOs. Fields are stored as read-only float arrays broadcast to the common shape.
    Equality is identity.
    """

    acceleration: ArrayLike = 0.0
    yaw_rate: ArrayLike = 0.0
    length: ArrayLike = 4.5
    width: ArrayLike = 1.8
    name: str = "vehicle"

    def __post_init__(self) -> None:
        arrays = []
        for f in STATE_FIELDS:
            try:
                arrays.append(np.asarray(getattr(self, f), dtype=float))
            except (TypeError, ValueError):
                raise SimcredError(f"{self.name}.{f} must be numeric") from None
        try:
            arrays = np.broadcast_arrays(*arrays)
        except ValueError:
            shapes = ", ".join(f"{f} {a.shape}" for f, a in zip(STATE_FIELDS, arrays, strict=True))
            raise SimcredError(f"{self.name}: fields do not broadcast to one shape: {shapes}"
                               ) from None
        if arrays[0].ndim > 2:
            raise SimcredError(f"{self.name}: states must be 0-, 1- or 2-D (scenes[, objects]), "
                               f"got shape {arrays[0].shape}")
        for f, a in zip(STATE_FIELDS, arrays, strict=True):
            _check_values(f"{self.name}.{f}", a)
            object.__setattr__(self, f, read_only(a))

    def as_dict(self) -> dict[str, np.ndarray]:
        """The fields by name (without ``name``)."""
        return {f: getattr(self, f) for f in STATE_FIELDS}


def _check_values(label: str, a: np.ndarray) -> None:
    """One-line error naming the first offending element of state field ``label``."""
    field = label.rsplit(".", 1)[1]
    rules = {"length": (a <= 0, "must be > 0"), "width": (a <= 0, "must be > 0")}
    bad, message = ~np.isfinite(a), "must be finite"
    if not bad.any() and field in rules:
        bad, message = rules[field]
    if bad.any():
        where = np.unravel_index(int(np.argmax(bad)), a.shape) if a.ndim else ()
        index = f"[{', '.join(map(str, where))}]" if where else ""
        raise SimcredError(f"{label}{index} {message}, got {float(a[where])}")


@dataclass(frozen=True, slots=True)
class Lanes:
    """Straight parallel lanes along +x.

    Parameters
    ----------
    width : float, default: 3.5
        Lane width (m); also the lateral offset of a lane change and of an evasive steer.
    centre : float, default: 0.0
        y of one lane centre (the EGO's lane in the main use case); the others lie at
        ``centre + k * width`` for every integer k. Road edges are not modelled.
    """

    width: float = LANE_WIDTH
    centre: float = 0.0

    def __post_init__(self) -> None:
        require(math.isfinite(self.width) and self.width > 0, "lanes.width must be > 0")
        require(math.isfinite(self.centre), "lanes.centre must be finite")


# -- frames: traffic in any direction ---------------------------------------------------------


def forward_states(s: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """States with reversing vehicles (v < 0) written as driving forward.

    A rectangle turned by π is the same rectangle, so a vehicle reversing at speed |v| is one
    driving forward with heading + π, speed |v| and acceleration -a (the rate of |v|); the
    yaw rate stays (the path's curvature is ω/|v| either way). Headings are wrapped to [-π, π).
    """
    back = s["v"] < 0
    heading = s["heading"] + np.where(back, np.pi, 0.0)
    return {**s, "v": np.abs(s["v"]), "heading": np.remainder(heading + np.pi, 2 * np.pi) - np.pi,
            "acceleration": np.where(back, -s["acceleration"], s["acceleration"])}


@dataclass(frozen=True, slots=True)
class RoadFrames:
    """Per vehicle, the frame its motion is predicted in: rotation by ``angle`` (cos, sin) from
    the world, ``x_l = cos·x + sin·y``, ``y_l = -sin·x + cos·y``; ``centre`` is the local y of
    one lane centre (lane centres lie at ``centre + k·lanes.width``)."""

    cos: np.ndarray
    sin: np.ndarray
    centre: np.ndarray

    def to_local(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World (x, y) to local coordinates."""
        return self.cos * x + self.sin * y, self.cos * y - self.sin * x

    def to_world(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Local (x, y) to world coordinates (also for direction vectors)."""
        return self.cos * x - self.sin * y, self.sin * x + self.cos * y


def road_frames(s: dict[str, np.ndarray], lanes: Lanes, limit: float
                ) -> tuple[RoadFrames, dict[str, np.ndarray]]:
    """The frames of forward-driving vehicles ``s`` (see :func:`forward_states`) and their
    states in them.

    A vehicle whose heading lies within ``limit`` of the road's +x direction follows the lanes
    along +x (frame angle 0); within ``limit`` of -x it follows them along -x (angle π: oncoming
    traffic, with its own left and right); otherwise (crossing, turning) it is predicted in its
    own frame (angle = heading) with "lanes" centred on its current line. Local headings thus
    lie in [-limit, limit], and are 0 in an own frame.
    """
    h = s["heading"]
    forward = np.abs(h) <= limit
    backward = np.abs(h) >= np.pi - limit
    aligned = forward | backward
    cos = np.where(forward, 1.0, np.where(backward, -1.0, np.cos(h)))
    sin = np.where(aligned, 0.0, np.sin(h))
    frames = RoadFrames(cos, sin, np.zeros_like(h))
    x, y = frames.to_local(s["x"], s["y"])
    local_heading = np.where(forward, h, np.where(backward, np.remainder(h, 2 * np.pi) - np.pi,
                                                  0.0))
    centre = np.where(aligned, cos * lanes.centre, y)
    frames = RoadFrames(cos, sin, centre)
    return frames, {**s, "x": x, "y": y, "heading": local_heading}
