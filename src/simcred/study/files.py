"""The car-following study's files: ``study.json``, ``matrix.csv``, ``bands/<band>.csv`` and
``comparisons/<row>__<band>.json`` (the response comparison of every compared cell)."""

from __future__ import annotations

import csv
import io
from pathlib import Path
from typing import Any

import numpy as np

from simcred.compare.effect import rate_unit
from simcred.io.openacc import UNITS
from simcred.study.car_following import Cell, StudyResult, band_label, fmt


def write_study(result: StudyResult, out: str | Path) -> list[Path]:
    """``study.json`` (findings + provenance), ``matrix.csv``, ``bands/<band>.csv`` and
    ``comparisons/<row>__<band>.json`` under ``out``."""
    out = Path(out)
    (out / "bands").mkdir(parents=True, exist_ok=True)
    (out / "comparisons").mkdir(parents=True, exist_ok=True)
    written = [out / "study.json", out / "matrix.csv"]
    written[0].write_text(result.to_json())
    written[1].write_text(matrix_csv(result))
    for band in result.options.bands:
        path = out / "bands" / f"{slug(band_label(band))}.csv"
        path.write_text(band_csv(result, band))
        written.append(path)
    for c in result.cells:
        if c.result.comparison is not None:
            path = out / "comparisons" / f"{cell_slug(c)}.json"
            path.write_text(c.result.comparison.to_json())
            written.append(path)
    return written


def slug(text: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in text).strip("_")


def cell_slug(c: Cell) -> str:
    return f"{slug(c.row)}__{slug(band_label(c.band))}"


def matrix_csv(result: StudyResult) -> str:
    """Rows × bands; a cell is ``<feature>=<deviation> [<95 % low>,<high>];...;p=<difference
    p>;<status>`` or ``unknown``."""
    lines = [",".join(["row", *(band_label(b) for b in result.options.bands)])]
    for row in result.rows:
        cells = []
        for band in result.options.bands:
            r = result.cell(row, band).result
            if r.comparison is None:
                cells.append(r.status.value)
                continue
            parts = [f"{b.feature}={fmt(b.estimate)} [{fmt(b.low)} {fmt(b.high)}]"
                     for b in r.bounds]
            cells.append(";".join([*parts, f"p={fmt(r.pvalue)}", r.status.value]))
        lines.append(",".join([_csv(row), *(_csv(c) for c in cells)]))
    return "\n".join(lines) + "\n"


def band_csv(result: StudyResult, band: tuple[float, float]) -> str:
    """One band: per row the status, the difference p-value, per reported feature the deviation
    with its 95 % interval and decision bounds, the units and samples, and descriptive statistics
    (units in the header)."""
    features = result.options.response
    unit = {f: rate_unit(UNITS[f]) for f in features}
    header = ["row", "status", "design", "difference_pvalue"]
    for f in features:
        u = _unit_slug(unit[f])
        header += [f"{f}_deviation_{u}", f"{f}_low_{u}", f"{f}_high_{u}", f"{f}_lower_{u}",
                   f"{f}_upper_{u}", f"{f}_tolerance_{u}", f"{f}_detectable_shift_{u}"]
    header += ["units_reference", "units_candidate", "samples_reference", "samples_candidate",
               "gap_median_m", "gap_median_reference_m", "headway_median_s",
               "headway_median_reference_s", "a_std_mps2", "a_std_reference_mps2"]
    lines = [",".join(header)]
    for row in result.rows:
        c = result.cell(row, band)
        r, a, b = c.result, c.a, c.b
        bounds = {x.feature: x for x in r.bounds}
        values: list[Any] = [row, r.status.value, r.design, r.pvalue]
        for f in features:
            x = bounds.get(f)
            values += [None] * 7 if x is None else [x.estimate, x.low, x.high, x.lower, x.upper,
                                                    x.tolerance, x.detectable]
        values += [r.reference_units, r.candidate_units, r.reference_samples,
                   r.candidate_samples, _get(b, "gap_median"), _get(a, "gap_median"),
                   _get(b, "headway_median"), _get(a, "headway_median"), _get(b, "a_std"),
                   _get(a, "a_std")]
        lines.append(",".join(_value(x) for x in values))
    return "\n".join(lines) + "\n"


def _unit_slug(unit: str) -> str:
    return unit.replace("²", "2").replace("³", "3").replace("m/s", "mps").replace("/", "p")


def _get(summary: Any, name: str) -> float | None:
    return None if summary is None else getattr(summary, name)


def _value(x: Any) -> str:
    if x is None:
        return ""
    if isinstance(x, str):
        return _csv(x)
    if isinstance(x, bool | np.bool_):
        return str(bool(x))
    return repr(float(x)) if isinstance(x, float | np.floating) else str(int(x))


def _csv(text: str) -> str:
    """One CSV field, quoted (inner quotes doubled) only where needed."""
    buffer = io.StringIO()
    csv.writer(buffer, lineterminator="").writerow([text])
    return buffer.getvalue()


__all__ = ["write_study", "matrix_csv", "band_csv", "cell_slug", "slug"]
