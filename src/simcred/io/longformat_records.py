"""Long-format records -> a TraceSet: runs, objects, missing rows, the rules of
:mod:`simcred.io.longformat`.

A :class:`Records` holds one record per (run, time, object) of any long source (a CSV/Parquet
table, SUMO FCD, OSI, CommonRoad); :func:`to_traceset` orders them by run, object and time,
checks duplicates, finite values and missing rows, and assembles the runs.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.compute as pc

from simcred.errors import OptionError, TraceSetError
from simcred.io._columns import check_signals
from simcred.traces import TIME, TraceSet, handed_over

OBJECTS_AS = ("signals", "runs")
MISSING = ("error", "intersect")
_INTEGER = re.compile(r"^[+-]?\d+$")


@dataclass(frozen=True, slots=True)
class Records:
    """Long-format records, one per (run, time, object), before they become runs.

    ``fields`` maps a value column to ``(values, present)``: float64 values and a boolean mask of
    the rows that have one. ``runs``/``objects`` are per-row labels (or None: one run / no
    objects). ``where`` names the source in errors; ``row_name`` is what a record is called there.
    """

    where: str
    time: np.ndarray
    runs: Sequence[str] | pa.Array | None
    objects: Sequence[str] | pa.Array | None
    fields: Mapping[str, tuple[np.ndarray, np.ndarray]]
    default_run: str
    row_name: str = "row"


# -- options ---------------------------------------------------------------------------------------


def check_choice(name: str, value: str, choices: Sequence[str]) -> None:
    if value not in choices:
        raise OptionError(f"{name} must be one of {', '.join(choices)}, got {value!r}")


def object_name(label: str, prefix: str | None) -> str:
    """The signal prefix of an object label: ``12`` -> ``obj12``, ``ego`` -> ``ego``.

    >>> object_name("12", None), object_name("ego", None), object_name("12", "veh")
    ('obj12', 'ego', 'veh12')
    """
    if prefix is not None:
        return f"{prefix}{label}"
    return f"obj{label}" if _INTEGER.match(label) else label


# -- records -> TraceSet ---------------------------------------------------------------------------


def _codes(labels) -> tuple[np.ndarray, list[str]]:
    """Integer codes of ``labels`` numbered by first appearance, and the labels in that order.

    Arrow's dictionary encoding numbers values by first appearance, in C (labels may be an Arrow
    array or a sequence of str).
    """
    array = labels if isinstance(labels, pa.Array) else pa.array(labels, type=pa.string())
    encoded = pc.dictionary_encode(array)
    codes = encoded.indices.to_numpy(zero_copy_only=False).astype(np.int64, copy=False)
    return codes, [str(v) for v in encoded.dictionary.to_pylist()]


def _first_appearance(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Codes of integer ``keys`` by first appearance, and the key of each code."""
    unique, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")
    rank = np.empty(len(unique), dtype=np.int64)
    rank[order] = np.arange(len(unique))
    return rank[inverse.ravel()], unique[order]


def to_traceset(records: Records, *, objects_as: str = "signals", missing: str = "error",
                object_prefix: str | None = None, metadata: Mapping[str, Any] | None = None,
                source: str | None = None, skip_short_runs: bool = False) -> TraceSet:
    """Assemble long-format ``records`` into a TraceSet following the rules of
    :mod:`simcred.io.longformat`.

    With ``skip_short_runs`` a run with fewer than two time steps (an object seen once) is left
    out and named in the metadata under ``runs_too_short``, instead of being an error.
    """
    check_choice("objects_as", objects_as, OBJECTS_AS)
    check_choice("missing", missing, MISSING)
    n = len(records.time)
    if n == 0:
        raise TraceSetError(f"{records.where}: the trace set is empty (no rows)")
    _check_finite(records)
    if records.runs is None:
        run_code, run_names = np.zeros(n, dtype=np.int64), [records.default_run]
    else:
        run_code, run_names = _codes(records.runs)
    if records.objects is None:
        if objects_as == "runs":
            raise OptionError("objects_as='runs' needs an object column")
        obj_code, obj_names = np.zeros(n, dtype=np.int64), [""]
    else:
        obj_code, obj_labels = _codes(records.objects)
        obj_names = [object_name(o, object_prefix) for o in obj_labels]
    if objects_as == "runs":  # every (run, object) pair is a run
        run_code, pairs = _first_appearance(run_code * len(obj_names) + obj_code)
        run_names = [obj_names[p % len(obj_names)] if records.runs is None
                     else f"{run_names[p // len(obj_names)]}.{obj_names[p % len(obj_names)]}"
                     for p in pairs]
        obj_code, obj_names = np.zeros(n, dtype=np.int64), [""]
    order = np.lexsort((records.time, obj_code, run_code))
    _check_duplicates(records, order, run_code, obj_code, run_names, obj_names)
    run_start = np.flatnonzero(np.diff(run_code[order], prepend=-1))
    run_stop = np.append(run_start[1:], n)
    blocks, times, signals, dropped, kept, short = [], [], None, 0, [], []
    for r, (lo, hi) in enumerate(zip(run_start, run_stop, strict=True)):
        rows = order[lo:hi]
        if skip_short_runs and len(np.unique(records.time[rows])) < 2:
            short.append(run_names[r])
            continue
        kept.append(run_names[r])
        where = f"{records.where}: run '{run_names[r]}'"
        t, names, block, lost = _run_block(records, rows, obj_code[rows], obj_names, where,
                                           missing)
        if signals is None:
            signals = names
        elif names != signals:
            block = _reorder(block, names, signals, where)
        blocks.append(block)
        times.append(t)
        dropped += lost
    meta = dict(metadata or {})
    if dropped:
        meta["rows_dropped_by_intersect"] = dropped
    if short:
        meta["runs_too_short"] = short
    if not kept:
        raise TraceSetError(f"{records.where}: no run has two time steps or more")
    return TraceSet(
        signals=tuple(signals),
        time=handed_over(np.concatenate(times)),
        values=handed_over(np.concatenate(blocks)),
        offsets=np.concatenate([[0], np.cumsum([len(t) for t in times])]),
        run_ids=tuple(kept),
        metadata=meta,
        source=source or records.where,
    )


def _check_finite(records: Records) -> None:
    for name, (values, present) in ((TIME, (records.time, np.ones(len(records.time), bool))),
                                    *records.fields.items()):
        bad = np.flatnonzero(present & ~np.isfinite(values))
        if bad.size:
            label = "time column" if name == TIME else f"column '{name}'"
            raise TraceSetError(f"{records.where}: {label}, {records.row_name} {bad[0] + 1}: "
                                f"value is {values[bad[0]]} (values must be finite)")


def _check_duplicates(records, order, run_code, obj_code, run_names, obj_names) -> None:
    t = records.time[order]
    same = (np.diff(run_code[order]) == 0) & (np.diff(obj_code[order]) == 0) & (t[1:] == t[:-1])
    bad = np.flatnonzero(same)
    if bad.size:
        a, b = sorted((int(order[bad[0]]), int(order[bad[0] + 1])))
        obj = obj_names[obj_code[a]]
        who = f"run '{run_names[run_code[a]]}'" + (f", object '{obj}'" if obj else "")
        raise TraceSetError(f"{records.where}: {who} has two {records.row_name}s at "
                            f"t={float(records.time[a])!r} "
                            f"({records.row_name}s {a + 1} and {b + 1})")


def _width(records: Records, rows: np.ndarray, codes: np.ndarray) -> int:
    """The signals :func:`_run_block` makes of a run: its (object, field) pairs with a value,
    counted in linear time (a run of 100,000 objects is refused before its columns are made)."""
    return sum(np.unique(codes[present[rows]]).size for _, present in records.fields.values())


def _run_block(records, rows, codes, obj_names, where, missing):
    """Time steps, signal names and the (steps, signals) block of one run; rows dropped."""
    check_signals(_width(records, rows, codes), where)  # before its columns are made
    groups = [rows[codes == c] for c in np.unique(codes)]  # objects by first appearance
    group_times = [records.time[g] for g in groups]
    if missing == "error":
        common = np.unique(np.concatenate(group_times))
        for gt, c in zip(group_times, np.unique(codes), strict=True):
            if len(gt) != len(common):
                absent = float(common[~np.isin(common, gt)][0])
                raise TraceSetError(
                    f"{where}, object '{obj_names[c]}': no {records.row_name} at t={absent!r} "
                    "(other objects have one); use missing='intersect' (--missing intersect) "
                    "or objects_as='runs' (--objects-as runs)")
    else:
        common = group_times[0]
        for gt in group_times[1:]:
            common = np.intersect1d(common, gt, assume_unique=True)
    names, columns = [], []
    for g, gt, c in zip(groups, group_times, np.unique(codes), strict=True):
        take = g[np.searchsorted(gt, common)]
        prefix = f"{obj_names[c]}." if obj_names[c] else ""
        for field, (values, present) in records.fields.items():
            have = present[g]
            if not have.any():
                continue
            if not have.all():
                row = int(g[np.flatnonzero(~have)[0]]) + 1
                raise TraceSetError(f"{where}: column '{field}', {records.row_name} {row}: value "
                                    "is missing (other rows of this object have one)")
            names.append(prefix + field)
            columns.append(values[take])
    lost = sum(len(g) for g in groups) - len(groups) * len(common)
    if len(common) < 2:
        raise TraceSetError(f"{where}: {len(common)} time step(s) where all objects have a "
                            f"{records.row_name}; at least 2 are needed")
    if not names:
        raise TraceSetError(f"{where}: no signal columns")
    return common, names, np.column_stack(columns), lost


def _reorder(block: np.ndarray, names: list[str], signals: list[str], where: str) -> np.ndarray:
    if sorted(names) != sorted(signals):
        missing = sorted(set(signals) - set(names))
        extra = sorted(set(names) - set(signals))
        raise TraceSetError(f"{where}: signal names differ from the first run (missing "
                            f"{missing}, extra {extra}); use objects_as='runs' if objects differ")
    return block[:, [names.index(s) for s in signals]]
