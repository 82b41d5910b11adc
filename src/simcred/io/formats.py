"""One façade over every trace-set format: ``read(path, **options)`` and ``write(traces, path)``.

The format follows from the path (as commonroad-io's ``FileReader`` façade does) unless
``format=`` names it:

============  =========================================  ==========================================
format        path                                       module
============  =========================================  ==========================================
csv-dir       a directory of ``*.csv`` (one run each)    :mod:`simcred.io.csvdir`
parquet       ``.parquet``/``.pq`` with a ``run`` column  :mod:`simcred.io.parquet`
long          ``.csv`` file; ``.parquet`` with column     :mod:`simcred.io.longformat`
              options (``run_column``, ...)
sumo-fcd      ``.xml`` (``.xml.gz``) rooted in            :mod:`simcred.io.sumo_fcd` (read only)
              ``<fcd-export>``
commonroad    ``.xml`` rooted in ``<commonRoad>``         :mod:`simcred.io.commonroad` (read only)
osi           ``.osi`` (length-prefixed), ``.mcap``       :mod:`simcred.io.osi`
levelx        a directory with ``NN_tracks.csv`` (highD,  :mod:`simcred.io.levelx` (read only)
              inD, rounD, exiD, uniD)
mdf           ``.mf4``/``.mdf``; a directory of them      :mod:`simcred.io.mdf` (read only)
ros2          a ROS 2 bag directory (``metadata.yaml``)  :mod:`simcred.io.rosbag` (read only)
              or a directory of bags
============  =========================================  ==========================================

Each format accepts only its own options; any other is a one-line :class:`OptionError`.
"""

from __future__ import annotations

import hashlib
import importlib
from collections.abc import Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from simcred._json import dumps, envelope, fields_dict, file_digest
from simcred.errors import OptionError, TraceSetError
from simcred.io._paths import check_regular
from simcred.io._xml import xml_root
from simcred.io.levelx import is_levelx
from simcred.io.mdf import SUFFIXES as MDF_SUFFIXES
from simcred.io.mdf import files_in as mdf_files
from simcred.io.rosbag import is_bag, is_ros2_mcap
from simcred.outputs import output_path
from simcred.traces import TraceSet

LONG_READ = ("run_column", "time_column", "object_column", "signals", "objects_as", "missing",
             "object_prefix", "time_scale")
LONG_WRITE = ("run_column", "time_column", "object_column")
OBJECT_OPTIONS = ("objects_as", "missing", "object_prefix")


@dataclass(frozen=True, slots=True)
class Format:
    """A trace-set format: the module implementing it and the options it takes."""

    name: str
    module: str
    description: str
    read_options: tuple[str, ...] = ()
    write_options: tuple[str, ...] | None = None  # None: cannot be written

    @property
    def writable(self) -> bool:
        return self.write_options is not None

    def implementation(self):
        return importlib.import_module(f"simcred.io.{self.module}")


FORMATS: dict[str, Format] = {f.name: f for f in (
    Format("csv-dir", "csvdir", "a directory of CSV files, one run each", (), ()),
    Format("parquet", "parquet", "one Parquet file with columns run, t and the signals", (), ()),
    Format("long", "longformat", "one long-format CSV or Parquet file (run/time/object columns)",
           LONG_READ, LONG_WRITE),
    Format("sumo-fcd", "sumo_fcd", "SUMO floating car data XML (<fcd-export>)", OBJECT_OPTIONS),
    Format("commonroad", "commonroad", "CommonRoad XML scenario", ("layout", "missing")),
    Format("osi", "osi", "ASAM OSI GroundTruth trace (.osi length-prefixed, .mcap)",
           ("objects_as", "missing"), ("host",)),
    Format("levelx", "levelx", "highD/inD/rounD/exiD/uniD folder (NN_tracks.csv, "
           "NN_tracksMeta.csv, NN_recordingMeta.csv)", ("recordings", "direction", "runs")),
    Format("mdf", "mdf", "ASAM MDF4 measurement file (.mf4, .mdf) or a directory of them",
           ("channels", "resample", "run_channel")),
    Format("ros2", "rosbag", "ROS 2 bag directory (.db3 or .mcap storage) or a directory of bags",
           ("topics", "fields", "runs")),
)}
PARQUET_SUFFIXES = (".parquet", ".pq")
OSI_SUFFIXES = (".osi", ".mcap")
XML_ROOTS = {"fcd-export": "sumo-fcd", "commonRoad": "commonroad"}


def _named(format: str) -> Format:
    try:
        return FORMATS[format]
    except KeyError:
        from simcred.io.sources import DATASETS  # sources reads through this module

        hint = (f"; {format!r} is a data set, read into its own type by "
                f"simcred.io.read_source(path, {format!r})" if format in DATASETS else "")
        raise OptionError(f"unknown format {format!r} (formats: {', '.join(FORMATS)}){hint}"
                          ) from None


def _suffix(path: Path) -> str:
    suffixes = [s.lower() for s in path.suffixes]
    if suffixes[-1:] == [".gz"] and len(suffixes) >= 2:
        return suffixes[-2] + ".gz"
    return path.suffix.lower()


def detect(path: str | Path, *, for_writing: bool = False,
           options: Mapping[str, Any] | None = None) -> Format:
    """The format a path has (reading) or asks for (writing), from its suffix or XML root."""
    path, options = Path(path), dict(options or {})
    suffix = _suffix(path)
    long_options = any(k in (LONG_WRITE if for_writing else LONG_READ) for k in options)
    if not for_writing:
        if path.is_dir():
            return _directory_format(path)
        if not path.exists():
            raise TraceSetError(f"{path}: no such file or directory")
        if suffix in (".xml", ".xml.gz"):
            root = xml_root(path)
            if root not in XML_ROOTS:
                raise TraceSetError(f"{path}: XML root <{root}> is neither SUMO FCD "
                                    "(<fcd-export>) nor CommonRoad (<commonRoad>)")
            return FORMATS[XML_ROOTS[root]]
    elif suffix in (".xml", ".xml.gz"):
        raise OptionError(f"{path}: SUMO FCD and CommonRoad XML can be read but not written "
                          "(writable: a directory, .csv, .parquet, .pq, .osi, .mcap)")
    if suffix == ".csv":
        return FORMATS["long"]
    if suffix in PARQUET_SUFFIXES:
        return FORMATS["long" if long_options else "parquet"]
    if suffix == ".mcap" and not for_writing and is_ros2_mcap(path):
        raise TraceSetError(f"{path}: the storage file of a ROS 2 bag; read the bag's directory "
                            f"(metadata.yaml beside this file: {path.parent}; `ros2 bag reindex` "
                            "writes a missing one)")
    if suffix in OSI_SUFFIXES:
        return FORMATS["osi"]
    if suffix in MDF_SUFFIXES and not for_writing:
        return FORMATS["mdf"]
    if for_writing:  # any other name is a directory of CSV files (names may contain dots)
        return FORMATS["csv-dir"]
    kinds = "a directory, .csv, .parquet, .pq, .osi, .mcap, .xml, .mf4, .mdf"
    raise TraceSetError(f"{path}: not a trace set in a known format (suffix {suffix or 'none'!r}; "
                        f"expected {kinds}, or name it with format=/--format)")


def _directory_format(path: Path) -> Format:
    """A directory's format: a levelX recording folder, a ROS 2 bag (or a folder of bags), a
    folder of MDF files (and no CSV files), else a CSV directory."""
    if is_levelx(path):
        return FORMATS["levelx"]
    if is_bag(path):
        return FORMATS["ros2"]
    if mdf_files(path) and not any(p.suffix.lower() == ".csv" for p in path.iterdir()):
        return FORMATS["mdf"]
    return FORMATS["csv-dir"]


def _check_options(fmt: Format, options: Mapping[str, Any], allowed: tuple[str, ...]) -> None:
    for name in options:
        if name not in allowed:
            takes = ", ".join(allowed) or "none"
            raise OptionError(f"format '{fmt.name}' has no option '{name}' (options: {takes})")


def read(path: str | Path, *, format: str | None = None, **options: Any) -> TraceSet:
    """Read a trace set in any supported format; ``options`` are the format's own. Data sets
    (A9, measurement, OpenACC) are read into their own types by :func:`simcred.io.read_source`.

    >>> import tempfile, pathlib
    >>> d = pathlib.Path(tempfile.mkdtemp())
    >>> _ = (d / "log.csv").write_text("trip,time,id,x\\na,0,7,1.5\\na,1,7,2.5\\n")
    >>> ts = read(d / "log.csv", run_column="trip", time_column="time", object_column="id")
    >>> ts.run_ids, ts.signals, ts.column("obj7.x").tolist()
    (('a',), ('obj7.x',), [1.5, 2.5])
    """
    path = Path(path)
    check_regular(path)
    fmt = _named(format) if format else detect(path, options=options)
    if format and not path.exists():
        raise TraceSetError(f"{path}: no such file or directory")
    _check_options(fmt, options, fmt.read_options)
    return fmt.implementation().read(path, **options)


def grouped_parquet(path: str | Path) -> Any:
    """The :class:`~simcred.io.parquet.GroupedRuns` of the file :func:`read` would read from
    ``path`` row group by row group (a Parquet file whose rows are grouped by run), or None:
    any other format or file, or anything wrong with it (:func:`read` then says what)."""
    path = Path(path)
    try:
        check_regular(path)
        if detect(path) is not FORMATS["parquet"]:
            return None
    except (TraceSetError, OptionError, OSError, ValueError):
        return None
    from simcred.io.parquet import GroupedRuns

    return GroupedRuns.open(path)


def write(traces: TraceSet, path: str | Path, *, format: str | None = None,
          **options: Any) -> Path:
    """Write ``traces`` in the format named or implied by ``path``; returns the path written."""
    path = Path(path)
    fmt = _named(format) if format else detect(path, for_writing=True, options=options)
    if not fmt.writable:
        writable = ", ".join(f.name for f in FORMATS.values() if f.writable)
        raise OptionError(f"format '{fmt.name}' can be read but not written (writable: "
                          f"{writable})")
    _check_options(fmt, options, fmt.write_options)
    return fmt.implementation().write(traces, path, **options)


# -- conversion ------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Conversion:
    """What :func:`convert` did: formats, options, sizes and the input's content hash."""

    source: str
    source_format: str
    source_sha256: str
    target: str
    target_format: str
    read_options: dict[str, Any]
    write_options: dict[str, Any]
    runs: int
    rows: int
    signals: tuple[str, ...]

    def to_dict(self) -> dict[str, Any]:
        return envelope("conversion", fields_dict(self))

    def to_json(self) -> str:
        return dumps(self.to_dict())


def content_sha256(path: Path) -> str:
    """SHA-256 of a file (:func:`~simcred._json.file_digest`), or of a directory's files
    (relative names and bytes, sorted)."""
    if not path.is_dir():
        return file_digest(path)
    h = hashlib.sha256()
    for file in sorted(p for p in path.rglob("*") if p.is_file()):
        h.update(str(file.relative_to(path)).encode() + b"\0")
        h.update(file.read_bytes())
    return "sha256:" + h.hexdigest()


def convert(source: str | Path, target: str | Path, *, source_format: str | None = None,
            target_format: str | None = None, overwrite: bool = False,
            **options: Any) -> Conversion:
    """Read ``source`` in any format and write it to ``target`` in any writable format.

    ``options`` go to the reader when its format takes them; the others go to the writer when
    its format takes them (column names of a long-format output), and so do the reader's when
    ``target_format`` is named (long CSV -> long Parquet with the same columns); an option
    neither side takes is an error. The
    output never replaces the input, and replaces an existing one only with ``overwrite=True``;
    it is written atomically (:func:`simcred.outputs.output_path`), so it exists complete or not
    at all.
    The written trace set's metadata records where it came from (path, format, hash, options).
    """
    source, target = Path(source), Path(target)
    fmt_in = _named(source_format) if source_format else detect(source, options=options)
    if source_format and not source.exists():
        raise TraceSetError(f"{source}: no such file or directory")
    read_options = {k: v for k, v in options.items() if k in fmt_in.read_options}
    rest = {k: v for k, v in options.items() if k not in read_options}
    fmt_out = (_named(target_format) if target_format
               else detect(target, for_writing=True, options=rest))
    # an option the reader takes goes to the writer, too, only when the output format is named
    pool = options if target_format else rest
    write_options = {k: v for k, v in pool.items() if k in (fmt_out.write_options or ())}
    unused = sorted(set(options) - set(read_options) - set(write_options))
    if unused:
        raise OptionError(f"option '{unused[0]}' applies neither to the input format "
                          f"'{fmt_in.name}' nor to the output format '{fmt_out.name}'")
    kind = "directory" if fmt_out.name == "csv-dir" else "file"
    with output_path(target, [source], kind=kind, overwrite=overwrite) as partial:
        traces = read(source, format=fmt_in.name, **read_options)
        digest = content_sha256(source)
        provenance = {"path": str(source), "format": fmt_in.name, "sha256": digest,
                      "options": read_options}
        traces = replace(traces, metadata={**traces.metadata, "converted_from": provenance})
        write(traces, partial, format=fmt_out.name, **write_options)
    return Conversion(str(source), fmt_in.name, digest, str(target), fmt_out.name, read_options,
                      write_options, traces.n_runs, traces.n_rows, traces.signals)
