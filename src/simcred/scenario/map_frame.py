"""Where a processing frame lies in the map: positions back to map coordinates.

A drive is reprocessed in a road frame (:mod:`simcred.reprocess.road`,
:func:`simcred.reprocess.inputs.road_frame`): a rigid frame (origin at the EGO's first position,
x along its direction of travel) or the Frenet frame of a reference line (x the arc length, y the
left offset, the heading relative to the tangent). An export that is to line up with the map
(the OpenSCENARIO file's positions beside its OpenDRIVE road) takes the description's states back
through the frame: :meth:`RigidFrame.to_map` and :meth:`PathFrame.to_map`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from simcred.errors import OptionError
from simcred.kinematics import Track
from simcred.scenario.frenet import path_points


@dataclass(frozen=True, slots=True)
class RigidFrame:
    """A frame with origin ``origin`` (map x, y) whose x axis points at ``angle`` (rad)."""

    origin: tuple[float, float]
    angle: float

    def __post_init__(self) -> None:
        values = (*self.origin, self.angle)
        if len(self.origin) != 2 or not all(math.isfinite(float(v)) for v in values):
            raise OptionError(f"a rigid frame needs a finite origin (x, y) and angle, got "
                              f"origin={self.origin!r}, angle={self.angle!r}")

    def to_map(self, track: Track) -> Track:
        """``track`` (in this frame) in map coordinates: rotated by ``angle``, shifted by
        ``origin``; speeds unchanged, headings + ``angle``."""
        c, s = math.cos(self.angle), math.sin(self.angle)
        (x0, y0) = self.origin
        return Track(track.t, x0 + c * track.x - s * track.y, y0 + s * track.x + c * track.y,
                     track.v, track.heading + self.angle)


@dataclass(frozen=True, slots=True, eq=False)
class PathFrame:
    """The Frenet frame of the reference line ``line`` ((n, 2) map vertices, in driving
    direction). Equality is identity (the line is an array)."""

    line: np.ndarray

    def __post_init__(self) -> None:
        line = np.asarray(self.line, dtype=np.float64)
        if line.ndim != 2 or line.shape[1] != 2 or len(line) < 2 or not np.isfinite(line).all():
            raise OptionError(f"a path frame needs an (n, 2) line of at least 2 finite vertices, "
                              f"got shape {line.shape}")
        line.flags.writeable = False
        object.__setattr__(self, "line", line)

    def to_map(self, track: Track) -> Track:
        """``track`` (x arc length, y left offset, heading relative to the tangent) in map
        coordinates (:func:`simcred.scenario.frenet.path_points`); speeds unchanged (as on the
        way in, :mod:`simcred.reprocess.road`), headings + the tangent's, unwrapped."""
        x, y, tangent = path_points(self.line[:, 0], self.line[:, 1], track.x, track.y)
        heading = np.unwrap(np.angle(np.exp(1j * (track.heading + tangent))))
        return Track(track.t, x, y, track.v, heading)


MapFrame = RigidFrame | PathFrame
