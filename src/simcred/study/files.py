"""The car-following study's files: ``study.json``, ``matrix.csv``, ``bands/<band>.csv`` and
``comparisons/<row>__<band>.json``."""

from __future__ import annotations

import csv
import io
from pathlib import Path
from typing import Any

import numpy as np

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
        if c.comparison is not None:
            path = out / "comparisons" / f"{cell_slug(c)}.json"
            path.write_text(c.comparison.to_json())
            written.append(path)
    return written


def slug(text: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "-_." else "_" for ch in text).strip("_")


def cell_slug(c: Cell) -> str:
    return f"{slug(c.row)}__{slug(band_label(c.band))}"


def matrix_csv(result: StudyResult) -> str:
    """Rows × bands; a cell is ``p=<chain p>;d=<distance>;<verdict>`` or ``insufficient data``."""
    lines = [",".join(["row", *(band_label(b) for b in result.options.bands)])]
    for row in result.rows:
        cells = []
        for band in result.options.bands:
            c = result.cell(row, band)
            if c.verdict is None:
                cells.append("insufficient data")
            else:
                word = "differs" if c.verdict.rejected else "not distinguishable"
                cells.append(f"p={fmt(c.verdict.pvalue)};d={fmt(c.distance)};{word}")
        lines.append(",".join([_csv(row), *cells]))
    return "\n".join(lines) + "\n"


def band_csv(result: StudyResult, band: tuple[float, float]) -> str:
    """One band: per row the verdict, distance, start test and descriptive statistics (units in
    the header)."""
    header = ["row", "status", "chain_pvalue", "rejected", "distance", "start_pvalue",
              "n_states", "n_tested", "n_rejected_states", "baseline_distance_low",
              "baseline_distance_high", "runs_reference", "runs_candidate",
              "gap_median_m", "gap_median_reference_m", "headway_median_s",
              "headway_median_reference_s", "a_std_mps2", "a_std_reference_mps2"]
    lines = [",".join(header)]
    for row in result.rows:
        d = result.cell(row, band).to_dict()
        v, a, b = d["verdict"] or {}, d["reference"] or {}, d["candidate"] or {}
        base = d["baseline"] or {}
        values = [_csv(row), d["status"], v.get("pvalue"), v.get("rejected"), d["distance"],
                  d["start_pvalue"], d["n_states"], d["n_tested"], d["n_rejected_states"],
                  base.get("low"), base.get("high"), a.get("runs"), b.get("runs"),
                  b.get("gap_median"), a.get("gap_median"),
                  b.get("headway_median"), a.get("headway_median"), b.get("a_std"),
                  a.get("a_std")]
        lines.append(",".join(_value(x) for x in values))
    return "\n".join(lines) + "\n"


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
