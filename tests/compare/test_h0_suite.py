"""Size of the run-level test under H0 on data that breaks the per-transition assumptions.

Five seeded generators, each producing two sets of runs of one and the same process:

* ``traits`` — per-run hidden driver traits (Beta(2, 5)) shift each run's level and noise;
* ``selfloops`` — a smooth speed/acceleration process sampled at 0.1 s (mostly self-loops);
* ``fewruns`` — 20–50 runs per set (unequal), AR(1) with a milder per-run trait;
* ``secondorder`` — an AR(2) process observed through first-order states;
* ``timephase`` — accelerate / cruise / brake phases: the law depends on the time since start;
* ``lengths`` — one first-order Markov chain, 40 runs × 10 steps against 40 runs × 100 steps;
* ``lengthsvar`` — one AR(1) process, run lengths U{20..40} against U{30..50}.

The last two are outside the permutation test's exact H0 (runs are not exchangeable when their
lengths differ); they check that the size-scaled per-state statistic keeps the level anyway.

For each, ``TRIALS`` comparisons with ``PERMUTATIONS`` run permutations: the chain-level rejection
rate must lie in [0.5α, 1.5α] at α = 0.05 and be ≤ 2α at α = 0.01; with FWER control the
probability of a non-zero distance must be ≤ 1.5α at α = 0.05 (issue 11). The per-transition
permutation test on the same designs is measured by ``main()`` (docs/calibration.md), not asserted.
Run ``python tests/compare/test_h0_suite.py`` to print the table.
"""

from __future__ import annotations

import time

import numpy as np
import pytest

from compare_designs import PAIRS, traits
from simcred.compare import compare

TRIALS = 1000
PERMUTATIONS = 99
BINS = 4


def trial(pair, seed: int, test: str = "runs", **options):
    """One H0 comparison: (chain p-value or None, distance > 0 at α = 0.05)."""
    rng = np.random.default_rng(seed)
    a, b = pair(rng)
    result = compare(a, b, bins=BINS, test=test, alpha=0.05, permutations=PERMUTATIONS,
                     seed=seed, continue_on_start_difference=True, **options)
    chain = None if result.chain is None else result.chain.pvalue
    return chain, bool(result.distance)


def rates(name: str, trials: int = TRIALS, **options) -> dict[str, float]:
    seeds = np.random.SeedSequence(list(name.encode())).generate_state(trials)
    outcomes = [trial(PAIRS[name], int(s), **options) for s in seeds]
    chain = np.array([c for c, _ in outcomes], dtype=float)
    return {"chain@0.05": float(np.mean(chain <= 0.05)),
            "chain@0.01": float(np.mean(chain <= 0.01)),
            "distance>0": float(np.mean([d for _, d in outcomes]))}


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(PAIRS))
def test_run_level_test_holds_its_level(name):
    measured = rates(name)
    assert 0.025 <= measured["chain@0.05"] <= 0.075, measured
    assert measured["chain@0.01"] <= 0.02, measured
    assert measured["distance>0"] <= 0.075, measured  # FWER (default multiplicity) at α = 0.05


def test_generators_break_the_per_transition_assumptions():
    """Sanity check that the designs matter: the per-transition permutation test, which treats
    transitions as independent, rejects far more often than its level on the trait design."""
    rejected = [trial(lambda rng: (traits(rng), traits(rng)), seed, test="permutation",
                      multiplicity="none")[1] for seed in range(20)]
    assert np.mean(rejected) > 0.5  # measured 1.0 (distance > 0 in every same-model pair)


def main() -> None:
    print(f"H0 suite: {TRIALS} comparisons per design, {PERMUTATIONS} permutations, "
          f"{BINS} bins per feature")
    print("| design | chain rejection α=0.05 | chain rejection α=0.01 | P(distance>0), fwer, "
          "α=0.05 | per-transition permutation: P(distance>0), α=0.05 |")
    print("|---|---|---|---|---|")
    for name in PAIRS:
        r = rates(name)
        per = rates(name, trials=200, test="permutation", multiplicity="none")
        print(f"| {name} | {r['chain@0.05']:.3f} | {r['chain@0.01']:.3f} | "
              f"{r['distance>0']:.3f} | {per['distance>0']:.3f} |")


if __name__ == "__main__":
    started = time.perf_counter()
    main()
    print(f"({time.perf_counter() - started:.0f} s)")
