"""Figures of the car-following study: the verdict matrix, a headway panel and state maps."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import ListedColormap  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

from simcred.io.openacc import UNITS  # noqa: E402
from simcred.regions import CellStatus  # noqa: E402
from simcred.report.figures import save_figure, state_map  # noqa: E402
from simcred.study.car_following import StudyResult, band_label  # noqa: E402
from simcred.study.files import cell_slug  # noqa: E402

STATUS_COLORS = {CellStatus.UNKNOWN: "#d9d9d9", CellStatus.COMPARED: "#c6dbef",
                 CellStatus.VALID: "#b7dfb0", CellStatus.INCONCLUSIVE: "#f2d27a",
                 CellStatus.NOT_VALID: "#d7301f"}
LABELS = {name: f"{name} [{unit}]" for name, unit in UNITS.items()}


def verdict_matrix(result: StudyResult, path: str | Path) -> Path:
    """Rows × speed bands, coloured by status, annotated with each response deviation and its
    95 % interval, the difference p-value and the units per side."""
    rows, bands = result.rows, result.options.bands
    shown = [s for s in STATUS_COLORS if any(c.status is s for c in result.cells)]
    code = np.zeros((len(rows), len(bands)), dtype=int)
    fig, ax = plt.subplots(figsize=(3.0 * len(bands) + 3.2, 0.8 * len(rows) + 1.8))
    for i, row in enumerate(rows):
        for j, band in enumerate(bands):
            c = result.cell(row, band)
            r = c.result
            code[i, j] = shown.index(c.status)
            if r.comparison is None:
                text = f"unknown\n{r.reference_units} vs {r.candidate_units} units"
            else:
                text = "\n".join([*(f"{b.feature}: {b.estimate:.2g} [{b.low:.2g}, {b.high:.2g}]"
                                     f" {b.unit}" for b in r.bounds),
                                  f"p = {r.pvalue:.2g}, {r.reference_units} vs "
                                  f"{r.candidate_units} units"])
            ax.text(j, i, text, ha="center", va="center", fontsize=7)
    ax.imshow(code, cmap=ListedColormap([STATUS_COLORS[s] for s in shown]), vmin=-0.5,
              vmax=len(shown) - 0.5, aspect="auto")
    ax.set_xticks(range(len(bands)), [f"leader {band_label(b)}" for b in bands])
    ax.set_yticks(range(len(rows)), rows)
    ax.set_xticks(np.arange(len(bands) + 1) - 0.5, minor=True)
    ax.set_yticks(np.arange(len(rows) + 1) - 0.5, minor=True)
    ax.grid(which="minor", color="white", linewidth=2)
    ax.tick_params(which="minor", length=0)
    ax.legend(handles=[Patch(facecolor=STATUS_COLORS[s], label=s.value) for s in shown],
              loc="upper center", bbox_to_anchor=(0.5, -0.08), ncol=len(shown), fontsize=8)
    o = result.options
    judged = ", ".join(f"{k} ≤ {v:g}" for k, v in o.tolerance.items()) or "none (not judged)"
    ax.set_title(f"vs real human following (OpenACC): response deviation [95 % interval], "
                 f"difference p\nresponse comparison per band, α = {o.alpha}; tolerance: "
                 f"{judged}", fontsize=8, wrap=True)
    return save_figure(fig, Path(path))


def headway_panel(result: StudyResult, path: str | Path) -> Path:
    """Median time headway [s] and std of acceleration [m/s²] per row and band (descriptive)."""
    rows, bands = result.rows, result.options.bands
    fig, axes = plt.subplots(1, 2, figsize=(12, 0.45 * len(rows) + 2), sharey=True,
                             constrained_layout=True)
    height = 0.8 / len(bands)
    for j, band in enumerate(bands):
        heads, accs = [], []
        for row in rows:
            c = result.cell(row, band)
            s = c.b if c.b is not None else None
            heads.append(np.nan if s is None else s.headway_median)
            accs.append(np.nan if s is None else s.a_std)
        y = np.arange(len(rows)) + (j - (len(bands) - 1) / 2) * height
        for ax, values in ((axes[0], heads), (axes[1], accs)):
            ax.barh(y, values, height=height, label=f"leader {band_label(band)}")
    reference_row = next(r for r in rows if not r.startswith("human vs human"))
    human = [result.cell(reference_row, b).a for b in bands]  # all human episodes of the band
    for j, s in enumerate(human):
        if s is not None:
            axes[0].axvline(s.headway_median, color=f"C{j}", linestyle="--", linewidth=1)
            axes[1].axvline(s.a_std, color=f"C{j}", linestyle="--", linewidth=1)
    axes[0].set_yticks(range(len(rows)), [r.replace("human vs human", "human half")
                                          for r in rows])
    axes[0].invert_yaxis()
    axes[0].set_xlabel("median time headway gap / v [s] (v > 1 m/s)")
    axes[1].set_xlabel("std of follower acceleration a [m/s²]")
    axes[0].legend(fontsize=8, title="bars: candidate; dashed: all human", title_fontsize=8)
    fig.suptitle("candidate sets per speed band (descriptive; second half / cars of the "
                 "baselines)", fontsize=10)
    return save_figure(fig, Path(path))


def study_figures(result: StudyResult, out: str | Path,
                  map_features: tuple[str, str] = ("gap", "v")) -> list[Path]:
    """``matrix.png``, ``headway.png`` and ``maps/<row>__<band>.png`` for every compared cell."""
    out = Path(out)
    paths = [verdict_matrix(result, out / "matrix.png"), headway_panel(result, out / "headway.png")]
    for c in result.cells:
        comparison = c.result.comparison
        if comparison is not None and all(len(e) > 0 for e in comparison.space.edges[:2]):
            drawn = map_features if set(map_features) <= set(comparison.space.features) \
                else None
            paths.append(state_map(comparison, out / "maps" / f"{cell_slug(c)}.png",
                                   drawn, labels=LABELS,
                                   title=f"human vs {c.row}, leader {band_label(c.band)}"
                                   if not c.row.startswith("human vs") else
                                   f"{c.row}, leader {band_label(c.band)}"))
    return paths
