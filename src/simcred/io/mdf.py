"""ASAM MDF4 measurement files (CANape, INCA, Vector loggers), read with asammdf.

Rules (also in ``docs/formats.md``)
-----------------------------------
* **Path**: an ``.mf4``/``.mdf`` file, or a directory of them (every file its runs, natural
  order of the names).
* **Signals**: the channels named in ``channels`` (default: every numeric channel that is not a
  master/time channel), under their names, as physical values (the file's conversions applied).
  A channel name found in two channel groups is refused (ambiguous). Non-numeric channels not
  named are skipped and listed in ``metadata["skipped_channels"]``.
* **Time**: the master channel of the signals' channel group, in seconds. Channels of different
  groups (rates) must share their time stamps exactly, unless ``resample`` names a method:
  ``"linear"`` (linear interpolation) or ``"previous"`` (sample and hold, the last value at or
  before the time). The common base is then the time stamps of the group with the most samples
  (the fastest), within the interval every channel covers; the method and base are recorded in
  ``metadata["resampling"]``. Without a method, different time bases are an error naming two
  channels and their rates — simcred never resamples silently.
* **Runs**: a numeric channel named ``run_channel`` (default ``"run"``), when the file has one,
  names the run of every sample (sample and hold onto the base; runs in order of first
  appearance, id = the value, ``7`` for integral values); otherwise the file is one run named
  after its stem. In a directory, run ids are ``<stem>:<value>`` (with a run channel) or
  ``<stem>``.
* **Units**: every channel's unit from the file, in ``metadata["units"]``.

A file asammdf cannot open (truncated, not MDF, encrypted) is a one-line
:class:`~simcred.errors.TraceSetError` naming it; asammdf's own log output is silenced while
reading (it would otherwise print beside that line).
"""

from __future__ import annotations

import contextlib
import gc
import logging
import re
import sys
import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from simcred.errors import OptionError, TraceSetError
from simcred.io._columns import check_signals
from simcred.traces import TraceSet, concat, handed_over

SUFFIXES = (".mf4", ".mdf")
RESAMPLE = ("linear", "previous")


@dataclass(frozen=True, slots=True)
class Channel:
    """One channel as read: physical samples on its group's time stamps."""

    name: str
    group: int
    samples: np.ndarray
    timestamps: np.ndarray
    unit: str


def files_in(directory: Path) -> list[Path]:
    """The MDF files of a directory, in natural order of their names."""
    def natural(path: Path) -> list[object]:
        return [int(p) if p.isdigit() else p for p in re.split(r"(\d+)", path.stem)]

    return sorted((p for p in directory.iterdir() if p.suffix.lower() in SUFFIXES
                   and p.is_file()), key=natural)


def read(path: Path, *, channels: Sequence[str] | None = None, resample: str | None = None,
         run_channel: str = "run") -> TraceSet:
    """Read an MDF4 file or a directory of them (see the module rules)."""
    if resample is not None and resample not in RESAMPLE:
        raise OptionError(f"resample must be one of {', '.join(RESAMPLE)} (or none), got "
                          f"{resample!r}")
    if isinstance(channels, str):
        channels = [c for c in channels.split(",") if c]
    path = Path(path)
    if path.is_dir():
        files = files_in(path)
        if not files:
            raise TraceSetError(f"{path}: no MDF files (*.mf4, *.mdf) in the directory")
        parts = [_read_file(f, channels, resample, run_channel, prefix=f"{f.stem}:")
                 for f in files]
        for part in parts[1:]:
            if part.signals != parts[0].signals:
                raise TraceSetError(f"{part.source}: channels {list(part.signals)} differ from "
                                    f"{parts[0].source}: {list(parts[0].signals)}")
        return concat(parts, source=str(path), metadata=_merged(parts))
    return _read_file(path, channels, resample, run_channel, prefix="")


def _merged(parts: list[TraceSet]) -> dict:
    """The first file's metadata, with the units of all and the files' resampling."""
    metadata = dict(parts[0].metadata)
    metadata["units"] = {k: v for p in parts for k, v in p.metadata.get("units", {}).items()}
    resampling = {p.source: p.metadata["resampling"] for p in parts if "resampling" in p.metadata}
    if resampling:
        metadata["resampling"] = resampling
    return metadata


@contextlib.contextmanager
def _quiet() -> Iterator[None]:
    """asammdf logs and warns about damaged blocks, and a half-built reader's ``__del__`` raises
    (Python prints that as "Exception ignored ... Traceback"); the caller reports one line
    instead. The readers left behind are collected before the hook is restored."""
    logger = logging.getLogger("asammdf")
    level, propagate, hook = logger.level, logger.propagate, sys.unraisablehook
    logger.setLevel(logging.CRITICAL + 1)
    logger.propagate = False
    sys.unraisablehook = lambda _: None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            yield
    finally:
        gc.collect()
        sys.unraisablehook = hook
        logger.setLevel(level)
        logger.propagate = propagate


def _read_file(path: Path, wanted: Sequence[str] | None, resample: str | None,
               run_channel: str, prefix: str) -> TraceSet:
    if not path.is_file():
        raise TraceSetError(f"{path}: no such file")
    with _quiet():
        found, skipped = _channels(path, wanted, run_channel)
    run = found.pop(run_channel, None)
    check_signals(len(found), str(path))  # before the channels are put on one time base
    if not found:
        raise TraceSetError(f"{path}: no numeric channel to read besides the time and run "
                            "channels")
    time, columns, resampling = _common_base(path, list(found.values()), resample)
    metadata: dict = {"units": {c.name: c.unit for c in found.values() if c.unit}}
    if resampling:
        metadata["resampling"] = resampling
    if skipped:
        metadata["skipped_channels"] = skipped
    values = np.column_stack(columns)
    signals = tuple(found)
    if run is None:
        return TraceSet(signals, handed_over(time), handed_over(values), [0, len(time)],
                        (prefix.rstrip(":") or path.stem,), metadata, source=str(path))
    labels = _hold(run.samples, run.timestamps, time)
    if not np.isfinite(labels).all():
        raise TraceSetError(f"{path}: channel '{run_channel}' (the run of each sample) has "
                            "non-finite values")
    _, first = np.unique(labels, return_index=True)
    ids = labels[np.sort(first)]  # in order of first appearance
    order = np.concatenate([np.flatnonzero(labels == v) for v in ids])
    lengths = [int(np.count_nonzero(labels == v)) for v in ids]
    return TraceSet(signals, handed_over(time[order]), handed_over(values[order]),
                    np.concatenate([[0], np.cumsum(lengths)]),
                    tuple(prefix + _label(v) for v in ids), metadata, source=str(path))


def _label(value: float) -> str:
    return str(int(value)) if float(value).is_integer() else repr(float(value))


def _channels(path: Path, wanted: Sequence[str] | None,
              run_channel: str) -> tuple[dict[str, Channel], list[str]]:
    """The channels to read (and the run channel), and the non-numeric ones skipped."""
    from asammdf import MDF

    reason = None
    try:
        mdf = MDF(str(path))
    except Exception as exc:  # asammdf raises many kinds on a damaged file
        reason = _reason(exc)
    if reason is not None:  # raised here, so the half-built reader is not kept alive with it
        raise TraceSetError(f"{path}: unreadable MDF ({reason})")
    try:
        locations: dict[str, list[tuple[int, int]]] = {}
        for name, places in mdf.channels_db.items():
            data = [(g, i) for g, i in places if mdf.masters_db.get(g) != i]
            if data:
                locations[name] = data
        if wanted is not None:
            for name in wanted:
                if name not in locations:
                    known = ", ".join(sorted(locations)) or "none"
                    raise TraceSetError(f"{path}: no channel '{name}' (channels: {known})")
        names = list(wanted) if wanted is not None else sorted(locations)
        if run_channel in locations and run_channel not in names:
            names.append(run_channel)
        found, skipped = {}, []
        for name in names:
            if len(locations[name]) > 1:
                groups = ", ".join(str(g) for g, _ in locations[name])
                raise TraceSetError(f"{path}: channel '{name}' is in channel groups {groups}; "
                                    "the name is ambiguous")
            group, index = locations[name][0]
            try:
                signal = mdf.get(name, group, index)
            except Exception as exc:
                raise TraceSetError(f"{path}: channel '{name}' unreadable ({_reason(exc)})"
                                    ) from None
            samples = np.asarray(signal.samples)
            if samples.ndim != 1 or samples.dtype.kind not in "biuf":
                if wanted is not None or name == run_channel:
                    raise TraceSetError(f"{path}: channel '{name}' is not numeric (dtype "
                                        f"{samples.dtype}, shape {samples.shape})")
                skipped.append(name)
                continue
            found[name] = Channel(name, group, samples.astype(np.float64),
                                  np.asarray(signal.timestamps, dtype=np.float64),
                                  str(signal.unit or ""))
        return found, skipped
    finally:
        mdf.close()


def _reason(exc: BaseException) -> str:
    """The first line of asammdf's message, without the repr of its memory map."""
    text = str(exc).strip().splitlines()
    line = text[0][:200] if text else type(exc).__name__
    return re.sub(r"'<mmap\.mmap [^>]*>' is", "the file is", line)


def _common_base(path: Path, channels: list[Channel], resample: str | None
                 ) -> tuple[np.ndarray, list[np.ndarray], dict | None]:
    """The time stamps and the channels' values on them (see the rules on resampling)."""
    base = max(channels, key=lambda c: len(c.timestamps))
    if all(np.array_equal(c.timestamps, base.timestamps) for c in channels):
        return base.timestamps, [c.samples for c in channels], None
    if resample is None:
        other = next(c for c in channels if not np.array_equal(c.timestamps, base.timestamps))
        raise TraceSetError(
            f"{path}: channels '{base.name}' ({_rate(base)}) and '{other.name}' ({_rate(other)}) "
            "have different time bases; give resample='linear' or 'previous' (simcred convert "
            "--resample-method) to put them on one")
    for c in channels:
        if len(c.timestamps) < 1 or np.any(np.diff(c.timestamps) <= 0):
            raise TraceSetError(f"{path}: channel '{c.name}': time stamps not strictly "
                                "increasing")
    low = max(c.timestamps[0] for c in channels)
    high = min(c.timestamps[-1] for c in channels)
    time = base.timestamps[(base.timestamps >= low) & (base.timestamps <= high)]
    if len(time) < 2:
        raise TraceSetError(f"{path}: the channels share less than two time stamps of "
                            f"'{base.name}' (their time ranges barely overlap)")
    columns = [np.interp(time, c.timestamps, c.samples) if resample == "linear"
               else _hold(c.samples, c.timestamps, time) for c in channels]
    return time, columns, {"method": resample, "base": base.name, "base_group": base.group,
                           "rate_hz": _hz(base)}


def _hold(samples: np.ndarray, timestamps: np.ndarray, time: np.ndarray) -> np.ndarray:
    """Sample and hold: the last sample at or before each time (the first before the start)."""
    index = np.searchsorted(timestamps, time, side="right") - 1
    return samples[np.clip(index, 0, len(samples) - 1)]


def _hz(channel: Channel) -> float | None:
    span = channel.timestamps[-1] - channel.timestamps[0] if len(channel.timestamps) else 0
    return float((len(channel.timestamps) - 1) / span) if span > 0 else None


def _rate(channel: Channel) -> str:
    hz = _hz(channel)
    return f"{hz:.4g} Hz, group {channel.group}" if hz else f"group {channel.group}"
