"""Classic surrogate safety measures, batched over scenes: time headway (THW) and TTC.

Both refer to the *lead*: the nearest TO ahead of the EGO (centre further along the road in
the EGO's direction of travel: +x, or -x for an EGO driving against +x) whose footprint
overlaps the EGO's laterally, ``|y_to - y_ego| < (width_ego + width_to) / 2`` (rectangles
taken axis-aligned). The gap is bumper to bumper, ``|x_to - x_ego| - (length_ego +
length_to) / 2``, floored at 0; speeds are along the EGO's direction of travel, ``±v
cos(heading)`` (an oncoming lead has a negative one: the EGO closes in at the sum of both
speeds).
"""

from __future__ import annotations

import numpy as np

from simcred.errors import SimcredError
from simcred.risk.scene import VehicleStates


def _lead(ego: VehicleStates, objects: VehicleStates
          ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Gap to the lead, EGO speed and lead speed (longitudinal), and whether there is a lead."""
    if not isinstance(ego, VehicleStates) or not isinstance(objects, VehicleStates):
        raise SimcredError("ego and objects must be VehicleStates")
    if ego.x.ndim > 1:
        raise SimcredError(f"ego states must be 1-D (scenes,), got shape {ego.shape}")
    e = {k: np.atleast_1d(v)[:, None] for k, v in ego.as_dict().items()}
    shape = {0: (1, 1), 1: (*objects.shape, 1), 2: objects.shape}[len(objects.shape)]
    o = {k: v.reshape(shape) for k, v in objects.as_dict().items()}
    if o["x"].shape[0] != e["x"].shape[0]:
        raise SimcredError(f"{objects.name} has {o['x'].shape[0]} scenes, ego has "
                           f"{e['x'].shape[0]}")
    direction = np.where(e["v"] * np.cos(e["heading"]) < 0, -1.0, 1.0)   # of travel along x
    ahead = direction * (o["x"] - e["x"]) > 0
    overlap = np.abs(o["y"] - e["y"]) < 0.5 * (e["width"] + o["width"])
    gap = np.maximum(np.abs(o["x"] - e["x"]) - 0.5 * (e["length"] + o["length"]), 0.0)
    gap = np.where(ahead & overlap, gap, np.inf)
    lead = np.argmin(gap, axis=1)
    rows = np.arange(gap.shape[0])
    v_ego = (direction * e["v"] * np.cos(e["heading"]))[:, 0]
    v_lead = (direction * o["v"] * np.cos(o["heading"]))[rows, lead]
    return gap[rows, lead], v_ego, v_lead, np.isfinite(gap[rows, lead])


def time_headway(ego: VehicleStates, objects: VehicleStates) -> np.ndarray:
    """Time headway THW = gap / v_ego to the lead, per scene.

    Parameters
    ----------
    ego : VehicleStates
        Shape (scenes,).
    objects : VehicleStates
        Shape (scenes,) or (scenes, objects).

    Returns
    -------
    numpy.ndarray
        Shape (scenes,), seconds: inf without a lead or when the EGO stands with a gap > 0;
        0 when the rectangles touch.

    Examples
    --------
    >>> ego = VehicleStates(x=0.0, y=0.0, v=20.0, heading=0.0)
    >>> time_headway(ego, VehicleStates(x=[[44.5, 30.0]], y=[[0.0, 3.5]], v=10.0, heading=0.0))
    array([2.])
    """
    gap, v_ego, _, has = _lead(ego, objects)
    with np.errstate(divide="ignore", invalid="ignore"):
        thw = np.where(gap == 0, 0.0, gap / v_ego)
    return np.where(has, thw, np.inf)


def time_to_collision(ego: VehicleStates, objects: VehicleStates) -> np.ndarray:
    """Time to collision TTC = gap / (v_ego - v_lead) to the lead at constant speeds, per scene.

    Parameters
    ----------
    ego, objects : VehicleStates
        As for :func:`time_headway`.

    Returns
    -------
    numpy.ndarray
        Shape (scenes,), seconds: inf without a lead or when the EGO does not close in; 0 when the
        rectangles touch.

    Examples
    --------
    >>> ego = VehicleStates(x=0.0, y=0.0, v=20.0, heading=0.0)
    >>> time_to_collision(ego, VehicleStates(x=24.5, y=0.5, v=[10.0], heading=0.0))
    array([2.])
    """
    gap, v_ego, v_lead, has = _lead(ego, objects)
    closing = v_ego - v_lead
    with np.errstate(divide="ignore", invalid="ignore"):
        ttc = np.where(gap == 0, 0.0, np.where(closing > 0, gap / closing, np.inf))
    return np.where(has, ttc, np.inf)
