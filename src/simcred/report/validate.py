"""The report of one validation (``simcred validate``): one self-contained HTML page.

Verdict first, in words; then what it rules out (tolerance, confidence, the error rates over the
test case), the ranking of the candidates with intervals (a figure and a table), per candidate
the validity-domain map (the operating space coloured valid / not valid / inconclusive /
unknown, with the data counts and deviations per cell), the per-cell deviations and bounds,
per-cell state maps, the configuration and the monitors' findings, and the provenance. Figures
are PNGs embedded as data URIs (no timestamp in their metadata) and the CSS is inline, so the
same validation gives the same bytes.
"""

from __future__ import annotations

import base64
import json
from pathlib import Path
from typing import Any

import jinja2
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

from simcred.report.figures import METADATA, state_map  # noqa: E402
from simcred.validate.domain import CellStatus, Domain  # noqa: E402
from simcred.validate.loop import Validation  # noqa: E402

COLORS = {CellStatus.VALID: "#8fd18a", CellStatus.NOT_VALID: "#e3634f",
          CellStatus.INCONCLUSIVE: "#f2d27a", CellStatus.UNKNOWN: "#d6d6d6"}
TEST_CASE_EDGE = "#1f4e9c"
MAX_STATE_MAPS = 8  # per candidate: not-valid cells first, then valid ones, in cell order


def write_validation_report(result: Validation, document: dict[str, Any], out: Path) -> Path:
    """Write ``out/report.html`` (figures under ``out/figures/``) and return its path."""
    figures = out / "figures"
    context = {
        "title": f"simcred validate: {result.spec.name}",
        "verdict": result.verdict,
        "summary": result.summary,
        "document": document,
        "candidates": [_candidate(result, name, domain, figures)
                       for name, domain in result.domains.items()],
        "ranking_figure": _uri(ranking_figure(result, figures / "ranking.png")),
        "provenance": json.dumps(document["provenance"], indent=1, ensure_ascii=False),
        "library": result.library_yaml(),
    }
    html = _environment().get_template("validate.html.j2").render(context)
    path = out / "report.html"
    path.write_bytes(html.encode("utf-8"))
    return path


def _candidate(result: Validation, name: str, domain: Domain, figures: Path) -> dict[str, Any]:
    verdict = result.candidates[name]
    compared = [c for c in domain.cells if c.comparison is not None]
    maps = sorted((c for c in compared if _drawable(c.comparison)),
                  key=lambda c: (c.status is not CellStatus.NOT_VALID, c.cell))
    flat = [c.label for c in compared if not _drawable(c.comparison)]
    return {
        "name": name,
        "verdict": verdict.verdict,
        "reasons": list(verdict.reasons),
        "domain_map": _uri(domain_map(domain, figures / f"{name}_domain.png",
                                      result.spec.test_case.conditions,
                                      verdict.relevant_cells)),
        "cells": [c.to_dict() for c in domain.cells],
        "design": domain.cells[0].design if domain.cells else "",
        "state_maps": [{"label": c.label, "status": c.status.value,
                        "uri": _uri(state_map(c.comparison,
                                              figures / f"{name}_cell{c.cell}_states.png"))}
                       for c in maps[:MAX_STATE_MAPS]],
        "more_maps": max(0, len(maps) - MAX_STATE_MAPS),
        "flat_cells": flat,
        "monitors": {k: v for k, v in result.monitors.items() if k.startswith(f"{name} on ")},
    }


def _drawable(comparison) -> bool:
    """A state map needs bin edges on the features it draws (the first two): a feature that is
    constant within a cell has none (report.figures.state_map cannot draw it)."""
    return all(len(e) > 0 for e in comparison.space.edges[:2])


def domain_map(domain: Domain, path: Path, conditions: str,
               test_case_cells: tuple[int, ...] = ()) -> Path:
    """The grid over the first one or two condition variables, cells coloured by status and
    annotated with segments (reference / candidate); the cells that meet the test case's
    conditions are outlined."""
    grid = domain.grid
    x_edges = np.asarray(grid.edges[0])
    two = len(grid.variables) > 1
    y_edges = np.asarray(grid.edges[1]) if two else np.array([0.0, 1.0])
    fig, ax = plt.subplots(figsize=(8.5, 3.8 if two else 2.4), constrained_layout=True)
    for cell in domain.cells:
        i = cell.index
        if len(i) > 2 and any(k != 0 for k in i[2:]):
            continue
        x0, x1 = x_edges[i[0]], x_edges[i[0] + 1]
        y0, y1 = (y_edges[i[1]], y_edges[i[1] + 1]) if two else (0.0, 1.0)
        ax.add_patch(plt.Rectangle((x0, y0), x1 - x0, y1 - y0, facecolor=COLORS[cell.status],
                                   edgecolor="#555555", linewidth=0.8))
        if cell.cell in test_case_cells:
            ax.add_patch(plt.Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False,
                                       edgecolor=TEST_CASE_EDGE, linewidth=2.5, linestyle="--"))
        text = f"{cell.status.value}\n{cell.reference_units} / {cell.candidate_units}"
        if cell.bounds:
            text += f"\nE/δ = {cell.worst():.2f}"
        ax.text((x0 + x1) / 2, (y0 + y1) / 2, text, ha="center", va="center", fontsize=7)
    ax.set_xlim(x_edges[0], x_edges[-1])
    ax.set_ylim(y_edges[0], y_edges[-1])
    ax.set_xlabel(f"{grid.variables[0]} [{grid.units[0]}]")
    if two:
        ax.set_ylabel(f"{grid.variables[1]} [{grid.units[1]}]")
    else:
        ax.set_yticks([])
    handles = [Patch(facecolor=c, edgecolor="#555555", label=s.value) for s, c in COLORS.items()]
    handles.append(Patch(fill=False, edgecolor=TEST_CASE_EDGE, linewidth=2, linestyle="--",
                         label="meets the test case"))
    ax.legend(handles=handles, loc="upper center",
              bbox_to_anchor=(0.5, -0.25 if not two else -0.14), ncol=4, fontsize=8)
    ax.set_title(f"{domain.candidate}: validity domain (units reference / candidate per cell, "
                 f"deviation / tolerance); test case: {conditions}", fontsize=9)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, metadata=METADATA)
    plt.close(fig)
    return path


def ranking_figure(result: Validation, path: Path) -> Path:
    """Each candidate's score (largest deviation / tolerance over the test case) with its
    simultaneous interval, best first, against the tolerance (1)."""
    ranked = [r for r in result.ranking if r.score is not None]
    fig, ax = plt.subplots(figsize=(7.5, 0.9 + 0.45 * max(len(ranked), 1)),
                           constrained_layout=True)
    for y, r in enumerate(ranked):
        ax.plot([r.low, r.high], [y, y], color="#1f4e9c", linewidth=2.5)
        ax.plot([r.score], [y], "o", color="#1f4e9c")
    ax.axvline(1.0, color="#a8200d", linestyle="--", linewidth=1.2, label="tolerance")
    ax.set_yticks(range(len(ranked)), [r.candidate for r in ranked])
    ax.invert_yaxis()
    ax.set_xlim(left=0)
    ax.set_xlabel("largest response deviation / tolerance over the test case's cells")
    ax.legend(loc="upper right", fontsize=8)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, metadata=METADATA)
    plt.close(fig)
    return path


def _uri(path: Path) -> str:
    return "data:image/png;base64," + base64.b64encode(path.read_bytes()).decode("ascii")


def _environment() -> jinja2.Environment:
    return jinja2.Environment(loader=jinja2.PackageLoader("simcred.report", "templates"),
                              autoescape=True, undefined=jinja2.StrictUndefined,
                              trim_blocks=True, lstrip_blocks=True, keep_trailing_newline=True)
