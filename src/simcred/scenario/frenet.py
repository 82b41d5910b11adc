"""Straighten a recording onto the EGO's path: road coordinates (s, d) for a straight-road model.

The AD function and the risk model of the cut-in assume a straight road along +x. A real drive
(e.g. the A9 recording) follows a gently curved road; as the EGO keeps its lane, its own path is
a good stand-in for the lane centre. :func:`to_path_frame` maps every object's position to the arc
length ``s`` along that path (x) and the signed lateral offset ``d`` from it (y, left positive),
and its heading to the heading relative to the path's tangent. The EGO itself lands on y = 0.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from simcred.errors import SimcredError
from simcred.traces import TIME, TraceSet


def _segments(px: np.ndarray, py: np.ndarray, empty: str
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The polyline's segments of positive length: start points, lengths, arc length at each
    start and unit directions (``empty``: the one-line error where none is left)."""
    seg = np.column_stack([np.diff(px), np.diff(py)])
    length = np.hypot(seg[:, 0], seg[:, 1])
    keep = length > 1e-9
    if keep.sum() < 1:
        raise SimcredError(empty)
    seg, length = seg[keep], length[keep]
    return (np.column_stack([px[:-1], py[:-1]])[keep], length,
            np.concatenate([[0.0], np.cumsum(length)[:-1]]), seg / length[:, None])


def path_coordinates(px: np.ndarray, py: np.ndarray, x: np.ndarray, y: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Arc length, signed lateral offset and tangent heading of points ``(x, y)`` on the polyline
    ``(px, py)``, by projection onto its nearest segment (beyond the ends: on the end segments'
    extensions)."""
    start, length, s0, unit = _segments(
        px, py, "the EGO's path has no length: it cannot serve as a road")
    rel = np.stack([x, y], axis=1)[:, None, :] - start[None]  # (points, segments, 2)
    along = np.einsum("psc,sc->ps", rel, unit)
    last = len(length) - 1
    lo = np.where(np.arange(len(length)) == 0, -np.inf, 0.0)
    hi = np.where(np.arange(len(length)) == last, np.inf, length)
    clipped = np.clip(along, lo, hi)
    foot = start[None] + clipped[..., None] * unit[None]
    distance = np.hypot(*(np.stack([x, y], axis=1)[:, None, :] - foot).transpose(2, 0, 1))
    best = np.argmin(distance, axis=1)
    rows = np.arange(len(x))
    cross = unit[best, 0] * rel[rows, best, 1] - unit[best, 1] * rel[rows, best, 0]
    heading = np.arctan2(unit[best, 1], unit[best, 0])
    return s0[best] + clipped[rows, best], cross, heading


def path_points(px: np.ndarray, py: np.ndarray, s: np.ndarray, d: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The inverse of :func:`path_coordinates`: the points at arc length ``s`` and signed
    lateral offset ``d`` (left positive) of the polyline ``(px, py)``, and the tangent heading
    there. Each point lies on the segment that holds ``s`` (before the start and beyond the end:
    on the end segments' extensions), offset along that segment's left normal.

    Exact where :func:`path_coordinates` projected onto a segment's interior; a point that
    projected onto a vertex (outside a bend of angle α) comes back up to |d|·α away.
    """
    start, length, s0, unit = _segments(px, py,
                                        "the reference line has no length: no points along it")
    s, d = np.asarray(s, dtype=np.float64), np.asarray(d, dtype=np.float64)
    k = np.clip(np.searchsorted(s0, s, side="right") - 1, 0, len(length) - 1)
    along = s - s0[k]
    x = start[k, 0] + along * unit[k, 0] - d * unit[k, 1]
    y = start[k, 1] + along * unit[k, 1] + d * unit[k, 0]
    return x, y, np.arctan2(unit[k, 1], unit[k, 0])


def to_path_frame(traces: TraceSet, *, ego: str = "ego",
                  objects: Sequence[str] = ("to",)) -> TraceSet:
    """The one-run trace set in path coordinates (see the module docstring)."""
    run = traces.run(0)
    px, py = run[f"{ego}.x"], run[f"{ego}.y"]
    out = {TIME: run[TIME]}
    for name in (ego, *objects):
        s, d, tangent = path_coordinates(px, py, run[f"{name}.x"], run[f"{name}.y"])
        out.update({f"{name}.x": s, f"{name}.y": d, f"{name}.v": run[f"{name}.v"],
                    f"{name}.heading": np.unwrap(run[f"{name}.heading"]) - np.unwrap(tangent)})
    metadata = {**traces.metadata, "frame": f"path of '{ego}' (x: arc length, y: left offset)"}
    return TraceSet.from_runs([out], run_ids=traces.run_ids[:1], metadata=metadata,
                              source=traces.source)
