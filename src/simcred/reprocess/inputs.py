"""What ``simcred reprocess`` accepts: a measurement directory or a real A9 recording."""

from __future__ import annotations

from pathlib import Path

from simcred.errors import TraceSetError
from simcred.io.a9 import read_a9
from simcred.io.a9_lanes import lane_changer
from simcred.io.measurement import INDEX, Measurement
from simcred.scenario.frenet import to_path_frame


def read_measurement(path: str | Path, object_id: int | None = None) -> Measurement:
    """A measurement directory as is; an A9 CSV as SD only, the chosen object (default: the
    lane changer) as ``to``, straightened onto the EGO's path (the AD function's road is
    straight, see :mod:`simcred.scenario.frenet`)."""
    path = Path(path)
    if path.is_dir():
        return Measurement.read(path)
    if path.suffix.lower() == ".csv" and path.is_file():
        recording = read_a9(path)
        chosen = lane_changer(recording) if object_id is None else object_id
        sd = to_path_frame(recording.to_traceset(chosen, name="to"))
        return Measurement(sd=sd, metadata={"source": str(path), "object": chosen,
                                            "kind": "A9 sensor data", **recording.metadata()})
    if not path.exists():
        raise TraceSetError(f"{path}: no such file or directory")
    raise TraceSetError(f"{path}: not a measurement (expected a directory with {INDEX} or an "
                        f"A9 .csv file)")
