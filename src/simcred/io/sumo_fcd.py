"""SUMO floating car data (FCD) XML as a trace set, stream-parsed.

SUMO writes ``--fcd-output`` as ``<fcd-export><timestep time="..."><vehicle id="..." x="..."
.../></timestep>...</fcd-export>`` (persons and containers as ``<person>``/``<container>``). The
file is parsed as a stream (``iterparse``, each timestep discarded once read) with defusedxml:
no DTDs, no entity expansion, no external resources. ``.xml.gz`` is read through gzip.

Every element in a timestep is an object (its ``id``); each attribute whose values all parse as
numbers becomes a signal (``x``, ``y``, ``angle`` in degrees clockwise from north, ``speed`` in m/s,
``pos``, ``slope``, ``acceleration`` with ``--fcd-output.acceleration``, ...); text attributes
(``type``, ``lane``, ``edge``) are skipped and listed in the metadata. Values are SUMO's printed
decimals (``--precision``, default 2), converted once to float64.

Layouts (the long-format rules of :mod:`simcred.io.longformat`):

* ``objects_as="runs"`` (default): every vehicle is a run named by its id (``obj<id>`` for an
  integer id); a vehicle seen in a single timestep cannot form a run and is listed in the
  metadata under ``runs_too_short``.
* ``objects_as="signals"``: the file is one run (named after the file) with ``<id>.<attribute>``
  signals; vehicles that enter or leave follow ``missing`` (``error`` or ``intersect``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from simcred.errors import TraceSetError
from simcred.io._xml import XML_ERRORS, iterparse, open_xml, unreadable
from simcred.io.longformat_records import Records, to_traceset
from simcred.traces import TraceSet

ROOT = "fcd-export"
OBJECT_TAGS = ("vehicle", "person", "container")


def parse(path: Path) -> tuple[list[float], list[str], dict[str, list[str | None]]]:
    """Per object row: time, id and the raw attribute strings (None where absent)."""
    times, ids, attributes = [], [], {}
    try:
        with open_xml(path) as stream:
            events = iterparse(stream, ("start", "end"))
            _, root = next(events)
            if root.tag != ROOT:
                raise TraceSetError(f"{path}: root element <{root.tag}> is not <{ROOT}>")
            for event, element in events:
                if event != "end" or element.tag != "timestep":
                    continue
                time = _time(element.get("time"), path, len(times))
                for obj in element:
                    if obj.tag not in OBJECT_TAGS:
                        continue
                    _append(obj, time, times, ids, attributes, path)
                root.clear()  # stream: forget every finished timestep
    except XML_ERRORS as exc:
        raise unreadable(path, exc) from None
    return times, ids, attributes


def _time(text: str | None, path: Path, row: int) -> float:
    try:
        return float(text)
    except (TypeError, ValueError):
        raise TraceSetError(f"{path}: a <timestep> after record {row} has time {text!r}, not "
                            "seconds (write FCD without --human-readable-time)") from None


def _append(obj, time, times, ids, attributes, path) -> None:
    ident = obj.get("id")
    if ident is None:
        raise TraceSetError(f"{path}: a <{obj.tag}> at time {time} has no id")
    row = len(times)
    times.append(time)
    ids.append(ident)
    for name, text in obj.attrib.items():
        if name == "id":
            continue
        column = attributes.get(name)
        if column is None:
            column = attributes[name] = [None] * row
        column.append(text)
    for column in attributes.values():
        if len(column) == row:
            column.append(None)


def _fields(attributes: dict[str, list[str | None]]) -> tuple[dict, list[str]]:
    fields, text = {}, []
    for name, column in attributes.items():
        present = np.array([v is not None for v in column], dtype=bool)
        try:
            values = np.array([v if v is not None else "0" for v in column], dtype=np.float64)
        except ValueError:
            text.append(name)
            continue
        fields[name] = (values, present)
    return fields, text


def read(path: str | Path, *, objects_as: str = "runs", missing: str = "error",
         object_prefix: str | None = None) -> TraceSet:
    """Read a SUMO FCD XML file (see the module docstring for layouts and rules).

    Parameters
    ----------
    path : path
        A SUMO ``--fcd-output`` file (``.xml`` or ``.xml.gz``).
    objects_as : {"runs", "signals"}
        Each vehicle a run, or the file one run with ``<id>.<attribute>`` signals.
    missing : {"error", "intersect"}
        ``objects_as="signals"``: what a vehicle absent at a timestep means.
    object_prefix : str, optional
        Prefix of every vehicle name (default: ``obj`` before integer ids).
    """
    path = Path(path)
    if not path.exists():
        raise TraceSetError(f"{path}: no such file or directory")
    times, ids, attributes = parse(path)
    if not times:
        raise TraceSetError(f"{path}: no vehicles in any timestep")
    fields, text = _fields(attributes)
    records = Records(
        where=str(path),
        time=np.asarray(times, dtype=np.float64),
        runs=None,
        objects=np.asarray(ids, dtype=object),
        fields=fields,
        default_run=path.name.split(".")[0],
        row_name="record",
    )
    metadata = {"format": "sumo-fcd", "skipped_attributes": text}
    return to_traceset(records, objects_as=objects_as, missing=missing,
                       object_prefix=object_prefix, metadata=metadata, source=str(path),
                       skip_short_runs=objects_as == "runs")
