"""Acceptance: on a universe with a known validity domain the learned domain matches the truth.

The candidate equals the reference below v = 20 m/s and deviates above it by the declared effect
size (0.15 in the AR(1) coefficient; simcred.validate.synthetic). Over 20 seeds (5 cells each):

* no cell above 20 m/s is declared valid (measured: 0 of 40; power 40/40, docs/validate.md);
* cells below 20 m/s are declared not valid at about the level alpha = 0.05 of the chain test
  (measured 7 of 60); the bound 10 of 60 is exceeded with probability < 0.2 % under
  Binomial(60, 0.05).

The same run also shows that unknown is never valid: with too little data per cell, every cell
is unknown and no candidate is valid.
"""

from __future__ import annotations

from collections import Counter

import pytest

from simcred.validate.loop import Inputs, validate
from simcred.validate.synthetic import universe, validation_spec

SEEDS = 20
EFFECT = 0.15

@pytest.mark.slow
def test_learned_domain_matches_the_truth_over_20_seeds():
    counts = Counter()
    for seed in range(SEEDS):
        reference = universe(100, 150, seed=1000 + seed)
        candidate = universe(100, 150, seed=2000 + seed, effect=EFFECT, v_switch=20, name="sim")
        result = validate(validation_spec(seed), Inputs(reference, {"sim": candidate}, ()))
        for cell in result.domains["sim"].cells:
            counts["above" if cell.index[0] >= 3 else "below", cell.status.value] += 1
    assert counts["above", "valid"] == 0  # no false validation
    assert counts["above", "not valid"] == 2 * SEEDS  # power 1 at the declared effect
    assert counts["below", "not valid"] <= 10  # false alarms at about alpha
    assert counts["below", "valid"] + counts["below", "not valid"] == 3 * SEEDS


def test_unknown_is_never_valid():
    reference = universe(100, 150, seed=1)
    candidate = universe(100, 150, seed=2, name="sim")  # the same process: truly valid
    spec = validation_spec(0, min_runs=10_000)
    result = validate(spec, Inputs(reference, {"sim": candidate}, ()))
    assert {c.status.value for c in result.domains["sim"].cells} == {"unknown"}
    assert result.verdict == "inconclusive" and result.exit_code == 3


def test_the_binomial_tail_quoted_in_the_docs():
    """Issue 22: docs/validate.md gave P(X ≥ 7 | 60, 0.05) ≈ 0.12; it is 0.030."""
    import re
    from pathlib import Path

    from scipy.stats import binom

    text = (Path(__file__).resolve().parents[2] / "docs" / "validate.md").read_text()
    quoted = re.findall(r"P\(X ≥ (\d+) \| n = (\d+), p = ([\d.]+)\) [=≈] ([\d.]+)", text)
    assert quoted
    for k, n, p, value in quoted:
        assert round(binom.sf(int(k) - 1, int(n), float(p)), 3) == float(value)
