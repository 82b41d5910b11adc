"""Limits on values that drive work or memory, checked up front with an error that says how to
change them.

Each limit has a default and an environment variable that overrides it (a positive integer), so a
user on a large machine can lift it without touching the code::

    SIMCRED_MAX_RUNS=50000000 simcred simulate simplecar --runs 20000000 --out big.parquet
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

from simcred.errors import OptionError


@dataclass(frozen=True, slots=True)
class Limit:
    """An upper bound on a count, with the environment variable that overrides it."""

    name: str
    default: int
    what: str

    @property
    def variable(self) -> str:
        return f"SIMCRED_MAX_{self.name.upper()}"

    @property
    def value(self) -> int:
        raw = os.environ.get(self.variable)
        if raw is None:
            return self.default
        try:
            value = int(raw)
        except ValueError:
            raise OptionError(f"{self.variable}={raw!r} must be a positive integer") from None
        if value < 1:
            raise OptionError(f"{self.variable}={raw!r} must be a positive integer")
        return value


LIMITS = {limit.name: limit for limit in (
    Limit("runs", 1_000_000, "runs per campaign or trace set"),
    Limit("steps", 1_000_000, "steps per run"),
    Limit("rows", 100_000_000, "rows (runs × steps) of a trace set held in memory"),
    Limit("permutations", 1_000_000, "permutations or resamples of a test"),
    Limit("bins", 10_000, "bins per feature"),
    Limit("variations", 1_000_000, "variations of a scenario"),
    Limit("workers", 256, "Dask worker processes"),
    Limit("threads", 64, "threads of one comparison (at most the cores it may use)"),
    Limit("episodes", 1_000_000, "episodes of a study"),
    Limit("scene_values", 100_000_000, "values (frames × objects × signals) of a levelX scene "
          "run"),
)}


def check_count(value: int, limit: str, option: str, *, minimum: int = 1) -> int:
    """``value`` if ``minimum <= value <= limit``, else a one-line error naming ``option``."""
    bound = LIMITS[limit]
    if value < minimum:
        raise OptionError(f"{option} must be at least {minimum}, got {value}")
    if value > bound.value:
        raise OptionError(f"{option} = {value} exceeds the limit of {bound.value} {bound.what} "
                          f"(raise it with the environment variable {bound.variable})")
    return value


def check_finite(value: float, option: str, *, minimum: float | None = None,
                 maximum: float | None = None, open_minimum: bool = False,
                 open_maximum: bool = False) -> float:
    """Return ``value`` if finite and inside the (half-)open or closed range; else one line."""
    if not math.isfinite(value):
        raise OptionError(f"{option} must be a finite number, got {value}")
    low_ok = minimum is None or (value > minimum if open_minimum else value >= minimum)
    high_ok = maximum is None or (value < maximum if open_maximum else value <= maximum)
    if not (low_ok and high_ok):
        low = "" if minimum is None else f"{'(' if open_minimum else '['}{minimum:g}"
        high = "" if maximum is None else f"{maximum:g}{')' if open_maximum else ']'}"
        interval = f"{low or '(-inf'}, {high or 'inf)'}"
        raise OptionError(f"{option} must be in {interval}, got {value:g}")
    return value
