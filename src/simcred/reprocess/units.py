"""Units of a drive's recordings, checked before the pipeline trusts them.

The pipeline computes in seconds, metres, m/s and radians (heading counter-clockwise from +x).
A recording in other units does not crash it: it gives a wrong answer (timestamps in ms start a
resimulation of hours; a speed in km/h is 3.6 times too fast). So every object of every
recording is checked against what its own positions say, and a mismatch is a one-line error
that names the recording, the object and the likely unit:

* **time**: the nominal sample step (median) must lie in [:data:`MIN_STEP`, :data:`MAX_STEP`]
  s; vehicle recordings are sampled at 0.5-1000 Hz (a step of 40 or 100 is milliseconds);
* **speed**: on the samples where the object moves (speed from positions, |Δp| / Δt, at least
  :data:`MOVING` m/s), the median of recorded over position-derived speed must lie in
  :data:`SPEED_RATIO` (3.6: km/h; 2.24: mph);
* **heading**: on the same samples, the median angle between the recorded heading and the
  direction of travel (atan2 of Δp) must be at most :data:`HEADING_TOLERANCE` rad; and read in
  degrees the heading must not fit the direction much better (an angle above
  :data:`DEGREES_FLOOR` rad that shrinks to under a quarter of itself): that is degrees.

Recorded speed and heading are compared at the midpoint of each step (mean of the two samples;
headings by their wrapped difference). An object with fewer than :data:`MIN_MOVING` moving
steps is not judged on speed and heading (a standing object has no direction of travel).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from simcred.errors import SimcredError
from simcred.kinematics import Track
from simcred.reprocess.decomposition import wrap
from simcred.reprocess.timebase import Drive, RecordedTracks

MIN_STEP = 1e-3  # s
MAX_STEP = 2.0  # s
MOVING = 2.0  # m/s: steps at least this fast (from positions) judge speed and heading
MIN_MOVING = 3  # moving steps needed to judge them
SPEED_RATIO = (0.67, 1.5)  # recorded / position-derived speed, median
KMH, MPH = 3.6, 2.23694  # recorded / true speed of a km/h and a mph column
HEADING_TOLERANCE = 0.5  # rad, median angle between heading and direction of travel
DEGREES_FLOOR = 0.1  # rad: a smaller median angle is never taken for degrees


def check_units(drive: Drive, objects: Sequence[str]) -> None:
    """Raise a one-line :class:`~simcred.errors.SimcredError` if a recording of ``drive`` is
    not in s, m, m/s and rad for one of ``objects`` (see the module docstring)."""
    for recording in drive.recordings().values():
        _check_step(recording)
        for name in objects:
            if name in recording.tracks:
                _check_motion(recording.source, name, recording.tracks[name])


def _check_step(recording: RecordedTracks) -> None:
    step = recording.step()
    if MIN_STEP <= step <= MAX_STEP:
        return
    guess = ("milliseconds? convert to seconds (--time-scale 0.001)" if step > MAX_STEP
             else "a time unit larger than seconds? convert to seconds (--time-scale)")
    raise SimcredError(f"{recording.source}: median sample step {step:g} is not a vehicle "
                       f"recording's step in seconds ({MIN_STEP:g}-{MAX_STEP:g} s): {guess}")


def _check_motion(source: str, name: str, track: Track) -> None:
    dt = np.diff(track.t)
    derived = np.hypot(np.diff(track.x), np.diff(track.y)) / dt
    moving = derived >= MOVING
    if int(moving.sum()) < MIN_MOVING:
        return
    where = f"{source}: object '{name}'"
    v = 0.5 * (track.v[1:] + track.v[:-1])
    ratio = float(np.median(v[moving] / derived[moving]))
    if not SPEED_RATIO[0] <= ratio <= SPEED_RATIO[1]:
        unit = next((f" (looks like {u}: convert to m/s)" for u, r in (("km/h", KMH),
                                                                        ("mph", MPH))
                     if abs(ratio / r - 1) < 0.15), "")
        raise SimcredError(f"{where}: speed v is {ratio:.3g} × the speed from its positions "
                           f"(median over {int(moving.sum())} moving steps){unit}")
    direction = np.arctan2(np.diff(track.y), np.diff(track.x))[moving]
    mid = (track.heading[:-1] + 0.5 * wrap(np.diff(track.heading)))[moving]
    off = float(np.median(np.abs(wrap(mid - direction))))
    degrees = (np.radians(track.heading[:-1])
               + 0.5 * wrap(np.radians(np.diff(track.heading))))[moving]
    off_degrees = float(np.median(np.abs(wrap(degrees - direction))))
    if off > DEGREES_FLOOR and off_degrees < min(off / 4, HEADING_TOLERANCE):
        raise SimcredError(f"{where}: heading looks like degrees ({off:.2f} rad off the "
                           "direction of travel from its positions, "
                           f"{off_degrees:.2f} rad read as degrees): convert to radians")
    if off > HEADING_TOLERANCE:
        raise SimcredError(f"{where}: heading is {off:.2f} rad (median; "
                           f"{math.degrees(off):.0f}°) off the direction of travel from its "
                           "positions: expected radians counter-clockwise from +x")
