"""Limits: checked up front, the error says the limit and how to lift it."""

from __future__ import annotations

import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from simcred.errors import OptionError
from simcred.limits import LIMITS, check_count, check_finite


def test_count_limit_names_option_limit_and_variable(monkeypatch):
    assert check_count(5, "runs", "--runs") == 5
    with pytest.raises(OptionError, match=r"--runs = 1000001 exceeds the limit of 1000000 .*"
                                          r"SIMCRED_MAX_RUNS"):
        check_count(1_000_001, "runs", "--runs")
    with pytest.raises(OptionError, match="--runs must be at least 1, got 0"):
        check_count(0, "runs", "--runs")
    monkeypatch.setenv("SIMCRED_MAX_RUNS", "2000000")
    assert check_count(1_000_001, "runs", "--runs") == 1_000_001
    monkeypatch.setenv("SIMCRED_MAX_RUNS", "lots")
    with pytest.raises(OptionError, match="SIMCRED_MAX_RUNS='lots' must be a positive integer"):
        check_count(1, "runs", "--runs")


@pytest.mark.parametrize("name", sorted(LIMITS))
def test_every_limit_is_positive_and_named(name):
    limit = LIMITS[name]
    assert limit.value == limit.default > 0 and limit.variable == f"SIMCRED_MAX_{name.upper()}"


@given(st.floats(allow_nan=True, allow_infinity=True), st.floats(-10, 10), st.floats(-10, 10),
       st.booleans(), st.booleans())
def test_check_finite_accepts_exactly_the_interval(value, a, b, open_low, open_high):
    low, high = min(a, b), max(a, b)
    inside = (math.isfinite(value) and (value > low if open_low else value >= low)
              and (value < high if open_high else value <= high))
    if inside:
        assert check_finite(value, "--x", minimum=low, maximum=high, open_minimum=open_low,
                            open_maximum=open_high) == value
    else:
        with pytest.raises(OptionError, match="--x must be"):
            check_finite(value, "--x", minimum=low, maximum=high, open_minimum=open_low,
                         open_maximum=open_high)
