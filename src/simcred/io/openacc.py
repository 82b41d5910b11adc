"""JRC OpenACC car-following recordings → leader–follower episodes as a TraceSet.

OpenACC (Makridis, Mattas, Anesiadou, Ciuffo 2021 [1]) recorded platoons of 4–11 production
cars with GNSS at 10 Hz on the ZalaZONE test track. A recording (one CSV file) starts with five
metadata rows (``Date``, ``Vehicle_order``, ``Number_of_vehicles``, ``ACC`` 0/1,
``Distance_setting``), then a header and the rows: ``Time`` [s], ``Speed<i>`` [m/s],
``E<i>``/``N<i>`` [m] and ``IVS<i>`` [m] for the vehicle at platoon position ``i`` (1 = the leader
of the platoon). Empty cells: no data.

``IVS<i>`` is the bumper-to-bumper gap between vehicle ``i`` and the vehicle *behind* it,
``i + 1`` (the data's README says "to the vehicle ahead"; the positions say otherwise: the
distance between the antennas of ``i`` and ``i + 1`` minus ``IVS<i>`` is 2.8–5.4 m, a car length,
in every file).

simcred ships the recordings as zstd Parquet (``simcred.data``, columns ``Time``, ``Speed<i>``,
``IVS<i>`` in hundredths as int32, the metadata rows as JSON); :func:`read_recording` reads both the
original CSV and that Parquet, and the two give the same numbers. :func:`episodes` cuts every
leader–follower pair into episodes by :class:`EpisodeRules` and counts what each rule removes.

Episode signals (units): ``gap`` [m] bumper to bumper; ``dv`` [m/s] = leader speed − follower
speed (positive: the gap opens); ``v`` [m/s] follower speed; ``a`` [m/s²] follower acceleration,
the central difference of ``v`` inside the episode (one-sided at its ends, :func:`acceleration`);
``v_leader`` [m/s]. Per-run facts sit in ``metadata["run_info"][run_id]``.

References
----------
.. [1] M. Makridis, K. Mattas, A. Anesiadou, B. Ciuffo, "OpenACC. An open database of car-following
   experiments to study the properties of commercial ACC systems", Transportation Research Part C
   125 (2021) 103047. Data © European Commission, JRC, CC BY 4.0.
"""

from __future__ import annotations

import io
import json
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

from simcred.errors import OptionError, TraceSetError
from simcred.io._columns import check_table, parquet_table
from simcred.io._paths import local
from simcred.limits import check_count, check_finite
from simcred.traces import RUN_INFO, TIME, TraceSet

SIGNALS = ("gap", "dv", "v", "a", "v_leader")
UNITS = {"gap": "m", "dv": "m/s", "v": "m/s", "a": "m/s²", "v_leader": "m/s", TIME: "s"}
META_ROWS = ("Date", "Vehicle_order", "Number_of_vehicles", "ACC", "Distance_setting")
SETTINGS = {"S": "short", "L": "long", "": None}
PARQUET_KEY = b"openacc"
SCALE = 100  # the shipped Parquet stores hundredths (the CSV has two decimals)
_COLUMN = re.compile(r"^(Speed|E|N|IVS)(\d+)$")
ATTRIBUTION = ("Contains data from OpenACC, © European Commission, Joint Research Centre (JRC), "
               "CC BY 4.0. Modified: column subset, values rounded to 2 decimals.")


# -- one recording ---------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True, eq=False)
class OpenACCRecording:
    """One OpenACC file: metadata rows and the time, speed and gap columns (NaN = no data).

    Parameters
    ----------
    name : str
        ``<folder>/<stem>`` of the file, e.g. ``no_ACC/handling_part22``.
    vehicles : tuple of str
        ``Vehicle_order``: the car at platoon position ``i`` is ``vehicles[i - 1]``.
    acc : bool
        True if the followers drove on ACC (``ACC,1``), False if humans drove them.
    setting : str or None
        ACC time-gap setting from the file header: "short", "long", or None.
    time : ndarray
        ``Time`` [s].
    speed, gap : mapping of int to ndarray
        ``Speed<i>`` [m/s] and ``IVS<i>`` [m] (gap between ``i`` and ``i + 1``), by position ``i``.
    """

    name: str
    date: str
    vehicles: tuple[str, ...]
    acc: bool
    setting: str | None
    time: np.ndarray
    speed: Mapping[int, np.ndarray]
    gap: Mapping[int, np.ndarray]

    @property
    def pairs(self) -> list[int]:
        """Leader positions ``i`` whose pair (i, i + 1) has speed and gap columns."""
        return sorted(i for i in self.gap if i in self.speed and i + 1 in self.speed)

    def vehicle(self, position: int) -> str:
        return self.vehicles[position - 1] if 0 < position <= len(self.vehicles) else "unknown"

    def header(self) -> dict[str, Any]:
        return {"date": self.date, "vehicles": list(self.vehicles), "acc": self.acc,
                "setting": self.setting}


def read_recording(path: str | Path, name: str | None = None) -> OpenACCRecording:
    """Read an OpenACC CSV (original layout) or the shipped Parquet of one; see the module doc."""
    path = Path(path)
    name = name or f"{path.parent.name}/{path.stem}"
    if not path.is_file():
        raise TraceSetError(f"{path}: no such OpenACC file")
    if path.suffix.lower() == ".parquet":
        header, table = _read_parquet(path)
    else:
        header, table = _read_csv(path)
    return _recording(path, name, header, table)


def _read_csv(path: Path) -> tuple[dict[str, list[str]], pa.Table]:
    text = path.read_text(encoding="utf-8", errors="replace").splitlines(keepends=True)
    header: dict[str, list[str]] = {}
    for line_no, key in enumerate(META_ROWS, start=1):
        cells = text[line_no - 1].rstrip("\r\n").split(",") if len(text) >= line_no else [""]
        if cells[0] != key:
            raise TraceSetError(f"{path}: line {line_no} should start with '{key}' (OpenACC "
                                f"metadata rows), found {cells[0]!r}")
        header[key] = cells[1:]
    body = "".join(text[len(META_ROWS):]).encode()
    try:
        table = check_table(pacsv.read_csv(io.BytesIO(body), convert_options=pacsv.ConvertOptions(
            null_values=[""], strings_can_be_null=True)), str(path))
    except (pa.ArrowInvalid, UnicodeDecodeError) as exc:
        raise TraceSetError(f"{path}: unreadable CSV body ({str(exc).splitlines()[0]})") from None
    return header, table


def _read_parquet(path: Path) -> tuple[dict[str, list[str]], pa.Table]:
    try:
        table = parquet_table(path)
    except (pa.ArrowException, OSError) as exc:
        raise TraceSetError(f"{path}: unreadable Parquet ({str(exc).splitlines()[0]})") from None
    raw = (table.schema.metadata or {}).get(PARQUET_KEY)
    if raw is None:
        raise TraceSetError(f"{path}: no OpenACC header (schema metadata "
                            f"'{PARQUET_KEY.decode()}')")
    header = json.loads(raw)
    columns = {n: _from_hundredths(table.column(n)) for n in table.column_names}
    return header, pa.table(columns)


def _from_hundredths(column: pa.ChunkedArray) -> pa.Array:
    """Hundredths (int) back to floats; the nearest double of the two-decimal CSV value."""
    values = column.to_numpy(zero_copy_only=False).astype(np.float64)
    return pa.array(values / SCALE, mask=column.is_null().to_numpy(zero_copy_only=False))


def _recording(path: Path, name: str, header: Mapping[str, list[str]], table: pa.Table
               ) -> OpenACCRecording:
    if "Time" not in table.column_names:
        raise TraceSetError(f"{path}: no column 'Time'")
    columns = {n: _float(table, n, path) for n in table.column_names}
    time = columns.pop("Time")
    bad = np.flatnonzero(~np.isfinite(time))
    if bad.size:
        raise TraceSetError(f"{path}: column 'Time', data row {bad[0] + 1}: value is missing")
    steps = np.flatnonzero(np.diff(time) <= 0)
    if steps.size:
        raise TraceSetError(f"{path}: column 'Time' is not strictly increasing at data row "
                            f"{steps[0] + 2}")
    speed, gap = {}, {}
    for column, values in columns.items():
        match = _COLUMN.match(column)
        if match is None:
            raise TraceSetError(f"{path}: unexpected column '{column}' (OpenACC has Time, "
                                "Speed<i>, E<i>, N<i>, IVS<i>)")
        kind, position = match.group(1), int(match.group(2))
        if kind == "Speed":
            speed[position] = values
        elif kind == "IVS":
            gap[position] = values
    acc = _cell(header, "ACC", path)
    if acc not in ("0", "1"):
        raise TraceSetError(f"{path}: metadata row 'ACC' must be 0 or 1, found {acc!r}")
    setting = _cell(header, "Distance_setting", path)
    if setting not in SETTINGS:
        raise TraceSetError(f"{path}: metadata row 'Distance_setting' must be S, L or empty, "
                            f"found {setting!r}")
    return OpenACCRecording(
        name=name,
        date=_date(header.get("Date", []), path),
        vehicles=tuple(v for v in header.get("Vehicle_order", []) if v),
        acc=acc == "1",
        setting=SETTINGS[setting],
        time=time,
        speed=speed,
        gap=gap,
    )


def _date(cells: Sequence[str], path: Path) -> str:
    """``Date,D,M,Y`` → ``YYYY-MM-DD``."""
    try:
        day, month, year = (int(c) for c in cells[:3])
    except ValueError:
        raise TraceSetError(f"{path}: metadata row 'Date' must be D,M,Y, found {cells}") from None
    return f"{year:04d}-{month:02d}-{day:02d}"


def _cell(header: Mapping[str, list[str]], key: str, path: Path) -> str:
    cells = header.get(key)
    if cells is None:
        raise TraceSetError(f"{path}: no metadata row '{key}'")
    return cells[0].strip() if cells else ""


def _float(table: pa.Table, name: str, path: Path) -> np.ndarray:
    column = table.column(name)
    if not (pa.types.is_floating(column.type) or pa.types.is_integer(column.type)
            or pa.types.is_null(column.type)):
        raise TraceSetError(f"{path}: column '{name}' is not numeric (type {column.type})")
    return column.to_numpy(zero_copy_only=False).astype(np.float64)


def to_parquet(csv_path: str | Path, out: str | Path) -> Path:
    """The shipped form of one OpenACC CSV: Time, Speed<i>, IVS<i> as int32 hundredths, zstd.

    Positions (``E<i>``, ``N<i>``) are dropped: the episodes do not use them, and they would
    triple the size. Reading the result with :func:`read_recording` gives the CSV's speeds and gaps
    exactly.
    """
    csv_path, out = Path(csv_path), Path(out)
    if out.resolve() == csv_path.resolve():
        raise TraceSetError(f"{out}: would overwrite the input")
    header, table = _read_csv(csv_path)
    keep = [n for n in table.column_names if n == "Time" or n.startswith(("Speed", "IVS"))]
    columns = {}
    for name in keep:
        values = _float(table, name, csv_path)
        scaled = np.round(values * SCALE)
        finite = np.isfinite(values)
        if not np.array_equal(scaled[finite] / SCALE, values[finite]):
            raise TraceSetError(f"{csv_path}: column '{name}' has more than two decimals")
        columns[name] = pa.array(np.where(finite, scaled, 0).astype(np.int32), mask=~finite)
    meta = json.dumps({k: header[k] for k in META_ROWS}).encode()
    out.parent.mkdir(parents=True, exist_ok=True)
    pq.write_table(pa.table(columns).replace_schema_metadata({PARQUET_KEY: meta}), local(out),
                   compression="zstd", compression_level=19)
    return out


# -- episodes --------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class EpisodeRules:
    """How leader–follower pairs are cut into episodes; applied in this order.

    Parameters
    ----------
    duration : float, default: 10.0
        Episode length [s]; an episode has ``duration / step + 1`` samples and episodes of one pair
        do not share samples.
    step : float, default: 0.1
        Sample period [s]; a time step that differs by more than 1 ms breaks a segment.
    min_leader_speed : float, default: 2.0
        Rule "leader moving": the leader's mean speed over the episode must exceed this [m/s].
    gap_range : (float, float), default: (0.5, 120.0)
        Rule "plausible gap": every gap sample must lie in this closed interval [m].

    Notes
    -----
    Rule "complete": leader speed, follower speed and gap are all present at every sample (a
    segment of complete, regularly spaced rows is cut into as many whole episodes as fit).
    """

    duration: float = 10.0
    step: float = 0.1
    min_leader_speed: float = 2.0
    gap_range: tuple[float, float] = (0.5, 120.0)

    def __post_init__(self) -> None:
        for name in ("duration", "step", "min_leader_speed"):
            check_finite(getattr(self, name), name.replace("_", " "))
        for value in self.gap_range:
            check_finite(value, "gap range")
        if not (self.step > 0 and self.duration >= self.step):
            raise OptionError(f"episode duration ({self.duration} s) and step ({self.step} s) "
                              "must be positive, duration ≥ step")
        lo, hi = self.gap_range
        if not lo < hi:
            raise OptionError(f"gap range must be (low, high) with low < high, "
                              f"got {self.gap_range}")

    @property
    def samples(self) -> int:
        return check_count(int(round(self.duration / self.step)) + 1, "steps",
                           "episode samples (duration / step + 1)", minimum=2)


@dataclass(frozen=True, slots=True)
class CutReport:
    """What the episode rules kept and removed, in episodes (windows of ``rules.samples``).

    ``possible`` is what the recorded pairs' durations would give with no data missing; each
    ``removed_*`` counts the episodes the rule took away after the rules before it.
    """

    files: int
    pairs: int
    possible: int
    removed_incomplete: int
    removed_leader_stopped: int
    removed_gap: int
    kept: int
    by_file: Mapping[str, Mapping[str, int]] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["by_file"] = {k: dict(v) for k, v in self.by_file.items()}
        return out


@dataclass(frozen=True, slots=True)
class _Window:
    recording: OpenACCRecording
    leader: int
    start: int


def acceleration(v: np.ndarray, step: float) -> np.ndarray:
    """Central differences of ``v`` [m/s] at sample period ``step`` [s]; one-sided at the ends."""
    return np.gradient(np.asarray(v, dtype=np.float64), step)


def _segments(ok: np.ndarray, regular: np.ndarray) -> list[tuple[int, int]]:
    """``[lo, hi)`` row ranges where ``ok`` holds and consecutive rows are one step apart."""
    joined = ok[1:] & ok[:-1] & regular
    out, lo = [], None
    for i, good in enumerate(ok):
        if good and lo is None:
            lo = i
        if lo is not None and (i == len(ok) - 1 or not joined[i]):
            if good:
                out.append((lo, i + 1))
            lo = None
    return out


def _windows(rec: OpenACCRecording, rules: EpisodeRules, counts: dict[str, int]) -> list[_Window]:
    n = rules.samples
    regular = np.abs(np.diff(rec.time) - rules.step) <= 1e-3
    lo_gap, hi_gap = rules.gap_range
    kept = []
    for i in rec.pairs:
        vl, vf, g = rec.speed[i], rec.speed[i + 1], rec.gap[i]
        counts["pairs"] += 1
        counts["possible"] += len(rec.time) // n
        ok = np.isfinite(vl) & np.isfinite(vf) & np.isfinite(g)
        complete = [lo + k * n for lo, hi in _segments(ok, regular) for k in range((hi - lo) // n)]
        counts["removed_incomplete"] += len(rec.time) // n - len(complete)
        for start in complete:
            rows = slice(start, start + n)
            if not vl[rows].mean() > rules.min_leader_speed:
                counts["removed_leader_stopped"] += 1
            elif not ((g[rows] >= lo_gap) & (g[rows] <= hi_gap)).all():
                counts["removed_gap"] += 1
            else:
                kept.append(_Window(rec, i, start))
    counts["kept"] += len(kept)
    return kept


def _run(w: _Window, n: int, step: float) -> dict[str, np.ndarray]:
    rows = slice(w.start, w.start + n)
    vl, vf = w.recording.speed[w.leader][rows], w.recording.speed[w.leader + 1][rows]
    return {TIME: w.recording.time[rows], "gap": w.recording.gap[w.leader][rows],
            "dv": vl - vf, "v": vf, "a": acceleration(vf, step), "v_leader": vl}


def _info(w: _Window) -> dict[str, Any]:
    rec = w.recording
    return {"file": rec.name, "leader_position": w.leader, "follower_position": w.leader + 1,
            "leader_vehicle": rec.vehicle(w.leader), "follower_vehicle": rec.vehicle(w.leader + 1),
            "follower": "acc" if rec.acc else "human", "setting": rec.setting, "date": rec.date,
            "t0": float(rec.time[w.start])}


def run_id(w: _Window) -> str:
    """``<folder>.<file>.p<follower position>.t<start time in 0.1 s>``, safe as a file name."""
    return (f"{w.recording.name.replace('/', '.')}.p{w.leader + 1}."
            f"t{int(round(w.recording.time[w.start] * 10)):06d}")


def episodes(recordings: Iterable[OpenACCRecording], rules: EpisodeRules | None = None, *,
             source: str = "openacc") -> TraceSet:
    """Cut leader–follower episodes from ``recordings`` into one TraceSet (see the module doc).

    Returns
    -------
    TraceSet
        Signals :data:`SIGNALS`; ``metadata`` holds ``units``, ``rules``, ``cut`` (a
        :class:`CutReport` as a dict), ``attribution`` and ``run_info`` (per run: file, leader and
        follower position and vehicle, follower "human"/"acc", setting, date, start time ``t0``).

    Raises
    ------
    TraceSetError
        If no episode survives the rules.
    """
    rules = rules or EpisodeRules()
    totals = dict.fromkeys(("pairs", "possible", "removed_incomplete", "removed_leader_stopped",
                            "removed_gap", "kept"), 0)
    windows, by_file, files = [], {}, 0
    for rec in recordings:
        files += 1
        counts = dict.fromkeys(totals, 0)
        windows += _windows(rec, rules, counts)
        by_file[rec.name] = counts
        for key, value in counts.items():
            totals[key] += value
    report = CutReport(files=files, by_file=by_file, **totals)
    if not windows:
        raise TraceSetError(f"{source}: no episode passes the rules ({report.to_dict()})")
    n = rules.samples
    ids = [run_id(w) for w in windows]
    metadata = {"source": "OpenACC (JRC), ZalaZONE test track", "attribution": ATTRIBUTION,
                "units": UNITS, "rules": asdict(rules), "cut": report.to_dict(),
                RUN_INFO: {rid: _info(w) for rid, w in zip(ids, windows, strict=True)}}
    return TraceSet.from_runs([_run(w, n, rules.step) for w in windows], run_ids=ids,
                              metadata=metadata, source=source)


# -- files and folders -----------------------------------------------------------------------------

FOLDERS = ("no_ACC", "short_setting", "long_setting")
HUMAN, ACC = "human", "acc"


def recording_files(root: str | Path) -> list[Path]:
    """OpenACC files under ``root`` (``*.parquet`` if any, else ``*.csv``), in a stable order."""
    root = Path(root)
    if root.is_file():
        return [root]
    if not root.is_dir():
        raise TraceSetError(f"{root}: no such OpenACC file or folder")
    files = sorted(root.rglob("*.parquet")) or sorted(root.rglob("*.csv"))
    if not files:
        raise TraceSetError(f"{root}: no OpenACC files (*.parquet or *.csv)")
    return sorted(files, key=lambda p: _natural(p.relative_to(root).as_posix()))


def _natural(text: str) -> list[object]:
    return [int(part) if part.isdigit() else part for part in re.split(r"(\d+)", text)]


def read_openacc(root: str | Path | None = None, rules: EpisodeRules | None = None, *,
                 follower: str | None = None, files: Sequence[str] | None = None) -> TraceSet:
    """Episodes of the OpenACC files under ``root`` (default: the copy shipped in simcred.data).

    Parameters
    ----------
    root : path, optional
        A folder of OpenACC CSV or Parquet files (searched recursively) or one file.
    rules : EpisodeRules, optional
        Episode rules (default: 10 s, complete, leader mean speed > 2 m/s, gap in [0.5, 120] m).
    follower : {"human", "acc"}, optional
        Keep only recordings whose followers are humans (``ACC,0``) or on ACC (``ACC,1``).
    files : sequence of str, optional
        Keep only these recordings, by ``<folder>/<stem>`` name.

    Examples
    --------
    >>> human = read_openacc(follower="human")
    >>> human.n_runs, human.signals
    (609, ('gap', 'dv', 'v', 'a', 'v_leader'))
    """
    if follower not in (None, HUMAN, ACC):
        raise OptionError(f"follower must be '{HUMAN}' or '{ACC}', got {follower!r}")
    if root is None:
        from simcred.data import path as data_path

        root = data_path("openacc")
    root = Path(root)
    paths = recording_files(root)
    base = root if root.is_dir() else root.parent.parent
    recordings = [read_recording(p, f"{p.relative_to(base).parent.as_posix()}/{p.stem}")
                  for p in paths]
    if files is not None:
        unknown = sorted(set(files) - {r.name for r in recordings})
        if unknown:
            raise OptionError(f"{root}: no OpenACC recording named {unknown[0]!r}")
        recordings = [r for r in recordings if r.name in set(files)]
    if follower is not None:
        recordings = [r for r in recordings if r.acc == (follower == ACC)]
    return episodes(recordings, rules, source=str(root))
