"""levelX scene mode (``runs="recordings"``): every recording one run, its tracks the objects.

The recordings come read and checked by :mod:`simcred.io.levelx` (the same columns, centres,
direction normalisation and metadata per track as in track mode); this module only lays them out:

* **Run**: one per recording, id ``<recording>`` (``01``); time ``frame / frameRate`` at every
  frame at which at least one track has a row (ascending).
* **Objects**: track ``17`` is the object ``obj17`` with the signals of track mode
  (``obj17.x``, ``obj17.vx``, ..., ``obj17.lane`` or ``obj17.heading``) plus ``obj17.present``:
  1 at the frames where the file has a row of the track, 0 elsewhere, where its other signals
  are 0 (a run's signals are fixed and finite, and vehicles come and go). Every row of the
  tracks files is one frame of one object, its values unchanged. A single-frame track is an
  object like any other. Several recordings share the union of their objects (track ids are per
  recording: ``obj17`` of ``01`` and of ``02`` are different vehicles, told apart by the run's
  metadata); an object not in a recording is absent (``present`` 0) throughout its run.
* **Metadata**: ``run_info[<recording>]["objects"]["obj17"]`` = recording, track, class, width,
  length (and highD's driving direction); ``recordings`` as in track mode; ``runs`` =
  ``"recordings"``.
* **Size**: the run is dense (frames × objects × signals); more than ``SIMCRED_MAX_SCENE_VALUES``
  values (default 100,000,000: 800 MB) or more than ``MAX_COLUMNS`` signals is a one-line error
  before anything is allocated.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np

from simcred.errors import TraceSetError
from simcred.io._columns import check_signals
from simcred.io.longformat_records import object_name
from simcred.limits import check_count
from simcred.traces import RUN_INFO, TraceSet, handed_over

if TYPE_CHECKING:  # the caller's loaded recordings (simcred.io.levelx imports this module)
    from simcred.io.levelx import LevelxRecording

PRESENT = "present"


def scenes(loaded: Sequence[LevelxRecording], units: Mapping[str, str], direction: str,
           source: str) -> TraceSet:
    """Every recording of ``loaded`` (same signals, in order) one run with its tracks as objects."""
    tracks = np.unique(np.concatenate([rec.ids for rec in loaded]))
    fields = (*loaded[0].signals, PRESENT)
    check_signals(len(tracks) * len(fields), f"{source}: runs='recordings'")
    frames = [_frames(rec) for rec in loaded]
    rows = sum(len(f) for f, _ in frames)
    check_count(rows * len(tracks) * len(fields), "scene_values",
                f"{source}: runs='recordings' (frames × objects × signals)")
    offsets = np.concatenate([[0], np.cumsum([len(f) for f, _ in frames])])
    values = np.zeros((rows, len(tracks) * len(fields)))
    for rec, (frame, _), lo in zip(loaded, frames, offsets[:-1], strict=True):
        _fill(values[lo:lo + len(frame)], rec, frame, np.searchsorted(tracks, rec.ids),
              len(fields))
    names = [object_name(str(t), None) for t in tracks]
    metadata = {
        "format": loaded[0].layout.name, "direction": direction, "runs": "recordings",
        "units": {f"{o}.{s}": units.get(s, "") for o in names for s in fields},
        RUN_INFO: {rec.name: {"recording": rec.name, "objects": {
            object_name(str(t), None): rec.info[int(t)] for t in rec.ids}} for rec in loaded},
        "recordings": {rec.name: rec.row for rec in loaded},
    }
    return TraceSet(
        signals=tuple(f"{o}.{s}" for o in names for s in fields),
        time=handed_over(np.concatenate([t for _, t in frames])),
        values=handed_over(values),
        offsets=offsets,
        run_ids=tuple(rec.name for rec in loaded),
        metadata=metadata,
        source=source,
    )


def _frames(rec: LevelxRecording) -> tuple[np.ndarray, np.ndarray]:
    """The recording's frames with a row of any track (ascending) and their times."""
    frame, first = np.unique(rec.frame, return_index=True)
    if len(frame) < 2:
        raise TraceSetError(f"{rec.where}: a single frame ({int(frame[0])}); a recording needs "
                            "two frames or more to be a run")
    return frame, rec.time[first]


def _fill(block: np.ndarray, rec: LevelxRecording, frame: np.ndarray, slots: np.ndarray,
          width: int) -> None:
    """Write ``rec``'s rows into its run's ``block`` (frames × objects × signals, zeros): each
    row at its frame and its track's ``slots`` entry, ``present`` set to 1."""
    at = np.searchsorted(frame, rec.frame)
    base = np.repeat(slots, rec.counts) * width
    for j in range(width - 1):
        block[at, base + j] = rec.values[:, j]
    block[at, base + width - 1] = 1.0
