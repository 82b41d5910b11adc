"""The experimental design of a comparison: which runs form one exchangeable unit, how units may
be reassigned under H0, and how they are resampled for intervals.

Three designs [1], [2]:

* **runs** (default): every run is a unit; under H0 the pooled units are exchangeable, so every
  split of them into sets of the observed sizes is equally likely (a permutation test).
* **groups** (``group_by``): runs that share a value of a per-run key (driver, recording, vehicle,
  the run a segment was cut from) form one unit, on its own side: whole groups are permuted, so
  dependence inside a group never counts as evidence. With few groups the test is exact but coarse
  (the smallest p-value is ``1 / C(units, units_A)``).
* **pairs** (``pair_by``): candidate unit *i* replays the scenario of reference unit *i*; under
  H0 the two members of a pair are exchangeable *within* the pair, so the null flips each pair
  independently (``2^pairs`` assignments). Scenarios may differ arbitrarily between pairs. A
  member may hold several runs (all runs of a set with the pair's key, e.g. the segments cut
  from one replayed run): whole members are flipped.

A unit key is ``"run_id"`` (the run's own id) or a key of the per-run facts
``metadata["run_info"][run_id]``. Intervals resample units with replacement within each side
(runs, groups) or whole pairs (the cluster bootstrap [3]).

References
----------
[1] Good, Permutation, Parametric, and Bootstrap Tests of Hypotheses, 3rd ed., Springer, 2005.
[2] Pesarin & Salmaso, Permutation Tests for Complex Data, Wiley, 2010 (paired and stratified
    designs).
[3] Field & Welsh, Bootstrapping clustered data, JRSS B 69, 2007.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from simcred.errors import OptionError
from simcred.traces import RUN_INFO, TraceSet

RUN_ID = "run_id"


class DesignKind(StrEnum):
    RUNS = "runs"
    GROUPS = "groups"
    PAIRS = "pairs"


@dataclass(frozen=True, slots=True, eq=False)
class Design:
    """Units of the pooled runs (A's runs first, then B's).

    ``unit_of_run[r]``: the unit of pooled run ``r``; units ``0 .. units_a - 1`` are A's. For
    pairs, unit ``i`` of A and unit ``units_a + i`` of B form pair ``i`` (``units_a`` pairs).
    ``labels``: one name per unit (group value or run id).
    """

    kind: DesignKind
    key: str | None
    unit_of_run: np.ndarray
    units_a: int
    labels: tuple[str, ...]

    @property
    def n_units(self) -> int:
        return len(self.labels)

    @property
    def observed(self) -> np.ndarray:
        """The observed assignment: True for A's units."""
        return np.arange(self.n_units) < self.units_a

    def assignments(self, permutations: int, rng: np.random.Generator) -> np.ndarray:
        """(P + 1, units) bool: row 0 the observed assignment, then P draws from the null."""
        rows = np.empty((permutations + 1, self.n_units), dtype=bool)
        rows[0] = self.observed
        if self.kind is DesignKind.PAIRS:
            flip = rng.random((permutations, self.units_a)) < 0.5
            rows[1:, :self.units_a] = ~flip
            rows[1:, self.units_a:] = flip
        else:
            pattern = np.broadcast_to(self.observed, (permutations, self.n_units))
            rows[1:] = rng.permuted(pattern, axis=1)
        return rows

    @property
    def smallest_pvalue(self) -> float:
        """The smallest p-value any permutation test on this design can give: one over the
        number of distinct assignments (0.0 when that number overflows a float)."""
        if self.kind is DesignKind.PAIRS:
            return math.ldexp(1.0, -self.units_a)
        n, k = self.n_units, self.units_a
        log_count = math.lgamma(n + 1) - math.lgamma(k + 1) - math.lgamma(n - k + 1)
        return math.exp(-log_count)

    def resamples(self, replicates: int, rng: np.random.Generator) -> np.ndarray:
        """(units, B) multiplicities of a cluster bootstrap: units drawn with replacement within
        each side, or whole pairs."""
        picks = np.empty((replicates, self.n_units), dtype=np.int64)
        n_b = self.n_units - self.units_a
        for b in range(replicates):  # the draws of one replicate after another
            if self.kind is DesignKind.PAIRS:
                picks[b, :self.units_a] = rng.integers(0, self.units_a, self.units_a)
                picks[b, self.units_a:] = picks[b, :self.units_a] + self.units_a
                continue
            picks[b, :self.units_a] = rng.integers(0, self.units_a, self.units_a)
            picks[b, self.units_a:] = self.units_a + rng.integers(0, n_b, n_b)
        picks += self.n_units * np.arange(replicates)[:, None]
        counts = np.bincount(picks.ravel(), minlength=replicates * self.n_units)
        return counts.reshape(replicates, self.n_units).T.astype(np.float64)


def build_design(a: TraceSet, b: TraceSet, *, pair_by: str | None = None,
                 group_by: str | None = None) -> Design:
    """The design of comparing ``a`` with ``b``; one-line error on keys that do not fit."""
    if pair_by is not None and group_by is not None:
        raise OptionError("pair-by and group-by cannot be combined: pair whole groups by giving "
                          "each group's runs one pair key, or choose one design")
    if pair_by is not None:
        return _paired(a, b, pair_by)
    if group_by is not None:
        return _grouped(a, b, group_by)
    return runs_design(a.n_runs, b.n_runs)


def runs_design(runs_a: int, runs_b: int) -> Design:
    """Every run its own unit."""
    labels = tuple(f"A:{i}" for i in range(runs_a)) + tuple(f"B:{i}" for i in range(runs_b))
    return Design(DesignKind.RUNS, None, np.arange(runs_a + runs_b), runs_a, labels)


def unit_keys(traces: TraceSet, key: str, option: str) -> list[str]:
    """Per run, its value of ``key`` as text: ``run_id``, a ``run_info`` key, or a signal that
    is constant within every run (a column naming the driver, the recording, the pair)."""
    if key == RUN_ID:
        return list(traces.run_ids)
    info = traces.metadata.get(RUN_INFO)
    if isinstance(info, Mapping) and all(isinstance(info.get(r), Mapping) and key in info[r]
                                         for r in traces.run_ids):
        return [str(info[r][key]) for r in traces.run_ids]
    if key in traces.signals:
        return _column_keys(traces, key, option)
    if not isinstance(info, Mapping):
        raise OptionError(f"{option} {key!r}: {traces.source} has no per-run facts "
                          f"(metadata '{RUN_INFO}') and no signal {key!r}; use run_id, a "
                          "signal constant within each run, or add the key per run")
    run = next(r for r in traces.run_ids if not isinstance(info.get(r), Mapping)
               or key not in info[r])
    raise OptionError(f"{option} {key!r}: {traces.source}, run {run!r} has no {key!r} "
                      f"in its per-run facts (and {key!r} is not a signal)")


def _column_keys(traces: TraceSet, key: str, option: str) -> list[str]:
    """Per run, the value of the signal ``key``, which must not change within the run."""
    column = traces.values[:, traces.signals.index(key)]
    out = []
    for i, run in enumerate(traces.run_ids):
        part = column[traces.offsets[i]:traces.offsets[i + 1]]
        if part.size and not np.all((part == part[0]) | (np.isnan(part) & np.isnan(part[0]))):
            row = int(np.flatnonzero(part != part[0])[0])
            raise OptionError(f"{option} {key!r}: {traces.source}, run {run!r}: the signal "
                              f"changes within the run (row {row}: {part[row]!r} after "
                              f"{part[0]!r}); a unit key must be constant per run")
        out.append(repr(float(part[0])) if part.size else "")
    return out


def _grouped(a: TraceSet, b: TraceSet, key: str) -> Design:
    unit_of_run, labels = [], []
    for side, traces in (("A", a), ("B", b)):
        keys = unit_keys(traces, key, "group-by")
        names = list(dict.fromkeys(keys))  # order of first appearance
        index = {name: len(labels) + i for i, name in enumerate(names)}
        unit_of_run += [index[k] for k in keys]
        labels += [f"{side}:{name}" for name in names]
    units_a = len(set(unit_keys(a, key, "group-by")))
    if units_a < 2 or len(labels) - units_a < 2:
        raise OptionError(f"group-by {key!r}: each set needs at least 2 groups "
                          f"({a.source}: {units_a}, {b.source}: {len(labels) - units_a})")
    return Design(DesignKind.GROUPS, key, np.asarray(unit_of_run), units_a, tuple(labels))


def _paired(a: TraceSet, b: TraceSet, key: str) -> Design:
    keys_a, keys_b = unit_keys(a, key, "pair-by"), unit_keys(b, key, "pair-by")
    names = list(dict.fromkeys(keys_a))  # pairs in order of first appearance in A
    set_a, set_b = set(keys_a), set(keys_b)
    missing_b = [k for k in names if k not in set_b]
    missing_a = list(dict.fromkeys(k for k in keys_b if k not in set_a))
    if missing_b or missing_a:
        where, k = (b.source, missing_b[0]) if missing_b else (a.source, missing_a[0])
        raise OptionError(f"pair-by {key!r}: {where} has no partner for {k!r} "
                          f"({len(missing_b) + len(missing_a)} unmatched)")
    if len(names) < 2:
        raise OptionError(f"pair-by {key!r}: at least 2 pairs are needed, got {len(names)}")
    position = {k: i for i, k in enumerate(names)}
    unit_of_run = np.r_[[position[k] for k in keys_a],
                        [len(names) + position[k] for k in keys_b]].astype(np.int64)
    labels = tuple(f"A:{k}" for k in names) + tuple(f"B:{k}" for k in names)
    return Design(DesignKind.PAIRS, key, unit_of_run, len(names), labels)
