"""Simulated data sets for the plan: design units drawn with replacement from observed ones.

Each drawn copy is renamed to be a unit of its own (run ids ``<tag><j>:<run>``, its unit key
``<tag><j>``), so a unit drawn twice counts as two units of the design, as a new episode of the
same kind would.
"""

from __future__ import annotations

import numpy as np

from simcred.compare.design import unit_keys
from simcred.regions.cells import SOURCE_RUN
from simcred.traces import RUN_INFO, TraceSet, concat, take


def draw_units(traces: TraceSet, key: str, n: int, rng: np.random.Generator, tag: str
               ) -> TraceSet:
    """``n`` units of ``key`` (a per-run key of the segments) drawn with replacement."""
    runs_of = _runs_of(traces, key, "groups")
    names = sorted(runs_of)
    picks = [(traces, runs_of[names[i]]) for i in rng.integers(0, len(names), n)]
    return _renamed(picks, key, tag, traces.metadata)


def draw_pairs(reference: TraceSet, candidate: TraceSet, key: str, n: int,
               rng: np.random.Generator) -> tuple[TraceSet, TraceSet]:
    """``n`` pairs of ``key`` (keys present on both sides) drawn with replacement, the two
    members of each drawn pair swapped with probability 1/2: the two sides then follow one law
    (a candidate exactly as good as the reference) while each pair keeps its scenario and the
    dependence of its members."""
    ref, cand = _runs_of(reference, key, "pairs"), _runs_of(candidate, key, "pairs")
    names = sorted(set(ref) & set(cand))
    picks = rng.integers(0, len(names), n)
    swap = rng.random(n) < 0.5
    members = [((reference, ref[names[i]]), (candidate, cand[names[i]])) for i in picks]
    side_a = [c if s else r for (r, c), s in zip(members, swap, strict=True)]
    side_b = [r if s else c for (r, c), s in zip(members, swap, strict=True)]
    return (_renamed(side_a, key, "p", reference.metadata),
            _renamed(side_b, key, "p", candidate.metadata))


def _runs_of(traces: TraceSet, key: str, option: str) -> dict[str, list[int]]:
    out: dict[str, list[int]] = {}
    for i, k in enumerate(unit_keys(traces, key, option)):
        out.setdefault(k, []).append(i)
    return out


def _renamed(picks: list[tuple[TraceSet, list[int]]], key: str, tag: str,
             metadata: dict) -> TraceSet:
    """The runs of every pick, as unit ``<tag><j>`` (also its source run, the segments' unit)."""
    parts, info = [], {}
    for j, (traces, runs) in enumerate(picks):
        part = take(traces, runs)
        ids = tuple(f"{tag}{j}:{r}" for r in part.run_ids)
        for new, old in zip(ids, part.run_ids, strict=True):
            info[new] = {**part.metadata[RUN_INFO][old], key: f"{tag}{j}",
                         SOURCE_RUN: f"{tag}{j}"}
        parts.append(TraceSet(part.signals, part.time, part.values, part.offsets, ids,
                              {}, part.source))
    return concat(parts, metadata={**metadata, RUN_INFO: info})
