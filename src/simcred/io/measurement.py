"""A measurement of one drive ([1] §II-A): ground truth (GT) and sensor data (SD).

On disk a measurement is a directory::

    measurement.json   {"kind": "measurement", ...metadata}
    gt.parquet         GT trace set, one run (optional: real recordings often have none)
    sd.parquet         SD trace set, one run

Both recordings name their signals ``<object>.<x|y|v|heading>`` (``ego``, ``to``, ...) in one
global metric frame, time ``t`` in seconds.

References
----------
[1] Wagner, Groh et al., Towards Cross-Verification and Use of Simulation in the Assessment of
    Automated Driving, IEEE IV 2019.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from simcred._json import dumps, envelope, read_json
from simcred.errors import TraceSetError
from simcred.io import parquet
from simcred.traces import TraceSet

INDEX = "measurement.json"
KINDS = ("gt", "sd")
_ENVELOPE = ("schema_version", "kind", "simcred_version")


@dataclass(frozen=True, slots=True)
class Measurement:
    """GT (or None) and SD of one drive, with free-form metadata."""

    sd: TraceSet
    gt: TraceSet | None = None
    metadata: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for kind in KINDS:
            traces = getattr(self, kind)
            if traces is not None and traces.n_runs != 1:
                raise TraceSetError(f"{traces.source}: a measurement's {kind.upper()} must be "
                                    f"one run, got {traces.n_runs}")

    def write(self, directory: str | Path) -> Path:
        directory = Path(directory)
        directory.mkdir(parents=True, exist_ok=True)
        for kind in KINDS:
            traces = getattr(self, kind)
            if traces is not None:
                parquet.write(traces, directory / f"{kind}.parquet")
        (directory / INDEX).write_text(dumps(envelope("measurement", dict(self.metadata))))
        return directory

    @classmethod
    def read(cls, directory: str | Path) -> Measurement:
        directory = Path(directory)
        if not (directory / INDEX).is_file():
            raise TraceSetError(f"{directory}: not a measurement (no {INDEX})")
        metadata = read_json(directory / INDEX, TraceSetError)
        if not (directory / "sd.parquet").is_file():
            raise TraceSetError(f"{directory}: a measurement needs sd.parquet")
        gt_path = directory / "gt.parquet"
        return cls(sd=parquet.read(directory / "sd.parquet"),
                   gt=parquet.read(gt_path) if gt_path.is_file() else None,
                   metadata={k: v for k, v in metadata.items() if k not in _ENVELOPE}
                   if isinstance(metadata, dict) else {})
