"""Acceptance: on a universe with a known validity domain the verdict keeps its error rates.

The candidate equals the reference below v = 20 m/s and changes the AR(1) coefficient by 0.15
above it (simcred.validate.synthetic): a response deviation of 1.06-1.17 /s there, twice the
tolerance 0.5. Over 20 seeds (5 cells each, the test case all of them, K = 5):

* no cell above 20 m/s is declared valid (its deviation is far beyond the tolerance);
* cells below 20 m/s (deviation 0) are declared not valid at most at the family level: each at
  alpha / K = 0.01, so 60 cells give 0.6 expected; 4 or more has probability 0.003 under
  Binomial(60, 0.01) (cells are independent across seeds, dependent within one).

Unknown is never valid: with too little data every cell is unknown and the verdict inconclusive.
The family-wise rates over 200+ seeds are measured by examples/validate/power.py.
"""

from __future__ import annotations

import sys
from collections import Counter
from pathlib import Path

import pytest

from simcred.validate.loop import Inputs, validate
from simcred.validate.synthetic import universe, validation_spec

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "examples" / "validate"))
from power import verdict as power_verdict  # noqa: E402  (the power study's draw)

SEEDS = 20
EFFECT = 0.15


@pytest.mark.slow
def test_an_identical_candidate_is_not_valid_at_most_at_alpha_over_the_test_case():
    """Family-wise: a candidate with the reference's law (deviation 0 in all K = 5 cells) makes
    the whole test case NOT VALID in at most α = 0.05 of seeds; 6 or more of 40 has probability
    0.014 under Binomial(40, 0.05). A candidate beyond the tolerance everywhere (examples/
    validate/power.py ``beyond``) is never VALID."""
    verdicts = {name: Counter(power_verdict(name, seed, 100) for seed in range(40))
                for name in ("same", "beyond")}
    assert verdicts["same"]["not valid"] <= 5, verdicts
    assert verdicts["beyond"]["valid"] == 0, verdicts


@pytest.mark.slow
def test_the_verdict_keeps_its_error_rates_over_20_seeds():
    counts = Counter()
    for seed in range(SEEDS):
        reference = universe(100, 150, seed=1000 + seed)
        candidate = universe(100, 150, seed=2000 + seed, effect=EFFECT, v_switch=20, name="sim")
        result = validate(validation_spec(seed), Inputs(reference, {"sim": candidate}, ()))
        for cell in result.domains["sim"].cells:
            counts["above" if cell.index[0] >= 3 else "below", cell.status.value] += 1
        assert result.verdict != "valid"
    assert counts["above", "valid"] == 0  # no false validation
    assert counts["above", "not valid"] >= 2 * SEEDS - 4  # shown beyond the tolerance
    assert counts["below", "not valid"] <= 3  # family-wise false alarms
    assert sum(v for (side, _), v in counts.items() if side == "below") == 3 * SEEDS


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
