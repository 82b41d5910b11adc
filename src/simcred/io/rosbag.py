"""ROS 2 bags (``.db3`` or ``.mcap`` storage), read with ``rosbags`` (no ROS installation).

Rules (also in ``docs/formats.md``)
-----------------------------------
* **Path**: a bag directory (``metadata.yaml`` beside its storage files), or a directory of bag
  directories (every bag its runs, natural order of the names).
* **Topics**: ``topics`` names them (default: every ``nav_msgs/msg/Odometry`` and
  ``geometry_msgs/msg/PoseStamped`` topic). Known types give ``x``, ``y``, ``z`` (position),
  ``yaw`` (rad, from the orientation quaternion), and for odometry ``vx``, ``vy`` (twist, in
  the child frame) and ``yaw_rate``. ``fields`` (dotted message paths, ``twist.twist.linear.x``)
  replaces those with the named numeric fields of any message type, signals named by the path.
* **Time**: the message's ``header.stamp`` (``sec + nanosec / 1e9``, seconds since the epoch);
  a message type without a header takes the bag's receive time, and ``metadata["time"]`` says
  which. Messages are ordered by that time.
* **Runs**: ``runs="bag"`` (default): a bag is a run; several topics in it become
  ``<topic leaf>.<signal>`` (``odom.x``, ``pose.x``) and must carry the same time stamps.
  ``runs="namespace"``: every topic namespace is a run (``/car1/odom`` and ``/car2/odom`` ->
  runs ``car1``, ``car2`` with the signals of ``odom``); every namespace needs the same topics.
  In a directory of bags, run ids are ``<bag>`` or ``<bag>:<namespace>``.
* **Metadata**: per run under ``run_info`` the bag and topics; ``units`` for the known types.

A bag ``rosbags`` cannot open (no or bad ``metadata.yaml``, damaged storage, a message that does
not deserialize) is a one-line :class:`~simcred.errors.TraceSetError` naming it.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from simcred.errors import OptionError, TraceSetError
from simcred.io._columns import check_signals
from simcred.traces import RUN_INFO, TraceSet, concat, handed_over

METADATA = "metadata.yaml"
ODOMETRY = "nav_msgs/msg/Odometry"
POSE = "geometry_msgs/msg/PoseStamped"
RUNS = ("bag", "namespace")
UNITS = {"x": "m", "y": "m", "z": "m", "yaw": "rad", "vx": "m/s", "vy": "m/s",
         "yaw_rate": "rad/s"}


def is_bag(directory: Path) -> bool:
    """Whether ``directory`` is a bag or holds bags (a ``metadata.yaml`` at most one level down)."""
    return (directory / METADATA).is_file() or any(
        (p / METADATA).is_file() for p in directory.iterdir() if p.is_dir())


def is_ros2_mcap(path: Path) -> bool:
    """Whether ``path`` is an MCAP file with the ``ros2`` profile (the storage file of a bag)."""
    # MCAP: magic (8 bytes), then the Header record: opcode 0x01, u64 length, u32 profile length,
    # profile (https://mcap.dev/spec#header-op0x01)
    try:
        with open(path, "rb") as stream:
            head = stream.read(8 + 1 + 8 + 4 + 4)
    except OSError:
        return False
    return (head[:5] == b"\x89MCAP" and head[8:9] == b"\x01"
            and int.from_bytes(head[17:21], "little") == 4 and head[21:25] == b"ros2")


def read(path: Path, *, topics: Sequence[str] | None = None,
         fields: Sequence[str] | None = None, runs: str = "bag") -> TraceSet:
    """Read a ROS 2 bag or a directory of bags (see the module rules)."""
    if runs not in RUNS:
        raise OptionError(f"runs must be one of {', '.join(RUNS)}, got {runs!r}")
    topics, fields = _names(topics), _names(fields)
    path = Path(path)
    if (path / METADATA).is_file():
        return _read_bag(path, topics, fields, runs, prefix="")
    bags = sorted((p for p in path.iterdir() if p.is_dir() and (p / METADATA).is_file()),
                  key=lambda p: [int(s) if s.isdigit() else s for s in re.split(r"(\d+)",
                                                                                   p.name)])
    if not bags:
        raise TraceSetError(f"{path}: not a ROS 2 bag (no {METADATA}) and holds no bags")
    parts = [_read_bag(b, topics, fields, runs, prefix=b.name) for b in bags]
    info = {k: v for p in parts for k, v in p.metadata[RUN_INFO].items()}
    return concat(parts, source=str(path), metadata={**parts[0].metadata, RUN_INFO: info})


def _names(value: Sequence[str] | str | None) -> list[str] | None:
    if value is None:
        return None
    return [v for v in value.split(",") if v] if isinstance(value, str) else list(value)


def _read_bag(bag: Path, topics: list[str] | None, fields: list[str] | None, runs: str,
              prefix: str) -> TraceSet:
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    where = str(bag)
    reason = None
    try:
        with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
            chosen = _topics(reader, topics, fields, where)
            series = {topic: _series(reader, conns, fields, where)
                      for topic, conns in chosen.items()}
    except TraceSetError:
        raise
    except Exception as exc:  # rosbags raises many kinds on a damaged bag
        text = str(exc).strip().splitlines()
        reason = text[0][:200] if text else type(exc).__name__
    if reason is not None:
        raise TraceSetError(f"{where}: unreadable ROS 2 bag ({reason})")
    parts, info = [], {}
    for name, members in _groups(list(series), runs, where).items():
        run_id = ":".join(p for p in (prefix, name) if p) or bag.name
        parts.append(_run(run_id, {leaf: series[topic] for leaf, topic in members.items()},
                          where))
        info[run_id] = {"bag": bag.name, "topics": sorted(members.values())}
    return concat(parts, source=where, metadata={
        "units": {} if fields else _units(parts[0].signals),
        "time": "header.stamp" if all(s[2] for s in series.values()) else "receive",
        RUN_INFO: info})


def _units(signals: Sequence[str]) -> dict[str, str]:
    return {s: UNITS[s.rpartition(".")[2]] for s in signals if s.rpartition(".")[2] in UNITS}


def _topics(reader, topics: list[str] | None, fields: list[str] | None,
            where: str) -> dict[str, list]:
    """The connections of each chosen topic (named, or every odometry and pose topic)."""
    by_topic: dict[str, list] = {}
    for connection in reader.connections:
        by_topic.setdefault(connection.topic, []).append(connection)
    if topics is None:
        chosen = sorted(t for t, c in by_topic.items() if c[0].msgtype in (ODOMETRY, POSE))
        if not chosen:
            kinds = ", ".join(f"{t} ({c[0].msgtype})" for t, c in sorted(by_topic.items()))
            raise TraceSetError(f"{where}: no {ODOMETRY} or {POSE} topic (topics: "
                                f"{kinds or 'none'}); name topics and fields")
    else:
        for topic in topics:
            if topic not in by_topic:
                raise TraceSetError(f"{where}: no topic '{topic}' (topics: "
                                    f"{', '.join(sorted(by_topic)) or 'none'})")
        chosen = list(topics)
    for topic in chosen:
        msgtype = by_topic[topic][0].msgtype
        if fields is None and msgtype not in (ODOMETRY, POSE):
            raise TraceSetError(f"{where}: topic '{topic}' is {msgtype}, not {ODOMETRY} or "
                                f"{POSE}; name the numeric fields to read (fields=)")
    return {t: by_topic[t] for t in chosen}


def _series(reader, connections: list, fields: list[str] | None,
            where: str) -> tuple[np.ndarray, dict[str, np.ndarray], bool]:
    """(time, {signal: values}, stamped) of one topic, ordered by time."""
    times, rows, stamped = [], [], True
    for connection, received, raw in reader.messages(connections=connections):
        message = reader.deserialize(raw, connection.msgtype)
        stamp = _stamp(message)
        stamped &= stamp is not None
        times.append(stamp if stamp is not None else received / 1e9)
        rows.append(_fields(message, fields, connection.topic, where) if fields
                    else _known(message, connection.msgtype))
    if not rows:
        raise TraceSetError(f"{where}: topic '{connections[0].topic}' has no messages")
    order = np.argsort(np.asarray(times), kind="stable")
    names = list(rows[0])
    return (np.asarray(times)[order],
            {n: np.asarray([r[n] for r in rows], dtype=np.float64)[order] for n in names},
            stamped)


def _stamp(message: Any) -> float | None:
    header = getattr(message, "header", None)
    stamp = getattr(header, "stamp", None)
    if stamp is None:
        return None
    return stamp.sec + stamp.nanosec / 1e9


def _yaw(q: Any) -> float:
    """Yaw of a unit quaternion (rotation about z), in rad."""
    return math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))


def _known(message: Any, msgtype: str) -> dict[str, float]:
    pose = message.pose.pose if msgtype == ODOMETRY else message.pose
    out = {"x": pose.position.x, "y": pose.position.y, "z": pose.position.z,
           "yaw": _yaw(pose.orientation)}
    if msgtype == ODOMETRY:
        twist = message.twist.twist
        out.update(vx=twist.linear.x, vy=twist.linear.y, yaw_rate=twist.angular.z)
    return out


def _fields(message: Any, fields: list[str], topic: str, where: str) -> dict[str, float]:
    out = {}
    for path in fields:
        value = message
        for part in path.split("."):
            if not hasattr(value, part):
                raise TraceSetError(f"{where}: topic '{topic}' ({message.__msgtype__}) has no "
                                    f"field '{path}'")
            value = getattr(value, part)
        if isinstance(value, bool) or not isinstance(value, int | float | np.number):
            raise TraceSetError(f"{where}: topic '{topic}': field '{path}' is not a number "
                                f"({type(value).__name__})")
        out[path] = float(value)
    return out


def _groups(topics: list[str], runs: str, where: str) -> dict[str, dict[str, str]]:
    """Runs and their topics by leaf name: ``{run: {leaf: topic}}``."""
    groups: dict[str, dict[str, str]] = {}
    for topic in topics:
        namespace, _, leaf = topic.rstrip("/").rpartition("/")
        key = namespace.strip("/").replace("/", ".") if runs == "namespace" else ""
        members = groups.setdefault(key, {})
        name = leaf if runs == "namespace" or len(topics) > 1 else ""
        if name in members:
            raise TraceSetError(f"{where}: topics '{members[name]}' and '{topic}' would give "
                                f"the same signals '{leaf}.*' in one run; read them with "
                                "runs='namespace' or one at a time (topics=)")
        members[name] = topic
    first = sorted(next(iter(groups.values())))
    for name, members in groups.items():
        if sorted(members) != first:
            raise TraceSetError(f"{where}: namespace '{name or '/'}' has topics "
                                f"{sorted(members)}, another has {first}; every run needs the "
                                "same topics")
    return groups


def _run(run_id: str, members: dict[str, tuple], where: str) -> TraceSet:
    """One run from its topics' series: plain signals for one topic, ``leaf.signal`` for more."""
    (first_leaf, (time, _, _)), *rest = members.items()
    for leaf, (other, _, _) in rest:
        if not np.array_equal(other, time):
            raise TraceSetError(f"{where}: topics '{first_leaf}' ({len(time)} messages) and "
                                f"'{leaf}' ({len(other)}) of run '{run_id}' have different "
                                "time stamps; read them as separate trace sets (topics=)")
    several = len(members) > 1
    check_signals(sum(len(values) for _, values, _ in members.values()), where)
    signals, columns = [], []
    for leaf, (_, values, _) in members.items():
        for name, column in values.items():
            signals.append(f"{leaf}.{name}" if several else name)
            columns.append(column)
    return TraceSet(tuple(signals), handed_over(np.array(time)),
                    handed_over(np.column_stack(columns)), [0, len(time)], (run_id,),
                    source=where)
