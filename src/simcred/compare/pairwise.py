"""Distance matrix of N trace sets (as Table 3 of Neurohr et al. 2023 [1])."""

from __future__ import annotations

import csv
import io
from collections import Counter
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from itertools import combinations
from pathlib import Path
from typing import Any

import numpy as np

import simcred._display as _display
from simcred._json import dumps, envelope
from simcred.compare import sorted_sets
from simcred.compare.facts import SetFacts
from simcred.compare.method import Method
from simcred.compare.process import Prepared, compare_prepared, comparison_options, load
from simcred.compare.result import Comparison, ComparisonOptions
from simcred.compare.run_level import assignment_draw
from simcred.compare.sorted_sets import SortedSet
from simcred.compare.tables import matrix_frame
from simcred.engine import Engine, Progress, balanced, engine
from simcred.errors import OptionError, TraceSetError
from simcred.traces import TraceSet


@dataclass(frozen=True, slots=True, eq=False)
class DistanceMatrix:
    """Pairwise distances ([1] eq. (6)) of ``names``; NaN where a pair stopped at the start test.

    The diagonal is 0 by construction (a set compared with itself has identical successor
    distributions, so no test rejects) and is not computed. The matrix is symmetric: each pair
    ``i < j`` is compared once, as ``compare(sets[i], sets[j])``.
    """

    names: tuple[str, ...]
    distances: np.ndarray
    comparisons: tuple[Comparison, ...]

    @property
    def pairs(self) -> list[tuple[int, int]]:
        return list(combinations(range(len(self.names)), 2))

    def to_dict(self) -> dict[str, Any]:
        first = self.comparisons[0]
        options = asdict(first.options)
        inputs = [asdict(first.inputs[0])] + [asdict(c.inputs[1]) for c in
                                              self.comparisons[: len(self.names) - 1]]
        body = {
            "names": list(self.names),
            "inputs": inputs,
            "options": options,
            "distances": [[None if np.isnan(v) else float(v) for v in row]
                          for row in self.distances],
            "pairs": [_pair_summary(self.names, ij, c) for ij, c in
                      zip(self.pairs, self.comparisons, strict=True)],
        }
        return envelope("distance_matrix", body)

    def to_json(self) -> str:
        return dumps(self.to_dict())

    def to_pandas(self):
        """The matrix as a square ``pandas.DataFrame`` indexed by the names (NaN: stopped)."""
        return matrix_frame(self)

    def _repr_html_(self) -> str:
        """Notebook display: a summary table and a figure (:mod:`simcred.report.notebook`)."""
        return _display.html(self)

    def to_csv(self) -> str:
        """The table as CSV: a header of names, one row per set, empty cells where stopped."""
        buffer = io.StringIO()
        writer = csv.writer(buffer, lineterminator="\n")
        writer.writerow(["", *self.names])
        for name, row in zip(self.names, self.distances, strict=True):
            writer.writerow([name, *("" if np.isnan(v) else repr(float(v)) for v in row)])
        return buffer.getvalue()


def _pair_summary(names, ij, c: Comparison) -> dict[str, Any]:
    i, j = ij
    return {"a": names[i], "b": names[j], "distance": c.distance, "stopped": c.stopped,
            "start_rejected": c.start.rejected, "n_states": c.n_states,
            "n_tested": len(c.states), "n_rejected": len(c.rejected_states),
            "n_untestable": len(c.untestable)}


def matrix(
    sets: Sequence[TraceSet | str | Path],
    method: Method | None = None,
    *,
    names: Sequence[str] | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    runner: Engine | None = None,
    progress: Progress | None = None,
    **options: Any,
) -> DistanceMatrix:
    """Compare every pair of ``sets`` with :func:`simcred.compare.compare` and ``method`` (or
    the :class:`~simcred.compare.method.Method` that ``options`` build or replace fields of).

    Pairs run in-process, on a local Dask cluster of ``workers`` processes, on the Dask
    ``scheduler`` at an address, or on an already started ``runner``. ``seed`` is resolved once,
    so every pair uses the same entropy (each pair's tests then draw from per-state streams, see
    :func:`compare`); the result is the same wherever the pairs run.

    Data go to the work once: every set is read (a path: by the worker itself) and prepared once,
    on one worker, and stays there; only its facts (signals, runs, sample period) come back for
    the option checks. For the run-level test (first order, no time windows or resampling) a
    set is also sorted and sketched once, and each pair is compared from its sets' parts
    (:mod:`simcred.compare.sorted_sets`): the tasks that tally and count a set run where it is
    held, and only sketches, tallies and one set's per-run counts move (2.8 MB per pair instead
    of 25 at 6,000 runs × 200 steps). Other options: a pair's task receives its two prepared
    sets. Either way what travels per pair does not grow with the number of sets
    (docs/benchmarks.md, scaling).

    >>> from simcred.examples import lane_change_sets
    >>> a, b = lane_change_sets(runs=40, steps=30, seed=2)
    >>> m = matrix([a, b, a], names=["a", "b", "a2"], features=["y"], bins=4)
    >>> m.distances.shape, float(m.distances[0, 2])
    ((3, 3), 0.0)
    """
    method = Method.of(method, **options)
    for given in sets:  # a stat, not a read: the workers read the files
        if not isinstance(given, TraceSet) and not Path(given).exists():
            raise TraceSetError(f"{given}: no such file or directory")
    if len(sets) < 2:
        raise OptionError(f"a distance matrix needs at least 2 trace sets, got {len(sets)}")
    if runner is None:
        with engine(workers, scheduler) as started:
            return matrix(sets, method, names=names, runner=started, progress=progress)
    # a path is read where it is used, by a task that can run again (a dead worker's sets are
    # read anew); sets in memory are sent once (scattered: lost with their worker)
    in_memory = [k for k, given in enumerate(sets) if isinstance(given, TraceSet)]
    placed = dict(zip(in_memory, runner.put([sets[k] for k in in_memory]) if in_memory else [],
                      strict=True))
    loaded = runner.keep(load, [placed.get(k, given) for k, given in enumerate(sets)])
    facts = runner.fetch(runner.keep(SetFacts.of, loaded))
    labels = tuple(names) if names is not None else tuple(_default_names(facts))
    if len(labels) != len(facts) or len(set(labels)) != len(labels):
        raise OptionError(f"names must be {len(facts)} unique labels, got {list(labels)}")
    settings = comparison_options(facts, method)
    split = sorted_sets.supports(settings)
    prepared = runner.keep(_prepare_sorted if split else _prepare,
                           [(traces, settings) for traces in loaded])
    del loaded  # on Dask: the workers drop the raw sets
    pairs = list(combinations(range(len(facts)), 2))
    if split:
        draws = _shared_draws(runner, [(facts[i].n_runs, facts[j].n_runs) for i, j in pairs],
                              settings)
        comparisons = _split_pairs(runner, prepared, pairs, settings, progress, draws) \
            if runner.distributed else runner.map(
                _compare_sorted, [(prepared[i], prepared[j], settings, draw)
                                  for (i, j), draw in zip(pairs, draws, strict=True)],
                progress=progress)
    else:
        comparisons = runner.map(_compare_pair,
                                 [(prepared[i], prepared[j], settings) for i, j in pairs],
                                 progress=progress)
    distances = np.zeros((len(facts), len(facts)))
    for (i, j), c in zip(pairs, comparisons, strict=True):
        distances[i, j] = distances[j, i] = np.nan if c.distance is None else c.distance
    return DistanceMatrix(labels, distances, tuple(comparisons))


def _prepare(item: tuple[TraceSet, ComparisonOptions]) -> Prepared:
    traces, settings = item
    return Prepared.for_options(traces, settings)


def _compare_pair(item: tuple[Prepared, Prepared, ComparisonOptions]) -> Comparison:
    return compare_prepared(*item)


def _prepare_sorted(item: tuple[TraceSet, ComparisonOptions]) -> SortedSet:
    return SortedSet.of(_prepare(item), item[1].bins)


def _compare_sorted(item: tuple[SortedSet, SortedSet, ComparisonOptions, Any]) -> Comparison:
    return sorted_sets.compare_sorted(*item)


def _shared_draws(runner: Engine, sizes: list[tuple[int, int]], settings: ComparisonOptions
                  ) -> list[Any]:
    """Per pair of sets of ``sizes`` runs, a handle of its test's permutations where another
    pair has the same sizes (every pair's test draws them from the same seed stream, so pairs
    of one size draw the same rows: drawn once, :class:`~simcred.compare.runs.AssignmentDraw`),
    else None (the pair draws its own)."""
    shared = sorted(size for size, n in Counter(sizes).items() if n > 1)
    handles = dict(zip(shared, runner.keep(_draw, [(n_a, n_a + n_b, settings)
                                                   for n_a, n_b in shared]), strict=True))
    return [handles.get(size) for size in sizes]


def _draw(item: tuple[int, int, ComparisonOptions]):
    return assignment_draw(*item)


def _split_pairs(runner: Engine, held: list[Any], pairs: list[tuple[int, int]],
                 settings: ComparisonOptions, progress: Progress | None,
                 draws: list[Any]) -> list[Comparison]:
    """Every pair where its sets are held (:mod:`simcred.compare.sorted_sets`): a pair whose
    two sets one worker holds is compared there in one task; of any other pair one set is
    counted where it is held, and the pair tested where the other set is (the tests spread
    evenly over the workers), so only sketches, tallies and one set's counts move."""
    where = runner.holders(held)
    tested = balanced([sorted({where[i], where[j]} - {None}) for i, j in pairs])
    here = [0 if w is None or w == where[i] else 1 for w, (i, j) in zip(tested, pairs,
                                                                          strict=True)]
    split = [k for k, (i, j) in enumerate(pairs) if where[i] is None or where[i] != where[j]]
    sketches = runner.keep(_sketches, held)
    plans = {k: (sketches[pairs[k][0]], sketches[pairs[k][1]], settings) for k in split}
    tallies = [runner.keep(_tallies, [(held[pairs[k][s]], *plans[k]) for k in split],
                           [held[pairs[k][s]] for k in split])
               for s in (0, 1)]
    counted = dict(zip(split, zip(*tallies, strict=True), strict=True))
    there = [held[pairs[k][1 - here[k]]] for k in split]
    sides = dict(zip(split, runner.keep(
        _pair_side, [(h, *counted[k], *plans[k]) for h, k in zip(there, split, strict=True)],
        there), strict=True))
    items = [(held[ij[0]], held[ij[1]], settings, draws[k]) if k not in sides
             else (held[ij[here[k]]], (here[k], sides[k], *counted[k], *plans[k]), settings,
                   draws[k])
             for k, ij in enumerate(pairs)]
    return runner.map(_finish, items, progress=progress,
                      near=[held[ij[here[k]]] for k, ij in enumerate(pairs)])


def _finish(item) -> Comparison:
    """A pair's comparison on a worker holding ``side`` (its first set, or the one at
    ``position``): with its second set held there too, or from the other set's counts."""
    side, other, settings, draw = item
    if isinstance(other, SortedSet):
        return sorted_sets.compare_sorted(side, other, settings, draw)
    position, counts, first, second, *plan = other
    mine = sorted_sets.pair_side(side, _plan(*plan), first, second)
    return sorted_sets.pair_comparison(*((mine, counts) if position == 0 else (counts, mine)),
                                       settings, draw)


def _sketches(side: SortedSet):
    return side.sketches


def _plan(sketches_a, sketches_b, settings: ComparisonOptions) -> sorted_sets.PairPlan:
    return sorted_sets.PairPlan.of(sketches_a, sketches_b, settings.bins)


def _tallies(item) -> sorted_sets.Tallies:
    side, *plan = item
    return _plan(*plan).tallies(side)


def _pair_side(item) -> sorted_sets.PairSide:
    side, first, second, *plan = item
    return sorted_sets.pair_side(side, _plan(*plan), first, second)


def _default_names(sets: Sequence[SetFacts]) -> list[str]:
    stems = [Path(s.source).stem or s.source for s in sets]
    return stems if len(set(stems)) == len(stems) else [f"{i}:{s}" for i, s in enumerate(stems)]
