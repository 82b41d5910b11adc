"""What option checking needs to know about a trace set, without its rows.

A distance matrix on Dask reads every set on a worker; only these few numbers travel back to the
client, which checks the options against them (:func:`~simcred.compare.process.comparison_options`)
exactly as it would against the sets themselves.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from simcred.compare.resample import sample_period
from simcred.errors import TraceSetError
from simcred.traces import TraceSet


@dataclass(frozen=True, slots=True)
class SetFacts:
    """A trace set's source, signals, number of runs, units and median sample period."""

    source: str
    signals: tuple[str, ...]
    n_runs: int
    units: dict[str, str]
    period: float

    @classmethod
    def of(cls, traces: TraceSet) -> SetFacts:
        return cls(traces.source, tuple(traces.signals), traces.n_runs, dict(traces.units),
                   sample_period(traces))

    def check_signals(self, names: Sequence[str]) -> None:
        """The error :meth:`TraceSet.features` raises for the first unknown name, if any."""
        for name in names:
            if name not in self.signals:
                raise TraceSetError(f"{self.source}: unknown signal '{name}' (signals are: "
                                    f"{', '.join(self.signals)})")
