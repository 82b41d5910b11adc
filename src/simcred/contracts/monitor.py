"""Monitors of contracts over recorded runs (paper 003, sec. V-D).

Every clause of a contract is evaluated over all rows of a :class:`TraceSet` at once (numpy):
assumption clauses say where a model was used outside its validity domain; guarantee clauses are
checked where the assumption holds (the saturated guarantee A → g). Each violation is reported as
in ASAM osi-validation style: contract, kind, clause, variables, run, time range (first and last
step) and margin — the signed distance to satisfaction (negative: by how much it is violated).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import asdict, dataclass

import numpy as np

from simcred._json import dumps, envelope
from simcred.contracts.algebra import Contract
from simcred.contracts.evaluate import evaluate, margin
from simcred.contracts.expr import Expr, conjuncts, implies, to_text, variables
from simcred.contracts.temporal import Timeline
from simcred.errors import SimcredError
from simcred.traces import TraceSet


@dataclass(frozen=True, slots=True)
class Violation:
    contract: str
    kind: str  # "assumption" (outside the validity domain) or "guarantee"
    clause: str
    variables: tuple[str, ...]
    run: str
    first_step: int
    last_step: int
    t_start: float
    t_end: float
    margin: float  # most negative margin within the range


@dataclass(frozen=True, slots=True)
class MonitorReport:
    source: str
    runs: int
    samples: int
    clauses: int
    violations: tuple[Violation, ...]
    not_monitored: tuple[str, ...] = ()  # "contract: clause" over variables no run carries

    @property
    def passed(self) -> bool:
        return not self.violations

    def to_json(self) -> str:
        body = {"source": self.source, "runs": self.runs, "samples": self.samples,
                "clauses_checked": self.clauses, "passed": self.passed,
                "violations": [asdict(v) for v in self.violations],
                "not_monitored": list(self.not_monitored)}
        return dumps(envelope("monitor_report", body))


def monitor(traces: TraceSet, contracts: Mapping[str, Contract], *, tolerance: float = 0.0,
            unobserved: frozenset[str] = frozenset()) -> MonitorReport:
    """Evaluate every clause of ``contracts`` over ``traces`` (signals named as the variables).

    A sample violates a clause where the clause is false and its margin is below
    ``-tolerance`` (default 0: every violation counts; a small tolerance absorbs rounding in
    signals that sit exactly on a domain's boundary, e.g. accelerations by differentiation).

    ``unobserved``: variables no run carries (a library's ``observed: false``, e.g. the learned
    contracts' ``distance``). Guarantee clauses over them cannot be monitored: they are named in
    ``not_monitored`` instead of checked; an assumption clause over them is an error (the
    validity domain itself could not be checked).
    """
    skipped = tuple(f"{name}: {to_text(clause)}" for name, contract in contracts.items()
                    for kind, clause, _ in _clauses(contract)
                    if kind == "guarantee" and variables(clause) & unobserved)
    columns = _columns(traces, contracts, unobserved)
    timeline = Timeline(np.asarray(traces.time, dtype=float), np.asarray(traces.offsets))
    found: list[Violation] = []
    clauses = 0
    for name, contract in contracts.items():
        for kind, clause, checked in _clauses(contract):
            if kind == "guarantee" and variables(clause) & unobserved:
                continue
            clauses += 1
            holds = np.broadcast_to(evaluate(checked, columns, timeline), (traces.n_rows,))
            if holds.all():
                continue
            # the margin of the clause itself: how far it is from holding where it is violated
            margins = np.broadcast_to(margin(clause, columns, timeline), (traces.n_rows,))
            violated = ~holds & ~(margins >= -tolerance) if tolerance > 0 else ~holds
            if violated.any():
                found += _segments(traces, name, kind, clause, violated, margins)
    return MonitorReport(traces.source, traces.n_runs, traces.n_rows, clauses, tuple(found),
                         skipped)


def _clauses(contract: Contract):
    """(kind, clause, what is checked): assumption clauses as they are, guarantee clauses under
    the whole assumption."""
    for clause in conjuncts(contract.assumption):
        yield "assumption", clause, clause
    for clause in conjuncts(contract.guarantee):
        yield "guarantee", clause, implies(contract.assumption, clause)


def _columns(traces: TraceSet, contracts: Mapping[str, Contract],
             unobserved: frozenset[str] = frozenset()) -> dict[str, np.ndarray]:
    """The signals the checked clauses need (guarantee clauses over ``unobserved`` variables
    are not checked; an assumption over one is an error)."""
    needed: set[str] = set()
    for contract in contracts.values():
        for kind, clause, checked in _clauses(contract):
            if kind == "assumption" or not variables(clause) & unobserved:
                needed |= variables(checked)
    needed_sorted = sorted(needed)
    missing = [n for n in needed_sorted if n not in traces.signals and n != "t"]
    if missing:
        why = (" (declared observed: false, but a validity domain uses it)"
               if missing[0] in unobserved else "")
        raise SimcredError(f"{traces.source}: no signal '{missing[0]}' for the contracts' "
                           f"variable{why} (signals are: {', '.join(traces.signals)})")
    return {n: traces.column(n) for n in needed_sorted}


def _segments(traces: TraceSet, name: str, kind: str, clause: Expr, violated: np.ndarray,
              margins: np.ndarray) -> list[Violation]:
    """Maximal runs of consecutive violated steps within each run."""
    starts = np.zeros(traces.n_rows, dtype=bool)
    starts[traces.offsets[:-1]] = True
    edges = np.diff(violated.astype(np.int8), prepend=0)
    begin = np.flatnonzero(violated & ((edges == 1) | starts))
    ends_mask = violated & np.r_[~violated[1:] | starts[1:], True]
    end = np.flatnonzero(ends_mask)
    text, names = to_text(clause), tuple(sorted(variables(clause)))
    runs = np.searchsorted(traces.offsets, begin, side="right") - 1
    first = traces.offsets[runs]
    # minimum margin over each segment [lo, hi]: reduceat over the pairs (lo, hi + 1)
    bounds = np.column_stack([begin, end + 1]).ravel()
    worst = np.minimum.reduceat(np.append(margins, 0.0), bounds)[::2] if len(begin) else begin
    return [Violation(name, kind, text, names, traces.run_ids[r], int(lo - f), int(hi - f),
                      float(traces.time[lo]), float(traces.time[hi]), float(w))
            for r, f, lo, hi, w in zip(runs.tolist(), first.tolist(), begin.tolist(),
                                       end.tolist(), worst.tolist(), strict=True)]
