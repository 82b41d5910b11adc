"""The result of comparing two trace sets: a frozen record that serialises to JSON."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from simcred._json import dumps, envelope
from simcred.compare.discretize import StateSpace
from simcred.compare.kernels import Kernel
from simcred.compare.mmd import Estimator, MMDTestResult, MMDTestSpec, Test


@dataclass(frozen=True, slots=True)
class ComparisonOptions:
    features: tuple[str, ...]
    bins: tuple[int, ...]
    kernel: str
    estimator: str
    test: str
    alpha: float
    permutations: int | None
    seed: int
    continue_on_start_difference: bool
    stop_early: bool

    @property
    def spec(self) -> MMDTestSpec:
        """The per-test settings, as the MMD module takes them."""
        return MMDTestSpec(Kernel(self.kernel), Estimator(self.estimator), Test(self.test),
                           self.alpha, self.permutations or 0, self.stop_early)


@dataclass(frozen=True, slots=True)
class InputInfo:
    """What was compared: the source path and a content hash, so a result names its inputs."""

    source: str
    digest: str
    runs: int
    rows: int


@dataclass(frozen=True, slots=True)
class StateTest:
    """The successor-distribution test of one start state (its bin-index vector)."""

    state: tuple[int, ...]
    result: MMDTestResult


@dataclass(frozen=True, slots=True)
class UntestableState:
    """A start state with too few successor samples on one side: ``m`` in A, ``n`` in B."""

    state: tuple[int, ...]
    m: int
    n: int


@dataclass(frozen=True, slots=True, eq=False)
class Comparison:
    """Result of [1] sec. V-A for trace sets A and B.

    ``start`` tests the start distributions (requirement R1). If it rejects and the options do not
    say to continue, ``stopped`` is True, no transition is tested and ``distance`` is None.
    Otherwise ``states`` holds one successor test per start state seen in both sets (R2),
    ``untestable`` the states seen in only one (or with too few samples for the estimator), and
    ``distance = #rejected / |S|`` ([1] eq. (6)).
    """

    options: ComparisonOptions
    inputs: tuple[InputInfo, InputInfo]
    space: StateSpace
    start: MMDTestResult
    stopped: bool
    states: tuple[StateTest, ...]
    untestable: tuple[UntestableState, ...]

    @property
    def n_states(self) -> int:
        return self.space.n_states

    @property
    def rejected_states(self) -> tuple[tuple[int, ...], ...]:
        return tuple(s.state for s in self.states if s.result.rejected)

    @property
    def distance(self) -> float | None:
        """Fraction of distinguishable transitions, [1] eq. (6); None if stopped at R1."""
        if self.stopped:
            return None
        return len(self.rejected_states) / self.n_states

    def to_dict(self) -> dict[str, Any]:
        body = {
            "inputs": [asdict(i) for i in self.inputs],
            "options": asdict(self.options),
            "features": list(self.space.features),
            "edges": [e.tolist() for e in self.space.edges],
            "bounds": [list(b) for b in self.space.bounds],
            "n_states": self.n_states,
            "start": _test_dict(self.start),
            "stopped": self.stopped,
            "states": [{"state": list(s.state), **_test_dict(s.result)} for s in self.states],
            "untestable": [list(u.state) for u in self.untestable],
            "untestable_samples": [[u.m, u.n] for u in self.untestable],
            "n_tested": len(self.states),
            "n_rejected": len(self.rejected_states),
            "distance": self.distance,
        }
        return envelope("comparison", body)

    def to_json(self) -> str:
        """Deterministic JSON: same inputs and seed give the same bytes."""
        return dumps(self.to_dict())

    def state_grid(self) -> dict[str, np.ndarray]:
        """Per-state arrays on the grid (shape = bins per feature), for maps and summaries.

        ``status``: 0 not a start state, 1 tested and not rejected, 2 rejected, 3 untestable.
        ``m``, ``n``: number of successor samples in A and B.
        """
        shape = self.space.shape
        status = np.zeros(shape, dtype=np.int8)
        m = np.zeros(shape, dtype=np.int64)
        n = np.zeros(shape, dtype=np.int64)
        for s in self.states:
            status[s.state] = 2 if s.result.rejected else 1
            m[s.state], n[s.state] = s.result.m, s.result.n
        for u in self.untestable:
            status[u.state] = 3
            m[u.state], n[u.state] = u.m, u.n
        return {"status": status, "m": m, "n": n}


def _test_dict(result: MMDTestResult) -> dict[str, Any]:
    return {"m": result.m, "n": result.n, "statistic": result.statistic,
            "threshold": result.threshold, "pvalue": result.pvalue, "rejected": result.rejected,
            "bandwidth": result.bandwidth, "permutations_used": result.n_resamples}
