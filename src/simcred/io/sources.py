"""One reader dispatch for everything io reads: trace-set formats and data sets.

Trace-set formats (:data:`simcred.io.formats.FORMATS`) read into a ``TraceSet``. Data sets are
read into their own types, because they hold more than runs of signals:

=============  ==============================================  ===============================
data set       what                                            reader
=============  ==============================================  ===============================
measurement    a measurement directory (``index.json``, GT     :meth:`.measurement.Measurement.
               and SD Parquet; ``simcred simulate cutin``)     read`
a9             an A9 sensor-data CSV (OSC-Generator)           :func:`.a9.read_a9`
openacc        one OpenACC recording (CSV or shipped Parquet)  :func:`.openacc.read_recording`
=============  ==============================================  ===============================

What a path is depends on who reads it, so the caller names its *role*
(:func:`detect_source`); io's default is unchanged by it:

* ``traces`` (``io.read``, ``TraceSet.read``): :func:`simcred.io.formats.detect` (a ``.csv``
  file is long format);
* ``drive`` (``simcred reprocess``): a directory is a measurement, ``.xml`` a CommonRoad
  scenario, ``.parquet``/``.pq`` a long-format table, and a ``.csv`` an A9 recording unless
  long-format columns are given (``long=True``).
"""

from __future__ import annotations

import importlib
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from simcred.errors import OptionError, TraceSetError
from simcred.io.formats import FORMATS, PARQUET_SUFFIXES, detect
from simcred.io.formats import read as read_traces
from simcred.io.measurement import INDEX

ROLES = ("traces", "drive")


@dataclass(frozen=True, slots=True)
class DataSet:
    """A data set read into its own type: ``reader`` is a function (or ``Class.method``) of
    ``simcred.io.<module>``."""

    name: str
    module: str
    reader: str
    description: str

    def read(self, path: str | Path, **options: Any):
        found: Any = importlib.import_module(f"simcred.io.{self.module}")
        for part in self.reader.split("."):
            found = getattr(found, part)
        return found(path, **options)


DATASETS: dict[str, DataSet] = {d.name: d for d in (
    DataSet("measurement", "measurement", "Measurement.read",
            "a measurement directory (index.json, sd.parquet, optional gt.parquet)"),
    DataSet("a9", "a9", "read_a9", "an A9 sensor-data CSV (OSC-Generator)"),
    DataSet("openacc", "openacc", "read_recording",
            "one OpenACC recording (original CSV or the shipped Parquet)"),
)}


def detect_source(path: str | Path, *, role: str = "traces", long: bool = False,
                  options: Mapping[str, Any] | None = None) -> str:
    """The name of the trace-set format or data set that ``path`` is for ``role`` (module
    docs); ``long``: the ``drive`` role was given long-format columns."""
    path = Path(path)
    if role == "traces":
        return detect(path, options=options).name
    if role != "drive":
        raise OptionError(f"unknown role {role!r} (roles: {', '.join(ROLES)})")
    suffix = path.suffix.lower()
    if path.is_dir():
        return "measurement"
    if suffix == ".xml":
        return "commonroad"
    if long or suffix in PARQUET_SUFFIXES:
        return "long"
    if suffix == ".csv":
        return "a9"
    raise TraceSetError(f"{path}: not a measurement (expected a directory with {INDEX}, an A9 "
                        ".csv, a CommonRoad .xml or a long-format .csv/.parquet file)")


def read_source(path: str | Path, name: str, **options: Any):
    """Read ``path`` as the data set or trace-set format ``name`` (a data set's own type, or a
    ``TraceSet``)."""
    if name in DATASETS:
        return DATASETS[name].read(path, **options)
    if name in FORMATS:
        return read_traces(path, format=name, **options)
    known = ", ".join([*DATASETS, *FORMATS])
    raise OptionError(f"unknown format or data set {name!r} (known: {known})")
