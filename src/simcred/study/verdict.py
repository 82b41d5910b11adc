"""One verdict per comparison: which two-sample test decides, and how its p-value is formed.

Two tests, switched by one option (``test``):

* ``"runs"`` (run-level, calibrated; the default): :func:`simcred.compare.compare` with
  ``test="runs"`` reassigns whole runs (episodes) between the sets, so the null distribution holds
  whatever the dependence within a run (successive transitions, a driver's preferred gap). The
  comparison carries the chain-level verdict itself (``result.chain``: Pesarin's sum of
  standardised state statistics, start distribution included); the cell takes its p-value and
  decision from there. Per-state verdicts are max-T family-wise controlled (``multiplicity=
  "fwer"``), so the distance (rejected states / |S|) is calibrated: under H0 it is > 0 with
  probability at most alpha.
* ``"permutation"`` (interim, per-transition; kept to compare with earlier results):
  :func:`simcred.compare.compare` with the permutation test gives one p-value per start state
  tested (successor samples exchangeable *within* the state). The chain-level p-value is Fisher's
  combination over the ``k`` tested states, ``P(χ²_{2k} ≥ −2 Σ_s ln p_s)``. Under the
  per-transition null (successors independent given the start state) the states' samples are
  disjoint and their permutation streams independent, so the p-values are independent; permutation
  p-values are valid (super-uniform), which keeps Fisher's test at or below its level. Bonferroni
  (``k · min p``) was the first choice and was dropped before any verdict was read: with B
  permutations no state p-value is below 1/(B + 1), so with ~100 states it cannot reject at 0.01
  even where half the states differ. Caveat: on real runs successive transitions of one run are
  dependent and runs carry per-run traits (a driver's preferred gap), which makes per-transition
  tests anti-conservative (docs/calibration.md). Results carry this method name and caveat; its
  distance is the paper's (states with p <= alpha, no multiplicity control).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from scipy.stats import chi2

from simcred.compare.result import Comparison
from simcred.errors import OptionError

TESTS = ("runs", "permutation")
METHODS = {
    "permutation": "per-transition permutation test per state, Fisher's combination over "
                   "tested states (interim; anti-conservative under within-run dependence)",
    "runs": "run-level permutation test (episodes reassigned between sets), chain-level "
            "p-value; per-state verdicts max-T FWER-controlled (calibrated distance)",
}


@dataclass(frozen=True, slots=True)
class CellVerdict:
    """The chain-level decision of one comparison.

    ``pvalue`` is None when nothing could be tested (no start state seen in both sets).
    ``rejected`` is True when ``pvalue <= alpha``. ``method`` says which test decided.
    """

    pvalue: float | None
    rejected: bool
    alpha: float
    method: str
    n_tested: int
    min_state_pvalue: float | None

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def check_test(test: str) -> str:
    """``test`` if the study knows it and :mod:`simcred.compare` offers it, else a one-line error
    before any simulation runs."""
    from simcred.compare.mmd import Test

    if test not in TESTS:
        raise OptionError(f"test must be one of {', '.join(TESTS)}; got {test!r}")
    if test not in {t.value for t in Test}:
        raise OptionError(f"test {test!r} is not offered by simcred.compare in this version "
                          f"(it has: {', '.join(t.value for t in Test)})")
    return test


def fisher(pvalues: list[float]) -> float | None:
    """Fisher's combined p-value ``P(χ²_{2k} ≥ −2 Σ ln p)``; None without p-values."""
    if not pvalues:
        return None
    statistic = -2.0 * float(np.sum(np.log(np.asarray(pvalues, dtype=np.float64))))
    return float(chi2.sf(statistic, 2 * len(pvalues)))


def chain_verdict(result: Comparison, test: str, alpha: float) -> CellVerdict:
    """The chain-level verdict of ``result`` under ``test`` (see the module doc)."""
    pvalues = [s.result.pvalue for s in result.states if s.result.pvalue is not None]
    smallest = min(pvalues) if pvalues else None
    if check_test(test) == "runs":
        if result.chain is None:
            raise OptionError("the run-level verdict needs a comparison made with test='runs'")
        pvalue, rejected = float(result.chain.pvalue), bool(result.chain.rejected)
    else:
        pvalue = fisher(pvalues)
        rejected = pvalue is not None and pvalue <= alpha
    return CellVerdict(pvalue=pvalue, rejected=rejected,
                        alpha=alpha, method=METHODS[test], n_tested=len(result.states),
                        min_state_pvalue=smallest)
