"""Which object of an A9 recording changes lanes: offsets from the ego lane's centre line.

The lane markings of the recording (``lin_left_*``, ``lin_right_*``, see :mod:`simcred.io.a9`)
give the ego lane's centre and width; where they are missing, the lane is
:data:`~simcred.kinematics.LANE_WIDTH` wide and centred on the ego.
"""

from __future__ import annotations

import numpy as np

from simcred.errors import TraceSetError
from simcred.io.a9 import A9Recording
from simcred.kinematics import LANE_WIDTH

__all__ = ["lane_changer", "lane_offset"]


def lane_offset(recording: A9Recording, object_id: int, *, lane_width: float | None = None
                ) -> tuple[np.ndarray, np.ndarray]:
    """Lateral offset of an object from the ego lane's centre line, and the lane width, per row.

    The centre line in the ego frame is ``c + kappa x^2 / 2`` with ``c`` the mean of the left and
    right marking offsets and ``kappa`` the mean marking curvature (small-angle form of the
    markings' circular arcs); the width is left minus right marking offset. Where the markings are
    not recorded: ``c = 0``, ``kappa = 0``, width ``lane_width`` (3.5 m by default). A given
    ``lane_width`` replaces the measured width everywhere.

    Returns
    -------
    offset, width : ndarray, shape (n,)
        Over the rows where the object is present [m]; the object is in the ego's lane where
        ``|offset| < width / 2``.
    """
    _lane_width_iv(recording, lane_width)
    track = recording.object(object_id)
    lanes = {key: value[track.rows] for key, value in recording.lanes.items()}
    left, right = lanes["left_y"], lanes["right_y"]
    marked = np.isfinite(left) & np.isfinite(right)
    centre = np.where(marked, 0.5 * (left + right), 0.0)
    curvatures = np.vstack([lanes["left_curvature"], lanes["right_curvature"]])
    known = np.isfinite(curvatures)
    kappa = np.where(known, curvatures, 0.0).sum(axis=0) / np.maximum(known.sum(axis=0), 1)
    width = np.where(marked, left - right, LANE_WIDTH)
    if lane_width is not None:
        width = np.full(len(track), float(lane_width))
    return track.rel_y - centre - 0.5 * kappa * track.rel_x**2, width


def _lane_width_iv(recording: A9Recording, lane_width: float | None) -> None:
    if lane_width is not None and not (np.isfinite(lane_width) and lane_width > 0):
        raise TraceSetError(f"{recording.source}: lane_width must be a positive number, "
                            f"not {lane_width!r}")


def lane_changer(recording: A9Recording, *, lane_width: float | None = None) -> int:
    """The object that enters or leaves the ego's lane and is present longest (ties: lowest id).

    An object crosses the ego's lane when its :func:`lane_offset` lies inside ``±width/2`` in some
    rows and outside in others.

    Raises
    ------
    TraceSetError
        If no object crosses the ego's lane.
    """
    _lane_width_iv(recording, lane_width)
    crossing = []
    for k, track in recording.objects.items():
        offset, width = lane_offset(recording, k, lane_width=lane_width)
        inside = np.abs(offset) < width / 2
        if inside.any() and not inside.all():
            crossing.append((-len(track), k))
    if not crossing:
        raise TraceSetError(f"{recording.source}: no object crosses the ego's lane "
                            f"(objects: {list(recording.objects)})")
    return min(crossing)[1]
