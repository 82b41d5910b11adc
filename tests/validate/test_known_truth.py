"""Known truth on car following (issue 22): a closed-loop IDM behind recorded OpenACC leaders,
its replay paired run by run (tests/validate_designs.py), tolerance 0.012 m/s² on the
acceleration response (the true deviation of a 0.15 s reaction delay). Small sizes and 25 seeds
here; the full study (200 seeds, 10-1,000 episodes, human halves) is
scripts/validate_known_truth.py, its tables in docs/validate.md.

* the same model: NOT VALID at most at the family level (each draw at most α = 0.05 over the two
  cells: ≥ 5 of 25 has probability 0.007 under Binomial(25, 0.05));
* a 1.0 s reaction delay and clipped acceleration: never VALID, at any size;
* at 40 episodes also the 0.3 and 0.5 s delays never VALID (the issue's own case: a 0.5 s delay
  was VALID in 11 of 20 draws with 40 episodes), and the truly valid real-data designs — two
  random halves of the human drivers (grouped by driver unit) and one real ACC car against
  itself split by recording file (grouped by file) — and one deterministic IDM behind leaders of
  two different halves of the recordings (unpaired: other scenarios, the same law) NOT VALID at
  most at the family level.
"""

from __future__ import annotations

import sys
from collections import Counter
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "scripts"))

from validate_known_truth import verdict  # noqa: E402

SEEDS = 25


@pytest.mark.slow
@pytest.mark.parametrize("episodes", [10, 40])
def test_known_truth_verdicts(episodes):
    same = Counter(verdict("none", episodes, seed).verdict for seed in range(SEEDS))
    assert same["not valid"] <= 4
    for defect in ("delay_1.0", "clip"):
        found = Counter(verdict(defect, episodes, seed).verdict for seed in range(SEEDS))
        assert found["valid"] == 0, (defect, found)


@pytest.mark.slow
def test_known_truth_at_40_episodes_delays_and_real_data():
    for defect in ("delay_0.3", "delay_0.5"):
        found = Counter(verdict(defect, 40, seed).verdict for seed in range(SEEDS))
        assert found["valid"] == 0, (defect, found)
    for same in ("humans", "acc_self", "leaders_split"):
        found = Counter(verdict(same, 40, seed).verdict for seed in range(SEEDS))
        assert found["not valid"] <= 4, (same, found)
