"""The car-following validity study: real human following vs SUMO models vs real ACC (OpenACC).

Question: in which operating region (speed band) can a SUMO car-following model stand in for a
human follower, and how sure is that? Procedure (all choices fixed before looking at results):

1. **Data.** OpenACC episodes (:func:`simcred.io.openacc.read_openacc`, default rules: 10 s, no
   missing values, leader mean speed > 2 m/s, gap in [0.5, 120] m): followers driven by humans
   (``no_ACC``) and by ACC (``short_setting``/``long_setting``).
2. **Simulation.** Every human episode is replayed in SUMO with each model
   (:func:`simcred.sim.sumo.replay`): the recorded leader is imposed, the follower starts from the
   recorded gap and speed. So the simulated and the real followers face the same leaders.
3. **Operating regions.** An episode belongs to the speed band that holds its leader's mean speed
   (default 0–10, 10–20, 20–30 m/s). The leader is the exogenous input, the same for a human
   episode and its replays, so paired sets fall in the same band.
4. **Comparison** per band (:func:`simcred.compare.compare`, Neurohr et al. 2023): features
   ``gap`` [m], ``dv`` [m/s], ``a`` [m/s²], each in 5 equal-frequency bins on the pooled values;
   episodes thinned to one sample every 0.5 s; start test reported, transitions always tested.
   Rows: two same-population baselines (the band's human episodes split at random into two
   halves; and split by follower car, half of the cars vs the other half), each SUMO model vs the
   human episodes, and real ACC vs the human episodes. The verdict's test is one option
   (:mod:`simcred.study.verdict`): by default the run-level test (``test="runs"``: whole
   episodes reassigned; chain-level p-value; per-state verdicts under max-T family-wise control,
   so the distance is calibrated), with a same-model baseline per cell (the cell's reference
   episodes split into random halves ``baseline`` times); ``test="permutation"`` is the interim
   per-transition test.
5. A band with fewer than ``min_runs`` episodes on a side is reported as "insufficient data", not
   as valid.
"""

from __future__ import annotations

import hashlib
import platform
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from simcred._json import dumps, envelope
from simcred._version import __version__
from simcred.compare import compare
from simcred.compare.result import Comparison
from simcred.engine import Engine, Progress, engine
from simcred.errors import OptionError
from simcred.io.openacc import ACC, HUMAN, UNITS, EpisodeRules, read_openacc, recording_files
from simcred.limits import check_count, check_finite
from simcred.seeds import derive_seed
from simcred.sim.sumo import replay, sumo_version
from simcred.study.verdict import METHODS, CellVerdict, chain_verdict, check_test
from simcred.traces import RUN_INFO, TIME, TraceSet, handed_over, take

BASELINE = "human vs human (random split)"
BASELINE_CARS = "human vs human (split by car)"
BASELINES = (BASELINE, BASELINE_CARS)
REAL_ACC = "real ACC"
DEFAULT_BANDS = ((0.0, 10.0), (10.0, 20.0), (20.0, 30.0))
DEFAULT_MODELS = ("Krauss", "IDM", "EIDM", "ACC")
ONE_SIDED = ("evidence", "neutral")  # run-level test: states one set never visits
# seed streams (keys of derive_seed)
_SUMO, _SPLIT, _COMPARE, _SPLIT_CARS = 1, 2, 3, 4


@dataclass(frozen=True, slots=True)
class StudyOptions:
    """Options of :func:`run_study` (defaults: the documented study)."""

    models: tuple[str, ...] = DEFAULT_MODELS
    bands: tuple[tuple[float, float], ...] = DEFAULT_BANDS
    features: tuple[str, ...] = ("gap", "dv", "a")
    bins: int = 5
    sample_step: float = 0.5
    test: str = "runs"
    alpha: float = 0.01
    permutations: int = 999
    baseline: int = 10
    one_sided: str = "evidence"
    seed: int = 0
    min_runs: int = 10
    max_episodes: int | None = None
    rules: EpisodeRules = field(default_factory=EpisodeRules)

    def __post_init__(self) -> None:
        object.__setattr__(self, "models", tuple(self.models))
        object.__setattr__(self, "features", tuple(self.features))
        object.__setattr__(self, "bands", tuple((float(lo), float(hi)) for lo, hi in self.bands))
        check_test(self.test)
        check_finite(self.alpha, "alpha", minimum=0, maximum=1, open_minimum=True,
                     open_maximum=True)
        check_count(self.permutations, "permutations", "permutations")
        check_count(self.baseline, "permutations", "baseline", minimum=0)
        if self.one_sided not in ONE_SIDED:
            raise OptionError(f"one-sided must be one of {', '.join(ONE_SIDED)}; "
                              f"got {self.one_sided!r}")
        check_count(self.bins, "bins", "bins", minimum=2)
        check_finite(self.sample_step, "sample step", minimum=0, open_minimum=True)
        for lo, hi in self.bands:
            check_finite(lo, "speed band low end")
            check_finite(hi, "speed band high end")
        if self.max_episodes is not None:
            check_count(self.max_episodes, "episodes", "max episodes", minimum=2)
        if not self.models:
            raise OptionError("give at least one SUMO model")
        signals = [name for name in UNITS if name != TIME]
        unknown = [f for f in self.features if f not in signals]
        if unknown or not self.features:
            raise OptionError(f"unknown feature(s) {', '.join(unknown) or '(none given)'}: the "
                              f"episodes' signals are {', '.join(signals)}")
        if not self.bands or any(not lo < hi for lo, hi in self.bands):
            raise OptionError(f"speed bands must be (low, high) with low < high, got {self.bands}")
        edges = sorted(self.bands)
        if any(a[1] > b[0] for a, b in zip(edges, edges[1:], strict=False)):
            raise OptionError(f"speed bands overlap: {self.bands}")
        if (self.permutations + 1) * self.alpha < 1:
            raise OptionError(f"{self.permutations} permutations cannot reject at alpha="
                              f"{self.alpha}: give at least {int(np.ceil(1 / self.alpha)) - 1}")
        if self.min_runs < 2:
            raise OptionError(f"min runs must be at least 2, got {self.min_runs}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise OptionError(f"seed must be a non-negative integer, got {self.seed!r}")

    @property
    def every(self) -> int:
        """Keep every ``every``-th sample (``sample_step / rules.step``, an integer ≥ 1)."""
        ratio = self.sample_step / self.rules.step
        if abs(ratio - round(ratio)) > 1e-9 or round(ratio) < 1:
            raise OptionError(f"sample step {self.sample_step} s must be a multiple of the "
                              f"episode step {self.rules.step} s")
        return int(round(ratio))

    def to_dict(self) -> dict[str, Any]:
        out = asdict(self)
        out["method"] = METHODS[self.test]
        return out


def band_label(band: tuple[float, float]) -> str:
    lo, hi = band
    return f"{lo:g}-{hi:g} m/s"


@dataclass(frozen=True, slots=True)
class Summary:
    """Descriptive statistics of one set of episodes (over all thinned samples)."""

    runs: int
    samples: int
    gap_median: float
    headway_median: float
    dv_std: float
    a_std: float

    @classmethod
    def of(cls, traces: TraceSet) -> Summary:
        gap, v = traces.column("gap"), traces.column("v")
        moving = v > 1.0
        headway = float(np.median(gap[moving] / v[moving])) if moving.any() else float("nan")
        return cls(traces.n_runs, traces.n_rows, float(np.median(gap)), headway,
                   float(np.std(traces.column("dv"))), float(np.std(traces.column("a"))))


@dataclass(frozen=True, slots=True, eq=False)
class Cell:
    """One row (a candidate vs the human reference) in one speed band.

    ``status`` is "tested" or "insufficient data" (then ``verdict`` and ``comparison`` are None).
    """

    row: str
    band: tuple[float, float]
    status: str
    a: Summary | None
    b: Summary | None
    verdict: CellVerdict | None = None
    comparison: Comparison | None = None

    @property
    def distance(self) -> float | None:
        return None if self.comparison is None else self.comparison.distance

    def to_dict(self) -> dict[str, Any]:
        c = self.comparison
        return {
            "row": self.row, "band": list(self.band), "band_label": band_label(self.band),
            "status": self.status,
            "reference": None if self.a is None else asdict(self.a),
            "candidate": None if self.b is None else asdict(self.b),
            "verdict": None if self.verdict is None else self.verdict.to_dict(),
            "distance": self.distance,
            "start_pvalue": None if c is None else c.start.pvalue,
            "start_rejected": None if c is None else c.start.rejected,
            "n_states": None if c is None else c.n_states,
            "n_tested": None if c is None else len(c.states),
            "n_rejected_states": None if c is None else len(c.rejected_states),
            "n_untestable": None if c is None else len(c.untestable),
            "baseline": None if c is None or c.baseline is None else {
                "distances": list(c.baseline.distances), "low": c.baseline.low,
                "high": c.baseline.high, "chain_pvalues": list(c.baseline.chain_pvalues)},
        }


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
        """One sentence per cell: valid / not valid / insufficient data, with p and distance."""
        out = []
        for c in self.cells:
            where = f"{c.row}, leader {band_label(c.band)}"
            if c.verdict is None:
                out.append(f"{where}: insufficient data ({episode_counts(c)})")
                continue
            word = "differs from human following" if c.verdict.rejected else \
                "not distinguishable from human following"
            if c.row == BASELINE:
                word = "random halves differ: the test is not calibrated here" \
                    if c.verdict.rejected else "random halves not distinguishable (as expected)"
            elif c.row == BASELINE_CARS:
                word = "the two groups of cars (drivers) differ among themselves" \
                    if c.verdict.rejected else "the two groups of cars not distinguishable"
            floor = c.comparison.chain is not None and \
                c.verdict.pvalue <= 1 / (c.comparison.chain.permutations + 1)
            out.append(f"{where}: {word} (chain p = {fmt(c.verdict.pvalue)}"
                       f"{' (smallest possible)' if floor else ''}, distance "
                       f"{fmt(c.distance)}{_baseline_range(c)}, {episode_counts(c)})")
        return out

    def to_dict(self) -> dict[str, Any]:
        body = {"study": "car-following", "options": self.options.to_dict(),
                "method": METHODS[self.options.test], "units": UNITS,
                "inputs": self.inputs, "episodes": self.episodes, "rows": list(self.rows),
                "bands": [list(b) for b in self.options.bands],
                "cells": [c.to_dict() for c in self.cells], "findings": self.findings()}
        return envelope("car_following_study", body)

    def to_json(self) -> str:
        return dumps(self.to_dict())


def fmt(value: float | None) -> str:
    """A number in three significant digits, ``n/a`` for None."""
    return "n/a" if value is None else f"{value:.3g}"


def _baseline_range(c: Cell) -> str:
    """The distance's same-model baseline as text (range over reference half-splits), or ""."""
    base = None if c.comparison is None else c.comparison.baseline
    if base is None:
        return ""
    return f" where halves of the reference give {fmt(base.low)}-{fmt(base.high)}"


def episode_counts(c: Cell) -> str:
    """``<reference> vs <candidate> episodes`` of a cell."""
    a = 0 if c.a is None else c.a.runs
    b = 0 if c.b is None else c.b.runs
    return f"{a} vs {b} episodes"


# -- the procedure -------------------------------------------------------------------------------


def thin(traces: TraceSet, every: int) -> TraceSet:
    """Every ``every``-th sample of each run (the first sample kept)."""
    if every == 1:
        return traces
    rows = np.concatenate([np.arange(lo, hi, every) for lo, hi in
                           zip(traces.offsets[:-1], traces.offsets[1:], strict=True)])
    lengths = np.array([len(range(lo, hi, every)) for lo, hi in
                        zip(traces.offsets[:-1], traces.offsets[1:], strict=True)])
    return TraceSet(traces.signals, handed_over(traces.time[rows]),
                    handed_over(traces.values[rows]),
                    np.concatenate([[0], np.cumsum(lengths)]), traces.run_ids,
                    traces.metadata, traces.source)


def band_index(traces: TraceSet, bands: Sequence[tuple[float, float]]) -> np.ndarray:
    """Per run, the index of the band holding the leader's mean speed [m/s]; -1 if none."""
    means = np.add.reduceat(traces.column("v_leader"), traces.offsets[:-1]) / traces.lengths
    out = np.full(traces.n_runs, -1)
    for k, (lo, hi) in enumerate(bands):
        last = k == len(bands) - 1 or bands[k + 1][0] > hi
        inside = (means >= lo) & ((means <= hi) if last else (means < hi))
        out[inside & (out < 0)] = k
    return out


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
        "versions": {"simcred": __version__, "sumo": sumo_version(),
                     "numpy": np.__version__, "python": platform.python_version()},
        "seeds": {"study": options.seed, "sumo": derive_seed(options.seed, _SUMO),
                  "split": [derive_seed(options.seed, _SPLIT, k)
                            for k in range(len(options.bands))],
                  "split_cars": [derive_seed(options.seed, _SPLIT_CARS, k)
                                 for k in range(len(options.bands))]},
    }


def _compare(a: TraceSet, b: TraceSet, options: StudyOptions, row: int, band: int
             ) -> tuple[Comparison, CellVerdict]:
    runs = options.test == "runs"
    result = compare(a, b, features=options.features, bins=options.bins, test=options.test,
                     alpha=options.alpha, permutations=options.permutations,
                     seed=derive_seed(options.seed, _COMPARE, row, band),
                     baseline=options.baseline if runs and a.n_runs >= 4 else 0,
                     one_sided=options.one_sided, continue_on_start_difference=True)
    return result, chain_verdict(result, options.test, options.alpha)


def _cell(row_name: str, row: int, k: int, a: TraceSet | None, b: TraceSet | None,
          options: StudyOptions) -> Cell:
    band = options.bands[k]
    sa = None if a is None else Summary.of(a)
    sb = None if b is None else Summary.of(b)
    if a is None or b is None or min(a.n_runs, b.n_runs) < options.min_runs:
        return Cell(row_name, band, "insufficient data", sa, sb)
    comparison, verdict = _compare(a, b, options, row, k)
    return Cell(row_name, band, "tested", sa, sb, verdict, comparison)


def _pick(traces: TraceSet, mask: np.ndarray) -> TraceSet | None:
    index = np.flatnonzero(mask)
    return take(traces, index) if index.size else None


def run_study(options: StudyOptions | None = None, *, source: str | Path | None = None,
              workers: int | None = None, scheduler: str | None = None,
              runner: Engine | None = None, progress: Progress | None = None) -> StudyResult:
    """Run the car-following study (see the module doc) and return every cell with provenance.

    Parameters
    ----------
    options : StudyOptions, optional
        Models, bands, features, test, seed...; the defaults are the documented study.
    source : path, optional
        OpenACC files (original CSV or shipped Parquet); default: the copy in ``simcred.data``.
    workers, scheduler, runner
        Where the SUMO replays run (in-process by default, or on Dask).
    progress : callable, optional
        Wraps the SUMO tasks (e.g. a progress bar).
    """
    options = options or StudyOptions()
    every = options.every
    if runner is None:
        with engine(workers, scheduler) as started:
            return run_study(options, source=source, runner=started, progress=progress)
    human = _subset(read_openacc(source, options.rules, follower=HUMAN), options.max_episodes)
    acc = _subset(read_openacc(source, options.rules, follower=ACC), options.max_episodes)
    sims = replay(human, options.models, seed=derive_seed(options.seed, _SUMO), runner=runner,
                  progress=progress)
    rows = (*BASELINES, *(f"SUMO {m}" for m in sims), REAL_ACC)
    h_band, a_band = band_index(human, options.bands), band_index(acc, options.bands)
    thinned = {"human": thin(human, every), "acc": thin(acc, every),
               **{name: thin(s, every) for name, s in sims.items()}}
    cells = []
    for k in range(len(options.bands)):
        ref = _pick(thinned["human"], h_band == k)
        cells.append(_baseline_cell(ref, options, k))
        cells.append(_car_split_cell(ref, options, k))
        for r, name in enumerate(sims, start=len(BASELINES)):
            cells.append(_cell(f"SUMO {name}", r, k, ref, _pick(thinned[name], h_band == k),
                               options))
        cells.append(_cell(REAL_ACC, len(rows) - 1, k, ref,
                           _pick(thinned["acc"], a_band == k), options))
    episodes = {"human": {"runs": human.n_runs, "cut": human.metadata["cut"]["kept"],
                          "per_band": np.bincount(h_band[h_band >= 0],
                                                  minlength=len(options.bands)).tolist(),
                          "outside_bands": int((h_band < 0).sum())},
                "acc": {"runs": acc.n_runs,
                        "per_band": np.bincount(a_band[a_band >= 0],
                                                minlength=len(options.bands)).tolist(),
                        "outside_bands": int((a_band < 0).sum())},
                "rules": asdict(options.rules),
                "cut": {"human": _cut(human), "acc": _cut(acc)}}
    return StudyResult(options, rows, tuple(cells),
                       _provenance(None if source is None else Path(source), options, human, acc,
                                   sims), episodes)


def _cut(traces: TraceSet) -> dict[str, Any]:
    return {k: v for k, v in traces.metadata["cut"].items() if k != "by_file"}


def _baseline_cell(ref: TraceSet | None, options: StudyOptions, k: int) -> Cell:
    """The band's human episodes split at random (seeded) into two halves."""
    if ref is None or ref.n_runs < 2 * options.min_runs:
        return Cell(BASELINE, options.bands[k], "insufficient data",
                    None if ref is None else Summary.of(ref), None)
    rng = np.random.default_rng(derive_seed(options.seed, _SPLIT, k))
    order = rng.permutation(ref.n_runs)
    first, second = np.sort(order[: ref.n_runs // 2]), np.sort(order[ref.n_runs // 2:])
    return _cell(BASELINE, 0, k, take(ref, first), take(ref, second), options)


def _car_split_cell(ref: TraceSet | None, options: StudyOptions, k: int) -> Cell:
    """The band's human episodes split by follower car: a seeded half of the cars vs the rest.

    Each car had its own driver, so this split keeps per-driver traits apart, unlike the random
    split; it shows how far human drivers differ among themselves.
    """
    cars = None if ref is None else [ref.metadata[RUN_INFO][r]["follower_vehicle"]
                                     for r in ref.run_ids]
    if ref is None or len(set(cars)) < 4:
        return Cell(BASELINE_CARS, options.bands[k], "insufficient data",
                    None if ref is None else Summary.of(ref), None)
    names = sorted(set(cars))
    rng = np.random.default_rng(derive_seed(options.seed, _SPLIT_CARS, k))
    first = {names[i] for i in rng.permutation(len(names))[: len(names) // 2]}
    mask = np.array([c in first for c in cars])
    return _cell(BASELINE_CARS, 1, k, take(ref, np.flatnonzero(mask)),
                 take(ref, np.flatnonzero(~mask)), options)


def repeat_baselines(seeds: Sequence[int], options: StudyOptions | None = None, *,
                     source: str | Path | None = None) -> list[Cell]:
    """The two human-vs-human baseline cells of every band for each study seed, without SUMO.

    The cells are those :func:`run_study` gives with the same options and seed (same splits, same
    test seeds); repeated over many seeds they measure how often the study's test rejects
    "human vs human" — its false-rejection rate on these data for the random split.
    """
    options = options or StudyOptions()
    human = _subset(read_openacc(source, options.rules, follower=HUMAN), options.max_episodes)
    bands = band_index(human, options.bands)
    thinned = thin(human, options.every)
    refs = [_pick(thinned, bands == k) for k in range(len(options.bands))]
    cells = []
    for seed in seeds:
        seeded = replace(options, seed=seed)
        for k, ref in enumerate(refs):
            cells += [_baseline_cell(ref, seeded, k), _car_split_cell(ref, seeded, k)]
    return cells


__all__ = ["StudyOptions", "StudyResult", "Cell", "run_study", "band_index",
           "thin", "repeat_baselines", "BASELINE", "REAL_ACC", "band_label"]
