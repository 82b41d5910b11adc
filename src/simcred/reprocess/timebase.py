"""A drive as the pipeline reads it, and the common time base its representations are compared on.

A :class:`Drive` is one or two recordings of the same drive (SD, and GT if there is one), each
a :class:`RecordedTracks`: every object's samples at its own times. Objects may be sampled at
different times and rates, and may miss samples (dropouts: rows whose values were missing or
NaN are removed by the readers and counted). :func:`align` makes the comparison explicit:

* **Gaps.** In each recording the nominal step is the median sample step over its objects; a
  step longer than 1.5 × nominal is a gap (``object``, ``start``, ``end``, ``duration``: the
  last sample before and the first after). Every gap is reported, none is bridged silently:
  the fit has no residual inside it (the description's splines span it, as they span any two
  samples), and no comparison time lies inside it.
* **Long gaps.** A gap longer than ``max_gap`` (default 0.5 s: five samples at 10 Hz, about the
  sensor delay and reaction times the pipeline measures) is refused with a one-line error, or,
  with ``long_gaps="longest"``, the drive is cut to its longest stretch without one (reported).
* **Time base.** All representations are compared at the samples of the *coarser* recording
  (larger nominal step; SD on a tie) inside the span every object of every recording covers,
  minus the times inside any gap. The finer recording is interpolated linearly onto them
  (headings unwrapped first), never the coarser onto the finer. Each recording is fitted on its
  own samples, at its own rate.
"""

from __future__ import annotations

import hashlib
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from simcred.errors import OptionError, SimcredError
from simcred.io.measurement import Measurement
from simcred.kinematics import MOTION_SIGNALS, TIME_TOLERANCE, Track
from simcred.traces import TIME, TraceSet

MAX_GAP = 0.5  # s: the longest gap reprocessed without being asked
GAP_FACTOR = 1.5  # a step longer than this times the nominal step is a gap
LONG_GAPS = ("error", "longest")


@dataclass(frozen=True, slots=True, eq=False)
class RecordedTracks:
    """One source of a drive (GT or SD): each object's samples at its own, increasing times.

    ``dropouts`` counts, per object, the samples a reader removed because a value was missing
    or NaN; ``digest`` identifies the input (content hash) in the result's envelope.
    """

    source: str
    tracks: Mapping[str, Track]
    digest: str
    dropouts: Mapping[str, int] = field(default_factory=dict)

    @classmethod
    def of_traceset(cls, traces: TraceSet) -> RecordedTracks:
        """A one-run trace set with ``<object>.<x|y|v|heading>`` signals (every object shares
        the run's times)."""
        run = traces.run(0)
        names = [c[:-2] for c in run if c.endswith(".x")]
        tracks = {n: Track.from_columns(run, n, time=TIME, source=traces.source) for n in names
                  if all(f"{n}.{s}" in run for s in MOTION_SIGNALS)}
        return cls(traces.source, tracks, traces.digest())

    def step(self) -> float:
        """Nominal sample step (s): the median step over all objects."""
        steps = np.concatenate([np.diff(t.t) for t in self.tracks.values()])
        return float(np.median(steps))

    def require(self, objects: Sequence[str], kind: str) -> None:
        missing = [o for o in objects if o not in self.tracks]
        if missing:
            names = ", ".join(map(repr, missing))
            raise SimcredError(f"{self.source}: {kind} has no object {names} with "
                               f"{'/'.join(MOTION_SIGNALS)} (objects: "
                               f"{', '.join(self.tracks) or 'none'})")


#: The earlier name of :class:`RecordedTracks` (kept for callers; one class per name).
Recording = RecordedTracks


@dataclass(frozen=True, slots=True, eq=False)
class Drive:
    """SD and (optionally) GT of one drive, with free-form metadata (provenance)."""

    sd: RecordedTracks
    gt: RecordedTracks | None = None
    metadata: Mapping[str, Any] = field(default_factory=dict)

    @classmethod
    def of_measurement(cls, measurement: Measurement) -> Drive:
        gt = None if measurement.gt is None else RecordedTracks.of_traceset(measurement.gt)
        return cls(RecordedTracks.of_traceset(measurement.sd), gt, dict(measurement.metadata))

    def recordings(self) -> dict[str, RecordedTracks]:
        return {"SD": self.sd} | ({} if self.gt is None else {"GT": self.gt})


@dataclass(frozen=True, slots=True)
class Gap:
    """Samples missing in one object's recording: none strictly between ``start`` and ``end``."""

    recording: str
    object: str
    start: float
    end: float
    step: float

    @property
    def duration(self) -> float:
        return self.end - self.start

    @property
    def missing(self) -> int:
        """Samples missing at the nominal step."""
        return max(0, int(round(self.duration / self.step)) - 1)

    def to_dict(self) -> dict[str, Any]:
        return {"recording": self.recording, "object": self.object, "start": self.start,
                "end": self.end, "duration": self.duration, "missing_samples": self.missing}

    def __str__(self) -> str:
        return (f"{self.recording} object '{self.object}': no sample from {self.start:.3f} s to "
                f"{self.end:.3f} s ({self.duration:.3f} s)")


@dataclass(frozen=True, slots=True, eq=False)
class Aligned:
    """The drive on its common time base (see the module docstring)."""

    times: np.ndarray
    tracks: Mapping[str, Mapping[str, Track]]  # recording -> object -> track (cut if asked)
    base: str
    steps: Mapping[str, float]
    gaps: tuple[Gap, ...]
    max_gap: float
    cut: tuple[float, float] | None
    dropouts: Mapping[str, Mapping[str, int]]

    def to_dict(self) -> dict[str, Any]:
        return {"time_base": self.base, "steps": dict(self.steps),
                "span": [float(self.times[0]), float(self.times[-1])],
                "samples": len(self.times), "max_gap": self.max_gap,
                "gaps": [g.to_dict() for g in self.gaps],
                "cut_to_longest_stretch": None if self.cut is None else list(self.cut),
                "dropouts": {k: dict(v) for k, v in self.dropouts.items() if v}}


def align(drive: Drive, objects: Sequence[str], *, max_gap: float = MAX_GAP,
          long_gaps: str = "error") -> Aligned:
    """The common time base of ``objects`` in every recording of ``drive`` (module docstring).

    Raises
    ------
    SimcredError
        An object missing, a gap longer than ``max_gap`` (with ``long_gaps="error"``), or fewer
        than two common sample times; one line naming the recording, object and times.
    """
    if not (isinstance(max_gap, int | float) and math.isfinite(max_gap) and max_gap > 0):
        raise OptionError(f"max_gap must be a finite number > 0 (seconds), got {max_gap!r}")
    if long_gaps not in LONG_GAPS:
        raise OptionError(f"long_gaps must be one of {', '.join(LONG_GAPS)}, got {long_gaps!r}")
    recordings = drive.recordings()
    for name, recording in recordings.items():
        recording.require(objects, name)
    tracks = {name: {o: r.tracks[o] for o in objects} for name, r in recordings.items()}
    steps = {name: r.step() for name, r in recordings.items()}
    gaps = tuple(g for name, by_object in tracks.items() for o, track in by_object.items()
                 for g in _gaps(track, steps[name], name, o))
    long = [g for g in gaps if g.duration > max_gap + TIME_TOLERANCE]
    cut = None
    if long and long_gaps == "error":
        raise SimcredError(f"{recordings[long[0].recording].source}: {long[0]} > max_gap "
                           f"{max_gap:g} s; raise --max-gap or cut to the longest stretch "
                           "without it (--long-gaps longest)")
    lo, hi = _common_span(tracks)
    if long:
        lo, hi = cut = _longest_stretch(lo, hi, long)
        tracks = {name: {o: _cut(t, lo, hi) for o, t in by.items()} for name, by in tracks.items()}
    base = max(steps, key=lambda name: (steps[name], name == "SD"))
    times = _base_times(tracks[base].values(), lo, hi, gaps)
    if len(times) < 2:
        raise SimcredError(f"{recordings[base].source}: {len(times)} sample time(s) shared by "
                           f"{', '.join(objects)} outside gaps; at least 2 are needed")
    dropouts = {name: {o: n for o, n in r.dropouts.items() if o in objects and n}
                for name, r in recordings.items()}
    return Aligned(times, tracks, base, steps, gaps, float(max_gap), cut, dropouts)


def _gaps(track: Track, step: float, recording: str, name: str) -> list[Gap]:
    dt = np.diff(track.t)
    return [Gap(recording, name, float(track.t[i]), float(track.t[i + 1]), step)
            for i in np.flatnonzero(dt > GAP_FACTOR * step)]


def _common_span(tracks: Mapping[str, Mapping[str, Track]]) -> tuple[float, float]:
    every = [t for by in tracks.values() for t in by.values()]
    lo, hi = max(float(t.t[0]) for t in every), min(float(t.t[-1]) for t in every)
    if not lo < hi:
        raise SimcredError(f"the objects' recordings share no time span (latest start "
                           f"{lo:.3f} s, earliest end {hi:.3f} s)")
    return lo, hi


def _longest_stretch(lo: float, hi: float, long: Sequence[Gap]) -> tuple[float, float]:
    """The longest part of [lo, hi] that no long gap's interior overlaps."""
    cuts = sorted((max(lo, g.start), min(hi, g.end)) for g in long if g.end > lo and g.start < hi)
    pieces, start = [], lo
    for a, b in cuts:
        pieces.append((start, a))
        start = max(start, b)
    pieces.append((start, hi))
    return max(pieces, key=lambda p: (p[1] - p[0], -p[0]))


def _cut(track: Track, lo: float, hi: float) -> Track:
    keep = (track.t >= lo - TIME_TOLERANCE) & (track.t <= hi + TIME_TOLERANCE)
    return track[keep]


def _base_times(tracks, lo: float, hi: float, gaps: Sequence[Gap]) -> np.ndarray:
    t = np.unique(np.concatenate([tr.t for tr in tracks]))
    t = t[(t >= lo - TIME_TOLERANCE) & (t <= hi + TIME_TOLERANCE)]
    if len(t) > 1:
        t = t[np.concatenate([[True], np.diff(t) > TIME_TOLERANCE])]
    inside = np.zeros(len(t), dtype=bool)
    for g in gaps:
        inside |= (t > g.start + TIME_TOLERANCE) & (t < g.end - TIME_TOLERANCE)
    return t[~inside]


def tracks_digest(tracks: Mapping[str, Track], *extra: str) -> str:
    """``sha256:`` over object names, extra provenance text and every column's bytes."""
    h = hashlib.sha256()
    for text in extra:
        h.update(text.encode())
    for name, track in tracks.items():
        h.update(name.encode())
        for column in (track.t, *(getattr(track, s) for s in MOTION_SIGNALS)):
            h.update(np.ascontiguousarray(column, dtype=np.float64).tobytes())
    return "sha256:" + h.hexdigest()
