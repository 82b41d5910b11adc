"""The result of comparing two trace sets: a frozen record that serialises to JSON."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

import simcred._display as _display
from simcred._json import dumps, envelope
from simcred.compare.discretize import StateSpace
from simcred.compare.kernels import Kernel
from simcred.compare.mmd import Estimator, MMDTestResult, MMDTestSpec, Test
from simcred.compare.runs import ChainStatistic, Multiplicity, OneSided, RunTestSpec
from simcred.compare.tables import states_frame


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
    multiplicity: str = "none"
    chain: str = "sum"
    one_sided: str = "evidence"
    history: int = 1
    time_bins: int | None = None
    resample: float | None = None
    baseline: int = 0
    bootstrap: int = 0
    inputs: tuple[str, ...] = ()
    pair_by: str | None = None
    group_by: str | None = None
    margin: tuple[tuple[str, float], ...] = ()

    @property
    def spec(self) -> MMDTestSpec:
        """The per-test settings, as the MMD module takes them."""
        return MMDTestSpec(Kernel(self.kernel), Estimator(self.estimator), Test(self.test),
                           self.alpha, self.permutations or 0, self.stop_early)

    def run_spec(self, permutations: int | None = None) -> RunTestSpec:
        """The run-level test's settings (``permutations``: fewer, for its companions)."""
        return RunTestSpec(Kernel(self.kernel), Estimator(self.estimator),
                           permutations or self.permutations, self.alpha,
                           Multiplicity(self.multiplicity), ChainStatistic(self.chain),
                           OneSided(self.one_sided))


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


@dataclass(frozen=True, slots=True)
class ChainVerdict:
    """One verdict for "A and B come from the same process" (run-level permutation test).

    ``statistic``: sum (or max) of the standardised per-state statistics, start distribution
    included; ``pvalue = (1 + #{T* ≥ T}) / (P + 1)``; ``states``: how many states entered.
    """

    test: str
    combine: str
    statistic: float
    pvalue: float
    rejected: bool
    permutations: int
    states: int


@dataclass(frozen=True, slots=True)
class Baseline:
    """The distance when the reference set is split against itself (random halves of its runs).

    A check that A's runs are interchangeable: with FWER control each split gives distance 0 with
    probability ≥ 1 − α when they are, so ``nonzero`` (splits with distance > 0) should be about
    α · splits or fewer. A comparison's distance is read against it.
    """

    reference: str
    distances: tuple[float, ...]
    chain_pvalues: tuple[float, ...]

    @property
    def low(self) -> float:
        return float(min(self.distances))

    @property
    def high(self) -> float:
        return float(max(self.distances))

    @property
    def nonzero(self) -> int:
        return sum(d > 0 for d in self.distances)


@dataclass(frozen=True, slots=True)
class DistanceInterval:
    """Re-test spread of the distance: the test redone on run resamples (with replacement)
    within each set, percentile range of the distances.

    Not a confidence interval of a "true" distance: a resample duplicates runs, which makes the
    sets look more different than they are, so the range is biased upward (under H0 too).
    """

    level: float
    low: float
    high: float
    replicates: tuple[float, ...]


@dataclass(frozen=True, slots=True)
class FeatureRelevance:
    """Chain statistic on one feature alone and with that feature left out."""

    feature: str
    alone_pvalue: float
    alone_statistic: float
    without_pvalue: float | None
    without_statistic: float | None


@dataclass(frozen=True, slots=True, eq=False)
class Comparison:
    """Result of [1] sec. V-A for trace sets A and B.

    ``start`` tests the start distributions (requirement R1). If it rejects and the options do not
    say to continue, ``stopped`` is True, no transition is tested and ``distance`` is None.
    Otherwise ``states`` holds one successor test per start state seen in both sets (R2),
    ``untestable`` the states seen in only one (or with too few samples for the estimator), and
    ``distance = #rejected / |S|`` ([1] eq. (6)).

    Run-level test (issue 11): ``chain`` is the chain-level verdict, per-state results carry
    ``adjusted_pvalue``; ``baseline``, ``interval`` and ``relevance`` are set when asked for.
    ``units``: unit per (base) feature from the sets' metadata, "" where unknown.
    """

    options: ComparisonOptions
    inputs: tuple[InputInfo, InputInfo]
    space: StateSpace
    start: MMDTestResult
    stopped: bool
    states: tuple[StateTest, ...]
    untestable: tuple[UntestableState, ...]
    chain: ChainVerdict | None = None
    baseline: Baseline | None = None
    interval: DistanceInterval | None = None
    relevance: tuple[FeatureRelevance, ...] | None = None
    units: tuple[str, ...] = ()
    response: Any = None  # ResponseAnalysis of the conditional test (compare.conditional)

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
            **({"units": list(self.units)} if self.units else {}),
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
        if self.chain is not None:
            body = {**_chain_first(body, asdict(self.chain))}
        if self.baseline is not None:
            body["baseline"] = {**asdict(self.baseline), "low": self.baseline.low,
                                "high": self.baseline.high,
                                "nonzero_splits": self.baseline.nonzero}
        if self.interval is not None:
            body["distance_interval"] = asdict(self.interval)
        if self.relevance is not None:
            body["relevance"] = [asdict(r) for r in self.relevance]
        if self.response is not None:
            body = _after(body, "chain", "response", _without_replicates(asdict(self.response)))
        return envelope("comparison", body)

    def to_json(self) -> str:
        """Deterministic JSON: same inputs and seed give the same bytes."""
        return dumps(self.to_dict())

    def to_pandas(self):
        """The start states as a ``pandas.DataFrame`` (:func:`simcred.compare.tables.states_frame`:
        bins and value ranges per feature, status, m, n, statistic, p-values)."""
        return states_frame(self)

    def _repr_html_(self) -> str:
        """Notebook display: a summary table and a figure (:mod:`simcred.report.notebook`)."""
        return _display.html(self)

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


def _chain_first(body: dict[str, Any], chain: dict[str, Any]) -> dict[str, Any]:
    """The body with "chain" right after the options: the verdict a reader looks for first."""
    return _after(body, "options", "chain", chain)


def _after(body: dict[str, Any], anchor: str, key: str, value: Any) -> dict[str, Any]:
    """``body`` with ``key: value`` inserted right after ``anchor``."""
    out: dict[str, Any] = {}
    for name, item in body.items():
        out[name] = item
        if name == anchor:
            out[key] = value
    return out


def _test_dict(result: MMDTestResult) -> dict[str, Any]:
    out = {"m": result.m, "n": result.n, "statistic": result.statistic,
           "threshold": result.threshold, "pvalue": result.pvalue, "rejected": result.rejected,
           "bandwidth": result.bandwidth, "permutations_used": result.n_resamples}
    if result.adjusted_pvalue is not None:
        out["adjusted_pvalue"] = result.adjusted_pvalue
    return out


def _without_replicates(response: dict[str, Any]) -> dict[str, Any]:
    """The response analysis without the bootstrap replicates and the permutation null (kept
    in memory for bounds at other levels, not written)."""
    effect = response["effect"]
    features = [{k: v for k, v in f.items() if k not in ("replicates", "shift_replicates",
                                                          "null")}
                for f in effect["features"]]
    return {**response, "effect": {**effect, "features": features}}
