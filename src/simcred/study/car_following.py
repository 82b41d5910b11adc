"""The car-following validity study: real human following vs SUMO models vs real ACC (OpenACC).

Question: in which operating region (band of the leader's speed) does a SUMO car-following model
respond like a human follower, and by how much does it deviate? The study is ``simcred validate``
without a test case: the same per-region engine (:mod:`simcred.regions`), every band a cell of
the test case. Procedure (choices fixed before looking at results):

1. **Data.** OpenACC episodes (:func:`simcred.io.openacc.read_openacc`, default rules: 10 s, no
   missing values, leader mean speed > 2 m/s, gap in [0.5, 120] m): followers driven by humans
   (``no_ACC``) and by ACC (``short_setting``/``long_setting``).
2. **Simulation.** Every human episode is replayed in SUMO with each model
   (:func:`simcred.sim.sumo.replay`, seeded with the study seed as ``simcred simulate
   sumo-following --seed``): the recorded leader is imposed, the follower starts from the
   recorded gap and speed. So the simulated and the real followers face the same leaders.
3. **Operating regions.** The cells of a grid over the leader's speed ``v_leader`` (default
   0–10, 10–20, 20–30 m/s; the leader is exogenous, the same in a human episode and its replays).
   Episodes are **cut**, not assigned whole: each is cut into maximal segments inside one band
   (:func:`simcred.regions.segments`, at least ``min_length`` samples), and the segments of one
   episode are one unit of the design.
4. **Comparison** per band: the response comparison (``compare(test="response")``) of the
   candidate's segments with the band's human segments — by default features ``gap``, ``v`` and
   ``v_leader`` with ``v_leader`` an input, resampled to 0.5 s, 3 bins — giving per response
   feature the response deviation with its interval, and the difference test's p-value. Rows:
   two same-population baselines (the band's human episodes split at random into two halves;
   split by follower car, a half of the cars vs the rest), each SUMO model (paired: a replay
   with the episode it replays) and real ACC (groups: the ACC episodes). With a ``tolerance``
   the engine also decides each cell (valid / not valid / inconclusive); without one it reports.
5. A cell with fewer than ``min_runs`` units or ``min_samples`` samples on a side is ``unknown``.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from simcred._json import dumps, envelope
from simcred._version import versions
from simcred.compare import Method
from simcred.compare.effect import check_margins
from simcred.compare.process import resolve_bins
from simcred.compare.transitions import response_features
from simcred.engine import Engine, Progress, engine
from simcred.errors import OptionError
from simcred.io.openacc import ACC, HUMAN, UNITS, EpisodeRules, read_openacc, recording_files
from simcred.limits import check_count
from simcred.regions import (
    SOURCE_RUN,
    CellComparison,
    CellResult,
    CellRule,
    CellStatus,
    Grid,
    MinData,
    Segments,
    cell_rule,
    cell_seed,
    compare_cell,
    halves,
)
from simcred.sim.sumo import replay, sumo_version
from simcred.traces import TIME, TraceSet, take

BASELINE = "human vs human (random split)"
BASELINE_CARS = "human vs human (split by car)"
BASELINES = (BASELINE, BASELINE_CARS)
REAL_ACC = "real ACC"
CAR = "follower_vehicle"  # the per-run fact that names the follower's car (its driver)
CONDITION = "v_leader"
DEFAULT_BANDS = ((0.0, 10.0), (10.0, 20.0), (20.0, 30.0))
DEFAULT_MODELS = ("Krauss", "IDM", "EIDM", "ACC")
METHOD = ("response comparison per band (compare test='response', the engine of simcred "
          "validate): response deviation with cluster-bootstrap interval, difference p-value; "
          "segments of one episode one unit")


@dataclass(frozen=True, slots=True)
class StudyOptions:
    """Options of :func:`run_study` (defaults: the documented study)."""

    models: tuple[str, ...] = DEFAULT_MODELS
    bands: tuple[tuple[float, float], ...] = DEFAULT_BANDS
    features: tuple[str, ...] = ("gap", "v", "v_leader")
    inputs: tuple[str, ...] = ("v_leader",)
    tolerance: Mapping[str, float] = field(default_factory=dict)
    bins: int = 3
    sample_step: float = 0.5
    alpha: float = 0.05
    permutations: int = 199
    bootstrap: int = 500
    seed: int = 0
    min_runs: int = 10
    min_samples: int = 500
    min_length: int = 25
    max_episodes: int | None = None
    rules: EpisodeRules = field(default_factory=EpisodeRules)

    def __post_init__(self) -> None:
        """The comparison's options are checked by :class:`~simcred.compare.Method` and
        compare's own checks of features, inputs and bins (one place, the messages of
        ``simcred compare``); the study adds the episodes' signals, its least sizes (19
        permutations, 100 bootstrap replicates: the interval's ends need them), an integer seed
        (it also seeds SUMO) and its own options (models, bands, minimum data)."""
        for name in ("models", "features", "inputs"):
            object.__setattr__(self, name, tuple(getattr(self, name)))
        object.__setattr__(self, "bands", tuple((float(lo), float(hi)) for lo, hi in self.bands))
        if not self.models:
            raise OptionError("give at least one SUMO model")
        self._check_comparison()
        if self.max_episodes is not None:
            check_count(self.max_episodes, "episodes", "max episodes", minimum=2)
        self.edges  # noqa: B018  (the bands form one grid)
        if self.min_runs < 2 or self.min_samples < 2 or self.min_length < 2:
            raise OptionError(f"min runs, min samples and min length must be at least 2, got "
                              f"{self.min_runs}, {self.min_samples}, {self.min_length}")

    def _check_comparison(self) -> None:
        for name, least in (("permutations", 19), ("bootstrap", 100)):  # before Method's
            value = getattr(self, name)                                  # "positive integer"
            if isinstance(value, int) and not isinstance(value, bool) and value < least:
                raise OptionError(f"{name} must be at least {least}, got {value}")
        if self.sample_step is None:
            raise OptionError("sample step must be a positive number of seconds (the segments "
                              "are resampled to it), got None")
        self.method  # noqa: B018  (Method checks every option it has)
        signals = [name for name in UNITS if name != TIME]
        unknown = [f for f in (*self.features, *self.inputs) if f not in signals]
        if unknown:
            raise OptionError(f"unknown feature(s) {', '.join(unknown)}: the episodes' signals "
                              f"are {', '.join(signals)}")
        response_features(self.features, self.inputs)
        resolve_bins(self.bins, len(self.features))
        check_count(self.permutations, "permutations", "permutations", minimum=19)
        check_count(self.bootstrap, "permutations", "bootstrap", minimum=100)
        if not isinstance(self.seed, int):
            raise OptionError(f"seed must be a non-negative integer (it seeds the SUMO replays "
                              f"too), got {self.seed!r}")
        object.__setattr__(self, "tolerance", dict(check_margins(self.tolerance or None,
                                                                 self.response)))

    @property
    def response(self) -> tuple[str, ...]:
        return tuple(f for f in self.features if f not in self.inputs)

    @property
    def edges(self) -> tuple[float, ...]:
        """The bands as the edges of one grid over the leader's speed (contiguous, increasing)."""
        bands = self.bands
        if not bands or any(not (np.isfinite(lo) and np.isfinite(hi) and lo < hi)
                            for lo, hi in bands):
            raise OptionError(f"speed bands must be (low, high) with finite low < high, got "
                              f"{bands}")
        if any(a[1] != b[0] for a, b in zip(bands, bands[1:], strict=False)):
            raise OptionError(f"speed bands must be contiguous and increasing (the cells of one "
                              f"grid: 0-10,10-20,...), got {bands}")
        return (bands[0][0], *(hi for _, hi in bands))

    def grid(self) -> Grid:
        return Grid((CONDITION,), (self.edges,), (UNITS[CONDITION],))

    def settings(self) -> CellComparison:
        """The engine's per-cell settings (those of a validation file with the same values)."""
        return CellComparison(self.method, dict(self.tolerance), self.response,
                              MinData(self.min_runs, self.min_samples), self.min_length)

    @property
    def method(self) -> Method:
        """The response comparison of every band (the study's seed; each cell derives its
        own)."""
        return Method(test="response", features=self.features, inputs=self.inputs,
                      bins=self.bins, alpha=self.alpha, permutations=self.permutations,
                      bootstrap=self.bootstrap, seed=self.seed, resample=self.sample_step)

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["tolerance"] = dict(self.tolerance)
        out["method"] = METHOD
        return out


def band_label(band: tuple[float, float]) -> str:
    lo, hi = band
    return f"{lo:g}-{hi:g} m/s"


@dataclass(frozen=True, slots=True)
class Summary:
    """Descriptive statistics of one side of a cell (over its segments' samples)."""

    runs: int
    samples: int
    gap_median: float
    headway_median: float
    dv_std: float
    a_std: float

    @classmethod
    def of(cls, traces: TraceSet | None) -> Summary | None:
        if traces is None:
            return None
        gap, v = traces.column("gap"), traces.column("v")
        moving = v > 1.0
        headway = float(np.median(gap[moving] / v[moving])) if moving.any() else float("nan")
        return cls(traces.n_runs, traces.n_rows, float(np.median(gap)), headway,
                   float(np.std(traces.column("dv"))), float(np.std(traces.column("a"))))


@dataclass(frozen=True, slots=True, eq=False)
class Cell:
    """One row (a candidate vs the human reference) in one band: the engine's cell result and
    descriptive statistics of both sides (``a``: the reference, ``b``: the candidate; for the
    baselines the two halves)."""

    row: str
    band: tuple[float, float]
    result: CellResult
    a: Summary | None
    b: Summary | None

    @property
    def status(self) -> CellStatus:
        return self.result.status

    @property
    def compared(self) -> bool:
        return self.result.comparison is not None

    def to_dict(self) -> dict[str, Any]:
        return {"row": self.row, "band": list(self.band), "band_label": band_label(self.band),
                "status": self.status.value,
                "reference": None if self.a is None else asdict(self.a),
                "candidate": None if self.b is None else asdict(self.b),
                "result": self.result.to_dict()}


@dataclass(frozen=True, slots=True, eq=False)
class StudyResult:
    """All cells of the study plus its provenance; ``to_json`` is the findings document."""

    options: StudyOptions
    rows: tuple[str, ...]
    cells: tuple[Cell, ...]
    inputs: dict[str, Any]
    episodes: dict[str, Any]

    def cell(self, row: str, band: tuple[float, float]) -> Cell:
        for c in self.cells:
            if c.row == row and c.band == tuple(band):
                return c
        raise KeyError((row, band))

    def findings(self) -> list[str]:
        """One sentence per cell: the deviations with their intervals, the difference p-value,
        the units; the status when a tolerance was given."""
        return [finding(c, self.options) for c in self.cells]

    def to_dict(self) -> dict[str, Any]:
        body = {"study": "car-following", "options": self.options.to_dict(), "method": METHOD,
                "units": UNITS, "inputs": self.inputs, "episodes": self.episodes,
                "rows": list(self.rows), "bands": [list(b) for b in self.options.bands],
                "cells": [c.to_dict() for c in self.cells], "findings": self.findings()}
        return envelope("car_following_study", body)

    def to_json(self) -> str:
        return dumps(self.to_dict())


def fmt(value: float | None) -> str:
    """A number in three significant digits, ``n/a`` for None."""
    return "n/a" if value is None else f"{value:.3g}"


def deviations(result: CellResult) -> str:
    """``v 0.52 m/s² (95 % 0.45–0.60), gap ...`` of a compared cell."""
    return ", ".join(f"{b.feature} {fmt(b.estimate)} {b.unit} (95 % {fmt(b.low)}–{fmt(b.high)})"
                     for b in result.bounds)


def finding(c: Cell, options: StudyOptions) -> str:
    r = c.result
    where = f"{c.row}, leader {band_label(c.band)}"
    if r.comparison is None:
        return f"{where}: unknown — {r.reason}"
    floor = r.pvalue is not None and r.pvalue <= 1 / (options.permutations + 1)
    judged = "" if r.status is CellStatus.COMPARED else f"; {r.status.value}: {r.reason}"
    return (f"{where}: response deviation {deviations(r)}; difference p = {fmt(r.pvalue)}"
            f"{' (smallest possible)' if floor else ''}; {r.reference_units} vs "
            f"{r.candidate_units} units ({r.design}){judged}")


# -- the procedure -------------------------------------------------------------------------------


def _subset(traces: TraceSet, limit: int | None) -> TraceSet:
    if limit is None or traces.n_runs <= limit:
        return traces
    return take(traces, np.unique(np.linspace(0, traces.n_runs - 1, limit).round().astype(int)))


def _provenance(source: Path | None, options: StudyOptions, human: TraceSet, acc: TraceSet,
                sims: dict[str, TraceSet]) -> dict[str, Any]:
    import simcred.data as data

    root = data.path("openacc") if source is None else Path(source)
    files = recording_files(root)
    hashes = {p.relative_to(root).as_posix() if root.is_dir() else p.name:
              "sha256:" + hashlib.sha256(p.read_bytes()).hexdigest() for p in files}
    return {
        "source": "simcred.data:openacc" if source is None else str(source),
        "files": hashes,
        "human": {"digest": human.digest(), "runs": human.n_runs},
        "acc": {"digest": acc.digest(), "runs": acc.n_runs},
        "sumo": {name: {"digest": s.digest(), "model": s.metadata["model"],
                        "negative_gap_runs": s.metadata["negative_gap_runs"]}
                 for name, s in sims.items()},
        "versions": versions("numpy", sumo=sumo_version()),
        "seeds": {"study": options.seed, "sumo": options.seed,
                  "cells": "SeedSequence(seed, spawn_key=(crc32(row), cell)) "
                           "(simcred.regions.cell_seed); halves: row + ':halves'"},
    }


def _row_cells(name: str, options: StudyOptions, grid: Grid, reference: Segments,
               candidate: TraceSet, rule: CellRule) -> list[Cell]:
    """A candidate's cells: its segments compared with the reference's in every band."""
    settings = options.settings()
    mine = settings.segments(candidate, grid)
    out = []
    for cell in range(grid.n_cells):
        ref, cand = reference.by_cell.get(cell), mine.by_cell.get(cell)
        result = compare_cell(settings, grid, cell, name, rule, ref, cand)
        out.append(Cell(name, options.bands[cell], result, Summary.of(ref), Summary.of(cand)))
    return out


def _split_cells(name: str, key: str, options: StudyOptions, grid: Grid, reference: Segments
                 ) -> list[Cell]:
    """A baseline: in every band the human segments split at random into two halves of whole
    units of ``key`` (episodes, or follower cars), compared with groups by episode."""
    settings = options.settings()
    rule = cell_rule(options.alpha, grid.n_cells)
    out = []
    for cell in range(grid.n_cells):
        traces = reference.by_cell.get(cell)
        split = None if traces is None else halves(
            traces, key, cell_seed(options.seed, f"{name}:halves", cell))
        a, b = (None, None) if split is None else split
        result = compare_cell(settings, grid, cell, name, rule, a, b)
        out.append(Cell(name, options.bands[cell], result, Summary.of(a), Summary.of(b)))
    return out


def baseline_cells(options: StudyOptions, grid: Grid, reference: Segments) -> list[Cell]:
    """Both human-vs-human baselines in every band (random split by episode, split by car)."""
    return (_split_cells(BASELINE, SOURCE_RUN, options, grid, reference)
            + _split_cells(BASELINE_CARS, CAR, options, grid, reference))


def run_study(options: StudyOptions | None = None, *, source: str | Path | None = None,
              workers: int | None = None, scheduler: str | None = None,
              runner: Engine | None = None, progress: Progress | None = None) -> StudyResult:
    """Run the car-following study (see the module doc) and return every cell with provenance.

    Parameters
    ----------
    options : StudyOptions, optional
        Models, bands, features, tolerance, seed...; the defaults are the documented study.
    source : path, optional
        OpenACC files (original CSV or shipped Parquet); default: the copy in ``simcred.data``.
    workers, scheduler, runner
        Where the SUMO replays run (in-process by default, or on Dask).
    progress : callable, optional
        Wraps the SUMO tasks (e.g. a progress bar).
    """
    options = options or StudyOptions()
    if runner is None:
        with engine(workers, scheduler) as started:
            return run_study(options, source=source, runner=started, progress=progress)
    human = _subset(read_openacc(source, options.rules, follower=HUMAN), options.max_episodes)
    acc = _subset(read_openacc(source, options.rules, follower=ACC), options.max_episodes)
    sims = replay(human, options.models, seed=options.seed, runner=runner, progress=progress)
    grid = options.grid()
    reference = options.settings().segments(human, grid)
    family = grid.n_cells  # no test case: every band is one of its cells
    cells = baseline_cells(options, grid, reference)
    for name, traces in sims.items():
        cells += _row_cells(f"SUMO {name}", options, grid, reference, traces,
                            cell_rule(options.alpha, family, replay=True))
    acc_cells = _row_cells(REAL_ACC, options, grid, reference, acc,
                           cell_rule(options.alpha, family))
    rows = (*BASELINES, *(f"SUMO {m}" for m in sims), REAL_ACC)
    order = {row: i for i, row in enumerate(rows)}
    cells = sorted([*cells, *acc_cells], key=lambda c: (c.band, order[c.row]))
    episodes = {"human": _episodes(human, reference, grid),
                "acc": _episodes(acc, options.settings().segments(acc, grid), grid),
                "rules": asdict(options.rules),
                "cut": {"human": _cut(human), "acc": _cut(acc)}}
    return StudyResult(options, rows, tuple(cells),
                       _provenance(None if source is None else Path(source), options, human, acc,
                                   sims), episodes)


def _episodes(traces: TraceSet, segs: Segments, grid: Grid) -> dict[str, Any]:
    """Episodes read and, per band, the segments cut there and the episodes they come from."""
    per_band = []
    for cell in range(grid.n_cells):
        part = segs.by_cell.get(cell)
        per_band.append({"band": grid.label(cell),
                         "segments": 0 if part is None else part.n_runs,
                         "episodes": 0 if part is None else len(set(
                             f[SOURCE_RUN] for f in part.metadata["run_info"].values())),
                         "samples": 0 if part is None else part.n_rows})
    return {"runs": traces.n_runs, "per_band": per_band}


def _cut(traces: TraceSet) -> dict[str, Any]:
    return {k: v for k, v in traces.metadata["cut"].items() if k != "by_file"}


def repeat_baselines(seeds: Sequence[int], options: StudyOptions | None = None, *,
                     source: str | Path | None = None) -> list[Cell]:
    """The two human-vs-human baseline rows of every band for each study seed, without SUMO.

    The cells are those :func:`run_study` gives with the same options and seed (same splits, same
    comparison seeds); repeated over many seeds they measure how often the difference test
    rejects "human vs human" and how large the deviation of two halves of the humans is.
    """
    options = options or StudyOptions()
    human = _subset(read_openacc(source, options.rules, follower=HUMAN), options.max_episodes)
    grid = options.grid()
    reference = options.settings().segments(human, grid)
    cells = []
    for seed in seeds:
        cells += baseline_cells(replace(options, seed=seed), grid, reference)
    return cells


__all__ = ["StudyOptions", "StudyResult", "Cell", "Summary", "run_study", "repeat_baselines",
           "baseline_cells", "BASELINE", "BASELINE_CARS", "REAL_ACC", "band_label", "deviations",
           "finding"]
