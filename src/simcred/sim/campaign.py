"""Seeded simulation campaigns: many runs, in chunks, in-process or on Dask.

A run's result depends only on the campaign seed, its run index and the parameters: run ``i``
draws from ``SeedSequence(seed, spawn_key=(i,))``. So the trace set is the same, bit for bit,
whether runs are simulated in one batch, in chunks, serially or on any number of Dask workers.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from simcred.engine import Engine, Progress, engine
from simcred.limits import check_count
from simcred.traces import TraceSet, concat

#: An experiment simulates the runs with the given indices; run i may use only
#: ``simcred.seeds.stream(seed, i)``.
Experiment = Callable[..., TraceSet]


def run_id(run: int) -> str:
    return f"run_{run:05d}"


@dataclass(frozen=True, slots=True)
class Campaign:
    """``runs`` runs of ``experiment(indices, seed, **params)``, split into chunks."""

    experiment: Experiment
    runs: int
    seed: int
    params: dict[str, Any] = field(default_factory=dict)
    chunk_size: int = 250

    def __post_init__(self) -> None:
        check_count(self.runs, "runs", "runs")
        check_count(self.chunk_size, "runs", "chunk size")

    @property
    def chunks(self) -> list[range]:
        return [range(lo, min(lo + self.chunk_size, self.runs))
                for lo in range(0, self.runs, self.chunk_size)]

    def simulate_chunk(self, indices: Sequence[int]) -> TraceSet:
        return self.experiment(indices, self.seed, **self.params)

    def run(self, *, workers: int | None = None, scheduler: str | None = None,
            runner: Engine | None = None, progress: Progress | None = None) -> TraceSet:
        """Simulate every chunk (in-process, on a local Dask cluster of ``workers`` processes, on
        the Dask ``scheduler`` at an address, or on a started ``runner``); join in run order."""
        if runner is None:
            with engine(workers, scheduler) as started:
                return self.run(runner=started, progress=progress)
        parts = runner.map(self.simulate_chunk, self.chunks, progress=progress)
        name = getattr(self.experiment, "__module__", "experiment").rsplit(".", 1)[-1]
        return concat(parts, metadata={**parts[0].metadata, "runs": self.runs, "seed": self.seed},
                      source=f"simcred:{name}")

