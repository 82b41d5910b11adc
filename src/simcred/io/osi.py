"""ASAM OSI traces (GroundTruth moving objects) as trace sets, via betterosi.

Reading: ``.osi`` (length-prefixed binary trace of GroundTruth or SensorView messages; a
SensorView's ``global_ground_truth`` is used) is one run named after the file; ``.mcap`` has one
run per OSI topic (channel), named by the topic. Every moving object becomes dotted signals
``obj<id>.<field>`` (the long-format rules of :mod:`simcred.io.longformat`; objects entering or
leaving follow ``missing``), with the fields the trace sets for that object:

==========================  =======================================================
field                       OSI (``MovingObject.base``), global frame, SI units
==========================  =======================================================
``x``, ``y``, ``z``         ``position`` [m] (centre of the bounding box)
``roll``, ``pitch``, ``yaw`` ``orientation`` [rad]
``vx``, ``vy``, ``vz``      ``velocity`` [m/s]
``ax``, ``ay``, ``az``      ``acceleration`` [m/s²]
``yaw_rate``                ``orientation_rate.yaw`` [rad/s]
``length``, ``width``,      ``dimension`` [m]
``height``
==========================  =======================================================

Time is ``timestamp.seconds + timestamp.nanos / 1e9`` (the nearest float64). The metadata
names each run's host vehicle (``host_vehicles``).

Writing: one GroundTruth per time step (OSI 3.8.0); an ``.osi`` file holds one run, an ``.mcap``
file one topic per run. Signals must be ``<object>.<field>`` with a field of the table. Objects
named ``obj<id>`` keep their id; other names (``ego``, ``lead``) get free ids, and MCAP stores the
names (and the trace set's metadata) in a ``simcred`` metadata record, so they read back; ``.osi``
cannot store names, so there they must be ``obj<id>``. The object named by ``host`` (default
``ego`` when present) is the host vehicle. Values are stored as doubles (exact); times are
stored in whole nanoseconds, so a time comes back within 0.5 ns. ``creation_time`` is written as
1970-01-01T00:00:00Z so the same trace set gives byte-identical files.
"""

from __future__ import annotations

import json
import re
import warnings
from fractions import Fraction
from pathlib import Path

import numpy as np

from simcred.errors import OptionError, TraceSetError
from simcred.io.longformat import split_signal
from simcred.io.longformat_records import Records, object_name, to_traceset
from simcred.traces import TraceSet

FIELDS = {
    "x": ("position", "x"), "y": ("position", "y"), "z": ("position", "z"),
    "roll": ("orientation", "roll"), "pitch": ("orientation", "pitch"),
    "yaw": ("orientation", "yaw"),
    "vx": ("velocity", "x"), "vy": ("velocity", "y"), "vz": ("velocity", "z"),
    "ax": ("acceleration", "x"), "ay": ("acceleration", "y"), "az": ("acceleration", "z"),
    "yaw_rate": ("orientation_rate", "yaw"),
    "length": ("dimension", "length"), "width": ("dimension", "width"),
    "height": ("dimension", "height"),
}
METADATA_RECORD = "simcred"
NANOS = 10**9
_OBJ_ID = re.compile(r"^obj(\d+)$")
_INT64 = 2**63


def _betterosi():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        import betterosi
    return betterosi


# -- reading ---------------------------------------------------------------------------------------


def _frames(path: Path, topic: str | None):
    b = _betterosi()
    options = {"mcap_topics": [topic]} if topic is not None else {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        yield from b.read(str(path), return_ground_truth=True, **options)


def _topics(path: Path) -> list[str | None]:
    if path.suffix.lower() != ".mcap":
        return [None]
    return list(_betterosi().read_channel_metadata(str(path)))


def _unreadable(path: Path, exc: BaseException) -> TraceSetError:
    reason = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
    return TraceSetError(f"{path}: unreadable OSI trace ({reason})")


def _stored(path: Path) -> dict:
    if path.suffix.lower() != ".mcap":
        return {}
    for record in _betterosi().read_file_metadata(str(path)):
        if record["name"] == METADATA_RECORD:
            try:
                return {k: json.loads(v) for k, v in record["data"].items()}
            except ValueError:
                raise TraceSetError(f"{path}: metadata record '{METADATA_RECORD}' is not "
                                    "JSON") from None
    return {}


def _collect(path: Path, topic: str | None, run: str, names: dict[str, str], out: dict) -> None:
    for frame, gt in enumerate(_frames(path, topic)):
        t = float(Fraction(gt.timestamp.seconds * NANOS + gt.timestamp.nanos, NANOS))
        if gt.has_field("host_vehicle_id"):
            host = str(gt.host_vehicle_id.value)
            out["hosts"].setdefault(run, object_name(names.get(host, host), None))
        for obj in gt.moving_object:
            if not obj.has_field("id"):
                raise TraceSetError(f"{path}: run '{run}', frame {frame}: a moving object "
                                    "has no id")
            ident = str(obj.id.value)
            out["time"].append(t)
            out["run"].append(run)
            out["object"].append(names.get(ident, ident))
            base = obj.base if obj.has_field("base") else None
            for field, (group, attr) in FIELDS.items():
                part = getattr(base, group) if base is not None and base.has_field(group) \
                    else None
                if part is not None and part.has_field(attr):
                    out[field].append(float(getattr(part, attr)))
                else:
                    out[field].append(None)


def read(path: str | Path, *, objects_as: str = "signals", missing: str = "error") -> TraceSet:
    """Read an OSI ``.osi`` or ``.mcap`` trace (see the module docstring for the rules)."""
    path = Path(path)
    if not path.exists():
        raise TraceSetError(f"{path}: no such file or directory")
    out = {"time": [], "run": [], "object": [], "hosts": {}, **{f: [] for f in FIELDS}}
    try:
        stored = _stored(path)
        names = {str(k): v for k, v in stored.get("objects", {}).items()}
        for topic in _topics(path):
            run = path.stem if topic is None else topic
            _collect(path, topic, run, names, out)
    except TraceSetError:
        raise
    except Exception as exc:  # protobuf/mcap decoding errors of many kinds
        raise _unreadable(path, exc) from None
    if not out["time"]:
        raise TraceSetError(f"{path}: no moving objects in any GroundTruth frame")
    fields = {}
    for field in FIELDS:
        present = np.array([v is not None for v in out[field]], dtype=bool)
        if present.any():
            values = np.array([0.0 if v is None else v for v in out[field]], dtype=np.float64)
            fields[field] = (values, present)
    records = Records(where=str(path), time=np.asarray(out["time"], dtype=np.float64),
                      runs=np.asarray(out["run"], dtype=object),
                      objects=np.asarray(out["object"], dtype=object), fields=fields,
                      default_run=path.stem, row_name="object state")
    metadata = {**stored.get("metadata", {}), "format": "osi", "host_vehicles": out["hosts"]}
    return to_traceset(records, objects_as=objects_as, missing=missing, metadata=metadata,
                       source=str(path))


# -- writing ---------------------------------------------------------------------------------------


def _object_ids(objects: list[str], osi_file: bool, path: Path) -> dict[str, int]:
    ids = {o: int(m.group(1)) for o in objects if (m := _OBJ_ID.match(o))}
    others = [o for o in objects if o not in ids]
    if others and osi_file:
        raise TraceSetError(f"{path}: an .osi trace cannot store object names ({others[0]!r}); "
                            "name objects obj<id> or write .mcap")
    free = max(ids.values(), default=0) + 1
    for k, name in enumerate(others):
        ids[name] = free + k
    return ids


def _timestamp(b, t: float, where: str):
    total = round(Fraction(t) * NANOS)
    seconds, nanos = divmod(total, NANOS)
    if not -_INT64 <= seconds < _INT64:
        raise TraceSetError(f"{where}: t={t!r} s does not fit an OSI timestamp")
    return b.Timestamp(seconds=seconds, nanos=nanos), total


def _layout(traces: TraceSet, path: Path):
    """Per object: its OSI id and its (field, signal column) pairs."""
    per_object: dict[str, list[tuple[str, int]]] = {}
    for j, signal in enumerate(traces.signals):
        obj, field = split_signal(signal, where=str(path), hint="OSI stores objects (read "
                                  "per-object formats with objects_as='signals')")
        if field not in FIELDS:
            raise TraceSetError(f"{path}: signal '{signal}': OSI stores no field '{field}' "
                                f"(fields: {', '.join(FIELDS)})")
        per_object.setdefault(obj, []).append((field, j))
    return per_object


def _moving_object(b, ident: int, fields: list[tuple[str, int]], row: np.ndarray):
    groups: dict[str, dict[str, float]] = {}
    for field, j in fields:
        group, attr = FIELDS[field]
        groups.setdefault(group, {})[attr] = float(row[j])
    kinds = {"position": b.Vector3d, "velocity": b.Vector3d, "acceleration": b.Vector3d,
             "orientation": b.Orientation3d, "orientation_rate": b.Orientation3d,
             "dimension": b.Dimension3d}
    base = b.BaseMoving(**{g: kinds[g](**v) for g, v in groups.items()})
    return b.MovingObject(id=b.Identifier(value=ident), base=base)


def write(traces: TraceSet, path: str | Path, *, host: str | None = None) -> Path:
    """Write ``traces`` as an OSI trace: ``.osi`` (one run) or ``.mcap`` (a topic per run)."""
    path = Path(path)
    b = _betterosi()
    osi_file = path.suffix.lower() == ".osi"
    if osi_file and traces.n_runs != 1:
        raise TraceSetError(f"{path}: an .osi trace holds one run, the trace set has "
                            f"{traces.n_runs} (write .mcap: one topic per run)")
    per_object = _layout(traces, path)
    ids = _object_ids(list(per_object), osi_file, path)
    host = host if host is not None else ("ego" if "ego" in ids else None)
    if host is not None and host not in ids:
        raise OptionError(f"host: no object named {host!r} (objects: {', '.join(ids)})")
    version = b.InterfaceVersion(version_major=3, version_minor=8, version_patch=0)
    path.parent.mkdir(parents=True, exist_ok=True)
    options = {} if osi_file else {"metadata": {"creation_time": "1970-01-01T00:00:00Z"}}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with b.Writer(str(path), **options) as writer:
            origin = _timestamp(b, float(np.min(traces.time)), traces.source)[1]
            for i, run_id in enumerate(traces.run_ids):
                _write_run(b, writer, traces, i, (per_object, ids, host, version, origin),
                           None if osi_file else run_id)
            if not osi_file:
                stored = {"objects": {str(v): k for k, v in ids.items()},
                          "metadata": dict(traces.metadata)}
                writer.add_metadata(METADATA_RECORD, {k: json.dumps(v, sort_keys=True)
                                                      for k, v in stored.items()})
    return path


def _write_run(b, writer, traces, i, frame, topic) -> None:
    """One GroundTruth per step of run ``i``; MCAP log times count ns from the set's first t."""
    per_object, ids, host, version, origin = frame
    lo, hi = traces.offsets[i], traces.offsets[i + 1]
    where = f"{traces.source}: run '{traces.run_ids[i]}'"
    previous = None
    for row in range(lo, hi):
        stamp, total = _timestamp(b, float(traces.time[row]), where)
        if previous is not None and total <= previous:
            raise TraceSetError(f"{where}: t={traces.time[row]!r} is within 1 ns of the step "
                                "before; OSI stores whole nanoseconds")
        previous = total
        objects = [_moving_object(b, ids[o], f, traces.values[row]) for o, f in
                   per_object.items()]
        gt = b.GroundTruth(version=version, timestamp=stamp, moving_object=objects,
                           **({"host_vehicle_id": b.Identifier(value=ids[host])} if host
                              else {}))
        if topic is None:
            writer.add(gt)
        else:
            writer.add(gt, topic=topic, log_time=total - origin)
