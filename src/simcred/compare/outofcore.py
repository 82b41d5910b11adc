"""The run-level comparison of trace sets that do not fit in memory, partition by partition.

Neurohr et al. 2023 [1], sec. V-A on Parquet data sets (:mod:`simcred.io.dataset`): the result
is the one :func:`~simcred.compare.process.compare` gives on the same runs in memory, byte for
byte in JSON, while at most one partition's rows are held at a time. Three passes over the
partitions of both sets:

1. read and validate every partition (as :class:`~simcred.traces.TraceSet` does, naming the
   partition); per feature a mergeable :class:`~simcred.compare.quantiles.Sketch` of the pooled
   values, per set one of the time steps within runs; run ids and lengths;
2. per feature the :class:`~simcred.compare.quantiles.Tally` that makes the quantiles exact, per
   set the one of the median time step (the sample-period check); the content hash's time part;
3. every partition encoded on the candidate edges (distinct quantiles), its per-run pair counts
   (``RunCounts``' entries, its runs given global indices) and per-bin counts of every feature
   (``feature_edges``' second amendment drops the edges whose left bin is empty: a relabelling
   of bins that keeps the order of every state, so counts and columns carry over); the content
   hash's value part.

The pooled count matrix then goes through the same run-level test as in memory
(:func:`~simcred.compare.run_level.counts_comparison`). Memory: one partition, the sketches and
tallies (about ``2 N / SKETCH_SIZE`` values per edge), the run ids and lengths, and the count
matrix: 8 bytes per non-zero (run, state, successor) entry (int32 run, float32 count), plus 2 to
8 bytes per entry while the partitions' entries are sorted into it; then the run-level test's
own arrays (among them one bit per run and permutation).

Supported: ``test="runs"`` with ``history=1``, no ``time_bins``, no ``resample``, no
``relevance``; other options are refused with one line (:data:`SUPPORTED`).

References
----------
[1] Neurohr et al., Determining the Validity of Simulation Models for the Verification of ADSs,
    IEEE Access, 2023.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse as sp

from simcred.compare.discretize import StateSpace, _check_size
from simcred.compare.facts import SetFacts
from simcred.compare.method import Method
from simcred.compare.quantiles import EdgePlan, Sketch, Tally
from simcred.compare.resample import within_run_steps
from simcred.compare.result import Comparison, InputInfo
from simcred.compare.run_counts import RunCounts, count_dtype, relabelled_keys
from simcred.compare.run_level import counts_comparison
from simcred.engine import Progress
from simcred.errors import OptionError
from simcred.io.dataset import ParquetDataset, is_dataset
from simcred.traces import TraceSet

SUPPORTED = ("trace sets read out of core (Parquet data sets) support the runs test "
             "(--test runs) with history 1, no time bins, no resampling and no relevance")
#: Largest pair-key space of the candidate grid: keys ``(from + 1) · |S| + to`` stay in int64.
MAX_CANDIDATE_STATES = 2**31


def compare_datasets(
    a: TraceSet | str | os.PathLike,
    b: TraceSet | str | os.PathLike,
    method: Method | None = None,
    *,
    progress: Progress | None = None,
    **options: Any,
) -> Comparison:
    """:func:`simcred.compare.compare` on data sets read partition by partition.

    Parameters
    ----------
    a, b : TraceSet or path
        A Parquet data set (folder, glob or URI; :mod:`simcred.io.dataset`), or a trace set in
        memory or any other path (read with :meth:`TraceSet.read`: one partition).
    method : Method, optional
        How to compare (:class:`~simcred.compare.method.Method`); see :data:`SUPPORTED`.
    progress : callable, optional
        Wraps the partitions (three passes over both sets), e.g. a progress bar.
    **options
        Fields of the method as keywords, as :func:`simcred.compare.compare` takes them.

    Returns
    -------
    Comparison
        The same as ``compare`` on the runs in memory.
    """
    from simcred.compare.process import (
        comparison_options,
        resolve_bins,
        resolve_features,
        with_units,
    )

    method = Method.of(method, **options)
    _refuse(method)
    sources = [_Source.open(x) for x in (a, b)]
    provisional = [s.provisional() for s in sources]
    comparison_options(provisional, method)  # before any pass
    names = resolve_features(provisional, method.features)
    bins = resolve_bins(method.bins, len(names))
    work = _Passes(sources, names, bins)
    steps = work.run()
    for _ in progress(steps, work.total) if progress else steps:
        pass
    facts = [s.facts() for s in sources]
    validated = comparison_options(facts, method)
    space, counts = work.result()
    inputs = tuple(s.input_info() for s in sources)
    return with_units(counts_comparison(counts, facts[0].n_runs, space, validated, inputs),
                      *facts)


def _refuse(method: Method) -> None:
    given = [name for name, bad in (
        ("test", method.test != "runs"), ("history", method.history != 1),
        ("time_bins", method.time_bins is not None),
        ("resample", method.resample is not None), ("relevance", method.relevance),
        ("inputs", bool(method.inputs)), ("pair_by", method.pair_by is not None),
        ("group_by", method.group_by is not None),
        ("margin", method.margin is not None)) if bad]
    if given:
        raise OptionError(f"{SUPPORTED}; got {', '.join(given)}")


@dataclass(eq=False)
class _Source:
    """One side: its partitions (a data set, or one trace set in memory) and what the passes
    learn about it."""

    source: str
    signals: tuple[str, ...]
    dataset: ParquetDataset | None
    traces: TraceSet | None
    run_ids: list[str] = field(default_factory=list)
    lengths: list[np.ndarray] = field(default_factory=list)
    metadata: Mapping[str, Any] | None = None
    steps: Sketch = field(default_factory=lambda: Sketch.empty(1))
    step_brackets: Any = None
    step_tally: Tally | None = None
    period: float = float("nan")
    hash: Any = None

    @classmethod
    def open(cls, given: TraceSet | str | os.PathLike) -> _Source:
        """A data set, or any other trace set (read in memory: one partition)."""
        if not isinstance(given, TraceSet) and not is_dataset(given):
            given = TraceSet.read(given)
        if isinstance(given, TraceSet):
            return cls(given.source, given.signals, None, given)
        dataset = ParquetDataset.open(given)
        return cls(dataset.source, dataset.signals, dataset, None)

    @property
    def n_partitions(self) -> int:
        return 1 if self.dataset is None else sum(1 for r in self.dataset.rows if r)

    def partitions(self) -> Iterator[TraceSet]:
        if self.dataset is None:
            yield self.traces
            return
        for _, part in self.dataset.partitions():
            yield part

    @property
    def n_runs(self) -> int:
        return sum(len(x) for x in self.lengths)

    def provisional(self) -> SetFacts:
        """Facts before any pass, for checking the options early: as many runs as there can
        be (two rows each), the sample period unknown (NaN passes the period check)."""
        rows = self.traces.n_rows if self.dataset is None else self.dataset.n_rows
        return SetFacts(self.source, self.signals, rows // 2, {}, float("nan"))

    def facts(self) -> SetFacts:
        units = TraceSet.units.fget(self) if self.metadata else {}  # validated as TraceSet's
        return SetFacts(self.source, self.signals, self.n_runs, units, self.period)

    def input_info(self) -> InputInfo:
        rows = int(sum(int(x.sum()) for x in self.lengths))
        return InputInfo(self.source, "sha256:" + self.hash.hexdigest(), self.n_runs, rows)


class _Passes:
    """The three passes over both sets (a generator of one step per partition)."""

    def __init__(self, sources: list[_Source], names: Sequence[str], bins: Sequence[int]):
        self.sources, self.names, self.bins = sources, tuple(names), tuple(bins)
        self.total = 3 * sum(s.n_partitions for s in sources)
        self.sketches = [Sketch.empty(b) for b in bins]
        self.plans: list[EdgePlan] = []
        self.tallies: list[Tally | None] = []
        self.candidates: list[np.ndarray] = []
        self.held: list[np.ndarray] = []
        self.blocks: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []
        self.shape: tuple[int, ...] = ()

    def run(self) -> Iterator[None]:
        for source in self.sources:
            for part in source.partitions():
                self._first(source, part)
                yield None
        self._plan()
        for source in self.sources:
            source.hash = hashlib.sha256()
            source.hash.update(json.dumps([list(source.signals), source.run_ids]).encode())
            source.hash.update(np.r_[0, np.cumsum(np.concatenate(source.lengths))]
                               .astype(np.int64).tobytes())
            source.step_brackets = source.steps.brackets(_middle(source.steps.count))
            source.step_tally = source.step_brackets.empty_tally()
            for part in source.partitions():
                self._second(source, part)
                yield None
            self._period(source)
        self._candidates()
        first_run = 0
        for source in self.sources:
            for part in source.partitions():
                self._third(source, part, first_run)
                first_run += part.n_runs
                yield None

    # -- pass 1 ------------------------------------------------------------------------------

    def _first(self, source: _Source, part: TraceSet) -> None:
        if source.metadata is None:
            source.metadata = dict(part.metadata)
        source.run_ids.extend(part.run_ids)
        source.lengths.append(part.lengths.astype(np.int64))
        values = part.features(self.names)
        for j, b in enumerate(self.bins):
            self.sketches[j] = self.sketches[j].merge(Sketch.of(values[:, j], cap=b))
        source.steps = source.steps.merge(Sketch.of(within_run_steps(part), cap=1))

    def _plan(self) -> None:
        self.plans = [EdgePlan.of(s, b) for s, b in zip(self.sketches, self.bins, strict=True)]
        self.tallies = [p.brackets.empty_tally() if p.needs_counts else None
                        for p in self.plans]

    # -- pass 2 ------------------------------------------------------------------------------

    def _second(self, source: _Source, part: TraceSet) -> None:
        source.hash.update(part.time.tobytes())
        values = part.features(self.names)
        for j, plan in enumerate(self.plans):
            if plan.needs_counts:
                self.tallies[j] = self.tallies[j].merge(plan.brackets.tally(values[:, j]))
        source.step_tally = source.step_tally.merge(
            source.step_brackets.tally(within_run_steps(part)))

    def _period(self, source: _Source) -> None:
        middle = source.step_tally.order_statistics(source.step_brackets)
        source.period = float(np.mean(middle)) if len(middle) == 2 else float(middle[0])

    def _candidates(self) -> None:
        self.candidates = [p.candidates(t) for p, t in zip(self.plans, self.tallies, strict=True)]
        self.held = [np.zeros(len(c) + 1, dtype=np.int64) for c in self.candidates]
        self.shape = tuple(len(c) + 1 for c in self.candidates)
        if int(np.prod(self.shape, dtype=np.float64)) > MAX_CANDIDATE_STATES:
            raise OptionError(f"state space of {int(np.prod(self.shape, dtype=np.float64))} "
                              f"states is too large (at most {MAX_CANDIDATE_STATES}); use "
                              "fewer features or bins")

    # -- pass 3 ------------------------------------------------------------------------------

    def _third(self, source: _Source, part: TraceSet, first_run: int) -> None:
        source.hash.update(part.values.tobytes())
        values = part.features(self.names)
        columns = []
        for j, edges in enumerate(self.candidates):
            column = np.searchsorted(edges, values[:, j], side="right")
            self.held[j] += np.bincount(column, minlength=len(edges) + 1)
            columns.append(column.astype(np.int32))
        codes = np.ravel_multi_index(tuple(columns), self.shape).astype(np.int64, copy=False)
        self.blocks.append(_partition_pairs(codes, part.offsets, int(np.prod(self.shape))))

    # -- result ------------------------------------------------------------------------------

    def result(self) -> tuple[StateSpace, RunCounts]:
        """The state space (final edges) and the pooled per-run counts on it."""
        kept = [p.kept(c, h) for p, c, h in zip(self.plans, self.candidates, self.held,
                                                  strict=True)]
        edges = tuple(c[k] for c, k in zip(self.candidates, kept, strict=True))
        bounds = tuple((float(s.minimum), float(s.maximum)) for s in self.sketches)
        space = StateSpace(self.names, edges, bounds)
        _check_size(space)
        keys, matrix = _pooled_matrix(self.blocks)
        self.blocks = []
        keys = relabelled_keys(keys, self.shape, kept, space.shape)
        return space, RunCounts.from_matrix(matrix, keys, space.n_states)


def _middle(n: int) -> np.ndarray:
    """The ranks numpy.median averages: one for an odd count, two for an even one."""
    return np.unique([(n - 1) // 2, n // 2])


def _partition_pairs(codes: np.ndarray, offsets: np.ndarray, n_states: int):
    """One partition's per-run pair counts, as ``RunCounts.from_codes`` keys them: (distinct
    keys, per entry its key's index, per entry its count, per run its number of entries);
    entries sorted by (run, key), in the smallest integer types that hold them."""
    size = np.int64(n_states)
    n_runs = len(offsets) - 1
    last = offsets[1:] - 1
    keys = (codes[:-1] + 1) * size + codes[1:]
    keys[last[:-1]] = -1
    keys = np.concatenate([codes[offsets[:-1]], keys[keys >= 0]])
    runs = np.concatenate([np.arange(n_runs, dtype=np.int64),
                           np.repeat(np.arange(n_runs, dtype=np.int64), np.diff(offsets) - 1)])
    distinct, inverse = np.unique(keys, return_inverse=True)
    del keys
    entry, count = np.unique(runs * len(distinct) + inverse.ravel(), return_counts=True)
    run_of, key_of = np.divmod(entry, len(distinct))
    per_run = np.bincount(run_of, minlength=n_runs)
    return (distinct, key_of.astype(np.min_scalar_type(len(distinct))),
            count.astype(np.min_scalar_type(int(count.max()))), per_run.astype(np.int64))


def _pooled_matrix(blocks: list) -> tuple[np.ndarray, sp.csr_matrix]:
    """Sorted distinct keys and the (keys × runs) CSR matrix of all partitions' entries, as
    ``RunCounts.from_codes`` builds it (entries sorted by (key, run), counts in its dtype:
    float32 below 2**24).

    A counting sort by key, partition by partition: the output arrays (8 bytes per entry: int32
    run, float32 count) are filled while the partitions' compact entries are released.
    """
    keys = np.unique(np.concatenate([b[0] for b in blocks]))
    where = [np.searchsorted(keys, b[0]) for b in blocks]
    totals = np.zeros(len(keys), dtype=np.int64)
    for w, (_, key_of, _, _) in zip(where, blocks, strict=True):
        totals += np.bincount(w[key_of], minlength=len(keys))
    indptr = np.r_[0, np.cumsum(totals)]
    n_runs = int(sum(len(b[3]) for b in blocks))
    run_index = np.int32 if n_runs < 2**31 else np.int64
    indices = np.empty(int(indptr[-1]), dtype=run_index)
    largest = np.array([max((int(b[2].max()) for b in blocks if len(b[2])), default=0)])
    data = np.empty(int(indptr[-1]), dtype=count_dtype(largest))
    cursor = indptr[:-1].copy()
    first_run = 0
    for i, w in enumerate(where):
        _, key_of, count, per_run = blocks[i]
        blocks[i] = None  # released as it is placed
        column = w[key_of]
        order = np.argsort(column, kind="stable")  # within a key: runs stay in order
        column = column[order]
        rank = np.arange(len(column)) - np.searchsorted(column, column, side="left")
        at = cursor[column] + rank
        runs = np.repeat(np.arange(first_run, first_run + len(per_run), dtype=run_index),
                         per_run)
        indices[at] = runs[order]
        data[at] = count[order]
        cursor += np.bincount(column, minlength=len(keys))
        first_run += len(per_run)
    return keys, sp.csr_matrix((data, indices, indptr), shape=(len(keys), n_runs))
