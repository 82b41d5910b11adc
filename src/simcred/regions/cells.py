"""The operating-condition grid: cells, and runs cut into per-cell segments.

A cell is a box: one interval per condition variable, ``[lo, hi)`` except the last interval of a
variable, which is closed. Runs cross cells (a car following at 12 m/s accelerates to 18 m/s), so
a run is not assigned to one cell as a whole: it is cut into *maximal segments* of consecutive
samples that lie in the same cell, and segments shorter than ``min_length`` samples are dropped.
A whole run would put transitions observed under other conditions into the cell. Each segment
carries its run's per-run facts plus ``source_run`` (the run it was cut from), so that the
segments of one run form one unit of the comparison's design: dependent segments are never
treated as exchangeable units.

Part of the per-region engine (:mod:`simcred.regions`) that ``validate`` and ``study`` share.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from fractions import Fraction

import numpy as np

from simcred.contracts.expr import Compare, Expr, Num, Var, conjoin, decimal_text
from simcred.traces import RUN_INFO, TraceSet, handed_over, spans

OUTSIDE = -1
#: The per-run fact of a segment that names the run it was cut from.
SOURCE_RUN = "source_run"


@dataclass(frozen=True, slots=True)
class Grid:
    """Cell edges per condition variable (in the order of ``variables``)."""

    variables: tuple[str, ...]
    edges: tuple[tuple[float, ...], ...]
    units: tuple[str, ...]

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(len(e) - 1 for e in self.edges)

    @property
    def n_cells(self) -> int:
        return int(np.prod(self.shape))

    def index(self, flat: int) -> tuple[int, ...]:
        return tuple(int(i) for i in np.unravel_index(flat, self.shape))

    def bounds(self, flat: int) -> tuple[tuple[float, float], ...]:
        return tuple((self.edges[j][i], self.edges[j][i + 1])
                     for j, i in enumerate(self.index(flat)))

    def label(self, flat: int) -> str:
        """``10 ≤ v < 15, 0 ≤ gap ≤ 40`` (the last interval of a variable is closed)."""
        parts = []
        for j, (lo, hi) in enumerate(self.bounds(flat)):
            last = self.index(flat)[j] == self.shape[j] - 1
            parts.append(f"{_num(lo)} ≤ {self.variables[j]} {'≤' if last else '<'} {_num(hi)}")
        return ", ".join(parts)

    def assertion(self, flat: int, *, half_open: bool = False) -> str:
        """The cell as a contract assertion in exact decimals: closed intervals (a union of
        cells then covers the boundaries between them), or ``half_open`` as rows are assigned
        (``lo <= v < hi``, the last interval of a variable closed)."""
        parts = []
        for j, (lo, hi) in enumerate(self.bounds(flat)):
            strict = half_open and self.index(flat)[j] < self.shape[j] - 1
            parts.append(f"{_exact(lo)} <= {self.variables[j]} {'<' if strict else '<='} "
                         f"{_exact(hi)}")
        return " and ".join(parts)

    def interior(self, flat: int) -> str:
        """The open box of the cell (``lo < v < hi`` per variable) as a contract assertion: the
        part of the cell no other cell shares."""
        return " and ".join(f"{_exact(lo)} < {self.variables[j]} < {_exact(hi)}"
                            for j, (lo, hi) in enumerate(self.bounds(flat)))

    def box(self, flat: int | None = None, *, interior: bool = False) -> Expr:
        """The cell ``flat`` (``None``: the whole grid, first to last edge) as a contract AST,
        closed (the tree :meth:`assertion` parses to) or ``interior`` (that of :meth:`interior`);
        numbers are the floats' shortest reprs, exactly."""
        bounds = (tuple((e[0], e[-1]) for e in self.edges) if flat is None
                  else self.bounds(flat))
        op = "<" if interior else "<="
        parts = []
        for name, (lo, hi) in zip(self.variables, bounds, strict=True):
            parts += [Compare(op, Num(_fraction(lo)), Var(name)),
                      Compare(op, Var(name), Num(_fraction(hi)))]
        return conjoin(*parts)

    def cells_of(self, traces: TraceSet) -> np.ndarray:
        """Flat cell index of every row of ``traces`` (``OUTSIDE`` beyond the edges)."""
        index = np.zeros(traces.n_rows, dtype=np.int64)
        inside = np.ones(traces.n_rows, dtype=bool)
        for j, (name, edges) in enumerate(zip(self.variables, self.edges, strict=True)):
            values = traces.column(name)
            e = np.asarray(edges)
            i = np.searchsorted(e, values, side="right") - 1
            i[values == e[-1]] = len(e) - 2
            inside &= (i >= 0) & (i < len(e) - 1)
            index = index * self.shape[j] + np.clip(i, 0, len(e) - 2)
        return np.where(inside, index, OUTSIDE)


def grid_of(conditions: Mapping[str, object]) -> Grid:
    names = tuple(conditions)
    return Grid(names, tuple(tuple(float(e) for e in conditions[n].edges) for n in names),
                tuple(conditions[n].unit for n in names))


@dataclass(frozen=True, slots=True)
class Segments:
    """The per-cell segments of one trace set: for each cell with any, a trace set whose runs are
    the segments (ids ``<run>@<first row>``)."""

    by_cell: dict[int, TraceSet]

    def runs(self, cell: int) -> int:
        return self.by_cell[cell].n_runs if cell in self.by_cell else 0

    def samples(self, cell: int) -> int:
        return self.by_cell[cell].n_rows if cell in self.by_cell else 0


def segments(traces: TraceSet, grid: Grid, min_length: int) -> Segments:
    """Cut every run of ``traces`` into maximal same-cell segments of ≥ ``min_length`` rows."""
    cells = grid.cells_of(traces)
    starts: dict[int, list[tuple[int, int, str]]] = {}
    for r in range(traces.n_runs):
        lo, hi = int(traces.offsets[r]), int(traces.offsets[r + 1])
        c = cells[lo:hi]
        cuts = np.flatnonzero(np.diff(c)) + 1
        for a, b in zip(np.r_[0, cuts], np.r_[cuts, hi - lo], strict=True):
            if c[a] != OUTSIDE and b - a >= min_length:
                starts.setdefault(int(c[a]), []).append((lo + int(a), lo + int(b),
                                                         f"{traces.run_ids[r]}@{int(a)}"))
    return Segments({cell: _subset(traces, parts, cell, grid) for cell, parts in
                     sorted(starts.items())})


def _subset(traces: TraceSet, parts: Sequence[tuple[int, int, str]], cell: int, grid: Grid
            ) -> TraceSet:
    rows, offsets = spans([a for a, _, _ in parts], [b for _, b, _ in parts])
    info = traces.metadata.get(RUN_INFO)
    info = info if isinstance(info, Mapping) else {}
    facts = {}
    for a, _, name in parts:
        run = traces.run_ids[int(np.searchsorted(traces.offsets, a, side="right")) - 1]
        own = info.get(run)
        facts[name] = {**(own if isinstance(own, Mapping) else {}), SOURCE_RUN: run}
    return TraceSet(traces.signals, handed_over(traces.time[rows]),
                    handed_over(traces.values[rows]),
                    offsets, tuple(n for _, _, n in parts),
                    {**traces.metadata, RUN_INFO: facts}, f"{traces.source} [{grid.label(cell)}]")


def _num(value: float) -> str:
    return f"{value:g}"


def _fraction(value: float) -> Fraction:
    """The float's shortest repr, exactly."""
    return Fraction(repr(float(value)))


def _exact(value: float) -> str:
    """The float's shortest repr as a plain decimal, which the contracts' parser reads exactly
    (no exponent: ``1e-05`` becomes ``0.00001``)."""
    text = decimal_text(_fraction(value))
    return text if not text.startswith("-") else f"({text})"
