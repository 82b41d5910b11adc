"""Figures of comparison results: the distance-matrix heatmap and the per-state map."""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.colors import ListedColormap  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402

from simcred.compare.pairwise import DistanceMatrix  # noqa: E402
from simcred.compare.result import Comparison  # noqa: E402

# status codes of Comparison.state_grid(): not a start state, accepted, rejected, untestable
STATUS_COLORS = ["#ffffff", "#b7dfb0", "#d7301f", "#bdbdbd"]
STATUS_LABELS = ["no transitions", "H0 kept", "H0 rejected (differs)", "untestable (one-sided)"]
METADATA = {"Software": "simcred", "Creation Time": None}  # no timestamp: reproducible PNGs


def save_figure(fig: plt.Figure, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=130, bbox_inches="tight", metadata=METADATA)
    plt.close(fig)
    return path


def distance_heatmap(result: DistanceMatrix, path: str | Path, title: str | None = None) -> Path:
    """Annotated heatmap of the distance matrix in percent; stopped pairs marked 'start ≠'."""
    d = result.distances * 100
    size = max(4.0, 0.75 * len(result.names) + 2)
    fig, ax = plt.subplots(figsize=(size + 1, size))
    vmax = max(np.nanmax(d), 1e-9) if np.isfinite(d).any() else 1.0
    image = ax.imshow(np.ma.masked_invalid(d), cmap="viridis", vmin=0, vmax=vmax)
    for (i, j), value in np.ndenumerate(d):
        text = "start ≠" if np.isnan(value) else f"{value:.2f}"
        light = np.isnan(value) or value < 0.6 * vmax
        ax.text(j, i, text, ha="center", va="center", fontsize=8,
                color="white" if light else "black")
    ax.set_xticks(range(len(result.names)), result.names, rotation=45, ha="right")
    ax.set_yticks(range(len(result.names)), result.names)
    options = result.comparisons[0].options
    ax.set_title(title or f"distinguishable transitions [%]  ({options.kernel}, {options.test}, "
                          f"α={options.alpha})")
    fig.colorbar(image, ax=ax, label="distance [%] (rejected states / |S|)")
    return save_figure(fig, Path(path))


def _cell_edges(edges: np.ndarray, bounds: tuple[float, float]) -> np.ndarray:
    """Bin boundaries in feature units: the data range closes the two outer bins."""
    lo, hi = bounds
    inner = np.asarray(edges, dtype=float)
    return np.concatenate([[min(lo, inner[0])], inner, [max(hi, inner[-1])]])


def _project(grid: dict[str, np.ndarray], axes: tuple[int, int]) -> dict[str, np.ndarray]:
    """Collapse the grid onto two features: counts add up, a cell is rejected if any state is."""
    other = tuple(k for k in range(grid["status"].ndim) if k not in axes)
    status = grid["status"]
    out = {key: grid[key].sum(axis=other).transpose(np.argsort(axes))
           for key in ("m", "n")}
    rejected = (status == 2).any(axis=other)
    tested = (status == 1).any(axis=other)
    untestable = (status == 3).any(axis=other)
    code = np.where(rejected, 2, np.where(tested, 1, np.where(untestable, 3, 0)))
    out["status"] = code.transpose(np.argsort(axes))
    return out


def unit_labels(result: Comparison) -> dict[str, str]:
    """Axis label per state feature, with the unit the trace sets declare: ``gap [m]``.

    A feature derived from a base signal (history ``x@t-1``, a time window) takes its unit.
    """
    units = {f: u for f, u in zip(result.options.features, result.units, strict=False) if u}
    labels = {}
    for name in result.space.features:
        base = max((f for f in units if name == f or name.startswith((f + "@", f + "["))),
                   key=len, default=None)
        if base is not None:
            labels[name] = f"{name} [{units[base]}]"
    return labels


def state_map(result: Comparison, path: str | Path, features: tuple[str, str] | None = None,
              *, labels: Mapping[str, str] | None = None, title: str | None = None) -> Path:
    """Where A and B differ: the state grid over two features, in feature units.

    Left: the verdict per start state (rejected, kept, untestable, no transitions). Right: the
    number of successor samples m + n per start state (log scale). With more than two features
    the grid is projected onto the two chosen ones (a cell is 'rejected' if any state in it is).
    With one feature the map is a strip. ``labels`` names the axes (e.g. with units:
    ``{"gap": "gap [m]"}``); ``title`` replaces the default title (the two input names).
    """
    names = result.space.features
    labels = {**unit_labels(result), **(labels or {})}
    chosen = features or (names[:2] if len(names) > 1 else (names[0], names[0]))
    axes = tuple(names.index(f) for f in chosen)
    grid = result.state_grid()
    if len(names) == 1:
        grid = {k: v[:, None] for k, v in grid.items()}
        axes = (0, 1)
        y_edges = np.array([0.0, 1.0])
    else:
        grid = _project(grid, axes)
        y_edges = _cell_edges(result.space.edges[axes[1]], result.space.bounds[axes[1]])
    x_edges = _cell_edges(result.space.edges[axes[0]], result.space.bounds[axes[0]])

    fig, (left, right) = plt.subplots(1, 2, figsize=(13, 5.2), constrained_layout=True)
    left.pcolormesh(x_edges, y_edges, grid["status"].T, cmap=ListedColormap(STATUS_COLORS),
                    vmin=-0.5, vmax=3.5, edgecolors="#888888", linewidth=0.3)
    left.legend(handles=[Patch(facecolor=c, edgecolor="#888888", label=lab)
                         for c, lab in zip(STATUS_COLORS, STATUS_LABELS, strict=True)],
                loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=2, fontsize=8)
    distance = "stopped: start distributions differ" if result.stopped \
        else f"distance {100 * result.distance:.2f} % of |S| = {result.n_states}"
    left.set_title(f"verdict per start state — {distance}", fontsize=10)
    samples = (grid["m"] + grid["n"]).astype(float)
    mesh = right.pcolormesh(x_edges, y_edges, np.ma.masked_equal(samples, 0).T, cmap="Blues",
                            norm=matplotlib.colors.LogNorm(vmin=1, vmax=max(samples.max(), 2)),
                            edgecolors="#cccccc", linewidth=0.3)
    fig.colorbar(mesh, ax=right, label="successor samples m + n")
    right.set_title("samples per start state (A + B)", fontsize=10)
    for ax in (left, right):
        ax.set_xlabel((labels or {}).get(chosen[0], chosen[0]))
        ax.set_ylabel((labels or {}).get(chosen[1], chosen[1]) if len(names) > 1 else "")
        if len(names) == 1:
            ax.set_yticks([])
    a, b = (Path(i.source).name for i in result.inputs)
    fig.suptitle(f"{title or f'{a} vs {b}'}: {result.options.kernel} kernel, "
                 f"{result.options.test} test, α = {result.options.alpha}", fontsize=11)
    return save_figure(fig, Path(path))
