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
from simcred.report.figures import save_figure, state_map  # noqa: E402
from simcred.study.car_following import StudyResult, band_label, episode_counts  # noqa: E402
from simcred.study.files import cell_slug  # noqa: E402

# insufficient data, not distinguishable, differs
VERDICT_COLORS = ["#d9d9d9", "#b7dfb0", "#d7301f"]
VERDICT_LABELS = ["insufficient data", "not distinguishable at α", "differs (H0 rejected)"]
LABELS = {name: f"{name} [{unit}]" for name, unit in UNITS.items()}


def verdict_matrix(result: StudyResult, path: str | Path) -> Path:
    """Rows × speed bands, coloured by verdict, annotated with chain p-value and distance."""
    rows, bands = result.rows, result.options.bands
    code = np.zeros((len(rows), len(bands)), dtype=int)
    fig, ax = plt.subplots(figsize=(2.8 * len(bands) + 3.2, 0.75 * len(rows) + 1.8))
    for i, row in enumerate(rows):
        for j, band in enumerate(bands):
            c = result.cell(row, band)
            if c.verdict is None:
                text = f"insufficient data\n{episode_counts(c)}"
            else:
                code[i, j] = 2 if c.verdict.rejected else 1
                text = (f"p = {c.verdict.pvalue:.2g}, d = {100 * c.distance:.1f} %\n"
                        f"{episode_counts(c)}")
                base = c.comparison.baseline
                if base is not None:
                    text += f"\nref. halves: d = {100 * base.low:.1f}–{100 * base.high:.1f} %"
            ax.text(j, i, text, ha="center", va="center", fontsize=7.5)
    ax.imshow(code, cmap=ListedColormap(VERDICT_COLORS), vmin=-0.5, vmax=2.5, aspect="auto")
    ax.set_xticks(range(len(bands)), [f"leader {band_label(b)}" for b in bands])
    ax.set_yticks(range(len(rows)), rows)
    ax.set_xticks(np.arange(len(bands) + 1) - 0.5, minor=True)
    ax.set_yticks(np.arange(len(rows) + 1) - 0.5, minor=True)
    ax.grid(which="minor", color="white", linewidth=2)
    ax.tick_params(which="minor", length=0)
    ax.legend(handles=[Patch(facecolor=c, label=lab) for c, lab in
                       zip(VERDICT_COLORS, VERDICT_LABELS, strict=True)],
              loc="upper center", bbox_to_anchor=(0.5, -0.08), ncol=3, fontsize=8)
    o = result.options
    ax.set_title(f"vs real human following (OpenACC): chain p-value, distance d = rejected "
                 f"states / |S|\n{result.to_dict()['method']}; α = {o.alpha}", fontsize=8,
                 wrap=True)
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
                  map_features: tuple[str, str] = ("gap", "dv")) -> list[Path]:
    """``matrix.png``, ``headway.png`` and ``maps/<row>__<band>.png`` for every tested cell."""
    out = Path(out)
    paths = [verdict_matrix(result, out / "matrix.png"), headway_panel(result, out / "headway.png")]
    for c in result.cells:
        if c.comparison is not None:
            paths.append(state_map(c.comparison, out / "maps" / f"{cell_slug(c)}.png",
                                   map_features, labels=LABELS,
                                   title=f"human vs {c.row}, leader {band_label(c.band)}"
                                   if not c.row.startswith("human vs") else
                                   f"{c.row}, leader {band_label(c.band)}"))
    return paths
